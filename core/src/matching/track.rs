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
//! bilinear samples for the template; for the column sums, `(2h + 1)(2R + 2h + 1)` pixels for
//! the first row of candidates and `2s (2R + 2h + 1)` for each coarse row after it (rows `s`
//! apart; from scratch when `s >= 2h + 1`), and per candidate `n` integer multiply-adds
//! (`(2 floor(R/s) + 1)^2 + (2s - 1)^2` candidates; at `s = 1` three adjacent candidates share
//! their pixel reads and, two of them, their multiplies: [`Quantized::products`]); then per
//! Lucas-Kanade step `n` shared-weight samples and ~10 flops each. Measured with callgrind on
//! 7-Scenes QVGA templates (host x86_64, release build) before the column sums slid (commit
//! 5a4ce29): about 30 k instructions per call at [`TrackParams::FINE`] (`h = 4`, `R = 1`,
//! `s = 1`: 9 candidates; the template warp is a quarter of it, the Lucas-Kanade steps,
//! typically 2-4 plus the final score, another third) and 58 k at [`TrackParams::GUIDE`]
//! (`R = 3`: 49 candidates). Sliding them took the mean over the calls of 100 frames from
//! 33.0 k to 31.4 k. The template's samples read a copy of the pixels they need (one word-wise
//! row copy per pixel row of a 16 x 16 template) instead of checking every read: on the
//! Cortex-M4 a sample went from about 54 to about 38 instructions, 43 with its share of the copy
//! (`profile-firmware`).
//!
//! # Memory
//!
//! No heap; under 5 KB of stack at the largest sizes: the template with its margin and its
//! zero-mean grid (15 x 15 and 13 x 13 f32), the steepest-descent images (2 x 13 x 13 f32), the
//! coarse scores (17 x 17 f32), the column sums (2 x 77 i32) and the copy of the template
//! pixels the warp reads (16 x 18 bytes).
//!
//! # Determinism
//!
//! Plain f32 adds and multiplies in fixed orders (never `mul_add`), square roots through `libm`;
//! ties go to the first candidate in scan order (rows top to bottom, each left to right).

use super::MatchError;
use super::affine::{Mat2, mat_apply, mat_inverse};
use crate::image::GrayView;

/// Largest template half-size of [`track_patch`], pixels (13 x 13 templates).
pub const MAX_TRACK_HALF_SIZE: usize = 6;

/// Largest search radius of [`track_patch`], pixels.
pub const MAX_TRACK_SEARCH_RADIUS: usize = 32;

/// Most coarse steps on each side of the prediction: `R / s` is at most this.
pub const MAX_TRACK_COARSE_STEPS: usize = 8;

/// Side of the largest coarse score grid.
const MAX_SCORE_SIDE: usize = 2 * MAX_TRACK_COARSE_STEPS + 1;

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
    /// radius 3 (49 candidates), with the ambiguity test. Measured on the fast-rotation demo
    /// with prediction errors of 0.5-3 px: an exhaustive radius 4 matched 148 of 164 landmarks
    /// right and 3 wrong; radius 8 in steps of 2 only 95 right and 25 wrong (a 9 x 9 template's
    /// correlation peak is about 2 px wide, so a step of 2 misses it, and a wider window holds
    /// more look-alikes). Radius 3 keeps the accuracy of radius 4 on the demo and 7-Scenes with
    /// 40% fewer candidates. Larger errors are left to the rotation re-prediction and
    /// [`Self::GUIDE_WIDE`].
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
/// This, [`Steepest`] and [`Quantized`] are filled in place (`EMPTY`, then a `&mut self` method)
/// rather than returned: returned by value, each was built on the stack and copied into its
/// caller's, and on the Cortex-M4 those copies (`__aeabi_memcpy4`, 320 k instructions a frame on
/// 7-Scenes) were a twentieth of the front end.
struct Template<const N: usize, const S: usize> {
    values: [[f32; S]; S],
    zero_mean: [[f32; N]; N],
    norm: f32,
}

impl<const N: usize, const S: usize> Template<N, S> {
    /// All zero, to be filled by [`Self::warp`].
    const EMPTY: Self = Self { values: [[0.0; S]; S], zero_mean: [[0.0; N]; N], norm: 0.0 };

    /// Fills `self` with `img` sampled at `centre + a_inv q` for the grid offsets `q` (margin
    /// included); `false` (and `self` unspecified) when a sample would leave the image.
    fn warp(&mut self, img: &GrayView<'_>, centre: (f32, f32), a_inv: &Mat2) -> bool {
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
        // Positions in 16.16 fixed point: a row's samples step by the map's first column in
        // integers (no float-to-integer conversion per sample, the same on every target). The
        // corners were checked in floating point and lie at most 0.5 px inside `0..w - 1`, so the
        // 1/65536 px rounding of a step, times 14 steps, cannot leave the image.
        let fixed = |v: f32| libm::roundf(v * FIXED_ONE) as i32;
        let step = (fixed(a_inv[0][0]), fixed(a_inv[1][0]));
        let mut starts = [(0i32, 0i32); S];
        for (j, start) in starts.iter_mut().enumerate() {
            let (dx, dy) = mat_apply(a_inv, (-m, j as f32 - m));
            *start = (fixed(centre.0 + dx), fixed(centre.1 + dy));
        }
        // Through a copy of the pixels read when they fit one (always for a tracked landmark's
        // 16 x 16 template), else one checked sample at a time: the same values either way.
        let mut window = Window::EMPTY;
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
        self.norm = libm::sqrtf(ss);
        true
    }
}

