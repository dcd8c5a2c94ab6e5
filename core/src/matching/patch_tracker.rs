//! Patch tracking under a predicted warp: the cheap path of region matching, used for every
//! landmark of every frame once the motion is predicted.
//!
//! [`match_region`](super::match_region) searches a bank of 45 affine maps because it does not
//! know how the patch deforms. When the camera motion is predicted (motion model, or a pose
//! already estimated from a few guide landmarks), the map the motion induces on the patch is known
//! to within a few percent, and the bank reduces to that one map: the paper's transformation
//! network evaluated at the transform the prediction selects. [`track_patch`]:
//!
//! 1. warps the keyframe patch by the predicted linear map `A` once: template
//!    `T(q) = I_kf(c_kf + A^-1 q)` over the grid `q in [-h, h]^2`, plus a one-sample margin for
//!    its gradients;
//! 2. scores ZNCC between the template rounded to integers and the target's pixels at integer
//!    offsets `-R..=R` from the rounded prediction in steps of `s`, then at every integer offset
//!    within `s - 1` of the best; all sums are exact integers, and a candidate's block sums come
//!    from column sums shared by its row of candidates (and slid down from the row above: minus
//!    the pixel rows that left, plus those that entered), so only the product with the template
//!    reads its pixels;
//! 3. rejects an ambiguous search (another local maximum more than `s` away within
//!    [`TrackParams::min_peak_margin`] of the best) and a hopeless one (best ZNCC more than 0.15
//!    below [`TrackParams::min_zncc`], not worth refining);
//! 4. refines the translation by inverse-compositional Lucas-Kanade with the template's
//!    photometric directions (offset and gain) projected out, so a brightness change does not bias
//!    the position; the 2 x 2 normal matrix is built once;
//! 5. accepts the result when its ZNCC is at least [`TrackParams::min_zncc`] and refinement moved
//!    it at most [`TrackParams::max_refine_shift_px`] from the best integer candidate.
//!
//! There is no forward-backward check here: the patch is always the keyframe's (tracking is
//! frame-to-keyframe, so errors do not chain), and the robust pose estimate that follows rejects
//! the outliers a wrong match makes. Only the linear part of the warp is predicted; the
//! translation is searched and refined.
//!
//! # Cost
//!
//! With `n = (2h + 1)^2` grid samples, search radius `R` and step `s`: `(2h + 3)^2` general
//! bilinear samples for the template; for the column sums, `(2h + 1)(2R + 2h + 1)` pixels for the
//! first row of candidates and `2s (2R + 2h + 1)` for each coarse row after it (rows `s` apart;
//! from scratch when `s >= 2h + 1`), and per candidate `n` integer multiply-adds
//! (`(2 floor(R/s) + 1)^2 + (2s - 1)^2` candidates; at `s = 1` up to seven adjacent candidates
//! share their row reads and slide their block sums, and every product takes two pixels a
//! multiply-accumulate: `Quantized::batch` in `integer_search.rs`); then per Lucas-Kanade step `n` shared-weight samples and ~10 flops
//! each. About 30 k host instructions per call at [`TrackParams::FINE`] (`h = 4`, `R = 1`, `s =
//! 1`: 9 candidates; the template warp is a quarter of it, the Lucas-Kanade steps, typically 2-4
//! plus the final score, another third) and 58 k at [`TrackParams::GUIDE`] (`R = 3`: 49
//! candidates). The template's samples read a copy of the pixels they need (one word-wise row
//! copy per pixel row of a 16 x 16 template) instead of checking every read: about 43 Cortex-M4
//! instructions a sample with its share of the copy. The figures: docs/decisions.md, "Patch
//! tracker cost" and "Template warp through a pixel window".
//!
//! # Memory
//!
//! No heap; under 5 KB of stack at the largest sizes: the template with its margin and its
//! zero-mean grid (15 x 15 and 13 x 13 f32), the steepest-descent images (2 x 13 x 13 f32), the
//! coarse scores (17 x 17 f32), the column sums (2 x 77 i32) and the copy of the template
//! pixels the warp reads (16 x 18 bytes). [`track_patch_with`] takes the last two and the
//! rounded template from a [`TrackScratch`] the caller keeps across calls, so they are not
//! zeroed for every track.
//!
//! # Determinism
//!
//! Plain f32 adds and multiplies in fixed orders (never `mul_add`), correctly rounded square
//! roots (`ferroslam_fpu::sqrtf`: the FPU on the board, libm on the host); ties go to the first
//! candidate in scan order (rows top to bottom, each left to right).

