//! Procedural surface textures: value noise and the materials of the room.
//!
//! Every function maps surface coordinates `(u, v)` in metres (on the face's own plane, see
//! `scene`) to an albedo in `[0, 1]`. All of them are pure functions of their inputs, so a surface
//! point has the same albedo in every frame (brightness constancy under the Lambertian shading).

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

/// Smooth value noise in `[0, 1]` with unit lattice spacing.
#[inline]
pub(crate) fn value_noise(x: f64, y: f64, salt: u32) -> f64 {
    let ((xf, i), (yf, j)) = (floor_cell(x), floor_cell(y));
    let (fx, fy) = (x - xf, y - yf);
    let sx = fx * fx * (3.0 - 2.0 * fx);
    let sy = fy * fy * (3.0 - 2.0 * fy);
    // hash2 of the four corners, sharing the lattice products ((i + 1) A = i A + A, wrapping).
    let (hi, hj, hs) = (
        (i as u32).wrapping_mul(HASH_I),
        (j as u32).wrapping_mul(HASH_J),
        salt.wrapping_mul(HASH_SALT),
    );
    let (hi1, hj1) = (hi.wrapping_add(HASH_I), hj.wrapping_add(HASH_J));
    let a = unit(finalize(hi ^ hj ^ hs));
    let b = unit(finalize(hi1 ^ hj ^ hs));
    let c = unit(finalize(hi ^ hj1 ^ hs));
    let d = unit(finalize(hi1 ^ hj1 ^ hs));
    let top = a + (b - a) * sx;
    let bottom = c + (d - c) * sx;
    top + (bottom - top) * sy
}

/// Fractal sum of `octaves` value-noise layers, frequency doubling and amplitude halving each
/// layer; normalized to `[0, 1]`.
#[inline]
pub(crate) fn fbm(x: f64, y: f64, octaves: u32, salt: u32) -> f64 {
    let (mut sum, mut norm, mut amp, mut freq) = (0.0, 0.0, 1.0, 1.0);
    for k in 0..octaves {
        // The offset keeps the lattices of successive octaves from lining up.
        let off = f64::from(k) * 17.31;
        sum += amp * value_noise(x * freq + off, y * freq - off, salt.wrapping_add(k));
        norm += amp;
        amp *= 0.5;
        freq *= 2.0;
    }
    sum / norm
}

/// Fine grain: zero-mean noise with wavelengths of 5 and 2.5 cm.
#[inline]
fn grain(u: f64, v: f64, salt: u32) -> f64 {
    fbm(u * 20.0, v * 20.0, 2, salt ^ 0x5EED) - 0.5
}

/// Smooth periodic bands in `[0, 1]` with period 1 (a cheap stand-in for `0.5 + 0.5 sin`).
#[inline]
fn bands(x: f64) -> f64 {
    let tri = 1.0 - (2.0 * (x - floor(x)) - 1.0).abs();
    tri * tri * (3.0 - 2.0 * tri)
}

/// A surface material; the albedo pattern is a function of face coordinates in metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Material {
    /// Running-bond bricks (24 x 8 cm) with light mortar joints.
    Brick,
    /// Painted plaster with soft blotches at several scales.
    Plaster,
    /// Glazed 30 cm wall tiles with grout lines and marbling.
    WallTiles,
    /// Floor planks (15 cm wide, staggered joints) with wood grain.
    FloorPlanks,
    /// Suspended-ceiling panels (60 cm grid) with a dark frame.
    CeilingPanels,
    /// Crate slats (20 cm) with wood grain; `along_v` turns the slats vertical.
    Wood {
        /// Slats run along `v` instead of `u`.
        along_v: bool,
    },
    /// A checkerboard of `square_m` squares.
    Checker {
        /// Side of one square in metres.
        square_m: f64,
    },
    /// Dots of varying size on a grid (blobs at several scales).
    Dots,
}