/// The template grid rounded to integers for the search.
struct Quantized<const N: usize> {
    /// Rounded values (gray level minus 128, so in -128..=127).
    values: [[i16; N]; N],
    /// `sum q` and `n sum q^2 - (sum q)^2` with `n = N^2` (exact in i64).
    sum: i64,
    var_n2: i64,
    /// `sqrt(var_n2)`, the template's factor of every candidate's ZNCC denominator.
    root_var_n2: f32,
}

impl<const N: usize> Quantized<N> {
    /// All zero, to be filled by [`Self::fill`].
    const EMPTY: Self = Self { values: [[0; N]; N], sum: 0, var_n2: 0, root_var_n2: 0.0 };

    /// Fills `self` with the rounded grid of `t` and its sums.
    fn fill<const S: usize>(&mut self, t: &Template<N, S>) {
        let (mut qs, mut qss) = (0i64, 0i64);
        for (q_row, v_row) in self.values.iter_mut().zip(&t.values[1..]) {
            for (q, &v) in q_row.iter_mut().zip(&v_row[1..]) {
                // Values are in -128..128, so `v + 128.5` is positive and truncation rounds it
                // half up: the same bits on every target, without a call to `roundf`.
                let r = ((v + 128.5) as i32 - 128) as i16;
                *q = r;
                qs += i64::from(r);
                qss += i64::from(r) * i64::from(r);
            }
        }
        // At most 169 * 169 * 128^2: far inside i64.
        let var_n2 = (N * N) as i64 * qss - qs * qs;
        (self.sum, self.var_n2) = (qs, var_n2);
        self.root_var_n2 = libm::sqrtf(exact_f32(var_n2));
    }

    /// `sum s q` over the `N x N` block of target pixels `s` whose top-left pixel is `(x0, y0)`
    /// (inside the image: checked by the caller); `None` when a row leaves the buffer.
    fn product(&self, data: &[u8], stride: usize, (x0, y0): (usize, usize)) -> Option<i32> {
        // |sum| <= 169 * 255 * 128: exact in i32.
        let mut st = 0i32;
        for (j, q_row) in self.values.iter().enumerate() {
            let start = (y0 + j) * stride + x0;
            let row: &[u8; N] = data.get(start..start + N)?.try_into().ok()?;
            for (&s, &v) in row.iter().zip(q_row) {
                st += i32::from(s) * i32::from(v);
            }
        }
        Some(st)
    }

    /// [`Self::product`] of the [`ROW_BATCH`] (3) blocks whose top-left pixels are `(x0 + k,
    /// y0)`, `k in 0..3`, or `None` when a row leaves the buffer or the template is too large
    /// for the packed sums (`N > 11`). The same exact integer sums as three calls, in fewer
    /// instructions: each pixel of a row is read once for all three blocks (`N + 2` pixels
    /// instead of `3N`), and the sums of blocks 0 and 1 share one 64-bit multiply-accumulate
    /// (`smlal` on the Cortex-M4): pixel `p` meets template column `p` of block 0 and `p - 1` of
    /// block 1, so `s * (q[p] + q[p - 1] 2^23)` adds to both at once, block 0's sum in the low
    /// 23 bits (its magnitude is at most `121 * 255 * 128 < 2^22` for `N <= 11`) and block 1's
    /// above them. On the Cortex-M4 at `N = 9` a template row of the three blocks compiles to
    /// about 88 instructions (the compiler still spills some values to the stack) against about
    /// 114 for three single products; over 1000 frames of 7-Scenes (`cargo xtask budgets`) the
    /// pipeline median went from 6.36 to 6.23 M instructions, every output bit the same.
    fn products(&self, data: &[u8], stride: usize, (x0, y0): (usize, usize)) -> Option<[i32; 3]> {
        if N * N * 255 * 128 >= 1 << (LANE_SHIFT - 1) {
            return None;
        }
        let (mut packed, mut third) = (0i64, 0i32);
        for (j, q_row) in self.values.iter().enumerate() {
            let start = (y0 + j) * stride + x0;
            let row = data.get(start..start + N + 2)?;
            // Template column `i` of this row, 0 outside it (`p - 1` and `p - 2` wrap below 0).
            let q = |i: usize| q_row.get(i).map_or(0, |&v| i32::from(v));
            for (p, &s) in row.iter().enumerate() {
                let s = i32::from(s);
                // |q| <= 128: the shifted value is within +-2^30.
                let pair = q(p) + (q(p.wrapping_sub(1)) << LANE_SHIFT);
                packed += i64::from(s) * i64::from(pair);
                third += s * q(p.wrapping_sub(2));
            }
        }
        // Block 0's sum is the low `LANE_SHIFT` bits, sign-extended (truncating to i32 keeps
        // them); block 1's is the rest, exactly.
        let first = ((packed as i32) << (32 - LANE_SHIFT)) >> (32 - LANE_SHIFT);
        let second = (packed - i64::from(first)) >> LANE_SHIFT;
        Some([first, i32::try_from(second).ok()?, third])
    }

