//! SURF's box filters on a `u16` integral image: det(H) along one sample row or at one sample, and
//! the sign of the Laplacian. Shared by the strip detector and the tests' full-frame reference.
//!
//! # Exact sums modulo 2^16
//! Integral rows hold the integral image modulo 2^16 (half the memory of `u32`). A box sum taken
//! from four such values with wrapping arithmetic is exact whenever the true sum is below 2^16,
//! and every box summed here is: the filters are evaluated lobe by lobe (`Dxx = L - 2M + R`, equal
//! to SURF's `outer - 3 * middle`), and the largest lobe, `(2l - 1) x l = 17 x 9` pixels in the
//! 27 filter, sums to at most `153 * 255 = 39,015`.
//!
//! # No bounds checks in the inner loop
//! Each sample reads ten integral rows over a window of `size + 1` columns (`x - b - 1 ..= x + b`,
//! `b = (size - 1) / 2`). The window length is a const generic (`2 * NP` columns as `NP` column
//! pairs; the sampling step is two columns, so consecutive samples' windows are one pair apart),
//! so every tap is a constant index into a fixed-size array.

/// Filter sizes (side, in pixels of the level) of the four layers of every pyramid level: SURF's
/// first octave.
pub const LEVEL_FILTER_SIZES: [usize; 4] = [9, 15, 21, 27];

/// Sampling step of every level, in pixels of the level (SURF's `init_sample = 2`).
pub const LEVEL_STEP: usize = 2;

/// Pyramid levels: the image, then its 2x2 mean (the second level's filters are SURF's sizes
/// 18-54 of the full-resolution image, sampled every fourth pixel).
pub const LEVELS: usize = 2;

/// Half size `(size - 1) / 2` of the largest filter.
pub(super) const MAX_HALF: usize = (LEVEL_FILTER_SIZES[3] - 1) / 2;

/// First sample coordinate (a multiple of the step) where the largest filter fits:
/// `coord - MAX_HALF - 1 >= 0`, so no box sum reads before the first integral row or column.
pub(super) const FIRST_SAMPLE: usize = (MAX_HALF + 1).div_ceil(LEVEL_STEP) * LEVEL_STEP;

/// Integral rows held by the rolling buffer: non-maximum suppression at sample row `yc` evaluates
/// the largest filter at rows `yc +- LEVEL_STEP`, which reads rows `yc - step - MAX_HALF - 1` to
/// `yc + step + MAX_HALF`.
pub const INTEGRAL_RING_ROWS: usize = 2 * MAX_HALF + 2 + 2 * LEVEL_STEP;

/// Rows of an integral image: `row(y)[x]` is the sum of pixels `(0..=x, 0..=y)` modulo 2^16.
pub(super) trait IntegralRows {
    /// Integral row `y`; empty (reads as zero) if not held.
    fn row(&self, y: usize) -> &[u16];
}

/// The geometry of one layer's filter, in pixels of the level.
#[derive(Debug, Clone, Copy)]
pub(super) struct Layer {
    /// Side of the filter.
    pub size: usize,
    /// Lobe length `size / 3`.
    l: usize,
    /// Half size `(size - 1) / 2`.
    b: usize,
    /// Half lobe `(l - 1) / 2`.
    h: usize,
}

impl Layer {
    /// The layer of index `k` in [`LEVEL_FILTER_SIZES`].
    pub(super) const fn of(k: usize) -> Self {
        let size = LEVEL_FILTER_SIZES[k];
        let l = size / 3;
        Self { size, l, b: (size - 1) / 2, h: (l - 1) / 2 }
    }

    /// `1 / size^2`: det(H) uses the derivatives normalized by the filter's area.
    fn inv_area(&self) -> f32 {
        1.0 / (self.size * self.size) as f32
    }

    /// The ten integral rows a sample at row `y` reads (`y >= b + 1`): `Dxx` rows `y - l` and
    /// `y + l - 1`; `Dyy` lobe edges `y - b - 1`, `y - h - 1`, `y + h`, `y + b`; `Dxy` quadrant
    /// edges `y - l - 1`, `y - 1`, `y`, `y + l`.
    fn rows<'a, I: IntegralRows>(&self, ii: &'a I, y: usize) -> [&'a [u16]; 10] {
        let (l, b, h) = (self.l, self.b, self.h);
        let up = |d: usize| ii.row(y.saturating_sub(d));
        let down = |d: usize| ii.row(y + d);
        [up(l), down(l - 1), up(b + 1), up(h + 1), down(h), down(b), up(l + 1), up(1), down(0), down(l)]
    }
}

