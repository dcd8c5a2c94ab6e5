//! SURF's box filters on a `u16` integral image: det(H) along one sample row or at one sample, and
//! the sign of the Laplacian. Shared by the strip detector and the tests' full-frame reference.
//!
//! # Exact sums modulo 2^16
//! Integral rows hold the integral image modulo 2^16 (half the memory of `u32`). A box sum taken
//! from four such values with wrapping arithmetic is exact whenever the true sum is below 2^16,
//! and every box summed here is: the filters are evaluated lobe by lobe (`Dxx = L - 2M + R`, equal
//! to SURF's `outer - 3 * middle`), and the largest lobe, `(2l - 1) x l = 17 x 9` pixels in the
//! 27 filter, sums to at most `153 * 255 = 39,015` (checked at compile time for every size).
//!
//! # Cost
//! A sample reads ten integral rows over a window of `size + 1` columns (`x - b - 1 ..= x + b`,
//! `b = (size - 1) / 2`): 16 taps for `Dxx` and `Dyy`, 16 more for `Dxy`. The window is a
//! fixed-size array (its length a const generic per layer), so every tap is a constant index.
//! Along a row, `Dxy` is computed only where `fxx * fyy` exceeds the threshold: det(H) cannot
//! exceed it elsewhere, and that is over 90% of the samples of 7-Scenes frames at threshold 30.

/// Filter sizes (side, in pixels of the level) of the four layers of every pyramid level: SURF's
/// first octave. Only the two middle layers can hold a maximum (they have a layer on either side).
pub const LEVEL_FILTER_SIZES: [usize; 4] = [9, 15, 21, 27];

/// Pyramid levels: the image, then its 2x2 mean, on which the filters of
/// [`LEVEL_FILTER_SIZES`] are those of sizes 18-54 of the image.
pub const LEVELS: usize = 2;

/// Sampling step of each level, in pixels of the level: the image every second pixel (SURF's
/// `init_sample = 2`), its 2x2 mean every pixel. Both levels are thus sampled every second image
/// pixel, as SURF's second octave was.
pub const LEVEL_STEPS: [usize; LEVELS] = [2, 1];

/// The largest of [`LEVEL_STEPS`].
const MAX_STEP: usize =
    if LEVEL_STEPS[0] > LEVEL_STEPS[1] { LEVEL_STEPS[0] } else { LEVEL_STEPS[1] };

// Every lobe (`(2l - 1) x l` pixels) and every pair of `Dxy` quadrants (`2 x l x l`) of every
// layer sums to less than 2^16 (see the module docs).
const _: () = {
    let mut k = 0;
    while k < LEVEL_FILTER_SIZES.len() {
        let l = LEVEL_FILTER_SIZES[k] / 3;
        assert!((2 * l - 1) * l * 255 < 1 << 16 && 2 * l * l * 255 < 1 << 16);
        // The lobes `with_window!` has window types for.
        assert!(LEVEL_FILTER_SIZES[k] == 3 * l && (l == 3 || l == 5 || l == 7 || l == 9));
        k += 1;
    }
};

/// Half size `(size - 1) / 2` of the largest filter.
pub(super) const MAX_HALF: usize = (LEVEL_FILTER_SIZES[LEVEL_FILTER_SIZES.len() - 1] - 1) / 2;

/// First sample coordinate (a multiple of every step) where the largest filter fits:
/// `coord - MAX_HALF - 1 >= 0`, so no box sum reads before the first integral row or column.
pub(super) const FIRST_SAMPLE: usize = (MAX_HALF + 1).div_ceil(2) * 2;

/// Integral rows held by the rolling buffer: non-maximum suppression at sample row `yc` evaluates
/// the largest filter at rows `yc +- step`, which reads rows `yc - step - MAX_HALF - 1` to
/// `yc + step + MAX_HALF`.
pub const INTEGRAL_RING_ROWS: usize = 2 * MAX_HALF + 2 + 2 * MAX_STEP;

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
        [
            up(l),
            down(l - 1),
            up(b + 1),
            up(h + 1),
            down(h),
            down(b),
            up(l + 1),
            up(1),
            down(0),
            down(l),
        ]
    }
}

