//! Lattice value noise, the building block of the procedural textures: an integer hash of a
//! lattice cell, smooth interpolation between the corners, fractal sums of octaves, and a cache of
//! recently used cells that saves the hashing without changing a bit.

/// Lattice multipliers of [`hash2`].
const HASH_I: u32 = 0x8DA6_B343;
const HASH_J: u32 = 0xD816_3841;
const HASH_SALT: u32 = 0xCB1A_B31F;

/// The murmur3-style finalizer of [`hash2`].
#[inline]
fn finalize(mut h: u32) -> u32 {
    h ^= h >> 16;
    h = h.wrapping_mul(0x7FEB_352D);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846C_A68B);
    h ^ (h >> 16)
}

/// A 32-bit integer hash of a lattice cell and a salt.
#[inline]
pub(crate) fn hash2(i: i32, j: i32, salt: u32) -> u32 {
    finalize(
        (i as u32).wrapping_mul(HASH_I)
            ^ (j as u32).wrapping_mul(HASH_J)
            ^ salt.wrapping_mul(HASH_SALT),
    )
}

/// A hash as a number in `[0, 1)`.
#[inline]
pub(crate) fn unit(h: u32) -> f64 {
    f64::from(h) * (1.0 / 4_294_967_296.0)
}

/// `1.5 * 2^52`: for `|x| < 2^51`, `x + ROUNDING_BIAS` is `x` rounded to the nearest integer
/// (the sum's unit in the last place is 1), held in the low bits of the sum's mantissa.
const ROUNDING_BIAS: f64 = 6_755_399_441_055_744.0;

/// `floor(x)` as a float and as a lattice index, exact for `|x| < 2^31` (texture coordinates are
/// a few metres times at most a few hundred). Two additions and a compare: the baseline x86-64
/// `floor` is a library call, and a saturating float-to-integer conversion costs several
/// instructions more.
#[inline]
pub(crate) fn floor_cell(x: f64) -> (f64, i32) {
    let biased = x + ROUNDING_BIAS;
    let nearest = biased - ROUNDING_BIAS;
    // The low 32 bits of the mantissa are the nearest integer in two's complement.
    let index = biased.to_bits() as u32 as i32;
    if nearest > x { (nearest - 1.0, index.wrapping_sub(1)) } else { (nearest, index) }
}

/// `floor(x)`, exact for `|x| < 2^31` (see [`floor_cell`]).
#[inline]
pub(crate) fn floor(x: f64) -> f64 {
    floor_cell(x).0
}

/// `floor(x)` as a lattice index, for `|x| < 2^31` (see [`floor_cell`]).
#[inline]
pub(crate) fn cell(x: f64) -> i32 {
    floor_cell(x).1
}

/// The values of the four corners `(i, j)`, `(i + 1, j)`, `(i, j + 1)`, `(i + 1, j + 1)` of a
/// lattice cell: `unit(hash2(corner, salt))`, sharing the lattice products
/// (`(i + 1) A = i A + A`, wrapping). `hi`, `hj`, `hs` are `i`, `j` and `salt` times their
/// multipliers.
#[inline]
fn cell_corners(hi: u32, hj: u32, hs: u32) -> [f64; 4] {
    let (hi1, hj1) = (hi.wrapping_add(HASH_I), hj.wrapping_add(HASH_J));
    [hi ^ hj, hi1 ^ hj, hi ^ hj1, hi1 ^ hj1].map(|h| unit(finalize(h ^ hs)))
}

/// Entries of a [`NoiseCache`] (a power of two).
const NOISE_CACHE_CELLS: usize = 128;

/// A lattice cell of one noise layer: `(i, j)` and the salt.
type CellKey = (i32, i32, u32);

/// One entry of a [`NoiseCache`]: a cell and the values of its four corners.
#[derive(Debug, Clone, Copy)]
struct CachedCell {
    key: CellKey,
    corners: [f64; 4],
}

/// The corner values of recently used value-noise lattice cells, so that samples falling in one
/// cell (the supersamples of a pixel, its neighbours) hash its corners once. Direct-mapped on
/// `(i, j, salt)`; every entry holds the true corners of its key, so [`value_noise`] returns the
/// same bits with any cache contents. The caller owns it, one per thread (about 6 KB).
#[derive(Debug, Clone)]
pub(crate) struct NoiseCache {
    cells: Vec<CachedCell>,
}

impl NoiseCache {
    /// An empty cache (every entry holds cell `(0, 0)` of salt 0, computed).
    pub(crate) fn new() -> Self {
        let origin = CachedCell { key: (0, 0, 0), corners: cell_corners(0, 0, 0) };
        Self { cells: vec![origin; NOISE_CACHE_CELLS] }
    }

    /// The corners of cell `key`; `(hi, hj, hs)` are its lattice products (see [`cell_corners`]).
    #[inline]
    fn corners(&mut self, key: CellKey, (hi, hj, hs): (u32, u32, u32)) -> [f64; 4] {
        // The top bits of the first corner's hash input mix all three keys.
        let index = ((hi ^ hj ^ hs) >> (32 - NOISE_CACHE_CELLS.trailing_zeros())) as usize;
        match self.cells.get_mut(index) {
            Some(entry) if entry.key == key => entry.corners,
            entry => Self::miss(entry, key, (hi, hj, hs)),
        }
    }