/// The layers of a level, smallest first.
pub(super) const LAYERS: [Layer; 4] = [Layer::of(0), Layer::of(1), Layer::of(2), Layer::of(3)];

/// Pairs of columns per window for a filter of lobe `l`: the window spans `3l + 1` columns.
const fn pairs_of(l: usize) -> usize {
    (3 * l + 1) / 2
}

/// One window of one integral row: `2 * NP` columns from `x - b - 1`, as column pairs.
type Window<'a, const NP: usize> = &'a [[u16; 2]; NP];

/// Column `c` of a window (a constant once `derivatives` is inlined for a given `NP`).
#[inline(always)]
fn tap<const NP: usize>(w: Window<'_, NP>, c: usize) -> u16 {
    w.get(c / 2).and_then(|p| p.get(c % 2)).copied().unwrap_or(0)
}

/// Lobe sum from two row-differences (or column-differences) modulo 2^16: exact, see module docs.
#[inline(always)]
fn lobe(hi: u16, lo: u16) -> i32 {
    i32::from(hi.wrapping_sub(lo))
}

/// Unnormalized integer `(Dxx, Dyy, Dxy)` of the filter whose windows (in [`Layer::rows`] order)
/// are `w`; the filter's lobe is `l = (2 * NP - 1) / 3`.
#[inline(always)]
fn derivatives<const NP: usize>(w: [Window<'_, NP>; 10]) -> (i32, i32, i32) {
    let l = (2 * NP - 1) / 3;
    let b = (3 * l - 1) / 2;
    let h = (l - 1) / 2;
    let [xt, xb, y0, y1, y2, y3, q0, q1, q2, q3] = w;
    // Dxx: three lobes side by side over rows y-l+1..=y+l-1, edges at x-b-1, x-h-1, x+h, x+b.
    let d = |c: usize| tap(xb, c).wrapping_sub(tap(xt, c));
    let (e0, e1, e2, e3) = (d(0), d(b - h), d(b + 1 + h), d(2 * b + 1));
    let dxx = lobe(e1, e0) + lobe(e3, e2) - 2 * lobe(e2, e1);
    // Dyy: three lobes stacked over columns x-l+1..=x+l-1, edges at rows y-b-1, y-h-1, y+h, y+b.
    let (ca, cb) = (b + 1 - l, b + l);
    let e = |r: Window<'_, NP>| tap(r, cb).wrapping_sub(tap(r, ca));
    let (f0, f1, f2, f3) = (e(y0), e(y1), e(y2), e(y3));
    let dyy = lobe(f1, f0) + lobe(f3, f2) - 2 * lobe(f2, f1);
    // Dxy: four l x l quadrants around the centre row and column, which they leave out.
    let quad = |t: Window<'_, NP>, bo: Window<'_, NP>, c0: usize, c1: usize| {
        let hi = tap(bo, c1).wrapping_sub(tap(t, c1));
        lobe(hi, tap(bo, c0).wrapping_sub(tap(t, c0)))
    };
    let (left, right) = ((b - l, b), (b + 1, b + 1 + l));
    let dxy = quad(q0, q1, left.0, left.1) + quad(q2, q3, right.0, right.1)
        - quad(q0, q1, right.0, right.1)
        - quad(q2, q3, left.0, left.1);
    (dxx, dyy, dxy)
}

/// det(H) of the area-normalized filters: `Dxx*Dyy - (0.9*Dxy)^2`.
#[inline(always)]
fn det_h((dxx, dyy, dxy): (i32, i32, i32), inv_area: f32) -> f32 {
    // Integer magnitudes stay below 2^24, so the conversions are exact.
    let fxx = dxx as f32 * inv_area;
    let fyy = dyy as f32 * inv_area;
    let wxy = 0.9 * (dxy as f32 * inv_area);
    fxx * fyy - wxy * wxy
}

/// det(H) of layer `layer` at the samples `x0, x0 + 2, ...` of row `y` into `out` (one per
/// element, as many as both `out` and the integral rows allow). Requires `x0, y >= b + 1`.
pub(super) fn response_row<I: IntegralRows>(
    ii: &I,
    layer: &Layer,
    x0: usize,
    y: usize,
    out: &mut [f32],
) {
    let rows = layer.rows(ii, y);
    let (base, inv_area) = (x0.saturating_sub(layer.b + 1), layer.inv_area());
    match layer.l {
        3 => row_kernel::<{ pairs_of(3) }>(rows, base, inv_area, out),
        5 => row_kernel::<{ pairs_of(5) }>(rows, base, inv_area, out),
        7 => row_kernel::<{ pairs_of(7) }>(rows, base, inv_area, out),
        _ => row_kernel::<{ pairs_of(9) }>(rows, base, inv_area, out),
    }
}

/// The windows of `NP` column pairs of row `r`, one per sample from column `base` on.
fn windows<const NP: usize>(r: &[u16], base: usize) -> core::slice::ArrayWindows<'_, [u16; 2], NP> {
    r.get(base..).unwrap_or(&[]).as_chunks::<2>().0.array_windows::<NP>()
}