    /// ZNCC of the block whose product with the template is `st` ([`Self::product`]) and whose
    /// sum and sum of squares are `block`, from exact integer sums; `None` when either is flat.
    fn zncc(&self, st: i32, block: BlockSums) -> Option<f32> {
        let len = (N * N) as i64;
        let (s1, s2, st) = (i64::from(block.sum), i64::from(block.sum_sq), i64::from(st));
        let var_s = len * s2 - s1 * s1;
        let cov = len * st - s1 * self.sum;
        // Less than ~0.05 gray levels of spread carries no correlation.
        if var_s * 1000 <= len * len || self.var_n2 <= 0 {
            return None;
        }
        // Both factors are below 1.87e9 (see `exact_f32`): their f32 roots lose nothing that
        // matters at ZNCC scale.
        let denom = libm::sqrtf(exact_f32(var_s)) * self.root_var_n2;
        Some((exact_f32(cov) / denom).clamp(-1.0, 1.0))
    }
}

/// `v as f32`, through `i32` when `v` fits (every sum of [`Quantized::zncc`] does: the largest,
/// `n sum s^2` and `|n sum s q|` at 13 x 13, are below 1.87e9): the same value (the nearest f32 to
/// the integer either way), but the Cortex-M4 converts an `i32` in one instruction and an `i64`
/// in a library call.
fn exact_f32(v: i64) -> f32 {
    match i32::try_from(v) {
        Ok(v) => v as f32,
        Err(_) => wide_f32(v),
    }
}

/// `v as f32` out of line: written inline, the compiler converted both ways and kept one, so the
/// library call ran for every ZNCC (146 k instructions a frame on the Cortex-M4, 7-Scenes).
#[cold]
#[inline(never)]
fn wide_f32(v: i64) -> f32 {
    v as f32
}

/// Adjacent candidates whose products with the template [`search`] computes together
/// ([`Quantized::products`]).
const ROW_BATCH: usize = 3;

/// Bit where the second block's sum starts in [`Quantized::products`]' packed sum.
const LANE_SHIFT: u32 = 23;

/// Widest search window of [`track_patch`], pixels: `2R + 2h + 1` at the largest `R` and `h`.
const MAX_WINDOW: usize = 2 * MAX_TRACK_SEARCH_RADIUS + 2 * MAX_TRACK_HALF_SIZE + 1;

/// The sum and the sum of squares of a block of target pixels (exact: at most 169 * 255^2).
#[derive(Debug, Clone, Copy)]
struct BlockSums {
    sum: i32,
    sum_sq: i32,
}

/// The target's column sums over the `N` rows of one row of candidates: for every window column,
/// the sum and the sum of squares of the `N` pixels below it. A candidate's block sums are then
/// `N` column sums instead of `N^2` pixels, so its ZNCC reads the pixels only for the product with
/// the template.
struct ColumnSums<const N: usize> {
    sum: [i32; MAX_WINDOW],
    sum_sq: [i32; MAX_WINDOW],
    /// Window row of the candidates these sums are for; `None` before the first row or when a
    /// row left the buffer (impossible after the caller's check; its candidates then score -1).
    row: Option<usize>,
}

impl<const N: usize> ColumnSums<N> {
    fn new() -> Self {
        Self { sum: [0; MAX_WINDOW], sum_sq: [0; MAX_WINDOW], row: None }
    }

    /// The block sums of the candidate at window column `ix` of the candidate row whose top
    /// pixel row is `y` (window row `iy`); the window starts at column `x0` and is `width`
    /// columns wide. Updates the column sums when the candidate row changes: by the rows that
    /// left and entered the `N` rows when it moved down by less than `N` (the coarse pass visits
    /// its rows top to bottom), otherwise from scratch. All sums are exact integers, so both ways
    /// give the same values.
    fn block(
        &mut self,
        data: &[u8],
        stride: usize,
        (x0, y): (usize, usize),
        (ix, iy): (usize, usize),
        width: usize,
    ) -> Option<BlockSums> {
        if self.row != Some(iy) {
            let previous = self.row.take();
            let width = width.min(MAX_WINDOW);
            let (sum, sum_sq) = (&mut self.sum[..width], &mut self.sum_sq[..width]);
            let pixels = |j: usize| {
                let start = j * stride + x0;
                data.get(start..start + width)
            };
            match previous {
                Some(p) if p < iy && iy - p < N => {
                    // Window row `r` is image row `y - iy + r`.
                    let top = y - iy;
                    for r in p..iy {
                        let (gone, new) = (pixels(top + r)?, pixels(top + r + N)?);
                        let columns =
                            sum.iter_mut().zip(sum_sq.iter_mut()).zip(gone.iter().zip(new));
                        for ((a, b), (&g, &n)) in columns {
                            let (g, n) = (i32::from(g), i32::from(n));
                            *a += n - g;
                            *b += n * n - g * g;
                        }
                    }
                }
                _ => {
                    sum.fill(0);
                    sum_sq.fill(0);
                    for j in 0..N {
                        let row = pixels(y + j)?;
                        for ((a, b), &s) in sum.iter_mut().zip(sum_sq.iter_mut()).zip(row) {
                            let s = i32::from(s);
                            *a += s;
                            *b += s * s;
                        }
                    }
                }
            }
            self.row = Some(iy);
        }
        let sum = self.sum.get(ix..ix + N)?.iter().sum();
        let sum_sq = self.sum_sq.get(ix..ix + N)?.iter().sum();
        Some(BlockSums { sum, sum_sq })
    }
}

