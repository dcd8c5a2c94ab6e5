//! Rotation from small blurry images: when the motion model's prediction is too far off for the
//! guides' search (a fast turn, shake, the first frames after a restart), the inter-frame
//! rotation is estimated by aligning two tiny images of whole frames, as PTAM does (Klein and
//! Murray, "Improving the agility of keyframe-based SLAM", ECCV 2008).
//!
//! # Method
//!
//! Each frame is reduced to a [`SmallImage`]: the mean of `s x s` blocks (`s` = width / 80, so
//! 80 x 60 at QVGA) blurred by a 3x3 binomial kernel, plus a 40 x 30 level. Assuming pure rotation
//! (at 30 Hz the translation moves pixels far less than a fast turn does), the current image is
//! the previous one warped by the homography `K R K^-1`. [`estimate_rotation`] finds `R` (3 DOF)
//! with a photometric gain and offset (2 DOF) by Gauss-Newton with a Huber weight, coarse level
//! first, starting from the rotation the motion model predicts.
//!
//! # Cost and memory
//!
//! A [`SmallImage`] is 6,000 bytes. Building one reads every pixel once, four pixels a word at
//! QVGA: 0.35 M host instructions a frame (`cargo xtask bench-frontend`, 7-Scenes). An estimate
//! visits at most 1,200 + 4,800 pixels per iteration, each pixel ~60 flops, on the coarse level
//! until the step is small and on the fine level for at most two steps
//! ([`RotationParams::DEFAULT`], which says why no more); it is paid only when the guides fail,
//! and is then, after the final stages, the largest part of such a frame: about 2 M Cortex-M4
//! instructions (docs/decisions.md, "Small-image rotation: at most two fine steps" and
//! "Small-image rotation cost").

use nalgebra::{Matrix5, Point3, Rotation3, UnitQuaternion, Vector3, Vector5};

use crate::geometry::{PinholeCamera, hat, so3_exp};
use crate::image::GrayView;

/// Width of the fine level, pixels.
pub const SMALL_W: usize = 80;
/// Height of the fine level, pixels.
pub const SMALL_H: usize = 60;
/// How far [`estimate_rotation_with`] iterates Gauss-Newton on each level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotationParams {
    /// Iterations on the coarse level (40 x 30) at most.
    pub coarse_iterations: usize,
    /// Iterations on the fine level (80 x 60) at most, from the coarse level's solution.
    pub fine_iterations: usize,
    /// A level stops iterating when the rotation step is below this, radians.
    pub stop_step_rad: f32,
}

impl RotationParams {
    /// The front end's: the coarse level to a step of 1e-3 rad (0.06 degrees, a quarter of a QVGA
    /// pixel at a 262-pixel focal length), then at most two steps on the fine level.
    ///
    /// The estimate's error is set by its model (pure rotation, while the camera also translates),
    /// not by how far Gauss-Newton converges: against ground truth (`tests/tests/rotation_real.rs`)
    /// these settings are as close to the truth as [`Self::CONVERGED`], with fewer pixel visits.
    /// The guides that start from the estimate search 3 pixels, about 0.7 degrees at QVGA. Why:
    /// docs/decisions.md, "Small-image rotation: at most two fine steps".
    pub const DEFAULT: Self =
        Self { coarse_iterations: 12, fine_iterations: 2, stop_step_rad: 1.0e-3 };

    /// Both levels converged to a step of 1e-4 rad (at most 12 iterations each): the front end's
    /// settings until the measurement above.
    pub const CONVERGED: Self =
        Self { coarse_iterations: 12, fine_iterations: 12, stop_step_rad: 1.0e-4 };
}

const COARSE_W: usize = SMALL_W / 2;
/// Largest block size: images up to 640 x 480.
const MAX_BLOCK: usize = 8;
const COARSE_H: usize = SMALL_H / 2;
/// Huber threshold on the photometric residual, gray levels.
const HUBER_GRAY: f32 = 12.0;
/// Fewest pixels that must overlap for an estimate, as a fraction of the level's pixels.
const MIN_OVERLAP: f32 = 0.3;
/// The estimate is accepted when the final RMS residual is below this, gray levels.
const MAX_RMS_GRAY: f32 = 20.0;

