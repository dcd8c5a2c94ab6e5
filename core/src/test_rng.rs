//! The one deterministic random generator of core's tests: [`TestRng`]. Its default stream is
//! xorshift64* (Vigna 2016), the algorithm of the product's RANSAC generator `pose::TrackingRng`
//! (the same `next_u32` stream for a seed); an xorshift32 stream serves the tests tuned on it.
//!
//! Test code only: compiled under `#[cfg(test)]` into the library's unit tests, and included
//! with `#[path]` by `tests/support/ba_synth.rs` (the integration tests and the benchmark cannot
//! see the library's test items; its own tests run there too). So this file names nothing of the
//! crate. Transcendental functions go through `libm`, so the samples are the same bits on every
//! host.

/// A tiny deterministic generator: xorshift64* by default ([`Self::new`]), or xorshift32
/// ([`Self::xorshift32`]) for the tests whose scenes were tuned on that stream. Every sampler
/// draws from [`Self::next_u32`] or [`Self::next_u64`], whichever the stream.
#[derive(Debug, Clone)]
pub struct TestRng(Stream);

#[derive(Debug, Clone)]
enum Stream {
    /// xorshift64* (Vigna 2016): the state, never zero.
    XorShift64Star(u64),
    /// xorshift32 (Marsaglia 2003): the state, never zero.
    XorShift32(u32),
}

impl TestRng {
    /// An xorshift64* generator from `seed`; zero (a fixed point of xorshift) is mapped to a
    /// constant.
    pub fn new(seed: u64) -> Self {
        Self(Stream::XorShift64Star(if seed == 0 { 0x9E37_79B9_7F4A_7C15 } else { seed }))
    }

    /// An xorshift32 generator from `seed` (zero is mapped to a constant). Kept for the matching
    /// tests, whose synthetic textures were tuned on this stream: on another one some of their
    /// known answers no longer hold.
    pub fn xorshift32(seed: u32) -> Self {
        Self(Stream::XorShift32(if seed == 0 { 0x9E37_79B9 } else { seed }))
    }

    /// The next 64 random bits (two outputs, high then low, from xorshift32).
    pub fn next_u64(&mut self) -> u64 {
        match &mut self.0 {
            Stream::XorShift64Star(x) => {
                *x ^= *x >> 12;
                *x ^= *x << 25;
                *x ^= *x >> 27;
                x.wrapping_mul(0x2545_F491_4F6C_DD1D)
            }
            Stream::XorShift32(_) => {
                (u64::from(self.next_u32()) << 32) | u64::from(self.next_u32())
            }
        }
    }

    /// The next 32 random bits: the high half of the xorshift64* output, or one xorshift32
    /// output.
    pub fn next_u32(&mut self) -> u32 {
        match &mut self.0 {
            Stream::XorShift64Star(_) => (self.next_u64() >> 32) as u32,
            Stream::XorShift32(x) => {
                *x ^= *x << 13;
                *x ^= *x >> 17;
                *x ^= *x << 5;
                *x
            }
        }
    }

    /// Uniform in `[0, 1)`, 53 random bits.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[lo, hi)`.
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// A standard normal sample (Box-Muller, one of the pair).
    pub fn normal(&mut self) -> f64 {
        let u1 = self.unit().max(1e-300);
        let u2 = self.unit();
        libm::sqrt(-2.0 * libm::log(u1)) * libm::cos(2.0 * core::f64::consts::PI * u2)
    }

    /// Uniform in `[0, 1)` in f32, 24 random bits of [`Self::next_u32`].
    pub fn unit_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 / (1u32 << 24) as f32
    }

    /// Uniform in `[lo, hi)` in f32.
    pub fn uniform_f32(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit_f32()
    }

    /// A standard normal sample in f32 (Box-Muller, one of the pair).
    pub fn normal_f32(&mut self) -> f32 {
        let u1 = self.unit_f32().max(1e-7);
        let u2 = self.unit_f32();
        libm::sqrtf(-2.0 * libm::logf(u1)) * libm::cosf(2.0 * core::f32::consts::PI * u2)
    }
}

#[cfg(test)]
mod tests {
    use super::TestRng;

    /// The stream is pinned: test scenes and images are made from it.
    #[test]
    fn the_stream_is_xorshift64_star() {
        let mut rng = TestRng::new(1);
        assert_eq!(rng.next_u64(), 0x47E4_CE4B_896C_DD1D);
        assert_eq!(rng.next_u32(), 0xABCF_A6A8);
        let (mut a, mut b) = (TestRng::new(0), TestRng::new(0x9E37_79B9_7F4A_7C15));
        assert_eq!(a.next_u64(), b.next_u64(), "seed 0 is mapped to a constant");
        let mut rng = TestRng::xorshift32(1);
        assert_eq!([rng.next_u32(), rng.next_u32()], [270_369, 67_634_689]);
        assert_eq!(TestRng::xorshift32(1).next_u64(), (270_369 << 32) | 67_634_689);
    }

    #[test]
    fn samples_lie_in_their_ranges_with_the_right_moments() {
        for rng in [TestRng::new(7), TestRng::xorshift32(7)] {
            check_samples(rng);
        }
    }

    fn check_samples(mut rng: TestRng) {
        let n = 20_000;
        let (mut sum, mut sum_sq, mut sum32, mut sum_sq32) = (0.0, 0.0, 0.0f64, 0.0f64);
        for _ in 0..n {
            let (u, v) = (rng.uniform(-2.0, 3.0), rng.uniform_f32(-2.0, 3.0));
            assert!((-2.0..3.0).contains(&u) && (-2.0..3.0).contains(&v));
            assert!((0.0..1.0).contains(&rng.unit()) && (0.0..1.0).contains(&rng.unit_f32()));
            let (g, g32) = (rng.normal(), f64::from(rng.normal_f32()));
            (sum, sum_sq, sum32, sum_sq32) =
                (sum + g, sum_sq + g * g, sum32 + g32, sum_sq32 + g32 * g32);
        }
        let n = f64::from(n);
        // Standard errors: 0.007 for the mean, 0.01 for the variance.
        for (mean, var) in [(sum / n, sum_sq / n), (sum32 / n, sum_sq32 / n)] {
            assert!(mean.abs() < 0.03 && (var - 1.0).abs() < 0.05, "{mean} {var}");
        }
    }
}