    /// Hashes a cell's corners and stores them in `entry` (out of line: most lookups hit).
    #[cold]
    #[inline(never)]
    fn miss(
        entry: Option<&mut CachedCell>,
        key: CellKey,
        (hi, hj, hs): (u32, u32, u32),
    ) -> [f64; 4] {
        let corners = cell_corners(hi, hj, hs);
        if let Some(entry) = entry {
            *entry = CachedCell { key, corners };
        }
        corners
    }
}

impl Default for NoiseCache {
    fn default() -> Self {
        Self::new()
    }
}

/// Smooth value noise in `[0, 1]` with unit lattice spacing; `noise` only saves work. Kept out of
/// line: inlined into the render loop it is slower (docs/decisions.md, "The demo's renderer").
#[inline(never)]
pub(crate) fn value_noise(x: f64, y: f64, salt: u32, noise: &mut NoiseCache) -> f64 {
    let ((xf, i), (yf, j)) = (floor_cell(x), floor_cell(y));
    let (fx, fy) = (x - xf, y - yf);
    let sx = fx * fx * (3.0 - 2.0 * fx);
    let sy = fy * fy * (3.0 - 2.0 * fy);
    let products = (
        (i as u32).wrapping_mul(HASH_I),
        (j as u32).wrapping_mul(HASH_J),
        salt.wrapping_mul(HASH_SALT),
    );
    let [a, b, c, d] = noise.corners((i, j, salt), products);
    let top = a + (b - a) * sx;
    let bottom = c + (d - c) * sx;
    top + (bottom - top) * sy
}

/// Fractal sum of `octaves` value-noise layers, frequency doubling and amplitude halving each
/// layer; normalized to `[0, 1]`.
#[inline]
pub(crate) fn fbm(x: f64, y: f64, octaves: u32, salt: u32, noise: &mut NoiseCache) -> f64 {
    let (mut sum, mut norm, mut amp, mut freq) = (0.0, 0.0, 1.0, 1.0);
    for k in 0..octaves {
        // The offset keeps the lattices of successive octaves from lining up.
        let off = f64::from(k) * 17.31;
        sum += amp * value_noise(x * freq + off, y * freq - off, salt.wrapping_add(k), noise);
        norm += amp;
        amp *= 0.5;
        freq *= 2.0;
    }
    sum / norm
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The former `floor` (truncation, then one down) and saturating `as i32`, on the domain.
    #[test]
    fn floor_cell_matches_truncating_floor() {
        let reference = |x: f64| {
            let t = x as i64 as f64;
            let f = if t > x { t - 1.0 } else { t };
            (f, f as i32)
        };
        let mut rng = crate::synth::rng::SplitMix64::new(3);
        let mut xs = vec![0.0, -0.0, 0.5, -0.5, 1.5, -1.5, 2.5, -2.5, 1e9, -1e9, 2.1e9, -2.1e9];
        for k in -2000..2000 {
            let x = f64::from(k) * 0.25;
            xs.extend([x, x.next_up(), x.next_down()]);
        }
        xs.extend((0..100_000).map(|_| rng.uniform(-3000.0, 3000.0)));
        for x in xs {
            let (f, i) = floor_cell(x);
            let (rf, ri) = reference(x);
            assert_eq!((f.to_bits(), i), (rf.to_bits(), ri), "{x:e}");
        }
    }

    #[test]
    fn shared_products_match_hash2() {
        for (i, j) in [(0, 0), (-1, 5), (i32::MAX, 3), (-77, i32::MIN)] {
            let x = f64::from(i.clamp(-1000, 1000));
            let y = f64::from(j.clamp(-1000, 1000));
            // At a lattice point the noise is exactly the corner's hash.
            assert_eq!(
                value_noise(x, y, 9, &mut NoiseCache::new()),
                unit(hash2(x as i32, y as i32, 9))
            );
        }
    }

    #[test]
    fn noise_is_in_range_and_continuous() {
        let mut cache = NoiseCache::new();
        let mut prev = value_noise(0.0, 0.3, 1, &mut cache);
        for k in 1..2000 {
            let x = f64::from(k) * 0.001;
            let n = value_noise(x, 0.3, 1, &mut cache);
            assert!((0.0..=1.0).contains(&n));
            assert!((n - prev).abs() < 0.01, "jump at {x}");
            prev = n;
        }
        let f = fbm(-3.7, 12.2, 4, 9, &mut cache);
        assert!((0.0..=1.0).contains(&f));
    }

    /// The cache never changes a value: a long walk through cells and salts (with evictions)
    /// against a fresh cache for every sample.
    #[test]
    fn cached_noise_matches_fresh_cache() {
        let mut cache = NoiseCache::new();
        let mut rng = crate::synth::rng::SplitMix64::new(11);
        for k in 0..50_000u32 {
            let (x, y) = (rng.uniform(-40.0, 40.0), rng.uniform(-40.0, 40.0));
            let salt = k % 37;
            let cached = value_noise(x, y, salt, &mut cache);
            let fresh = value_noise(x, y, salt, &mut NoiseCache::new());
            assert_eq!(cached.to_bits(), fresh.to_bits());
        }
    }
}