/// A whole frame reduced to 80 x 60 (and 40 x 30), blurred.
#[derive(Debug, Clone)]
pub struct SmallImage {
    fine: [u8; SMALL_W * SMALL_H],
    coarse: [u8; COARSE_W * COARSE_H],
    /// Block size `s` of the fine level in source pixels (0: not built).
    block: usize,
}

impl Default for SmallImage {
    fn default() -> Self {
        Self::new()
    }
}

impl SmallImage {
    /// An empty small image (`const`, for `static` use).
    pub const fn new() -> Self {
        Self { fine: [0; SMALL_W * SMALL_H], coarse: [0; COARSE_W * COARSE_H], block: 0 }
    }

    /// Whether it holds a frame.
    pub fn is_built(&self) -> bool {
        self.block > 0
    }

    /// The blurred [`SMALL_W`] x [`SMALL_H`] level, row-major, when it holds a frame.
    pub fn fine(&self) -> Option<&[u8]> {
        self.is_built().then_some(&self.fine[..])
    }

    /// Reduces `img` (from 80 x 60 to 719 x 539; its size an exact multiple `s` of 80 x 60 is
    /// best: other sizes use the top-left `80 s x 60 s` pixels). Returns `false` (and holds no
    /// frame) for a size outside that range.
    pub fn build(&mut self, img: &GrayView<'_>) -> bool {
        let (w, h) = img.size();
        let s = (w / SMALL_W).min(h / SMALL_H);
        if s == 0 || s > MAX_BLOCK {
            self.block = 0;
            return false;
        }
        // The block means go straight into `fine` (means of 8-bit values fit a byte) and are
        // blurred there; the same for the coarse level: no image-sized scratch on the stack.
        let n = (s * s) as u32;
        let used = SMALL_W * s;
        for (by, out) in self.fine.chunks_exact_mut(SMALL_W).enumerate() {
            // Each image row's sums of `s` adjacent pixels, added over the block row's `s` rows
            // (at most 64 x 255: fits u16). Exact integers, so any order gives the same sums.
            let mut sums = [0u16; SMALL_W];
            for y in by * s..(by + 1) * s {
                let Some(row) = img.row(y).and_then(|r| r.get(..used)) else { continue };
                if s == 4 {
                    // The QVGA case, four pixels a word: pairs summed in 16-bit lanes, then the
                    // lanes (a third of the instructions of a pixel at a time on the Cortex-M4).
                    for (acc, quad) in sums.iter_mut().zip(row.chunks_exact(4)) {
                        let Ok(bytes) = <[u8; 4]>::try_from(quad) else { continue };
                        let w = u32::from_le_bytes(bytes);
                        let pairs = (w & 0x00FF_00FF) + ((w >> 8) & 0x00FF_00FF);
                        *acc += ((pairs & 0xFFFF) + (pairs >> 16)) as u16;
                    }
                } else {
                    for (acc, chunk) in sums.iter_mut().zip(row.chunks_exact(s)) {
                        *acc += chunk.iter().map(|&p| u16::from(p)).sum::<u16>();
                    }
                }
            }
            for (b, &sum) in out.iter_mut().zip(&sums) {
                // The rounded mean of 8-bit values: at most 255.
                *b = ((u32::from(sum) + n / 2) / n) as u8;
            }
        }
        blur_in_place(&mut self.fine, SMALL_W, SMALL_H);
        for (k, v) in self.coarse.iter_mut().enumerate() {
            let (x, y) = (2 * (k % COARSE_W), 2 * (k / COARSE_W));
            let at = |x: usize, y: usize| {
                u16::from(self.fine.get(y * SMALL_W + x).copied().unwrap_or(0))
            };
            // The rounded mean of four bytes: at most 255.
            *v = ((at(x, y) + at(x + 1, y) + at(x, y + 1) + at(x + 1, y + 1) + 2) / 4) as u8;
        }
        blur_in_place(&mut self.coarse, COARSE_W, COARSE_H);
        self.block = s;
        true
    }
}