/// The layers of a level, smallest first.
pub(super) const LAYERS: [Layer; LEVEL_FILTER_SIZES.len()] = {
    let mut out = [Layer::of(0); LEVEL_FILTER_SIZES.len()];
    let mut k = 0;
    while k < out.len() {
        out[k] = Layer::of(k);
        k += 1;
    }
    out
};

/// The columns `x - b - 1 ..= x + b` of one integral row that one sample of a filter reads (its
/// length is `3l + 1`), as a fixed-size array so that every tap is a constant index: single
/// columns when samples are one column apart, column pairs when they are two apart (consecutive
/// samples' windows are then one pair apart).
trait Window<'a>: Copy + 'a {
    /// The windows of consecutive samples of row `r`, the first starting at column `base`.
    type Iter: Iterator<Item = Self>;
    fn iter(r: &'a [u16], base: usize) -> Self::Iter;
    /// The window starting at column `base`, if `r` holds it.
    fn at(r: &'a [u16], base: usize) -> Option<Self>;
    /// Column `c` of the window, zero-extended (wrapping `u32` arithmetic on taps is exact
    /// modulo 2^16, which is all that [`lobe`] keeps).
    fn tap(self, c: usize) -> u32;
}

impl<'a, const N: usize> Window<'a> for &'a [u16; N] {
    type Iter = core::slice::ArrayWindows<'a, u16, N>;
    fn iter(r: &'a [u16], base: usize) -> Self::Iter {
        r.get(base..).unwrap_or(&[]).array_windows::<N>()
    }
    fn at(r: &'a [u16], base: usize) -> Option<Self> {
        r.get(base..base + N)?.try_into().ok()
    }
    #[inline(always)]
    fn tap(self, c: usize) -> u32 {
        self.get(c).map_or(0, |&v| u32::from(v))
    }
}

impl<'a, const N: usize> Window<'a> for &'a [[u16; 2]; N] {
    type Iter = core::slice::ArrayWindows<'a, [u16; 2], N>;
    fn iter(r: &'a [u16], base: usize) -> Self::Iter {
        r.get(base..).unwrap_or(&[]).as_chunks::<2>().0.array_windows::<N>()
    }
    fn at(r: &'a [u16], base: usize) -> Option<Self> {
        r.get(base..base + 2 * N)?.as_chunks::<2>().0.try_into().ok()
    }
    #[inline(always)]
    fn tap(self, c: usize) -> u32 {
        self.get(c / 2).and_then(|p| p.get(c % 2)).map_or(0, |&v| u32::from(v))
    }
}

/// Calls `$func::<window type>(l, args...)` for sampling step `$step` (1 or 2) and lobe `$l` (one
/// of the layers' 3, 5, 7, 9): the lobe becomes a constant in each instance.
macro_rules! with_window {
    ($step:expr, $l:expr, $func:ident($($arg:expr),*)) => {
        match ($step, $l) {
            (1, 3) => $func::<&[u16; 10]>(3, $($arg),*),
            (1, 5) => $func::<&[u16; 16]>(5, $($arg),*),
            (1, 7) => $func::<&[u16; 22]>(7, $($arg),*),
            (1, _) => $func::<&[u16; 28]>(9, $($arg),*),
            (_, 3) => $func::<&[[u16; 2]; 5]>(3, $($arg),*),
            (_, 5) => $func::<&[[u16; 2]; 8]>(5, $($arg),*),
            (_, 7) => $func::<&[[u16; 2]; 11]>(7, $($arg),*),
            (_, _) => $func::<&[[u16; 2]; 14]>(9, $($arg),*),
        }
    };
}

/// A lobe's (or two quadrants') pixel sum from its four corner taps combined with wrapping
/// arithmetic: exact once reduced modulo 2^16, since the true sum is below 2^16 (module docs).
#[inline(always)]
fn lobe(v: u32) -> i32 {
    (v & 0xFFFF) as i32
}