mod integer_search;
mod sample;

use super::MatchError;
use super::affine::{Mat2, mat_apply, mat_inverse};
use crate::image::GrayView;
use integer_search::{ColumnSums, Quantized, search};
use sample::{Window, fixed_grid, sample_each};

/// Largest template half-size of [`track_patch`], pixels (13 x 13 templates).
pub const MAX_TRACK_HALF_SIZE: usize = 6;

/// Largest search radius of [`track_patch`], pixels.
pub const MAX_TRACK_SEARCH_RADIUS: usize = 32;

/// Most coarse steps on each side of the prediction: `R / s` is at most this.
pub const MAX_TRACK_COARSE_STEPS: usize = 8;

/// Samples are stored minus this so that one-pass sums of squares stay accurate in f32.
const GRAY_OFFSET: f32 = 128.0;

/// A search whose best ZNCC is this far below [`TrackParams::min_zncc`] is not refined.
const HOPELESS_MARGIN: f32 = 0.15;

/// Tunables of [`track_patch`]. Distances are in pixels of the images passed in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackParams {
    /// Template half-size `h`, 1..=[`MAX_TRACK_HALF_SIZE`]: the template is `2h + 1` pixels square.
    pub half_size: usize,
    /// Search radius `R` around the prediction, 0..=[`MAX_TRACK_SEARCH_RADIUS`].
    pub search_radius: usize,
    /// Step `s` of the first search pass, 1..=8, with `R / s` at most
    /// [`MAX_TRACK_COARSE_STEPS`] (the second pass fills in around the best).
    pub search_step: usize,
    /// Templates with a gray-level standard deviation below this are rejected as flat.
    pub min_template_std: f32,
    /// Tracks whose refined ZNCC is below this are rejected.
    pub min_zncc: f32,
    /// Ambiguity test of the first pass; `None` skips it.
    pub min_peak_margin: Option<f32>,
    /// Most Lucas-Kanade steps.
    pub max_iterations: usize,
    /// Lucas-Kanade stops when a step is shorter than this, pixels.
    pub epsilon_px: f32,
    /// Refinement may move at most this far from the best integer candidate, pixels.
    pub max_refine_shift_px: f32,
}

impl TrackParams {
    /// Per-landmark tracking once the pose is well predicted: 9 x 9 template, search radius 1.
    pub const FINE: Self = Self {
        half_size: 4,
        search_radius: 1,
        search_step: 1,
        min_template_std: 3.0,
        min_zncc: 0.8,
        min_peak_margin: None,
        max_iterations: 10,
        epsilon_px: 0.01,
        max_refine_shift_px: 1.5,
    };

    /// The few guide landmarks tracked from the motion model alone: an exhaustive search of
    /// radius 3 (49 candidates), with the ambiguity test: a 9 x 9 template's correlation peak is
    /// about 2 px wide, so a step of 2 misses it, and a wider window holds more look-alikes.
    /// Larger errors are left to the rotation re-prediction and [`Self::GUIDE_WIDE`]. Why radius
    /// 3: docs/decisions.md, "Guide search radius".
    pub const GUIDE: Self = Self {
        search_radius: 3,
        search_step: 1,
        min_peak_margin: Some(0.05),
        max_refine_shift_px: 2.0,
        ..Self::FINE
    };

    /// The guides' last resort before the affine bank: radius 16 in steps of 2.
    pub const GUIDE_WIDE: Self = Self { search_radius: 16, search_step: 2, ..Self::GUIDE };