/// 3x3 binomial blur (1 2 1 / 16 per axis) of `img` (`w` x `h`, both at least 2, `w` at most
/// [`SMALL_W`]) in place, edges clamped: each output row is made from the original rows above,
/// at and below it; the original rows above and at it, already overwritten or about to be, are
/// kept in two row buffers that swap roles as the rows go down.
fn blur_in_place(img: &mut [u8], w: usize, h: usize) {
    let (mut first_buffer, mut second_buffer) = ([0u8; SMALL_W], [0u8; SMALL_W]);
    let (Some(mut up), Some(mut mid)) = (first_buffer.get_mut(..w), second_buffer.get_mut(..w))
    else {
        return;
    };
    let Some(first) = img.get(..w) else { return };
    // Row -1 is row 0, clamped.
    up.copy_from_slice(first);
    mid.copy_from_slice(first);
    for y in 0..h {
        // The original row y + 1 (the last row clamped): rows below y are not yet overwritten.
        let down_start = (y + 1).min(h - 1) * w;
        let Some(down) = img.get(down_start..down_start + w) else { return };
        // Vertical pass into the row's column sums, then the horizontal pass.
        let mut col = [0u32; SMALL_W];
        for (((c, &a), &b), &d) in col.iter_mut().zip(&*up).zip(&*mid).zip(down) {
            *c = u32::from(a) + 2 * u32::from(b) + u32::from(d);
        }
        // The original row y becomes the row above, row y + 1 the row at the next output row.
        core::mem::swap(&mut up, &mut mid);
        mid.copy_from_slice(down);
        let Some(out) = img.get_mut(y * w..y * w + w) else { return };
        for (x, o) in out.iter_mut().enumerate() {
            let at = |i: usize| col.get(i).copied().unwrap_or(0);
            let acc = at(x.saturating_sub(1)) + 2 * at(x) + at((x + 1).min(w - 1));
            // At most 255 after the rounded division.
            *o = ((acc + 8) / 16) as u8;
        }
    }
}

/// One level of a small image with the camera scaled to it.
struct Level<'a> {
    data: &'a [u8],
    w: usize,
    h: usize,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
}

impl<'a> Level<'a> {
    /// Level `coarse` (or fine) of `img` for the source camera `cam`.
    fn of(img: &'a SmallImage, cam: &PinholeCamera, coarse: bool) -> Self {
        let (data, w, h, s): (&[u8], _, _, _) = if coarse {
            (&img.coarse, COARSE_W, COARSE_H, 2 * img.block)
        } else {
            (&img.fine, SMALL_W, SMALL_H, img.block)
        };
        // Block `i` covers source pixels `s i .. s i + s - 1`, centred at `s i + (s - 1) / 2`.
        let s = s as f32;
        let off = (s - 1.0) * 0.5;
        Self {
            data,
            w,
            h,
            fx: cam.fx() / s,
            fy: cam.fy() / s,
            cx: (cam.cx() - off) / s,
            cy: (cam.cy() - off) / s,
        }
    }

    fn at(&self, x: usize, y: usize) -> f32 {
        f32::from(self.data.get(y * self.w + x).copied().unwrap_or(0))
    }

    /// Bilinear value and gradient at `(u, v)`, when the 4x4 neighbourhood is inside.
    fn sample(&self, u: f32, v: f32) -> Option<(f32, f32, f32)> {
        // The level's size as constants (see `sample_in`); `of` makes no other sizes.
        match (self.w, self.h) {
            (SMALL_W, SMALL_H) => sample_in::<SMALL_W, SMALL_H>(self.data, u, v),
            (COARSE_W, COARSE_H) => sample_in::<COARSE_W, COARSE_H>(self.data, u, v),
            _ => None,
        }
    }
}

