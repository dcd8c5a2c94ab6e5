//! Posters pasted on faces of the room: geometric shapes, letter-like text, a calibration
//! checkerboard, a logo and a landscape print.
//!
//! A poster is a rectangle in a face's `(u, v)` coordinates (metres; see `scene`) with a thin dark
//! frame. Its content is drawn in poster coordinates `(x, y)`: metres from the lower-left corner,
//! `x` to the right, `y` up.

use super::face::FaceId;
use super::noise::{NoiseCache, fbm, floor, hash2};
use super::rng::SplitMix64;

/// Albedo of poster paper.
const PAPER: f64 = 0.92;
/// Albedo of ink.
const INK: f64 = 0.08;
/// Width of the dark frame around every poster, in metres.
const FRAME_M: f64 = 0.012;

/// One filled shape of a [`PosterKind::Shapes`] poster, in poster coordinates (metres).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Shape {
    /// A filled disc.
    Disc { cx: f64, cy: f64, r: f64, albedo: f64 },
    /// An axis-aligned filled rectangle.
    Rect { x0: f64, y0: f64, x1: f64, y1: f64, albedo: f64 },
    /// A filled triangle.
    Triangle { p: [[f64; 2]; 3], albedo: f64 },
}

impl Shape {
    fn albedo_at(&self, x: f64, y: f64) -> Option<f64> {
        match *self {
            Self::Disc { cx, cy, r, albedo } => {
                ((x - cx) * (x - cx) + (y - cy) * (y - cy) < r * r).then_some(albedo)
            }
            Self::Rect { x0, y0, x1, y1, albedo } => {
                (x >= x0 && x < x1 && y >= y0 && y < y1).then_some(albedo)
            }
            Self::Triangle { p, albedo } => {
                let edge = |a: [f64; 2], b: [f64; 2]| {
                    (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0])
                };
                let (e0, e1, e2) = (edge(p[0], p[1]), edge(p[1], p[2]), edge(p[2], p[0]));
                let inside =
                    (e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0) || (e0 <= 0.0 && e1 <= 0.0 && e2 <= 0.0);
                inside.then_some(albedo)
            }
        }
    }
}

/// What a poster shows.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum PosterKind {
    /// Random discs, rectangles and triangles of sizes from 1 to 12 cm on paper; later shapes
    /// cover earlier ones.
    Shapes(Vec<Shape>),
    /// Lines of letter-like glyphs (segment-display strokes) `glyph_h` metres high.
    Text { glyph_h: f64, salt: u32 },
    /// A calibration checkerboard of `square_m` squares with a white margin of one square.
    Checker { square_m: f64 },
    /// Concentric rings, a centre disc and four satellite dots.
    Logo,
    /// A landscape print: sky, sun, two mountain ridges.
    Landscape { salt: u32 },
}

/// A poster on a face.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Poster {
    /// The face the poster is pasted on.
    pub face: FaceId,
    /// Lower-left corner in the face's `(u, v)` coordinates, metres.
    pub origin: [f64; 2],
    /// `(width, height)` in metres.
    pub size: [f64; 2],
    /// Content.
    pub kind: PosterKind,
}

impl Poster {
    /// A poster of random shapes (`count` of them) drawn from `rng`.
    pub(crate) fn shapes(
        face: FaceId,
        origin: [f64; 2],
        size: [f64; 2],
        count: usize,
        rng: &mut SplitMix64,
    ) -> Self {
        let [w, h] = size;
        let shapes = (0..count)
            .map(|_| {
                let cx = rng.uniform(0.08 * w, 0.92 * w);
                let cy = rng.uniform(0.08 * h, 0.92 * h);
                // Log-uniform size between 1 and 12 cm.
                let r = 0.01 * libm::exp(rng.uniform(0.0, libm::log(12.0)));
                let albedo = rng.uniform(0.04, 0.6);
                match rng.next_u64() % 3 {
                    0 => Shape::Disc { cx, cy, r, albedo },
                    1 => {
                        let aspect = rng.uniform(0.5, 2.0);
                        Shape::Rect {
                            x0: cx - r * aspect,
                            y0: cy - r,
                            x1: cx + r * aspect,
                            y1: cy + r,
                            albedo,
                        }
                    }
                    _ => {
                        let a0 = rng.uniform(0.0, core::f64::consts::TAU);
                        let p = [0.0, 2.1, 4.2].map(|da: f64| {
                            [cx + 1.3 * r * libm::cos(a0 + da), cy + 1.3 * r * libm::sin(a0 + da)]
                        });
                        Shape::Triangle { p, albedo }
                    }
                }
            })
            .collect();
        Self { face, origin, size, kind: PosterKind::Shapes(shapes) }
    }