/// Unnormalized integer `(Dxx, Dyy)` of the filter of lobe `l` from its `Dxx` and `Dyy` windows
/// (the first six of [`Layer::rows`]).
#[inline(always)]
fn second_xx_yy<'a, T: Window<'a>>(l: usize, w: [T; 6]) -> (i32, i32) {
    let b = (3 * l - 1) / 2;
    let h = (l - 1) / 2;
    let [xt, xb, y0, y1, y2, y3] = w;
    // Dxx: three lobes side by side over rows y-l+1..=y+l-1, edges at x-b-1, x-h-1, x+h, x+b.
    let d = |c: usize| xb.tap(c).wrapping_sub(xt.tap(c));
    let (e0, e1, e2, e3) = (d(0), d(b - h), d(b + 1 + h), d(2 * b + 1));
    let dxx = lobe(e1.wrapping_sub(e0)) + lobe(e3.wrapping_sub(e2)) - 2 * lobe(e2.wrapping_sub(e1));
    // Dyy: three lobes stacked over columns x-l+1..=x+l-1, edges at rows y-b-1, y-h-1, y+h, y+b.
    let (ca, cb) = (b + 1 - l, b + l);
    let e = |r: T| r.tap(cb).wrapping_sub(r.tap(ca));
    let (f0, f1, f2, f3) = (e(y0), e(y1), e(y2), e(y3));
    let dyy = lobe(f1.wrapping_sub(f0)) + lobe(f3.wrapping_sub(f2)) - 2 * lobe(f2.wrapping_sub(f1));
    (dxx, dyy)
}

/// Unnormalized integer `Dxy` of the filter of lobe `l` from its `Dxy` windows (the last four of
/// [`Layer::rows`]): four `l x l` quadrants around the centre row and column, which they leave
/// out. Two quadrants sum to at most `2 * 81 * 255 < 2^16`, so each diagonal pair is reduced once.
#[inline(always)]
fn second_xy<'a, T: Window<'a>>(l: usize, [q0, q1, q2, q3]: [T; 4]) -> i32 {
    let b = (3 * l - 1) / 2;
    let quad = |t: T, bo: T, (c0, c1): (usize, usize)| {
        bo.tap(c1).wrapping_sub(t.tap(c1)).wrapping_sub(bo.tap(c0)).wrapping_add(t.tap(c0))
    };
    let (left, right) = ((b - l, b), (b + 1, b + 1 + l));
    let pos = quad(q0, q1, left).wrapping_add(quad(q2, q3, right));
    let neg = quad(q0, q1, right).wrapping_add(quad(q2, q3, left));
    lobe(pos) - lobe(neg)
}

/// `fxx * fyy` of the area-normalized filters: det(H) before its `Dxy` term, and an upper bound
/// of det(H) (also in floats: subtracting a square never rounds up).
#[inline(always)]
fn xx_yy_product((dxx, dyy): (i32, i32), inv_area: f32) -> f32 {
    // Integer magnitudes stay below 2^24, so the conversions are exact.
    let fxx = dxx as f32 * inv_area;
    let fyy = dyy as f32 * inv_area;
    fxx * fyy
}

/// det(H) `= fxx*fyy - (0.9*fxy)^2` from [`xx_yy_product`] and the integer `Dxy`.
#[inline(always)]
fn det_h(product: f32, dxy: i32, inv_area: f32) -> f32 {
    let wxy = 0.9 * (dxy as f32 * inv_area);
    product - wxy * wxy
}

/// det(H) of `layer` at the samples `x0, x0 + step, ...` (`step` 1 or 2) of row `y` into `out`
/// (one per element, as many as both `out` and the integral rows allow), except that a sample
/// whose `fxx * fyy` is at most `threshold` gets [`BELOW`]: its det(H), no larger, cannot be a
/// maximum above the threshold, and most samples are such (over 90% on 7-Scenes at threshold
/// 30), so their `Dxy` (half the taps) is never computed. Requires `x0, y >= b + 1`.
pub(super) fn response_row<I: IntegralRows>(
    ii: &I,
    layer: &Layer,
    step: usize,
    (x0, y): (usize, usize),
    threshold: f32,
    out: &mut [f32],
) {
    let [a, b, c, d, e, f, g, h, i, j] = layer.rows(ii, y);
    let (base, inv_area) = (x0.saturating_sub(layer.b + 1), layer.inv_area());
    let xx_yy = [a, b, c, d, e, f];
    with_window!(step, layer.l, products_row(xx_yy, base, (inv_area, threshold), out));
    for (k, o) in out.iter_mut().enumerate() {
        if *o > threshold {
            let base = base + k * step;
            let dxy = with_window!(1, layer.l, second_xy_from([g, h, i, j], base));
            *o = dxy.map_or(BELOW, |dxy| det_h(*o, dxy, inv_area));
        }
    }
}