/// Bilinear value and gradient at `(u, v)` of the `W x H` image `data`, when the 4x4
/// neighbourhood is inside. The size is a constant so that the bounds are: one check for the
/// four rows read, the rows' offsets in the block checked at compile time, and the bounds of
/// `(u, v)` literals (with the size read at run time each row was checked on its own: about 30
/// Cortex-M4 instructions a pixel more).
#[inline(always)]
fn sample_in<const W: usize, const H: usize>(
    data: &[u8],
    u: f32,
    v: f32,
) -> Option<(f32, f32, f32)> {
    // NaN fails the comparisons.
    if !(u >= 1.0 && v >= 1.0 && u < (W - 2) as f32 && v < (H - 2) as f32) {
        return None;
    }
    let (x0, y0) = (u as usize, v as usize);
    let (fx, fy) = (u - x0 as f32, v - y0 as f32);
    // The 4x4 neighbourhood, read once: rows `y0 - 1..=y0 + 2`, columns `x0 - 1..=x0 + 2`.
    let start = (y0 - 1) * W + x0 - 1;
    let block = data.get(start..start + 3 * W + 4)?;
    let row = |k: usize| -> Option<[f32; 4]> {
        let px: &[u8; 4] = block.get(k * W..k * W + 4)?.try_into().ok()?;
        Some(px.map(f32::from))
    };
    let n = [row(0)?, row(1)?, row(2)?, row(3)?];
    // Bilinear at the pixel `(x0 + c - 1, y0 + r - 1)` plus `(fx, fy)`.
    let bil = |c: usize, r: usize| {
        let (p00, p10, p01, p11) = (n[r][c], n[r][c + 1], n[r + 1][c], n[r + 1][c + 1]);
        let top = p00 + fx * (p10 - p00);
        let bot = p01 + fx * (p11 - p01);
        top + fy * (bot - top)
    };
    let value = bil(1, 1);
    let gx = (bil(2, 1) - bil(0, 1)) * 0.5;
    let gy = (bil(1, 2) - bil(1, 0)) * 0.5;
    Some((value, gx, gy))
}

/// The rotation `r_cp` (previous camera to current camera) that best aligns `prev` with `cur`,
/// starting from `initial` (e.g. the motion model's predicted rotation); `None` when the images
/// overlap too little, the solve is degenerate or the final residual is too large (the frames do
/// not show the same scene, or translation dominates).
pub fn estimate_rotation(
    prev: &SmallImage,
    cur: &SmallImage,
    cam: &PinholeCamera,
    initial: &UnitQuaternion<f32>,
) -> Option<UnitQuaternion<f32>> {
    estimate_rotation_with(prev, cur, cam, initial, &RotationParams::DEFAULT)
}

/// [`estimate_rotation`] iterating as `params` says.
pub fn estimate_rotation_with(
    prev: &SmallImage,
    cur: &SmallImage,
    cam: &PinholeCamera,
    initial: &UnitQuaternion<f32>,
    params: &RotationParams,
) -> Option<UnitQuaternion<f32>> {
    if !prev.is_built() || prev.block != cur.block {
        return None;
    }
    let mut r = *initial;
    let mut photo = (1.0f32, 0.0f32);
    let mut rms = f32::INFINITY;
    for coarse in [true, false] {
        let (lp, lc) = (Level::of(prev, cam, coarse), Level::of(cur, cam, coarse));
        let iterations = if coarse { params.coarse_iterations } else { params.fine_iterations };
        for _ in 0..iterations {
            let (h, g, n, sq) = normal_equations(&lp, &lc, &r, photo)?;
            let min_n = MIN_OVERLAP * (lp.w * lp.h) as f32;
            if (n as f32) < min_n {
                return None;
            }
            rms = ferroslam_fpu::sqrtf(sq / n as f32);
            let delta = h.cholesky()?.solve(&(-g));
            let w = Vector3::new(delta[0], delta[1], delta[2]);
            if !w.iter().all(|v| v.is_finite()) {
                return None;
            }
            r = so3_exp(&w) * r;
            photo = (photo.0 + delta[3], photo.1 + delta[4]);
            if w.norm() < params.stop_step_rad {
                break;
            }
        }
    }
    (rms < MAX_RMS_GRAY).then_some(r)
}

/// One pixel's part of the normal equations: the residual's Jacobian with respect to the
/// rotation (`dw`; the gain's is `-ip`, the offset's `-1`), the previous image's gray value `ip`,
/// the Huber weight and the residual.
#[derive(Debug, Clone, Copy, Default)]
struct Term {
    dw: [f32; 3],
    ip: f32,
    wgt: f32,
    res: f32,
}

impl Term {
    /// The Jacobian of the residual with respect to `(w, a, b)`.
    #[inline(always)]
    fn j(&self) -> [f32; 5] {
        [self.dw[0], self.dw[1], self.dw[2], -self.ip, -1.0]
    }
}

/// The entries `(i, l)` of `H`'s upper triangle (`l >= i`, row by row: the order of the sums),
/// in the three groups [`Sums::add_row`] sums in one pass each.
const H_ROW_0: [(usize, usize); 5] = [(0, 0), (0, 1), (0, 2), (0, 3), (0, 4)];
const H_ROW_1: [(usize, usize); 4] = [(1, 1), (1, 2), (1, 3), (1, 4)];
const H_ROWS_2_TO_4: [(usize, usize); 6] = [(2, 2), (2, 3), (2, 4), (3, 3), (3, 4), (4, 4)];