/// One in 16.16 fixed point.
const FIXED_ONE: f32 = 65536.0;

/// Bilinear sample of the image buffer `data` (rows `stride` apart) at the 16.16 fixed-point
/// position `(x, y)`, which the caller has checked lies in `[0, w - 1) x [0, h - 1)`; a read past
/// the buffer (impossible then) gives 0.
fn bilinear_fixed(data: &[u8], stride: usize, x: i32, y: i32) -> f32 {
    // Non-negative by the caller's check; a negative value would read index 0's neighbourhood.
    let (x0, y0) = ((x >> 16).max(0) as usize, (y >> 16).max(0) as usize);
    let i = y0 * stride + x0;
    // The four pixels are the first two and the last two of one slice: one bounds check.
    let quad = data.get(i..i.saturating_add(stride + 2)).unwrap_or(&[]);
    let (Some((&[p00, p10], _)), Some(&[p01, p11])) =
        (quad.split_first_chunk::<2>(), quad.last_chunk::<2>())
    else {
        return 0.0;
    };
    lerp_fixed(x, y, [p00, p10, p01, p11])
}

/// Fills `out` with [`bilinear_fixed`] samples of `data` (rows `stride` apart) at the 16.16
/// fixed-point positions `starts[j] + k step` (row `j`, column `k`), minus the gray offset.
fn sample_each<const S: usize>(
    data: &[u8],
    stride: usize,
    starts: &[(i32, i32); S],
    step: (i32, i32),
    out: &mut [[f32; S]; S],
) {
    for (out_row, &(mut x, mut y)) in out.iter_mut().zip(starts) {
        for v in out_row.iter_mut() {
            *v = bilinear_fixed(data, stride, x, y) - GRAY_OFFSET;
            (x, y) = (x.wrapping_add(step.0), y.wrapping_add(step.1));
        }
    }
}

/// Bilinear interpolation of the pixels `[p00, p10, p01, p11]` (top-left, top-right,
/// bottom-left, bottom-right) at the fractional parts of the 16.16 fixed-point `x` and `y`.
///
/// The horizontal passes are exact integers: `p00 2^16 + (x mod 2^16)(p10 - p00)` lies between
/// `p00 2^16` and `p10 2^16`, below `2^24`, so it and the difference of the two rows are exact
/// in f32 too. The vertical pass rounds once for the product and once for the sum, the same two
/// roundings as `top + fy (bottom - top)` in floating point throughout: `fy = (y mod 2^16)
/// 2^-32` is the fraction pre-scaled by the rows' `2^-16`, exact as a power-of-two scaling.
#[inline(always)]
fn lerp_fixed(x: i32, y: i32, [p00, p10, p01, p11]: [u8; 4]) -> f32 {
    let fx = x & 0xFFFF;
    let pass = |a: u8, b: u8| (i32::from(a) << 16) + fx * (i32::from(b) - i32::from(a));
    let (top, bottom) = (pass(p00, p10), pass(p01, p11));
    let fy = (y & 0xFFFF) as f32 * (1.0 / (FIXED_ONE * FIXED_ONE));
    top as f32 * (1.0 / FIXED_ONE) + fy * (bottom - top) as f32
}

/// Side of a [`Window`], pixels: a tracked landmark's template (16 x 16) fits one, and a power
/// of two makes a masked index in bounds by construction, so the samples read it unchecked.
const WINDOW_SIDE: usize = 16;

/// `dst = src` as word moves: a plain `*dst = *src` of unaligned bytes compiles to a call of the
/// byte-wise `memcpy` on the Cortex-M4, several times slower.
#[inline(always)]
fn copy_row(dst: &mut [u8; WINDOW_SIDE], src: &[u8; WINDOW_SIDE]) {
    for (d, s) in dst.as_chunks_mut::<4>().0.iter_mut().zip(src.as_chunks::<4>().0) {
        *d = u32::from_ne_bytes(*s).to_ne_bytes();
    }
}

/// A copy of the pixels a template warp reads, in rows of [`WINDOW_SIDE`] pixels, with two
/// spare rows so that the neighbours of any masked index are in the array too.
struct Window {
    rows: [[u8; WINDOW_SIDE]; WINDOW_SIDE + 2],
}

impl Window {
    /// All zero, to be filled by [`Self::sample`].
    const EMPTY: Self = Self { rows: [[0; WINDOW_SIDE]; WINDOW_SIDE + 2] };