impl Material {
    /// Albedo in `[0, 1]` at face coordinates `(u, v)` in metres; `salt` decorrelates faces.
    pub(crate) fn albedo(self, u: f64, v: f64, salt: u32) -> f64 {
        let a = match self {
            Self::Brick => brick(u, v, salt),
            Self::Plaster => plaster(u, v, salt),
            Self::WallTiles => wall_tiles(u, v, salt),
            Self::FloorPlanks => floor_planks(u, v, salt),
            Self::CeilingPanels => ceiling_panels(u, v, salt),
            Self::Wood { along_v } => {
                if along_v {
                    wood(v, u, salt)
                } else {
                    wood(u, v, salt)
                }
            }
            Self::Checker { square_m } => checker(u, v, square_m, salt),
            Self::Dots => dots(u, v, salt),
        };
        a.clamp(0.0, 1.0)
    }
}

fn brick(u: f64, v: f64, salt: u32) -> f64 {
    const W: f64 = 0.24;
    const H: f64 = 0.08;
    const MORTAR: f64 = 0.012;
    let row = cell(v / H);
    let shift = if row & 1 == 1 { 0.5 * W } else { 0.0 };
    let us = u + shift;
    let col = cell(us / W);
    let fu = us - f64::from(col) * W;
    let fv = v - f64::from(row) * H;
    let fine = grain(u, v, salt);
    if fu < MORTAR || fv < MORTAR {
        return 0.74 + 0.12 * fine;
    }
    let id = unit(hash2(col, row, salt));
    let blotch = value_noise(u * 9.0, v * 9.0, salt ^ 0xB1) - 0.5;
    0.26 + 0.26 * id + 0.16 * blotch + 0.14 * fine
}

fn plaster(u: f64, v: f64, salt: u32) -> f64 {
    let broad = fbm(u * 2.2, v * 2.2, 3, salt) - 0.5;
    0.64 + 0.4 * broad + 0.12 * grain(u, v, salt)
}

fn wall_tiles(u: f64, v: f64, salt: u32) -> f64 {
    const S: f64 = 0.3;
    const GROUT: f64 = 0.008;
    let (i, j) = (cell(u / S), cell(v / S));
    let fu = u - f64::from(i) * S;
    let fv = v - f64::from(j) * S;
    if fu < GROUT || fv < GROUT {
        return 0.3 + 0.05 * grain(u, v, salt);
    }
    let id = unit(hash2(i, j, salt));
    let vein = fbm(u * 5.0 + 3.0 * v, v * 5.0, 3, salt ^ 0x3C);
    // Thin dark veins where the fractal field crosses a level.
    let vein_line = (1.0 - 16.0 * (vein - 0.5).abs()).max(0.0);
    0.58 + 0.26 * id - 0.22 * vein_line + 0.05 * grain(u, v, salt)
}

fn floor_planks(u: f64, v: f64, salt: u32) -> f64 {
    const W: f64 = 0.15;
    const L: f64 = 1.1;
    const SEAM: f64 = 0.005;
    let row = cell(v / W);
    let shift = unit(hash2(row, 7, salt)) * L;
    let us = u + shift;
    let col = cell(us / L);
    let fu = us - f64::from(col) * L;
    let fv = v - f64::from(row) * W;
    if fu < SEAM || fv < SEAM {
        return 0.08;
    }
    let id = unit(hash2(col, row, salt ^ 0x51));
    let warp = value_noise(us * 1.3, fv * 10.0, salt ^ (row as u32));
    let bands = bands(fv * 22.0 + 3.0 * warp + id * 5.0);
    0.28 + 0.2 * id + 0.14 * bands + 0.08 * grain(u, v, salt)
}