/// Adds `j_i j_l w` of every term to the sum of entry `(i, l)`, term by term.
#[inline(always)]
fn add_products<const N: usize>(sums: &mut [f32; N], entries: &[(usize, usize); N], row: &[Term]) {
    // A local copy, so that the sums live in registers for the whole pass.
    let mut s = *sums;
    for t in row {
        let j = t.j();
        for (e, &(i, l)) in s.iter_mut().zip(entries) {
            *e += j[i] * j[l] * t.wgt;
        }
    }
    *sums = s;
}

/// The sums of the Gauss-Newton normal equations: `H`'s upper triangle in three groups (see
/// [`H_ROW_0`]), the gradient `g` and the sum of squared residuals.
#[derive(Default)]
struct Sums {
    h0: [f32; 5],
    h1: [f32; 4],
    h2: [f32; 6],
    g: [f32; 5],
    sq: f32,
}

impl Sums {
    /// Adds one image row's terms, in pixel order. Each sum gets the same products in the same
    /// order as adding the terms pixel by pixel, every sum at once, gives it (so the same bits:
    /// a unit test compares the two), but the sums are taken a group at a time, one pass over
    /// the row each, after the row's terms are computed: on the Cortex-M4F the 21 sums and a
    /// pixel's sampling do not fit its 32 float registers together, and summed with the
    /// sampling, pixel by pixel, they were spilled to the stack on every pixel.
    fn add_row(&mut self, row: &[Term]) {
        add_products(&mut self.h0, &H_ROW_0, row);
        add_products(&mut self.h1, &H_ROW_1, row);
        add_products(&mut self.h2, &H_ROWS_2_TO_4, row);
        let (mut g, mut sq) = (self.g, self.sq);
        for t in row {
            let rw = t.res * t.wgt;
            for (gi, &ji) in g.iter_mut().zip(&t.j()) {
                *gi += ji * rw;
            }
            sq += t.res * t.res;
        }
        (self.g, self.sq) = (g, sq);
    }

    /// `H` (mirrored from its upper triangle) and `g`.
    fn system(&self) -> (Matrix5<f32>, Vector5<f32>) {
        let mut h = Matrix5::<f32>::zeros();
        let sums = self.h0.iter().zip(&H_ROW_0);
        let sums = sums.chain(self.h1.iter().zip(&H_ROW_1));
        for (&e, &(i, l)) in sums.chain(self.h2.iter().zip(&H_ROWS_2_TO_4)) {
            h[(i, l)] = e;
            h[(l, i)] = e;
        }
        (h, Vector5::from(self.g))
    }
}

/// [`term`] written into `out`: whether there is one (`out` is left as it was when not).
// Never inlined: on the Cortex-M4F a pixel's sampling and Jacobian then have the float registers
// to themselves. Inlined into the row loop, with the loop's invariants (the rotation, both
// cameras, the photometric parameters) held in registers, the sampled neighbourhood was spilled
// to the stack on every pixel, and the call costs less than those spills. It writes the term into
// the row's slot itself: returned as an `Option<Term>`, the term went through two stack copies on
// the way there. The figures: docs/decisions.md, "Small-image rotation cost".
#[inline(never)]
fn term_into(
    out: &mut Term,
    lp: &Level<'_>,
    lc: &Level<'_>,
    rot: &Rotation3<f32>,
    photo: (f32, f32),
    xy: (usize, usize),
) -> bool {
    match term(lp, lc, rot, photo, xy) {
        Some(t) => {
            *out = t;
            true
        }
        None => false,
    }
}

