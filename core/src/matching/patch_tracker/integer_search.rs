//! The integer search of step 2 of the [module documentation](super): the template rounded to
//! integers, candidates' block sums from shared column sums, their ZNCC from exact integer sums,
//! and the ambiguity test over the coarse scores.

use ferroslam_fpu::smlad;

use super::{Template, TrackParams};
use crate::image::GrayView;
use crate::matching::MatchError;
use crate::matching::patch_tracker::{
    MAX_TRACK_COARSE_STEPS, MAX_TRACK_HALF_SIZE, MAX_TRACK_SEARCH_RADIUS,
};

/// Side of the largest coarse score grid.
const MAX_SCORE_SIDE: usize = 2 * MAX_TRACK_COARSE_STEPS + 1;

/// The template grid rounded to integers for the search.
pub(super) struct Quantized<const N: usize> {
    /// Rounded values (gray level minus 128, so in -128..=127).
    values: [[i16; N]; N],
    /// For the products ([`row_product`]): each row's columns `(4g, 4g + 2)` and `(4g + 1, 4g + 3)` of
    /// group `g` as the 16-bit halves of a word (low half first), groups `0..N / 4`.
    pairs: [[u32; 2 * MAX_GROUPS]; N],
    /// `sum q` and `n sum q^2 - (sum q)^2` with `n = N^2` (exact in i64).
    sum: i64,
    var_n2: i64,
    /// `sqrt(var_n2)`, the template's factor of every candidate's ZNCC denominator.
    root_var_n2: f32,
}

