//! Procedural surface textures: the materials of the room, built on value noise (`noise`).
//!
//! Every function maps surface coordinates `(u, v)` in metres (on the face's own plane, see
//! `scene`) to an albedo in `[0, 1]`. All of them are pure functions of their inputs (the
//! [`NoiseCache`] they take only saves work), so a surface point has the same albedo in every
//! frame (brightness constancy under the Lambertian shading).

use super::noise::{NoiseCache, cell, fbm, floor, hash2, unit, value_noise};

/// Fine grain: zero-mean noise with wavelengths of 5 and 2.5 cm.
#[inline]
fn grain(u: f64, v: f64, salt: u32, noise: &mut NoiseCache) -> f64 {
    fbm(u * 20.0, v * 20.0, 2, salt ^ 0x5EED, noise) - 0.5
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
    /// `noise` only saves work (any cache gives the same value).
    pub(crate) fn albedo(self, u: f64, v: f64, salt: u32, noise: &mut NoiseCache) -> f64 {
        let a = match self {
            Self::Brick => brick(u, v, salt, noise),
            Self::Plaster => plaster(u, v, salt, noise),
            Self::WallTiles => wall_tiles(u, v, salt, noise),
            Self::FloorPlanks => floor_planks(u, v, salt, noise),
            Self::CeilingPanels => ceiling_panels(u, v, salt, noise),
            Self::Wood { along_v } => {
                if along_v {
                    wood(v, u, salt, noise)
                } else {
                    wood(u, v, salt, noise)
                }
            }
            Self::Checker { square_m } => checker(u, v, square_m, salt, noise),
            Self::Dots => dots(u, v, salt, noise),
        };
        a.clamp(0.0, 1.0)
    }
}

fn brick(u: f64, v: f64, salt: u32, noise: &mut NoiseCache) -> f64 {
    const W: f64 = 0.24;
    const H: f64 = 0.08;
    const MORTAR: f64 = 0.012;
    let row = cell(v / H);
    let shift = if row & 1 == 1 { 0.5 * W } else { 0.0 };
    let us = u + shift;
    let col = cell(us / W);
    let fu = us - f64::from(col) * W;
    let fv = v - f64::from(row) * H;
    let fine = grain(u, v, salt, noise);
    if fu < MORTAR || fv < MORTAR {
        return 0.74 + 0.12 * fine;
    }
    let id = unit(hash2(col, row, salt));
    let blotch = value_noise(u * 9.0, v * 9.0, salt ^ 0xB1, noise) - 0.5;
    0.26 + 0.26 * id + 0.16 * blotch + 0.14 * fine
}

fn plaster(u: f64, v: f64, salt: u32, noise: &mut NoiseCache) -> f64 {
    let broad = fbm(u * 2.2, v * 2.2, 3, salt, noise) - 0.5;
    0.64 + 0.4 * broad + 0.12 * grain(u, v, salt, noise)
}

fn wall_tiles(u: f64, v: f64, salt: u32, noise: &mut NoiseCache) -> f64 {
    const S: f64 = 0.3;
    const GROUT: f64 = 0.008;
    let (i, j) = (cell(u / S), cell(v / S));
    let fu = u - f64::from(i) * S;
    let fv = v - f64::from(j) * S;
    if fu < GROUT || fv < GROUT {
        return 0.3 + 0.05 * grain(u, v, salt, noise);
    }
    let id = unit(hash2(i, j, salt));
    let vein = fbm(u * 5.0 + 3.0 * v, v * 5.0, 3, salt ^ 0x3C, noise);
    // Thin dark veins where the fractal field crosses a level.
    let vein_line = (1.0 - 16.0 * (vein - 0.5).abs()).max(0.0);
    0.58 + 0.26 * id - 0.22 * vein_line + 0.05 * grain(u, v, salt, noise)
}

fn floor_planks(u: f64, v: f64, salt: u32, noise: &mut NoiseCache) -> f64 {
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
    let warp = value_noise(us * 1.3, fv * 10.0, salt ^ (row as u32), noise);
    let bands = bands(fv * 22.0 + 3.0 * warp + id * 5.0);
    0.28 + 0.2 * id + 0.14 * bands + 0.08 * grain(u, v, salt, noise)
}

fn ceiling_panels(u: f64, v: f64, salt: u32, noise: &mut NoiseCache) -> f64 {
    const S: f64 = 0.6;
    const FRAME: f64 = 0.025;
    let fu = u - f64::from(cell(u / S)) * S;
    let fv = v - f64::from(cell(v / S)) * S;
    if fu < FRAME || fv < FRAME {
        return 0.38;
    }
    0.8 + 0.12 * (value_noise(u * 6.0, v * 6.0, salt, noise) - 0.5)
        + 0.12 * grain(u, v, salt, noise)
}

fn wood(along: f64, across: f64, salt: u32, noise: &mut NoiseCache) -> f64 {
    const SLAT: f64 = 0.2;
    const GAP: f64 = 0.012;
    let slat = cell(across / SLAT);
    let f = across - f64::from(slat) * SLAT;
    if f < GAP {
        return 0.1;
    }
    let id = unit(hash2(slat, 3, salt));
    let warp = value_noise(along * 1.6, f * 8.0, salt ^ (slat as u32), noise);
    let bands = bands(f * 30.0 + 4.0 * warp + 7.0 * id);
    // Knots: a few dark elliptical blobs per slat.
    let knot = value_noise(along * 3.0, f * 12.0, salt ^ 0x4B0, noise);
    let knot_dark = ((knot - 0.72) * 5.0).clamp(0.0, 1.0);
    0.42 + 0.16 * id + 0.2 * bands - 0.3 * knot_dark + 0.06 * grain(along, across, salt, noise)
}

fn checker(u: f64, v: f64, square_m: f64, salt: u32, noise: &mut NoiseCache) -> f64 {
    let odd = (cell(u / square_m) + cell(v / square_m)) & 1 == 1;
    let base = if odd { 0.12 } else { 0.86 };
    base + 0.04 * grain(u, v, salt, noise)
}

fn dots(u: f64, v: f64, salt: u32, noise: &mut NoiseCache) -> f64 {
    const S: f64 = 0.09;
    let (i, j) = (cell(u / S), cell(v / S));
    let h = hash2(i, j, salt);
    // Centre jittered inside the cell; radius 0.6 to 3.6 cm, so blobs span several scales.
    let cu = (f64::from(i) + 0.3 + 0.4 * unit(h)) * S;
    let cv = (f64::from(j) + 0.3 + 0.4 * unit(h.rotate_left(11))) * S;
    let r = 0.006 + 0.03 * unit(h.rotate_left(22)) * unit(h.rotate_left(5));
    let (du, dv) = (u - cu, v - cv);
    let bg = 0.8 + 0.06 * grain(u, v, salt, noise);
    if du * du + dv * dv < r * r { 0.1 + 0.25 * unit(h.rotate_left(17)) } else { bg }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let mut noise = NoiseCache::new();
        for m in materials {
            let (mut lo, mut hi) = (1.0f64, 0.0f64);
            for k in 0..4000 {
                let u = f64::from(k % 63) * 0.0173 - 0.4;
                let v = f64::from(k / 63) * 0.0191 - 0.3;
                let a = m.albedo(u, v, 5, &mut noise);
                assert!((0.0..=1.0).contains(&a));
                lo = lo.min(a);
                hi = hi.max(a);
            }
            assert!(hi - lo > 0.3, "{m:?} has too little contrast: {lo}..{hi}");
        }
    }
}