/// The term of the pixel `(x, y)` of `lp` (interior pixels only) at rotation `rot` and
/// photometric `(a, b)`: `None` when it projects behind the camera or outside `lc`.
#[inline(always)]
fn term(
    lp: &Level<'_>,
    lc: &Level<'_>,
    rot: &Rotation3<f32>,
    (a, b): (f32, f32),
    (x, y): (usize, usize),
) -> Option<Term> {
    let ray = Point3::new((x as f32 - lp.cx) / lp.fx, (y as f32 - lp.cy) / lp.fy, 1.0);
    let p = rot * ray;
    if p.z <= 1.0e-3 {
        return None;
    }
    let iz = 1.0 / p.z;
    let (u, v) = (lc.fx * p.x * iz + lc.cx, lc.fy * p.y * iz + lc.cy);
    let (ic, gx, gy) = lc.sample(u, v)?;
    let ip = lp.at(x, y);
    let res = ic - (a * ip + b);
    // d(u, v)/dp, then dp/dw = -[p]x for the left perturbation R <- exp(w) R.
    let du = Vector3::new(lc.fx * iz, 0.0, -lc.fx * p.x * iz * iz);
    let dv = Vector3::new(0.0, lc.fy * iz, -lc.fy * p.y * iz * iz);
    let dw = -(du * gx + dv * gy).transpose() * hat(&p.coords);
    let abs = res.abs();
    let wgt = if abs <= HUBER_GRAY { 1.0 } else { HUBER_GRAY / abs };
    Some(Term { dw: [dw[0], dw[1], dw[2]], ip, wgt, res })
}