    /// Whether every value is in range.
    pub fn is_valid(&self) -> bool {
        (1..=MAX_TRACK_HALF_SIZE).contains(&self.half_size)
            && self.search_radius <= MAX_TRACK_SEARCH_RADIUS
            && (1..=8).contains(&self.search_step)
            && self.search_radius / self.search_step.max(1) <= MAX_TRACK_COARSE_STEPS
            && self.min_template_std.is_finite()
            && self.min_zncc.is_finite()
            && self.min_peak_margin.is_none_or(f32::is_finite)
            && self.epsilon_px.is_finite()
            && self.epsilon_px >= 0.0
            && self.max_refine_shift_px.is_finite()
            && self.max_refine_shift_px > 0.0
    }
}

impl Default for TrackParams {
    fn default() -> Self {
        Self::FINE
    }
}

/// A tracked patch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchTrack {
    /// Where the keyframe centre lands in the target, pixels.
    pub uv: (f32, f32),
    /// ZNCC of the refined track, in [-1, 1].
    pub zncc: f32,
    /// Distance from the prediction, pixels.
    pub offset_px: f32,
}

/// The warped template of one call: `N x N` grid values (`N = 2h + 1`) with a one-sample margin
/// for their gradients (`S = N + 2` per side), gray offset removed; the grid's zero-mean values and
/// their norm. Every size is fixed at compile time (see [`track_patch`]'s dispatch), so the loops
/// unroll and index without checks.
///
/// This, [`Steepest`] and the integer search's `Quantized` are filled in place (`EMPTY`, then a
/// `&mut self` method) rather than returned: returned by value, each was built on the stack and
/// copied into its caller's (`__aeabi_memcpy4` on the Cortex-M4). Why: docs/decisions.md,
/// "Tracking code generation on the Cortex-M4".
struct Template<const N: usize, const S: usize> {
    values: [[f32; S]; S],
    zero_mean: [[f32; N]; N],
    norm: f32,
}

impl<const N: usize, const S: usize> Template<N, S> {
    /// All zero, to be filled by [`Self::warp`].
    const EMPTY: Self = Self { values: [[0.0; S]; S], zero_mean: [[0.0; N]; N], norm: 0.0 };

    /// Fills `self` with `img` sampled at `centre + a_inv q` for the grid offsets `q` (margin
    /// included), through `window` (scratch); `false` (and `self` unspecified) when a sample
    /// would leave the image.
    fn warp(
        &mut self,
        img: &GrayView<'_>,
        centre: (f32, f32),
        a_inv: &Mat2,
        window: &mut Window,
    ) -> bool {
        // A linear map sends the square's corners to the extremes: check them once.
        let m = (S / 2) as f32;
        let (w, h) = img.size();
        let (x_max, y_max) = ((w - 1) as f32, (h - 1) as f32);
        for (i, j) in [(-m, -m), (m, -m), (-m, m), (m, m)] {
            let (dx, dy) = mat_apply(a_inv, (i, j));
            let (x, y) = (centre.0 + dx, centre.1 + dy);
            // NaN fails the comparisons.
            if !(x >= 0.0 && y >= 0.0 && x < x_max && y < y_max) {
                return false;
            }
        }
        let (data, stride) = (img.data(), img.stride());
        let (starts, step) = fixed_grid::<S>(centre, a_inv);
        // Through a copy of the pixels read when they fit one (always for a tracked landmark's
        // 16 x 16 template), else one checked sample at a time: the same values either way.
        if !window.sample(data, stride, &starts, step, &mut self.values) {
            sample_each(data, stride, &starts, step, &mut self.values);
        }
        let mut sum = 0.0f32;
        for (z_row, v_row) in self.zero_mean.iter_mut().zip(&self.values[1..]) {
            for (z, &v) in z_row.iter_mut().zip(&v_row[1..]) {
                *z = v;
                sum += v;
            }
        }
        let mean = sum / (N * N) as f32;
        let mut ss = 0.0f32;
        for z in self.zero_mean.as_flattened_mut() {
            *z -= mean;
            ss += *z * *z;
        }
        self.norm = ferroslam_fpu::sqrtf(ss);
        true
    }
}