/// [`response_row`] for one window length, windows starting at column `base`.
fn row_kernel<const NP: usize>(rows: [&[u16]; 10], base: usize, inv_area: f32, out: &mut [f32]) {
    let [r0, r1, r2, r3, r4, r5, r6, r7, r8, r9] = rows.map(|r| windows::<NP>(r, base));
    let xx = r0.zip(r1);
    let yy = r2.zip(r3).zip(r4.zip(r5));
    let xy = r6.zip(r7).zip(r8.zip(r9));
    let samples = out.iter_mut().zip(xx.zip(yy.zip(xy)));
    for (o, ((a, b), (((c, d), (e, f)), ((g, h), (i, j))))) in samples {
        *o = det_h(derivatives([a, b, c, d, e, f, g, h, i, j]), inv_area);
    }
}

/// The windows of the sample at column `x` (`x >= b + 1`), if the rows hold them.
fn windows_at<'a, const NP: usize>(rows: [&'a [u16]; 10], x: usize, b: usize) -> Option<[Window<'a, NP>; 10]> {
    let base = x.checked_sub(b + 1)?;
    let mut out: [Window<'a, NP>; 10] = [&[[0; 2]; NP]; 10];
    for (o, r) in out.iter_mut().zip(rows) {
        let cols = r.get(base..base + 2 * NP)?;
        *o = cols.as_chunks::<2>().0.try_into().ok()?;
    }
    Some(out)
}

/// Integer `(Dxx, Dyy, Dxy)` of layer `layer` at sample `(x, y)`, if the integral rows hold it.
fn derivatives_at<I: IntegralRows>(ii: &I, layer: &Layer, x: usize, y: usize) -> Option<(i32, i32, i32)> {
    let rows = layer.rows(ii, y);
    let b = layer.b;
    Some(match layer.l {
        3 => derivatives(windows_at::<{ pairs_of(3) }>(rows, x, b)?),
        5 => derivatives(windows_at::<{ pairs_of(5) }>(rows, x, b)?),
        7 => derivatives(windows_at::<{ pairs_of(7) }>(rows, x, b)?),
        _ => derivatives(windows_at::<{ pairs_of(9) }>(rows, x, b)?),
    })
}

/// det(H) of layer `layer` at sample `(x, y)` (`x, y >= b + 1`): the value [`response_row`]
/// gives there, bit for bit. `None` if the integral rows do not hold the filter.
pub(super) fn response_at<I: IntegralRows>(ii: &I, layer: &Layer, x: usize, y: usize) -> Option<f32> {
    Some(det_h(derivatives_at(ii, layer, x, y)?, layer.inv_area()))
}

/// Whether the trace `Dxx + Dyy` (the Laplacian) of layer `layer` at `(x, y)` is `>= 0`.
pub(super) fn laplacian_positive_at<I: IntegralRows>(ii: &I, layer: &Layer, x: usize, y: usize) -> Option<bool> {
    let (dxx, dyy, _) = derivatives_at(ii, layer, x, y)?;
    Some(dxx + dyy >= 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ring_holds_the_largest_filter_one_step_either_side() {
        assert_eq!(INTEGRAL_RING_ROWS, 32);
        assert_eq!(FIRST_SAMPLE, 14);
        assert_eq!(LAYERS.map(|l| pairs_of(l.l)), [5, 8, 11, 14]);
    }
}