    /// Albedo at face coordinates `(u, v)`, or `None` outside the poster (`noise` only saves
    /// work).
    pub(crate) fn albedo(&self, u: f64, v: f64, noise: &mut NoiseCache) -> Option<f64> {
        let (x, y) = (u - self.origin[0], v - self.origin[1]);
        let [w, h] = self.size;
        if !(x >= 0.0 && x < w && y >= 0.0 && y < h) {
            return None;
        }
        if x < FRAME_M || y < FRAME_M || x > w - FRAME_M || y > h - FRAME_M {
            return Some(0.15);
        }
        Some(match &self.kind {
            PosterKind::Shapes(shapes) => {
                shapes.iter().rev().find_map(|s| s.albedo_at(x, y)).unwrap_or(PAPER)
            }
            PosterKind::Text { glyph_h, salt } => text(x, h - y, w, *glyph_h, *salt),
            PosterKind::Checker { square_m } => checkerboard(x, y, w, h, *square_m),
            PosterKind::Logo => logo(x - 0.5 * w, y - 0.5 * h, 0.45 * w.min(h)),
            PosterKind::Landscape { salt } => landscape(x / w, y / h, *salt, noise),
        })
    }
}

/// Text at `(x, down)`: `down` is measured from the poster's top edge.
fn text(x: f64, down: f64, w: f64, glyph_h: f64, salt: u32) -> f64 {
    let margin = 2.0 * glyph_h;
    let (x, down) = (x - margin, down - margin);
    if x < 0.0 || down < 0.0 || x > w - 2.0 * margin {
        return PAPER;
    }
    let line = floor(down / (1.7 * glyph_h));
    let gy = (down - line * 1.7 * glyph_h) / glyph_h;
    let glyph_w = 0.62 * glyph_h;
    let col = floor(x / (0.85 * glyph_h));
    let gx = (x - col * 0.85 * glyph_h) / glyph_w;
    if gy >= 1.0 || gx >= 1.0 {
        return PAPER;
    }
    let (line, col) = (line as i32, col as i32);
    // Ragged right edge and word gaps.
    let line_len = 8 + (hash2(line, -1, salt) % 24) as i32;
    let h = hash2(col, line, salt);
    if col >= line_len || h.is_multiple_of(6) {
        return PAPER;
    }
    if glyph_ink(gx, gy, h >> 3) { INK } else { PAPER }
}

/// Whether glyph cell point `(gx, gy)` in `[0, 1)^2` (gy down) is inked for the stroke set `bits`.
fn glyph_ink(gx: f64, gy: f64, bits: u32) -> bool {
    const T: f64 = 0.2;
    let mut mask = bits & 0x3FF;
    if mask.count_ones() < 3 {
        mask |= 0b00_0111_0001;
    }
    let strokes = [
        gy < T,
        (gy - 0.5).abs() < 0.5 * T,
        gy > 1.0 - T,
        gx < 1.2 * T && gy < 0.5,
        gx < 1.2 * T && gy >= 0.5,
        gx > 1.0 - 1.2 * T && gy < 0.5,
        gx > 1.0 - 1.2 * T && gy >= 0.5,
        (gx - 0.5).abs() < 0.6 * T,
        (gx - gy).abs() < 0.7 * T,
        (gx - (1.0 - gy)).abs() < 0.7 * T,
    ];
    strokes.iter().enumerate().any(|(k, &s)| s && mask & (1 << k) != 0)
}

fn checkerboard(x: f64, y: f64, w: f64, h: f64, s: f64) -> f64 {
    let (x, y) = (x - s, y - s);
    if x < 0.0 || y < 0.0 || x >= w - 2.0 * s || y >= h - 2.0 * s {
        return PAPER;
    }
    let odd = (floor(x / s) as i64 + floor(y / s) as i64) & 1 == 1;
    if odd { INK } else { PAPER }
}

/// A logo centred at the origin with outer radius `r` (metres).
fn logo(x: f64, y: f64, r: f64) -> f64 {
    let rho = libm::sqrt(x * x + y * y) / r;
    let ring = rho < 0.2 || (0.32..0.46).contains(&rho) || (0.6..0.68).contains(&rho);
    // A notch cut into the middle ring makes the logo rotation-asymmetric.
    let notch = (0.3..0.5).contains(&rho) && x > 0.0 && y.abs() < 0.06 * r;
    // Four satellite dots on the diagonals.
    let d = 0.86 * r * core::f64::consts::FRAC_1_SQRT_2;
    let sat = [(d, d), (-d, d), (d, -d), (-d, -d)]
        .iter()
        .any(|&(sx, sy)| (x - sx) * (x - sx) + (y - sy) * (y - sy) < 0.01 * r * r);
    if (ring && !notch) || sat { INK } else { PAPER }
}