/// The template's steepest-descent images with the photometric directions projected out, and
/// their 2 x 2 normal matrix.
struct Steepest<const N: usize> {
    gx: [[f32; N]; N],
    gy: [[f32; N]; N],
    hxx: f32,
    hxy: f32,
    hyy: f32,
    det: f32,
}

impl<const N: usize> Steepest<N> {
    /// All zero, to be filled by [`Self::fill`].
    const EMPTY: Self =
        Self { gx: [[0.0; N]; N], gy: [[0.0; N]; N], hxx: 0.0, hxy: 0.0, hyy: 0.0, det: 0.0 };

    /// Fills `self` with the central-difference gradients of `t`, with the offset (the mean) and
    /// the gain (the template itself) projected out (variable projection of
    /// `I(x + c) = g T(x) + b`); `false` (and `self` unspecified) when both directions do not
    /// carry gradient (an edge alone slides along itself).
    fn fill<const S: usize>(&mut self, t: &Template<N, S>) -> bool {
        let Self { gx, gy, .. } = self;
        for j in 0..N {
            let (up, mid, down) = (&t.values[j], &t.values[j + 1], &t.values[j + 2]);
            for i in 0..N {
                gx[j][i] = (mid[i + 2] - mid[i]) * 0.5;
                gy[j][i] = (down[i + 1] - up[i + 1]) * 0.5;
            }
        }
        let len = (N * N) as f32;
        let norm2 = t.norm * t.norm;
        for g in [&mut *gx, &mut *gy] {
            let mean = g.as_flattened().iter().sum::<f32>() / len;
            let mut coeff = 0.0f32;
            for (v, z) in g.as_flattened().iter().zip(t.zero_mean.as_flattened()) {
                coeff += (v - mean) * z;
            }
            coeff /= norm2;
            for (v, z) in g.as_flattened_mut().iter_mut().zip(t.zero_mean.as_flattened()) {
                *v = *v - mean - coeff * z;
            }
        }
        let (mut hxx, mut hxy, mut hyy) = (0.0f32, 0.0f32, 0.0f32);
        for (x, y) in gx.as_flattened().iter().zip(gy.as_flattened()) {
            hxx += x * x;
            hxy += x * y;
            hyy += y * y;
        }
        let det = hxx * hyy - hxy * hxy;
        (self.hxx, self.hxy, self.hyy, self.det) = (hxx, hxy, hyy, det);
        !(det.is_nan() || det <= 1e-6 * (hxx + hyy) * (hxx + hyy))
    }
}

/// Sums over the `N x N` block of the target sampled at `(x0 + i, y0 + j)` by bilinear
/// interpolation (all samples share one set of weights, so the interpolation is separable: rows
/// first, then columns), against the steepest-descent images and the template's zero-mean values.
#[derive(Debug, Clone, Copy)]
struct Moments {
    /// `sum v`.
    sum: f32,
    /// `sum v^2`.
    sum_sq: f32,
    /// `sum gx v`.
    gx_v: f32,
    /// `sum gy v`.
    gy_v: f32,
    /// `sum z v`.
    z_v: f32,
}

impl Moments {
    /// The moments at block origin `(x0, y0)`; `None` when the block (with the extra column and
    /// row the interpolation reads) leaves the image or a coordinate is NaN. `STEP` computes the
    /// sums a Lucas-Kanade step needs (`gx_v`, `gy_v`), `SCORE` the one the final ZNCC needs
    /// (`z_v`); the others stay 0. Each sum is accumulated in the same order either way, so a
    /// sum computed has the same bits whatever else is.
    fn at<const N: usize, const STEP: bool, const SCORE: bool>(
        img: &GrayView<'_>,
        (x0, y0): (f32, f32),
        sd: &Steepest<N>,
        z: &[[f32; N]; N],
    ) -> Option<Self> {
        let (w, h) = img.size();
        // NaN fails the comparisons; the casts below only see values in 0..w.
        if !(x0 >= 0.0 && y0 >= 0.0 && x0 + (N as f32) < w as f32 && y0 + (N as f32) < h as f32) {
            return None;
        }
        let (bx, by) = (x0 as usize, y0 as usize);
        if bx + N >= w || by + N >= h {
            return None;
        }
        let (fx, fy) = (x0 - bx as f32, y0 - by as f32);
        if fx == 0.0 && fy == 0.0 {
            return Self::at_pixels::<N, STEP, SCORE>(img, (bx, by), sd, z);
        }
        Self::interpolated::<N, STEP, SCORE>(img, (bx, by), (fx, fy), sd, z)
    }