fn ceiling_panels(u: f64, v: f64, salt: u32) -> f64 {
    const S: f64 = 0.6;
    const FRAME: f64 = 0.025;
    let fu = u - f64::from(cell(u / S)) * S;
    let fv = v - f64::from(cell(v / S)) * S;
    if fu < FRAME || fv < FRAME {
        return 0.38;
    }
    0.8 + 0.12 * (value_noise(u * 6.0, v * 6.0, salt) - 0.5) + 0.12 * grain(u, v, salt)
}

fn wood(along: f64, across: f64, salt: u32) -> f64 {
    const SLAT: f64 = 0.2;
    const GAP: f64 = 0.012;
    let slat = cell(across / SLAT);
    let f = across - f64::from(slat) * SLAT;
    if f < GAP {
        return 0.1;
    }
    let id = unit(hash2(slat, 3, salt));
    let warp = value_noise(along * 1.6, f * 8.0, salt ^ (slat as u32));
    let bands = bands(f * 30.0 + 4.0 * warp + 7.0 * id);
    // Knots: a few dark elliptical blobs per slat.
    let knot = value_noise(along * 3.0, f * 12.0, salt ^ 0x4B0);
    let knot_dark = ((knot - 0.72) * 5.0).clamp(0.0, 1.0);
    0.42 + 0.16 * id + 0.2 * bands - 0.3 * knot_dark + 0.06 * grain(along, across, salt)
}

fn checker(u: f64, v: f64, square_m: f64, salt: u32) -> f64 {
    let odd = (cell(u / square_m) + cell(v / square_m)) & 1 == 1;
    let base = if odd { 0.12 } else { 0.86 };
    base + 0.04 * grain(u, v, salt)
}

fn dots(u: f64, v: f64, salt: u32) -> f64 {
    const S: f64 = 0.09;
    let (i, j) = (cell(u / S), cell(v / S));
    let h = hash2(i, j, salt);
    // Centre jittered inside the cell; radius 0.6 to 3.6 cm, so blobs span several scales.
    let cu = (f64::from(i) + 0.3 + 0.4 * unit(h)) * S;
    let cv = (f64::from(j) + 0.3 + 0.4 * unit(h.rotate_left(11))) * S;
    let r = 0.006 + 0.03 * unit(h.rotate_left(22)) * unit(h.rotate_left(5));
    let (du, dv) = (u - cu, v - cv);
    let bg = 0.8 + 0.06 * grain(u, v, salt);
    if du * du + dv * dv < r * r { 0.1 + 0.25 * unit(h.rotate_left(17)) } else { bg }
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
            assert_eq!(value_noise(x, y, 9), unit(hash2(x as i32, y as i32, 9)));
        }
    }

    #[test]
    fn noise_is_in_range_and_continuous() {
        let mut prev = value_noise(0.0, 0.3, 1);
        for k in 1..2000 {
            let x = f64::from(k) * 0.001;
            let n = value_noise(x, 0.3, 1);
            assert!((0.0..=1.0).contains(&n));
            assert!((n - prev).abs() < 0.01, "jump at {x}");
            prev = n;
        }
        let f = fbm(-3.7, 12.2, 4, 9);
        assert!((0.0..=1.0).contains(&f));
    }

    #[test]
    fn materials_stay_in_unit_range_and_vary() {
        let materials = [
            Material::Brick,
            Material::Plaster,
            Material::WallTiles,
            Material::FloorPlanks,
            Material::CeilingPanels,
            Material::Wood { along_v: false },
            Material::Checker { square_m: 0.1 },
            Material::Dots,
        ];
        for m in materials {
            let (mut lo, mut hi) = (1.0f64, 0.0f64);
            for k in 0..4000 {
                let u = f64::from(k % 63) * 0.0173 - 0.4;
                let v = f64::from(k / 63) * 0.0191 - 0.3;
                let a = m.albedo(u, v, 5);
                assert!((0.0..=1.0).contains(&a));
                lo = lo.min(a);
                hi = hi.max(a);
            }
            assert!(hi - lo > 0.3, "{m:?} has too little contrast: {lo}..{hi}");
        }
    }
}