/// A landscape at normalized poster coordinates `(s, t)` in `[0, 1)^2`.
fn landscape(s: f64, t: f64, salt: u32, noise: &mut NoiseCache) -> f64 {
    let far = 0.45 + 0.3 * fbm(s * 3.0, 0.5, 3, salt, noise);
    let near = 0.2 + 0.25 * fbm(s * 5.0, 7.5, 3, salt ^ 0x99, noise);
    if t < near {
        return 0.18 + 0.12 * fbm(s * 20.0, t * 20.0, 2, salt ^ 3, noise);
    }
    if t < far {
        return 0.4 + 0.12 * fbm(s * 12.0, t * 12.0, 2, salt ^ 5, noise);
    }
    let (ds, dt) = (s - 0.72, t - 0.8);
    if ds * ds + dt * dt < 0.008 {
        return 0.99;
    }
    // Sky brightening upwards, with soft clouds.
    0.62 + 0.25 * (t - far) + 0.16 * (fbm(s * 4.0, t * 9.0, 3, salt ^ 7, noise) - 0.5)
}

/// The posters of the demo room (fixed layout; the shapes come from a fixed seed).
pub(crate) fn demo_posters() -> Vec<Poster> {
    let mut rng = SplitMix64::new(0x005E_ED0F_F00D);
    let text = |face, origin, size, glyph_h, salt| Poster {
        face,
        origin,
        size,
        kind: PosterKind::Text { glyph_h, salt },
    };
    let north = FaceId::Room(3);
    let west = FaceId::Room(0);
    let east = FaceId::Room(1);
    let south = FaceId::Room(2);
    vec![
        Poster::shapes(north, [-2.5, 1.0], [1.1, 0.9], 28, &mut rng),
        text(north, [-1.1, 1.15], [0.9, 0.85], 0.035, 1),
        Poster {
            face: north,
            origin: [0.2, 1.0],
            size: [1.3, 0.9],
            kind: PosterKind::Landscape { salt: 2 },
        },
        Poster { face: north, origin: [1.9, 1.2], size: [0.6, 0.6], kind: PosterKind::Logo },
        Poster {
            face: west,
            origin: [-1.6, 0.8],
            size: [1.0, 0.8],
            kind: PosterKind::Checker { square_m: 0.1 },
        },
        Poster::shapes(west, [-0.2, 0.9], [1.2, 1.1], 35, &mut rng),
        text(west, [1.2, 1.3], [0.7, 0.5], 0.06, 3),
        text(east, [-1.5, 1.2], [1.0, 0.7], 0.025, 4),
        Poster {
            face: east,
            origin: [0.2, 0.9],
            size: [1.2, 0.9],
            kind: PosterKind::Landscape { salt: 5 },
        },
        Poster::shapes(east, [-3.0, 1.0], [0.9, 0.8], 22, &mut rng),
        Poster::shapes(south, [-0.6, 1.0], [1.2, 0.9], 30, &mut rng),
        // The cabinet (box 2): a logo on its east face, text on its south face.
        Poster {
            face: FaceId::Box { index: 2, face: 1 },
            origin: [-0.35, 1.1],
            size: [0.7, 0.7],
            kind: PosterKind::Logo,
        },
        text(FaceId::Box { index: 2, face: 2 }, [-0.3, 0.9], [0.6, 0.8], 0.03, 6),
        // The pillar (box 5): shapes on its south face.
        Poster::shapes(FaceId::Box { index: 5, face: 2 }, [-0.3, 0.5], [0.6, 0.8], 16, &mut rng),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poster_is_bounded_and_framed() {
        let p = Poster {
            face: FaceId::Room(0),
            origin: [1.0, 2.0],
            size: [0.5, 0.4],
            kind: PosterKind::Logo,
        };
        let mut noise = NoiseCache::new();
        assert_eq!(p.albedo(0.99, 2.1, &mut noise), None);
        assert_eq!(p.albedo(1.2, 2.41, &mut noise), None);
        assert_eq!(p.albedo(1.005, 2.2, &mut noise), Some(0.15));
        // Centre of the logo is the ink disc.
        assert_eq!(p.albedo(1.25, 2.2, &mut noise), Some(INK));
    }

    #[test]
    fn text_has_ink_and_paper() {
        let mut ink = 0;
        let n = 200 * 200;
        for k in 0..n {
            let x = f64::from(k % 200) * 0.004;
            let d = f64::from(k / 200) * 0.004;
            if text(x, d, 0.8, 0.03, 1) == INK {
                ink += 1;
            }
        }
        assert!(ink > n / 20 && ink < n / 2, "ink fraction {}", f64::from(ink) / f64::from(n));
    }
}