    /// [`Self::at`] at an integer origin `(bx, by)` (the first Lucas-Kanade step, from the
    /// integer search's best candidate): every interpolation weight is 0, and `a + 0 (b - a)` is
    /// `a`, so the pixels themselves give the same sums bit for bit, in the same order, without
    /// interpolating (about a third of the step's work). The caller checked the bounds.
    fn at_pixels<const N: usize, const STEP: bool, const SCORE: bool>(
        img: &GrayView<'_>,
        (bx, by): (usize, usize),
        sd: &Steepest<N>,
        z: &[[f32; N]; N],
    ) -> Option<Self> {
        let mut m = Self { sum: 0.0, sum_sq: 0.0, gx_v: 0.0, gy_v: 0.0, z_v: 0.0 };
        let rows = sd.gx.iter().zip(&sd.gy).zip(z).enumerate();
        for (j, ((gxr, gyr), zr)) in rows {
            let px = img.row(by + j)?.get(bx..bx + N)?;
            for (i, &p) in px.iter().enumerate() {
                m.add::<STEP, SCORE>(f32::from(p) - GRAY_OFFSET, (gxr[i], gyr[i], zr[i]));
            }
        }
        Some(m)
    }

    /// [`Self::at`] at origin `(bx + fx, by + fy)` by bilinear interpolation (rows first, then
    /// columns). The caller checked the bounds.
    fn interpolated<const N: usize, const STEP: bool, const SCORE: bool>(
        img: &GrayView<'_>,
        (bx, by): (usize, usize),
        (fx, fy): (f32, f32),
        sd: &Steepest<N>,
        z: &[[f32; N]; N],
    ) -> Option<Self> {
        let mut m = Self { sum: 0.0, sum_sq: 0.0, gx_v: 0.0, gy_v: 0.0, z_v: 0.0 };
        // The horizontal pass of the previous row, reused as the top of the next.
        let mut top = Self::row::<N>(img, bx, by, fx)?;
        let rows = sd.gx.iter().zip(&sd.gy).zip(z).enumerate();
        for (j, ((gxr, gyr), zr)) in rows {
            let bot = Self::row::<N>(img, bx, by + j + 1, fx)?;
            for i in 0..N {
                m.add::<STEP, SCORE>(top[i] + fy * (bot[i] - top[i]), (gxr[i], gyr[i], zr[i]));
            }
            top = bot;
        }
        Some(m)
    }

    /// Adds the sample `v` with its steepest-descent and zero-mean template values `(gx, gy, z)`,
    /// each sum in the order of the samples (`STEP`, `SCORE` as in [`Self::at`]).
    #[inline(always)]
    fn add<const STEP: bool, const SCORE: bool>(&mut self, v: f32, (gx, gy, z): (f32, f32, f32)) {
        self.sum += v;
        self.sum_sq += v * v;
        if STEP {
            self.gx_v += gx * v;
            self.gy_v += gy * v;
        }
        if SCORE {
            self.z_v += z * v;
        }
    }

    /// Row `y` of `img` from column `bx`, interpolated at `+fx` (minus the gray offset).
    #[inline(always)]
    fn row<const N: usize>(img: &GrayView<'_>, bx: usize, y: usize, fx: f32) -> Option<[f32; N]> {
        let px = img.row(y)?.get(bx..=bx + N)?;
        let mut out = [0.0f32; N];
        for (o, pair) in out.iter_mut().zip(px.windows(2)) {
            if let [a, b] = *pair {
                let (a, b) = (f32::from(a), f32::from(b));
                *o = a + fx * (b - a) - GRAY_OFFSET;
            }
        }
        Some(out)
    }

    /// The block's squared norm about its mean over `len` samples.
    fn variance(&self, len: f32) -> f32 {
        self.sum_sq - self.sum * self.sum / len
    }
}