    /// Fills `out` with the bilinear samples of `data` (rows `stride` apart) at the 16.16
    /// fixed-point positions `starts[j] + k step` (row `j`, column `k`), minus the gray offset,
    /// through a copy of the pixels they read; `false` (and `out` untouched) when those pixels
    /// do not fit a window or its rows leave the buffer, for [`sample_each`]. The values are those
    /// of [`sample_each`], bit for bit: the same pixels, the same [`lerp_fixed`]; only the
    /// per-sample bounds checks of [`bilinear_fixed`] are gone, with the copy paid once.
    fn sample<const S: usize>(
        &mut self,
        data: &[u8],
        stride: usize,
        starts: &[(i32, i32); S],
        step: (i32, i32),
        out: &mut [[f32; S]; S],
    ) -> bool {
        // A row's positions move linearly, so its extremes are its ends (the wrapping product
        // matches the samples' wrapping steps).
        let span = (S as i32 - 1).wrapping_mul(step.0);
        let span_y = (S as i32 - 1).wrapping_mul(step.1);
        let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (i32::MAX, i32::MIN, i32::MAX, i32::MIN);
        for &(x, y) in starts {
            let (x_end, y_end) = (x.wrapping_add(span), y.wrapping_add(span_y));
            x_lo = x_lo.min(x.min(x_end) >> 16);
            x_hi = x_hi.max(x.max(x_end) >> 16);
            y_lo = y_lo.min(y.min(y_end) >> 16);
            y_hi = y_hi.max(y.max(y_end) >> 16);
        }
        // The pixels read: columns `x_lo..=x_hi + 1`, rows `y_lo..=y_hi + 1`.
        let side = WINDOW_SIDE as i32;
        if x_lo < 0 || y_lo < 0 || y_hi - y_lo + 2 > side {
            return false;
        }
        // The window's first column: `x_lo`, or further left so that each row's copy ends
        // inside that row (a buffer's last row has no pixels after it). A 16 x 16 template is
        // copied whole-row from column 0.
        let x_org = x_lo.min(i32::try_from(stride.saturating_sub(WINDOW_SIDE)).unwrap_or(i32::MAX));
        if x_hi - x_org + 2 > side {
            return false;
        }
        let (x_org, y_lo) = (x_org as usize, y_lo as usize);
        let rows = (y_hi - y_lo as i32 + 2) as usize;
        for (r, dst) in self.rows.iter_mut().take(rows).enumerate() {
            let start = (y_lo + r) * stride + x_org;
            let Some(src) = data.get(start..).and_then(<[u8]>::first_chunk::<WINDOW_SIDE>) else {
                return false;
            };
            copy_row(dst, src);
        }
        let origin = ((x_org as i32) << 16, (y_lo as i32) << 16);
        let px = self.rows.as_flattened();
        let at = |k: usize| px.get(k).copied().unwrap_or(0);
        for (out_row, &(x, y)) in out.iter_mut().zip(starts) {
            let (mut x, mut y) = (x.wrapping_sub(origin.0), y.wrapping_sub(origin.1));
            for v in out_row.iter_mut() {
                // In 0..WINDOW_SIDE - 1 on both axes by the bounds above; the mask says so.
                let i = ((y >> 16) as usize * WINDOW_SIDE + (x >> 16) as usize)
                    & (WINDOW_SIDE * WINDOW_SIDE - 1);
                let quad = [at(i), at(i + 1), at(i + WINDOW_SIDE), at(i + WINDOW_SIDE + 1)];
                *v = lerp_fixed(x, y, quad) - GRAY_OFFSET;
                (x, y) = (x.wrapping_add(step.0), y.wrapping_add(step.1));
            }
        }
        true
    }
}