/// Gauss-Newton normal equations of the alignment at rotation `r` and photometric `(a, b)`:
/// `(H, g, pixels used, sum of squared residuals)`. The terms of an image row are computed
/// first, then summed ([`Sums::add_row`]).
fn normal_equations(
    lp: &Level<'_>,
    lc: &Level<'_>,
    r: &UnitQuaternion<f32>,
    photo: (f32, f32),
) -> Option<(Matrix5<f32>, Vector5<f32>, usize, f32)> {
    let rot = r.to_rotation_matrix();
    let mut sums = Sums::default();
    let mut n = 0usize;
    // One row's terms: at most `SMALL_W - 2` interior pixels.
    let mut row = [Term::default(); SMALL_W];
    for y in 1..lp.h - 1 {
        let mut len = 0;
        for x in 1..lp.w - 1 {
            // The row holds every interior pixel: there is always a slot.
            let Some(slot) = row.get_mut(len) else { break };
            if term_into(slot, lp, lc, &rot, photo, (x, y)) {
                len += 1;
            }
        }
        sums.add_row(row.get(..len).unwrap_or(&[]));
        n += len;
    }
    let (mut h, g) = sums.system();
    // A tiny diagonal keeps the photometric block positive definite on flat images.
    for i in 0..5 {
        h[(i, i)] += 1.0e-3;
    }
    h.iter().all(|v| v.is_finite()).then_some((h, g, n, sums.sq))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The two-buffer blur `blur_in_place` replaced, as the reference.
    fn blur_reference(src: &[u8], w: usize, h: usize) -> [u8; SMALL_W * SMALL_H] {
        let mut dst = [0u8; SMALL_W * SMALL_H];
        let at = |x: usize, y: usize| u32::from(src[y.min(h - 1) * w + x.min(w - 1)]);
        for y in 0..h {
            for x in 0..w {
                let col = |x: usize| at(x, y.saturating_sub(1)) + 2 * at(x, y) + at(x, y + 1);
                let acc = col(x.saturating_sub(1)) + 2 * col(x) + col(x + 1);
                dst[y * w + x] = ((acc + 8) / 16) as u8;
            }
        }
        dst
    }

    /// The normal equations summed pixel by pixel, every sum at once (how `normal_equations`
    /// summed the same terms before it summed by rows), as the reference.
    fn normal_equations_per_pixel(
        lp: &Level<'_>,
        lc: &Level<'_>,
        r: &UnitQuaternion<f32>,
        photo: (f32, f32),
    ) -> Option<(Matrix5<f32>, Vector5<f32>, usize, f32)> {
        let rot = r.to_rotation_matrix();
        // `H` is symmetric: its upper triangle is summed (row by row) and mirrored at the end.
        let mut upper = [0.0f32; 15];
        let mut g = [0.0f32; 5];
        let (mut n, mut sq) = (0usize, 0.0f32);
        for y in 1..lp.h - 1 {
            for x in 1..lp.w - 1 {
                let Some(t) = term(lp, lc, &rot, photo, (x, y)) else { continue };
                let j = t.j();
                let mut k = 0;
                for (i, &ji) in j.iter().enumerate() {
                    for &jl in &j[i..] {
                        upper[k] += ji * jl * t.wgt;
                        k += 1;
                    }
                }
                let rw = t.res * t.wgt;
                for (gi, &ji) in g.iter_mut().zip(&j) {
                    *gi += ji * rw;
                }
                n += 1;
                sq += t.res * t.res;
            }
        }
        let mut h = Matrix5::<f32>::zeros();
        let mut k = 0;
        for i in 0..5 {
            for l in i..5 {
                h[(i, l)] = upper[k];
                h[(l, i)] = upper[k];
                k += 1;
            }
        }
        for i in 0..5 {
            h[(i, i)] += 1.0e-3;
        }
        let g = Vector5::from(g);
        h.iter().all(|v| v.is_finite()).then_some((h, g, n, sq))
    }

    /// A smooth pseudo-random QVGA scene (sums of sines) shifted by `(dx, dy)` pixels, plus
    /// hash noise; for odd seeds a 32 x 32 pixel square saturates, so the Huber weight acts.
    fn scene(dx: f32, dy: f32, seed: u32) -> [u8; 320 * 240] {
        core::array::from_fn(|k| {
            let (x, y) = ((k % 320) as f32 + dx, (k / 320) as f32 + dy);
            let v = 128.0
                + 60.0 * libm::sinf(x * 0.05) * libm::cosf(y * 0.07)
                + 40.0 * libm::sinf((x + y) * 0.021 + seed as f32);
            let noise = ((k as u32 ^ seed).wrapping_mul(0x9E37_79B9) >> 29) as f32;
            let bright = (100..132).contains(&(k % 320)) && (60..92).contains(&(k / 320));
            if bright && seed % 2 == 1 { 255 } else { (v + noise).clamp(0.0, 255.0) as u8 }
        })
    }

    #[test]
    fn row_sums_equal_pixel_sums() {
        let cam = PinholeCamera::new(262.0, 262.0, 160.2, 119.7, 320, 240).unwrap();
        let cases = [
            (0.0, 0.0, 0, [0.0, 0.0, 0.0], (1.0, 0.0)),
            (3.5, -2.0, 1, [0.004, -0.01, 0.002], (1.05, -3.0)),
            (-12.0, 7.25, 2, [-0.03, 0.02, -0.01], (0.9, 6.5)),
            (40.0, 30.0, 3, [0.2, -0.15, 0.05], (1.2, -20.0)),
        ];
        let mut checked = 0;
        for (dx, dy, seed, w, photo) in cases {
            let (a, b) = (scene(0.0, 0.0, seed), scene(dx, dy, seed + 10));
            let (mut prev, mut cur) = (SmallImage::new(), SmallImage::new());
            assert!(prev.build(&GrayView::packed(&a, 320, 240).unwrap()));
            assert!(cur.build(&GrayView::packed(&b, 320, 240).unwrap()));
            let r = so3_exp(&Vector3::from(w));
            for coarse in [true, false] {
                let (lp, lc) = (Level::of(&prev, &cam, coarse), Level::of(&cur, &cam, coarse));
                let want = normal_equations_per_pixel(&lp, &lc, &r, photo).unwrap();
                let got = normal_equations(&lp, &lc, &r, photo).unwrap();
                let bits = |m: &[f32]| -> [u32; 25] {
                    core::array::from_fn(|k| m.get(k).map_or(0, |v| v.to_bits()))
                };
                assert_eq!(bits(got.0.as_slice()), bits(want.0.as_slice()), "H, case {seed}");
                assert_eq!(bits(got.1.as_slice()), bits(want.1.as_slice()), "g, case {seed}");
                assert_eq!((got.2, got.3.to_bits()), (want.2, want.3.to_bits()), "case {seed}");
                checked += got.2;
            }
        }
        // Most pixels overlap in every case: the comparison covered them.
        assert!(checked > 15_000, "{checked} pixels");
    }

    #[test]
    fn the_in_place_blur_is_the_binomial_blur() {
        for (w, h) in [(SMALL_W, SMALL_H), (COARSE_W, COARSE_H), (2, 2), (5, 3)] {
            let mut img: [u8; SMALL_W * SMALL_H] =
                core::array::from_fn(|k| (k as u32).wrapping_mul(0x9E37_79B9).rotate_left(7) as u8);
            let want = blur_reference(&img, w, h);
            blur_in_place(&mut img[..w * h], w, h);
            assert_eq!(img[..w * h], want[..w * h], "{w} x {h}");
        }
    }
}