/// Inverse-compositional translation Lucas-Kanade from `start` (step 4 of the module
/// documentation), with `sd` as scratch; the refined position and its ZNCC.
fn refine<const N: usize, const S: usize>(
    t: &Template<N, S>,
    sd: &mut Steepest<N>,
    target: &GrayView<'_>,
    start: (f32, f32),
    params: &TrackParams,
) -> Result<((f32, f32), f32), MatchError> {
    if !sd.fill(t) {
        return Err(MatchError::RefinementFailed);
    }
    let half = (N / 2) as f32;
    let len = (N * N) as f32;
    let origin = |c: (f32, f32)| (c.0 - half, c.1 - half);
    let mut c = start;
    for _ in 0..params.max_iterations {
        let m = Moments::at::<N, true, false>(target, origin(c), sd, &t.zero_mean)
            .ok_or(MatchError::RefinementFailed)?;
        let norm_i = ferroslam_fpu::sqrtf(m.variance(len));
        if norm_i.is_nan() || norm_i <= 0.0 {
            return Err(MatchError::RefinementFailed);
        }
        // The error image is `(v - mean) * gain - z`; `gx`, `gy` have zero mean and are
        // orthogonal to `z` (projected above), so `sum gx err = gain * sum gx v`.
        let gain = t.norm / norm_i;
        let (bx, by) = (gain * m.gx_v, gain * m.gy_v);
        let dx = (sd.hyy * bx - sd.hxy * by) / sd.det;
        let dy = (sd.hxx * by - sd.hxy * bx) / sd.det;
        c = (c.0 - dx, c.1 - dy);
        let (sx, sy) = (c.0 - start.0, c.1 - start.1);
        let shift2 = sx * sx + sy * sy;
        if shift2.is_nan() || shift2 > params.max_refine_shift_px * params.max_refine_shift_px {
            return Err(MatchError::RefinementFailed);
        }
        if dx * dx + dy * dy < params.epsilon_px * params.epsilon_px {
            break;
        }
    }
    let m = Moments::at::<N, false, true>(target, origin(c), sd, &t.zero_mean)
        .ok_or(MatchError::RefinementFailed)?;
    let var = m.variance(len);
    // Less than ~0.05 gray levels of spread carries no correlation.
    if var.is_nan() || var <= 1e-3 * len || t.norm.is_nan() || t.norm <= 0.0 {
        return Err(MatchError::RefinementFailed);
    }
    // `sum z (v - mean) = sum z v` as `z` has zero mean. Rounding can push a perfect match a few
    // ulps past 1.
    let score = (m.z_v / (ferroslam_fpu::sqrtf(var) * t.norm)).clamp(-1.0, 1.0);
    Ok((c, score))
}

/// The scratch of one track of template size `N` that can outlive it: each part is written
/// before it is read ([`Window::sample`] copies the rows it reads, [`Quantized::fill`] writes
/// every field, the column sums say which candidate row they hold), so nothing a track computes
/// depends on what an earlier track left here.
///
/// The template and its steepest-descent images are not in it: they stay on the stack of each
/// track, zeroed first. Read through a pointer instead, the Lucas-Kanade loops took more
/// Cortex-M4 instructions than their zeroing costs (docs/decisions.md, "One tracking scratch per
/// final stage").
struct Workspace<const N: usize> {
    window: Window,
    quantized: Quantized<N>,
    columns: ColumnSums<N>,
}

impl<const N: usize> Workspace<N> {
    /// All zero.
    const fn new() -> Self {
        Self { window: Window::EMPTY, quantized: Quantized::EMPTY, columns: ColumnSums::EMPTY }
    }
}

/// The reusable scratch of [`track_patch_with`]: the pixel window, the rounded template and the
/// column sums of the 9 x 9 templates (`half_size` 4, that of every [`TrackParams`] constant and
/// of the front end), about 1.1 KB.
///
/// Why it exists: built afresh for every track, that scratch has to be zeroed first (safe Rust
/// cannot leave it uninitialized). A caller that tracks many patches builds one `TrackScratch`
/// and passes it to every call (the figures: docs/decisions.md, "One tracking scratch per final
/// stage"). Other template sizes build their scratch per call.
pub struct TrackScratch {
    nine: Workspace<9>,
}