/// The integer search of step 2 of the module documentation: the best pixel (integer
/// coordinates, within `R` of the rounded prediction on each axis) and its ZNCC.
fn search<const N: usize, const S: usize>(
    t: &Template<N, S>,
    target: &GrayView<'_>,
    predicted: (f32, f32),
    params: &TrackParams,
) -> Result<((usize, usize), f32), MatchError> {
    let (h, r) = (N / 2, params.search_radius);
    let (w, img_h) = target.size();
    let (px, py) = (libm::roundf(predicted.0), libm::roundf(predicted.1));
    let reach = (r + h) as f32;
    // NaN fails the comparisons; the casts below only see values inside the image.
    let inside = px - reach >= 0.0
        && py - reach >= 0.0
        && px + reach <= (w - 1) as f32
        && py + reach <= (img_h - 1) as f32;
    if !inside {
        return Err(MatchError::NoCandidate);
    }
    // Top-left pixel of the candidate at score index (0, 0).
    let (x0, y0) = ((px - reach) as usize, (py - reach) as usize);
    let (data, stride) = (target.data(), target.stride());
    let step = params.search_step;
    let mut q = Quantized::EMPTY;
    q.fill(t);
    let width = 2 * r + N;
    let mut columns = ColumnSums::<N>::new();
    // The score of the candidate at window position `(ix, iy)` whose product with the template
    // is `st` (computed here when `None`).
    let mut score = |ix: usize, iy: usize, st: Option<i32>| {
        columns
            .block(data, stride, (x0, y0 + iy), (ix, iy), width)
            .and_then(|b| {
                let st = st.or_else(|| q.product(data, stride, (x0 + ix, y0 + iy)))?;
                q.zncc(st, b)
            })
            .unwrap_or(-1.0)
    };
    // Kept only for the ambiguity test: filling its 1,156 bytes on every fine track too cost
    // about 0.02 M instructions a frame on the Cortex-M4.
    let mut scores =
        params.min_peak_margin.map(|_| [f32::NEG_INFINITY; MAX_SCORE_SIDE * MAX_SCORE_SIDE]);
    let k_max = r / step;
    let csize = 2 * k_max + 1;
    // Coarse pass on offsets `k * step`, `k in -k_max..=k_max` (the prediction itself included);
    // scores are kept on the coarse grid, index `ky * csize + kx`.
    let coarse = |k: usize| r + k * step - k_max * step;
    let mut best = (r, r, f32::NEG_INFINITY);
    let mut best_k = (k_max, k_max);
    for ky in 0..csize {
        let iy = coarse(ky);
        let mut kx = 0;
        while kx < csize {
            // Adjacent candidates (step 1) share their pixels: their products come in batches
            // of [`ROW_BATCH`] ([`Quantized::products`]). Scores, and so the order of ties, are
            // those of single products.
            let batch = (step == 1 && kx + ROW_BATCH <= csize)
                .then(|| q.products(data, stride, (x0 + coarse(kx), y0 + iy)))
                .flatten();
            let n = batch.map_or(1, |_| ROW_BATCH);
            for k in 0..n {
                let ix = coarse(kx + k);
                let s = score(ix, iy, batch.and_then(|b| b.get(k).copied()));
                if let Some(slot) = scores.as_mut().and_then(|g| g.get_mut(ky * csize + kx + k)) {
                    *slot = s;
                }
                if s > best.2 {
                    best = (ix, iy, s);
                    best_k = (kx + k, ky);
                }
            }
            kx += n;
        }
    }
    if let (Some(margin), Some(scores)) = (params.min_peak_margin, &scores) {
        let second = second_peak(scores, csize, best_k);
        if second > best.2 - margin {
            return Err(MatchError::Ambiguous { best: best.2, second });
        }
    }
    if step > 1 {
        // Fine pass: every integer offset within `step - 1` of the coarse best.
        let (cx, cy) = (best.0, best.1);
        best.2 = f32::NEG_INFINITY;
        let reach_fine = step - 1;
        for iy in cy.saturating_sub(reach_fine)..=(cy + reach_fine).min(2 * r) {
            for ix in cx.saturating_sub(reach_fine)..=(cx + reach_fine).min(2 * r) {
                let s = score(ix, iy, None);
                if s > best.2 {
                    best = (ix, iy, s);
                }
            }
        }
    }
    if best.2 <= -1.0 {
        return Err(MatchError::NoCandidate);
    }
    Ok(((x0 + h + best.0, y0 + h + best.1), best.2))
}

