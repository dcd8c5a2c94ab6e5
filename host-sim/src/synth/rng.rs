//! The one pseudo-random generator of the synthetic sequence: SplitMix64, keyed by stream.
//!
//! Every random quantity (noise, holes, shake phases, poster layout) comes from a [`SplitMix64`]
//! whose state is derived from the user's seed and a stream key (frame index, pixel index, purpose).
//! Keying by position instead of drawing from one shared sequence makes the output independent of
//! the order in which rows are rendered, hence of the thread count.

/// SplitMix64 (Steele, Lea, Flood 2014): a 64-bit counter passed through a bijective mixer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SplitMix64 {
    state: u64,
}

/// The golden-ratio increment of SplitMix64.
const GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

/// SplitMix64's output mixer (a bijection of `u64`).
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl SplitMix64 {
    /// A generator started at `seed`.
    pub fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    /// A generator for the stream `(seed, a, b)`: distinct keys give unrelated sequences.
    pub fn keyed(seed: u64, a: u64, b: u64) -> Self {
        let k = mix64(seed ^ GAMMA);
        let k = mix64(k ^ a.wrapping_mul(0xD6E8_FEB8_6659_FD93));
        Self { state: mix64(k ^ b.wrapping_mul(0xA076_1D64_78BD_642F)) }
    }

    /// The next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GAMMA);
        mix64(self.state)
    }

    /// Uniform in `[0, 1)` with 53 random bits.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        // 2^-53: exact in f64.
        (self.next_u64() >> 11) as f64 * (1.0 / 9_007_199_254_740_992.0)
    }

    /// Uniform in `[lo, hi)`.
    #[inline]
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }

    /// A standard normal sample (Box-Muller through libm, so the bits do not depend on the
    /// platform's math library).
    pub fn gaussian(&mut self) -> f64 {
        // 1 - u is in (0, 1], so the logarithm is finite.
        let u1 = 1.0 - self.next_f64();
        let u2 = self.next_f64();
        libm::sqrt(-2.0 * libm::log(u1)) * libm::cos(core::f64::consts::TAU * u2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_first_output() {
        // Reference value of SplitMix64 seeded with 0 (from the published reference code).
        let mut r = SplitMix64::new(0);
        assert_eq!(r.next_u64(), 0xE220_A839_7B1D_CDAF);
    }

    #[test]
    fn keyed_streams_differ_and_repeat() {
        let a = SplitMix64::keyed(7, 1, 2).next_u64();
        assert_eq!(a, SplitMix64::keyed(7, 1, 2).next_u64());
        assert_ne!(a, SplitMix64::keyed(7, 2, 1).next_u64());
        assert_ne!(a, SplitMix64::keyed(8, 1, 2).next_u64());
    }

    #[test]
    fn gaussian_moments() {
        let mut r = SplitMix64::new(42);
        let n = 100_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let g = r.gaussian();
            s += g;
            s2 += g * g;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!(mean.abs() < 0.02, "mean {mean}");
        assert!((var - 1.0).abs() < 0.03, "var {var}");
    }
}