impl TrackScratch {
    /// A zeroed scratch (`const`).
    pub const fn new() -> Self {
        Self { nine: Workspace::new() }
    }
}

impl Default for TrackScratch {
    fn default() -> Self {
        Self::new()
    }
}

impl core::fmt::Debug for TrackScratch {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("TrackScratch")
    }
}

/// [`track_patch`] for one template size (`N = 2h + 1`, `S = N + 2`), after its checks.
fn track_fixed<const N: usize, const S: usize>(
    ws: &mut Workspace<N>,
    template_img: &GrayView<'_>,
    (centre, a_inv): ((f32, f32), &Mat2),
    target: &GrayView<'_>,
    predicted: (f32, f32),
    params: &TrackParams,
) -> Result<PatchTrack, MatchError> {
    let Workspace { window, quantized, columns } = ws;
    let mut t = Template::<N, S>::EMPTY;
    let mut steepest = Steepest::EMPTY;
    if !t.warp(template_img, centre, a_inv, window) {
        return Err(MatchError::TemplateOutOfImage);
    }
    let std_dev = t.norm / N as f32;
    if std_dev.is_nan() || std_dev < params.min_template_std {
        return Err(MatchError::FlatTemplate { std_dev });
    }
    let start = if params.search_radius == 0 {
        // No search: Lucas-Kanade from the sub-pixel prediction itself.
        predicted
    } else {
        let ((x, y), best) = search(&t, (quantized, columns), target, predicted, params)?;
        if best < params.min_zncc - HOPELESS_MARGIN {
            return Err(MatchError::LowCorrelation { zncc: best });
        }
        // Pixel coordinates are far below 2^24: exact in f32.
        (x as f32, y as f32)
    };
    let (uv, zncc) = refine(&t, &mut steepest, target, start, params)?;
    if zncc.is_nan() || zncc < params.min_zncc {
        return Err(MatchError::LowCorrelation { zncc });
    }
    let (dx, dy) = (uv.0 - predicted.0, uv.1 - predicted.1);
    Ok(PatchTrack { uv, zncc, offset_px: ferroslam_fpu::sqrtf(dx * dx + dy * dy) })
}

/// Tracks the patch of `template_img` centred at `centre` into `target`, where it is predicted at
/// `predicted` with the linear map `affine` (`d(uv_target) / d(uv_template)`, from the predicted
/// motion). All coordinates are pixels, origin at the top-left pixel's centre. See the module
/// documentation for the steps and their cost.
///
/// # Errors
/// [`MatchError::InvalidParams`] (also for a singular `affine` or a non-finite position),
/// [`MatchError::TemplateOutOfImage`], [`MatchError::FlatTemplate`], [`MatchError::NoCandidate`]
/// (the search window leaves the target), [`MatchError::Ambiguous`],
/// [`MatchError::RefinementFailed`] or [`MatchError::LowCorrelation`].
pub fn track_patch(
    template_img: &GrayView<'_>,
    centre: (f32, f32),
    affine: &Mat2,
    target: &GrayView<'_>,
    predicted: (f32, f32),
    params: &TrackParams,
) -> Result<PatchTrack, MatchError> {
    let mut scratch = TrackScratch::new();
    track_patch_with(&mut scratch, template_img, centre, affine, target, predicted, params)
}