/// The best coarse local maximum (over its 8 coarse neighbours) more than one coarse step from
/// `best` (coarse grid indices), over the `csize` x `csize` coarse grid `scores`; `-1` when there
/// is none.
fn second_peak(scores: &[f32], csize: usize, best: (usize, usize)) -> f32 {
    let n = csize as isize;
    let at = |kx: isize, ky: isize| -> f32 {
        if kx < 0 || ky < 0 || kx >= n || ky >= n {
            return f32::NEG_INFINITY;
        }
        scores.get((ky * n + kx) as usize).copied().unwrap_or(f32::NEG_INFINITY)
    };
    let mut second = -1.0f32;
    for ky in 0..n {
        for kx in 0..n {
            if (kx as usize).abs_diff(best.0) <= 1 && (ky as usize).abs_diff(best.1) <= 1 {
                continue;
            }
            let s = at(kx, ky);
            // Only a candidate above the best so far is checked for being a peak (the check reads
            // 8 neighbours; most candidates fail the cheap comparison first).
            if s <= second || s.is_nan() {
                continue;
            }
            let is_peak = (-1..=1)
                .all(|dy| (-1..=1).all(|dx| (dx == 0 && dy == 0) || at(kx + dx, ky + dy) <= s));
            if is_peak {
                second = s;
            }
        }
    }
    second
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
        let mut m = Self { sum: 0.0, sum_sq: 0.0, gx_v: 0.0, gy_v: 0.0, z_v: 0.0 };
        // The horizontal pass of the previous row, reused as the top of the next.
        let mut top = Self::row::<N>(img, bx, by, fx)?;
        let rows = sd.gx.iter().zip(&sd.gy).zip(z).enumerate();
        for (j, ((gxr, gyr), zr)) in rows {
            let bot = Self::row::<N>(img, bx, by + j + 1, fx)?;
            for i in 0..N {
                let v = top[i] + fy * (bot[i] - top[i]);
                m.sum += v;
                m.sum_sq += v * v;
                if STEP {
                    m.gx_v += gxr[i] * v;
                    m.gy_v += gyr[i] * v;
                }
                if SCORE {
                    m.z_v += zr[i] * v;
                }
            }
            top = bot;
        }
        Some(m)
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
/// documentation); the refined position and its ZNCC.
fn refine<const N: usize, const S: usize>(
    t: &Template<N, S>,
    target: &GrayView<'_>,
    start: (f32, f32),
    params: &TrackParams,
) -> Result<((f32, f32), f32), MatchError> {
    let mut sd = Steepest::EMPTY;
    if !sd.fill(t) {
        return Err(MatchError::RefinementFailed);
    }
    let half = (N / 2) as f32;
    let len = (N * N) as f32;
    let origin = |c: (f32, f32)| (c.0 - half, c.1 - half);
    let mut c = start;
    for _ in 0..params.max_iterations {
        let m = Moments::at::<N, true, false>(target, origin(c), &sd, &t.zero_mean)
            .ok_or(MatchError::RefinementFailed)?;
        let norm_i = libm::sqrtf(m.variance(len));
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
    let m = Moments::at::<N, false, true>(target, origin(c), &sd, &t.zero_mean)
        .ok_or(MatchError::RefinementFailed)?;
    let var = m.variance(len);
    // Less than ~0.05 gray levels of spread carries no correlation.
    if var.is_nan() || var <= 1e-3 * len || t.norm.is_nan() || t.norm <= 0.0 {
        return Err(MatchError::RefinementFailed);
    }
    // `sum z (v - mean) = sum z v` as `z` has zero mean. Rounding can push a perfect match a few
    // ulps past 1.
    let score = (m.z_v / (libm::sqrtf(var) * t.norm)).clamp(-1.0, 1.0);
    Ok((c, score))
}

/// [`track_patch`] for one template size (`N = 2h + 1`, `S = N + 2`), after its checks.
fn track_fixed<const N: usize, const S: usize>(
    template_img: &GrayView<'_>,
    centre: (f32, f32),
    a_inv: &Mat2,
    target: &GrayView<'_>,
    predicted: (f32, f32),
    params: &TrackParams,
) -> Result<PatchTrack, MatchError> {
    let mut t = Template::<N, S>::EMPTY;
    if !t.warp(template_img, centre, a_inv) {
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
        let ((x, y), best) = search(&t, target, predicted, params)?;
        if best < params.min_zncc - HOPELESS_MARGIN {
            return Err(MatchError::LowCorrelation { zncc: best });
        }
        // Pixel coordinates are far below 2^24: exact in f32.
        (x as f32, y as f32)
    };
    let (uv, zncc) = refine(&t, target, start, params)?;
    if zncc.is_nan() || zncc < params.min_zncc {
        return Err(MatchError::LowCorrelation { zncc });
    }
    let (dx, dy) = (uv.0 - predicted.0, uv.1 - predicted.1);
    Ok(PatchTrack { uv, zncc, offset_px: libm::sqrtf(dx * dx + dy * dy) })
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
    let finite = centre.0.is_finite()
        && centre.1.is_finite()
        && predicted.0.is_finite()
        && predicted.1.is_finite();
    if !params.is_valid() || !finite {
        return Err(MatchError::InvalidParams);
    }
    let a_inv = mat_inverse(affine).ok_or(MatchError::InvalidParams)?;
    let args = (template_img, centre, &a_inv, target, predicted, params);
    match params.half_size {
        1 => track_fixed::<3, 5>(args.0, args.1, args.2, args.3, args.4, args.5),
        2 => track_fixed::<5, 7>(args.0, args.1, args.2, args.3, args.4, args.5),
        3 => track_fixed::<7, 9>(args.0, args.1, args.2, args.3, args.4, args.5),
        4 => track_fixed::<9, 11>(args.0, args.1, args.2, args.3, args.4, args.5),
        5 => track_fixed::<11, 13>(args.0, args.1, args.2, args.3, args.4, args.5),
        6 => track_fixed::<13, 15>(args.0, args.1, args.2, args.3, args.4, args.5),
        _ => Err(MatchError::InvalidParams),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 40 x 40 image of pseudo-random pixels from `seed` (a linear congruential generator).
    fn noise_image(seed: u32) -> [u8; 40 * 40] {
        let mut state = seed;
        let mut img = [0u8; 40 * 40];
        for p in img.iter_mut() {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            *p = (state >> 24) as u8;
        }
        img
    }

    /// The batched, packed products equal one product per block, at the extremes of the
    /// template and pixel ranges too; too large a template is left to the single products.
    #[test]
    fn batched_products_equal_single_ones() {
        fn check<const N: usize>(img: &[u8], w: usize, fill: impl Fn(usize) -> i16) {
            let mut q = Quantized::<N>::EMPTY;
            for (k, v) in q.values.as_flattened_mut().iter_mut().enumerate() {
                *v = fill(k);
            }
            for (x0, y0) in [(0usize, 0usize), (5, 3), (w - N - 2, 40 - N)] {
                let batch = q.products(img, w, (x0, y0));
                let single: [Option<i32>; 3] =
                    core::array::from_fn(|k| q.product(img, w, (x0 + k, y0)));
                if N <= 11 {
                    assert_eq!(batch.map(|b| b.map(Some)), Some(single), "{N} at {x0}, {y0}");
                } else {
                    assert_eq!(batch, None);
                }
            }
        }
        let w = 40usize;
        let noise = noise_image(777);
        let white = [255u8; 40 * 40];
        for img in [&noise, &white] {
            check::<9>(img, w, |k| (k as i16 * 37) % 256 - 128);
            check::<9>(img, w, |_| -128);
            check::<9>(img, w, |_| 127);
            check::<11>(img, w, |k| if k % 2 == 0 { -128 } else { 127 });
            check::<11>(img, w, |_| -128);
            check::<13>(img, w, |_| 1);
        }
    }

    /// The window's samples equal the checked ones bit for bit, on a 16 x 16 template and on a
    /// larger image; warps whose pixels do not fit a window, or leave the image, are refused.
    #[test]
    fn window_samples_equal_checked_ones() {
        const S: usize = 11;
        /// The start of each row and the step, as [`Template::warp`] makes them.
        fn grid(centre: (f32, f32), a_inv: &Mat2) -> ([(i32, i32); S], (i32, i32)) {
            let fixed = |v: f32| libm::roundf(v * FIXED_ONE) as i32;
            let m = (S / 2) as f32;
            let starts = core::array::from_fn(|j| {
                let (dx, dy) = mat_apply(a_inv, (-m, j as f32 - m));
                (fixed(centre.0 + dx), fixed(centre.1 + dy))
            });
            (starts, (fixed(a_inv[0][0]), fixed(a_inv[1][0])))
        }
        let (c, s) = (libm::cosf(0.5), libm::sinf(0.5));
        let maps: [Mat2; 5] = [
            [[1.0, 0.0], [0.0, 1.0]],
            [[c, -s], [s, c]],
            [[0.8 * c, 0.8 * s], [-0.8 * s, 0.8 * c]],
            [[1.1, 0.2], [-0.15, 0.9]],
            [[-1.0, 0.0], [0.0, -1.0]],
        ];
        let bits = |g: &[[f32; S]; S]| g.map(|row| row.map(f32::to_bits));
        let noise = noise_image(4242);
        let patch = noise.get(..16 * 16).unwrap_or(&[]);
        // Centres whose grids stay inside `[0, w - 1)` under every map, as warp checks.
        for (data, stride, centres) in [
            (patch, 16usize, [(7.5, 7.5), (7.0, 7.75), (8.0, 7.2)]),
            (&noise[..], 40, [(20.0, 20.0), (31.0, 30.5), (8.4, 8.2)]),
        ] {
            for a_inv in &maps {
                for &centre in &centres {
                    let (starts, step) = grid(centre, a_inv);
                    let (mut fast, mut each) = ([[0.0f32; S]; S], [[0.0f32; S]; S]);
                    let mut window = Window::EMPTY;
                    let taken = window.sample(data, stride, &starts, step, &mut fast);
                    assert!(taken, "{centre:?} {a_inv:?} fits a window");
                    sample_each(data, stride, &starts, step, &mut each);
                    assert_eq!(bits(&fast), bits(&each), "{centre:?} {a_inv:?}");
                }
            }
        }
        let refused = |data: &[u8], centre: (f32, f32), a_inv: &Mat2| {
            let (starts, step) = grid(centre, a_inv);
            let mut window = Window::EMPTY;
            !window.sample(data, 40, &starts, step, &mut [[0.0f32; S]; S])
        };
        let scale = |k: f32| [[k, 0.0], [0.0, k]];
        // Twice the scale: 21 pixels on a side, more than a window.
        assert!(refused(&noise, (20.0, 20.0), &scale(2.0)));
        // Left of the image.
        assert!(refused(&noise, (3.0, 20.0), &scale(1.0)));
        // Rows past the buffer's end.
        assert!(refused(noise.get(..24 * 40).unwrap_or(&[]), (20.0, 20.0), &scale(1.0)));
    }

    /// Column sums slid from any earlier candidate row equal the sums computed from scratch.
    #[test]
    fn slid_column_sums_equal_fresh_ones() {
        const N: usize = 9;
        let (w, h) = (40usize, 40usize);
        let img = noise_image(12345);
        let (x0, y0, width) = (3usize, 2usize, 2 * 8 + N);
        // Row visits as the coarse (steps 1, 2, 3, 8) and fine passes make them, and jumps back;
        // every visited block lies inside the image.
        let visits = [0usize, 1, 2, 4, 7, 15, 16, 3, 3, 12, 11, 20];
        assert!(y0 + visits.iter().max().copied().unwrap_or(0) + N <= h);
        let mut slid = ColumnSums::<N>::new();
        for &iy in &visits {
            let mut fresh = ColumnSums::<N>::new();
            for ix in [0usize, 5, width - N] {
                let a =
                    slid.block(&img, w, (x0, y0 + iy), (ix, iy), width).map(|b| (b.sum, b.sum_sq));
                let b =
                    fresh.block(&img, w, (x0, y0 + iy), (ix, iy), width).map(|b| (b.sum, b.sum_sq));
                assert!(a.is_some(), "row {iy} column {ix} inside the image");
                assert_eq!(a, b, "row {iy} column {ix}");
            }
        }
    }
}