impl<const N: usize> Quantized<N> {
    /// All zero, to be filled by [`Self::fill`] (which writes every field).
    pub(super) const EMPTY: Self = Self {
        values: [[0; N]; N],
        pairs: [[0; 2 * MAX_GROUPS]; N],
        sum: 0,
        var_n2: 0,
        root_var_n2: 0.0,
    };

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
        self.pack_pairs();
        // At most 169 * 169 * 128^2: far inside i64.
        let var_n2 = (N * N) as i64 * qss - qs * qs;
        (self.sum, self.var_n2) = (qs, var_n2);
        self.root_var_n2 = ferroslam_fpu::sqrtf(exact_f32(var_n2));
    }

    /// Sets [`Self::pairs`] from the values.
    fn pack_pairs(&mut self) {
        for (pairs, q_row) in self.pairs.iter_mut().zip(&self.values) {
            // Columns past the row are 0 (only in groups that `products` does not read).
            let q = |c: usize| q_row.get(c).map_or(0, |&v| u32::from(v as u16));
            for (g, pair) in pairs.chunks_exact_mut(2).enumerate() {
                let c = 4 * g;
                if let [even, odd] = pair {
                    (*even, *odd) = (q(c) | (q(c + 2) << 16), q(c + 1) | (q(c + 3) << 16));
                }
            }
        }
    }

    /// `sum s q` over the `N x N` block of target pixels `s` whose top-left pixel is `(x0, y0)`
    /// (inside the image: checked by the caller); `None` when a row leaves the buffer. Exact in
    /// i32 (`|sum| <= 169 * 255 * 128`).
    fn product(&self, data: &[u8], stride: usize, (x0, y0): (usize, usize)) -> Option<i32> {
        let mut st = 0i32;
        for (j, (q_row, pairs)) in self.values.iter().zip(&self.pairs).enumerate() {
            let start = (y0 + j) * stride + x0;
            st = row_product(q_row, pairs, data.get(start..start + N)?, st)?;
        }
        Some(st)
    }

    /// [`Self::product`] of the `B` blocks whose top-left pixels are `(x0 + k, y0)`, `k in
    /// 0..B`, or `None` when a row leaves the buffer. The same exact integer sums as `B` calls,
    /// in fewer instructions: each row is found and checked once for all the blocks, and the
    /// template's pairs are loaded once (docs/decisions.md, "Batched search products").
    fn products<const B: usize>(
        &self,
        data: &[u8],
        stride: usize,
        (x0, y0): (usize, usize),
    ) -> Option<[i32; B]> {
        let mut sums = [0i32; B];
        for (j, (q_row, pairs)) in self.values.iter().zip(&self.pairs).enumerate() {
            let start = (y0 + j) * stride + x0;
            let row = data.get(start..start + N + B - 1)?;
            for (b, sum) in sums.iter_mut().enumerate() {
                *sum = row_product(q_row, pairs, row.get(b..)?, *sum)?;
            }
        }
        Some(sums)
    }

    /// The products of the widest batch of adjacent blocks from `at` that `left` blocks hold
    /// ([`WIDE_BATCH`] or [`ROW_BATCH`]), and its width; `None` when none fits or a row leaves
    /// the buffer.
    fn batch(
        &self,
        data: &[u8],
        stride: usize,
        at: (usize, usize),
        left: usize,
    ) -> Option<([i32; WIDE_BATCH], usize)> {
        if left >= WIDE_BATCH {
            return Some((self.products::<WIDE_BATCH>(data, stride, at)?, WIDE_BATCH));
        }
        if left < ROW_BATCH {
            return None;
        }
        let three = self.products::<ROW_BATCH>(data, stride, at)?;
        let mut out = [0; WIDE_BATCH];
        for (o, v) in out.iter_mut().zip(three) {
            *o = v;
        }
        Some((out, ROW_BATCH))
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
        let denom = ferroslam_fpu::sqrtf(exact_f32(var_s)) * self.root_var_n2;
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
/// library call ran for every ZNCC (docs/decisions.md, "Tracking code generation on the
/// Cortex-M4").
#[cold]
#[inline(never)]
fn wide_f32(v: i64) -> f32 {
    v as f32
}

/// `acc + sum s q` over one row: template row `q_row` (and its [`Quantized::pairs`]) against the
/// first `N` of `pixels` (`None` when there are fewer). Pixels `k` and `k + 2` are the halves of
/// one word (`w & 0x00FF_00FF` of a 4-byte read), so a group of four template columns takes one
/// word of pixels and two dual multiply-accumulates ([`smlad`], one `SMLAD` each on the
/// Cortex-M4); columns past the last whole group are single products.
#[inline(always)]
fn row_product<const N: usize>(
    q_row: &[i16; N],
    pairs: &[u32],
    pixels: &[u8],
    acc: i32,
) -> Option<i32> {
    let mut st = acc;
    for (g, q) in pairs.chunks_exact(2).take(N / 4).enumerate() {
        let w = u32::from_le_bytes(pixels.get(4 * g..4 * g + 4)?.try_into().ok()?);
        let (even, odd) = (w & LOW_BYTES, (w >> 8) & LOW_BYTES);
        st = smlad(odd, q.get(1).copied()?, smlad(even, q.first().copied()?, st));
    }
    for c in N / 4 * 4..N {
        st += i32::from(*pixels.get(c)?) * i32::from(*q_row.get(c)?);
    }
    Some(st)
}

/// Adjacent candidates whose products with the template [`search`] computes together
/// ([`Quantized::batch`]): a row of the guides' 7 x 7 candidates at once.
const WIDE_BATCH: usize = 7;

/// The narrower batch, where fewer than [`WIDE_BATCH`] candidates are left in a row: a row of
/// the final stage's 3 x 3 candidates at once.
const ROW_BATCH: usize = 3;

/// The even bytes of a word, each in its 16-bit half: pixels `k` and `k + 2` of a 4-byte read
/// at `k`, as [`smlad`] takes them (one `UXTB16` on the Cortex-M4).
const LOW_BYTES: u32 = 0x00FF_00FF;

/// Groups of four template columns in the widest template row ([`Quantized::pairs`]).
const MAX_GROUPS: usize = (2 * MAX_TRACK_HALF_SIZE + 1) / 4;

/// Widest search window of [`track_patch`](super::track_patch), pixels: `2R + 2h + 1` at the
/// largest `R` and `h`.
const MAX_WINDOW: usize = 2 * MAX_TRACK_SEARCH_RADIUS + 2 * MAX_TRACK_HALF_SIZE + 1;

/// The sum and the sum of squares of a block of target pixels (exact: at most 169 * 255^2).
#[derive(Debug, Clone, Copy)]
struct BlockSums {
    sum: i32,
    sum_sq: i32,
}

/// The target's column sums over the `N` rows of one row of candidates: for every window column,
/// the sum and the sum of squares of the `N` pixels below it. A candidate's block sums are then
/// `N` column sums instead of `N^2` pixels (two, slid from the candidate before it in its row), so
/// its ZNCC reads the pixels only for the product with the template.
///
/// Only the first `width` columns of a search are ever written or read, and `row` says whether
/// they hold a candidate row's sums, so one value serves search after search (see
/// [`super::Workspace`]) once [`Self::restart`] forgets the last one's row.
pub(super) struct ColumnSums<const N: usize> {
    sum: [i32; MAX_WINDOW],
    sum_sq: [i32; MAX_WINDOW],
    /// Window row of the candidates these sums are for; `None` before the first row or when a
    /// row left the buffer (impossible after the caller's check; its candidates then score -1).
    row: Option<usize>,
    /// The column and the sums of the last block of `row`, from which the next column's block
    /// slides (one column out, one in) instead of summing its `N` columns.
    last: Option<(usize, BlockSums)>,
}

impl<const N: usize> ColumnSums<N> {
    /// No candidate row yet.
    pub(super) const EMPTY: Self =
        Self { sum: [0; MAX_WINDOW], sum_sq: [0; MAX_WINDOW], row: None, last: None };

    /// Forgets the candidate row: the next [`Self::block`] computes its sums from scratch.
    fn restart(&mut self) {
        self.row = None;
        self.last = None;
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
            self.last = None;
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
                    // The first row sets the sums (no clearing pass), the others add to them.
                    let first = pixels(y)?;
                    for ((a, b), &s) in sum.iter_mut().zip(sum_sq.iter_mut()).zip(first) {
                        let s = i32::from(s);
                        (*a, *b) = (s, s * s);
                    }
                    for j in 1..N {
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
        let block = match self.last {
            // The next column (a batch's candidates come in order): exact integers, so the same
            // sums as from scratch.
            Some((last, b)) if last + 1 == ix => {
                let (out, new) = (ix - 1, ix + N - 1);
                BlockSums {
                    sum: b.sum - self.sum.get(out)? + self.sum.get(new)?,
                    sum_sq: b.sum_sq - self.sum_sq.get(out)? + self.sum_sq.get(new)?,
                }
            }
            _ => BlockSums {
                sum: self.sum.get(ix..ix + N)?.iter().sum(),
                sum_sq: self.sum_sq.get(ix..ix + N)?.iter().sum(),
            },
        };
        self.last = Some((ix, block));
        Some(block)
    }
}

/// The integer search of step 2 of the module documentation: the best pixel (integer
/// coordinates, within `R` of the rounded prediction on each axis) and its ZNCC. `q` and
/// `columns` are scratch, overwritten.
pub(super) fn search<const N: usize, const S: usize>(
    t: &Template<N, S>,
    (q, columns): (&mut Quantized<N>, &mut ColumnSums<N>),
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
    q.fill(t);
    let q = &*q;
    let width = 2 * r + N;
    columns.restart();
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
    // Kept only for the ambiguity test: filling its 1,156 bytes on every fine track too costs
    // instructions for nothing (docs/decisions.md, "Tracking code generation on the Cortex-M4").
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
            // Adjacent candidates (step 1) share their rows: their products come in batches
            // ([`Quantized::batch`]). Scores, and so the order of ties, are those of single
            // products.
            let batch = (step == 1)
                .then(|| q.batch(data, stride, (x0 + coarse(kx), y0 + iy), csize - kx))
                .flatten();
            let n = batch.map_or(1, |(_, n)| n);
            for k in 0..n {
                let ix = coarse(kx + k);
                let s = score(ix, iy, batch.and_then(|(b, _)| b.get(k).copied()));
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matching::patch_tracker::test_images::noise_image;

    /// The single and the batched products (3 and 7 blocks) equal the products computed pixel
    /// by pixel, at the extremes of the template and pixel ranges too, for template sizes 3 to
    /// 13; a batch is the widest that what is left of a row holds.
    #[test]
    fn batched_products_equal_single_ones() {
        fn check<const N: usize>(img: &[u8], w: usize, fill: impl Fn(usize) -> i16) {
            let mut q = Quantized::<N>::EMPTY;
            for (k, v) in q.values.as_flattened_mut().iter_mut().enumerate() {
                *v = fill(k);
            }
            q.pack_pairs();
            for (x0, y0) in [(0usize, 0usize), (5, 3), (w - N - 6, 40 - N)] {
                // Pixel by pixel, as the definition reads.
                let reference: [Option<i32>; WIDE_BATCH] = core::array::from_fn(|k| {
                    let mut st = 0i32;
                    for (j, q_row) in q.values.iter().enumerate() {
                        for (c, &v) in q_row.iter().enumerate() {
                            st += i32::from(img[(y0 + j) * w + x0 + k + c]) * i32::from(v);
                        }
                    }
                    Some(st)
                });
                let single: [Option<i32>; WIDE_BATCH] =
                    core::array::from_fn(|k| q.product(img, w, (x0 + k, y0)));
                assert_eq!(single, reference, "{N} at {x0}, {y0}");
                let wide = q.products::<WIDE_BATCH>(img, w, (x0, y0));
                assert_eq!(wide.map(|b| b.map(Some)), Some(single), "{N} at {x0}, {y0}");
                let three = q.products::<ROW_BATCH>(img, w, (x0, y0));
                assert_eq!(three.map(|b| b.map(Some)).as_ref().map(|b| &b[..]), Some(&single[..3]));
                // The widest batch that fits what is left of a row, as `search` asks.
                for (left, n) in [(2, None), (3, Some(3)), (6, Some(3)), (7, Some(7)), (9, Some(7))]
                {
                    let batch = q.batch(img, w, (x0, y0), left);
                    assert_eq!(batch.map(|(_, n)| n), n, "{left} left");
                    if let Some((b, n)) = batch {
                        for (k, (v, want)) in b.iter().zip(&single).take(n).enumerate() {
                            assert_eq!(Some(*v), *want, "block {k} of {n}");
                        }
                    }
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
            check::<13>(img, w, |k| if k % 3 == 0 { -128 } else { 127 });
            check::<5>(img, w, |k| (k as i16 * 53) % 256 - 128);
            check::<7>(img, w, |_| -128);
            check::<3>(img, w, |k| 127 - k as i16);
        }
    }

    /// Column sums slid from any earlier candidate row, and block sums slid from the column
    /// before, equal the sums computed from scratch, and those do not depend on what the sums
    /// held before.
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
        let mut slid = ColumnSums::<N>::EMPTY;
        for &iy in &visits {
            // Runs of next columns (the block sums slide), jumps, and a column again.
            for ix in [0usize, 1, 2, 5, 6, width - N - 1, width - N, 3, 3] {
                // A value left over from another search: no row, sums that are not zero.
                let mut fresh = ColumnSums::<N> {
                    sum: [12_345; MAX_WINDOW],
                    sum_sq: [-7; MAX_WINDOW],
                    row: None,
                    last: None,
                };
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