/// [`track_patch`] with a scratch kept by the caller: the same result, bit for bit, whatever
/// earlier calls left in `scratch`, without zeroing a workspace on every call (see
/// [`TrackScratch`]).
///
/// # Errors
/// As [`track_patch`].
pub fn track_patch_with(
    scratch: &mut TrackScratch,
    template_img: &GrayView<'_>,
    centre: (f32, f32),
    affine: &Mat2,
    target: &GrayView<'_>,
    predicted: (f32, f32),
    params: &TrackParams,
) -> Result<PatchTrack, MatchError> {
    let finite = centre.0.is_finite()
        && centre.1.is_finite()
        && predicted.0.is_finite()
        && predicted.1.is_finite();
    if !params.is_valid() || !finite {
        return Err(MatchError::InvalidParams);
    }
    let a_inv = mat_inverse(affine).ok_or(MatchError::InvalidParams)?;
    let (img, at) = (template_img, (centre, &a_inv));
    match params.half_size {
        1 => track_fixed::<3, 5>(&mut Workspace::new(), img, at, target, predicted, params),
        2 => track_fixed::<5, 7>(&mut Workspace::new(), img, at, target, predicted, params),
        3 => track_fixed::<7, 9>(&mut Workspace::new(), img, at, target, predicted, params),
        4 => track_fixed::<9, 11>(&mut scratch.nine, img, at, target, predicted, params),
        5 => track_fixed::<11, 13>(&mut Workspace::new(), img, at, target, predicted, params),
        6 => track_fixed::<13, 15>(&mut Workspace::new(), img, at, target, predicted, params),
        _ => Err(MatchError::InvalidParams),
    }
}

/// Test images shared by the submodules' tests.
#[cfg(test)]
mod test_images {
    use crate::test_rng::TestRng;

    /// A 40 x 40 image of pseudo-random pixels from `seed`.
    pub(crate) fn noise_image(seed: u64) -> [u8; 40 * 40] {
        let mut rng = TestRng::new(seed);
        core::array::from_fn(|_| (rng.next_u32() >> 24) as u8)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::test_images::noise_image;
    use super::*;
    use crate::test_rng::TestRng;

    /// Every sum as its bits, so that `-0.0` and `0.0` differ.
    fn bits(m: &Moments) -> [u32; 5] {
        [m.sum, m.sum_sq, m.gx_v, m.gy_v, m.z_v].map(f32::to_bits)
    }

    /// At an integer origin the pixels' sums are the interpolation's, bit for bit: every weight is
    /// 0. Checked at every origin of two images (noise, and a flat 128, whose centred values are
    /// 0), with both the step's and the score's sums.
    #[test]
    fn moments_at_integer_origins_are_the_interpolated_ones() {
        let mut rng = TestRng::new(5);
        let mut sd = Steepest::<9>::EMPTY;
        let mut z = [[0.0f32; 9]; 9];
        for ((gx, gy), zv) in sd
            .gx
            .as_flattened_mut()
            .iter_mut()
            .zip(sd.gy.as_flattened_mut())
            .zip(z.as_flattened_mut())
        {
            (*gx, *gy, *zv) = (
                rng.uniform_f32(-20.0, 20.0),
                rng.uniform_f32(-20.0, 20.0),
                rng.uniform_f32(-50.0, 50.0),
            );
        }
        let (noise, flat) = (noise_image(31), [128u8; 40 * 40]);
        for data in [&noise[..], &flat[..]] {
            let img = GrayView::new(data, 40, 40, 40).unwrap();
            for (by, bx) in (0..30).flat_map(|y| (0..30).map(move |x| (y, x))) {
                let fast = Moments::at_pixels::<9, true, true>(&img, (bx, by), &sd, &z).unwrap();
                let slow =
                    Moments::interpolated::<9, true, true>(&img, (bx, by), (0.0, 0.0), &sd, &z)
                        .unwrap();
                assert_eq!(bits(&fast), bits(&slow), "origin {bx}, {by}");
                let origin = (bx as f32, by as f32);
                let step = Moments::at::<9, true, false>(&img, origin, &sd, &z).unwrap();
                let score = Moments::at::<9, false, true>(&img, origin, &sd, &z).unwrap();
                assert_eq!((step.gx_v, step.gy_v, score.z_v), (slow.gx_v, slow.gy_v, slow.z_v));
            }
            // The last origin whose block, with the interpolation's extra row and column, fits.
            assert!(Moments::at::<9, true, false>(&img, (30.0, 30.0), &sd, &z).is_some());
            assert!(Moments::at::<9, true, false>(&img, (31.0, 30.0), &sd, &z).is_none());
            assert!(Moments::at::<9, true, false>(&img, (30.0, 31.0), &sd, &z).is_none());
        }
    }
}