/// Responses not computed because they are at most the threshold (see [`response_row`]).
pub(super) const BELOW: f32 = f32::NEG_INFINITY;

/// The first pass of [`response_row`] for one window type (lobe `l`), windows from column
/// `base`: `fxx * fyy` where it exceeds the threshold, [`BELOW`] elsewhere.
fn products_row<'a, T: Window<'a>>(
    l: usize,
    rows: [&'a [u16]; 6],
    base: usize,
    (inv_area, threshold): (f32, f32),
    out: &mut [f32],
) {
    let [r0, r1, r2, r3, r4, r5] = rows.map(|r| T::iter(r, base));
    let samples = out.iter_mut().zip(r0.zip(r1)).zip(r2.zip(r3).zip(r4.zip(r5)));
    for ((o, (a, b)), ((c, d), (e, f))) in samples {
        let p = xx_yy_product(second_xx_yy(l, [a, b, c, d, e, f]), inv_area);
        *o = if p > threshold { p } else { BELOW };
    }
}

/// The windows of `rows` starting at column `base`, if the rows hold them.
fn windows_from<'a, T: Window<'a>, const N: usize>(
    rows: [&'a [u16]; N],
    base: usize,
) -> Option<[T; N]> {
    let w = rows.map(|r| T::at(r, base));
    if w.iter().any(Option::is_none) {
        return None;
    }
    let first = (*w.first()?)?;
    Some(w.map(|v| v.unwrap_or(first)))
}

/// Integer `Dxy` of lobe `l` at the windows starting at column `base`.
fn second_xy_from<'a, T: Window<'a>>(l: usize, rows: [&'a [u16]; 4], base: usize) -> Option<i32> {
    Some(second_xy(l, windows_from::<T, 4>(rows, base)?))
}

/// Integer `(Dxx, Dyy, Dxy)` of lobe `l` at the windows starting at column `base`.
fn second_all_from<'a, T: Window<'a>>(
    l: usize,
    rows: [&'a [u16]; 10],
    base: usize,
) -> Option<(i32, i32, i32)> {
    let [a, b, c, d, e, f, g, h, i, j] = windows_from::<T, 10>(rows, base)?;
    let (dxx, dyy) = second_xx_yy(l, [a, b, c, d, e, f]);
    Some((dxx, dyy, second_xy(l, [g, h, i, j])))
}

/// Integer `(Dxx, Dyy, Dxy)` of `layer` at sample `(x, y)`, if the integral rows hold it.
pub(super) fn derivatives_at<I: IntegralRows>(
    ii: &I,
    layer: &Layer,
    x: usize,
    y: usize,
) -> Option<(i32, i32, i32)> {
    let rows = layer.rows(ii, y);
    let base = x.checked_sub(layer.b + 1)?;
    // Single columns: the window of one sample needs no alignment.
    with_window!(1, layer.l, second_all_from(rows, base))
}

/// det(H) of `layer` at sample `(x, y)` (`x, y >= b + 1`), exactly (never [`BELOW`]): the value
/// [`response_row`] gives there when it computes it, bit for bit. `None` if the integral rows do
/// not hold the filter.
pub(super) fn response_at<I: IntegralRows>(
    ii: &I,
    layer: &Layer,
    x: usize,
    y: usize,
) -> Option<f32> {
    let (dxx, dyy, dxy) = derivatives_at(ii, layer, x, y)?;
    let inv_area = layer.inv_area();
    Some(det_h(xx_yy_product((dxx, dyy), inv_area), dxy, inv_area))
}

/// Whether the trace `Dxx + Dyy` (the Laplacian) of `layer` at `(x, y)` is `>= 0`.
pub(super) fn laplacian_positive_at<I: IntegralRows>(
    ii: &I,
    layer: &Layer,
    x: usize,
    y: usize,
) -> Option<bool> {
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
        assert_eq!(LAYERS.map(|l| l.l), [3, 5, 7, 9]);
    }
}
