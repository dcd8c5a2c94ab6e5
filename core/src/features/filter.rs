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
//! exceed it elsewhere, and that is most samples (over 90% on real frames at threshold 30).
//!
//! On the Cortex-M4 a row is computed in two passes so that each loop keeps its row pointers in
//! registers (the six `Dxx`/`Dyy` rows of one loop did not fit): `Dyy` into the output row, then
//! `Dxx`, whose product with `Dyy` is first tested in integers against a bound that provably
//! keeps `fxx * fyy` at or below the threshold (see [`Threshold`]), so that most samples skip
//! the float conversions and products. The few samples left get `Dxy` after each block of 32,
//! in a function of their own. About 24 instructions per sample for the first pass and 37 for
//! the second, about 92 per sample for `Dxy` and det(H); why two passes: docs/decisions.md,
//! "Fast-Hessian detector cost".

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
    /// Columns from one sample's window to the next's (the sampling step).
    const COLUMNS: usize;
    /// The windows of consecutive samples of row `r`, the first starting at column `base`.
    type Iter: ExactSizeIterator<Item = Self>;
    fn iter(r: &'a [u16], base: usize) -> Self::Iter;
    /// The window starting at column `base`, if `r` holds it.
    fn at(r: &'a [u16], base: usize) -> Option<Self>;
    /// Column `c` of the window, zero-extended (wrapping `u32` arithmetic on taps is exact
    /// modulo 2^16, which is all that [`lobe`] keeps).
    fn tap(self, c: usize) -> u32;
}

impl<'a, const N: usize> Window<'a> for &'a [u16; N] {
    const COLUMNS: usize = 1;
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
    const COLUMNS: usize = 2;
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

/// Unnormalized integer `Dxx` of the filter of lobe `l` from its two `Dxx` windows (the first
/// two of [`Layer::rows`]): three lobes side by side over rows `y-l+1..=y+l-1`, edges at
/// `x-b-1`, `x-h-1`, `x+h`, `x+b`.
#[inline(always)]
fn second_xx<'a, T: Window<'a>>(l: usize, [xt, xb]: [T; 2]) -> i32 {
    let b = (3 * l - 1) / 2;
    let h = (l - 1) / 2;
    let d = |c: usize| xb.tap(c).wrapping_sub(xt.tap(c));
    let (e0, e1, e2, e3) = (d(0), d(b - h), d(b + 1 + h), d(2 * b + 1));
    lobe(e1.wrapping_sub(e0)) + lobe(e3.wrapping_sub(e2)) - 2 * lobe(e2.wrapping_sub(e1))
}

/// Unnormalized integer `Dyy` of the filter of lobe `l` from its four `Dyy` windows (the third
/// to sixth of [`Layer::rows`]): three lobes stacked over columns `x-l+1..=x+l-1`, edges at rows
/// `y-b-1`, `y-h-1`, `y+h`, `y+b`.
#[inline(always)]
fn second_yy<'a, T: Window<'a>>(l: usize, [y0, y1, y2, y3]: [T; 4]) -> i32 {
    let b = (3 * l - 1) / 2;
    let (ca, cb) = (b + 1 - l, b + l);
    let e = |r: T| r.tap(cb).wrapping_sub(r.tap(ca));
    let (f0, f1, f2, f3) = (e(y0), e(y1), e(y2), e(y3));
    lobe(f1.wrapping_sub(f0)) + lobe(f3.wrapping_sub(f2)) - 2 * lobe(f2.wrapping_sub(f1))
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

/// The threshold on det(H) as [`response_row`] applies it to one layer: the value, and an
/// integer bound on the unnormalized `Dxx * Dyy` at or below which `fxx * fyy` (hence det(H))
/// cannot exceed it. The integer test spares most samples the float conversions and products.
#[derive(Debug, Clone, Copy)]
pub(super) struct Threshold {
    value: f32,
    /// `floor(value * size^4 * (1 - 2^-10))`, computed in `f32` (saturating), for `value >= 0`.
    /// With `u = 2^-24`: `inv_area <= (1 + u) / size^2`, and the two scalings and the product
    /// each round by at most `1 + u` (the integers, below 2^24, convert exactly), so
    /// `fxx * fyy <= Dxx * Dyy * (1 + u)^5 / size^4`; the bound's own two roundings add
    /// `(1 + u)^2`, and `(1 + u)^7 * (1 - 2^-10) < 1`, so `Dxx * Dyy <= bound` gives
    /// `fxx * fyy < value`. A product `<= 0` gives `fxx * fyy <= 0 <= value`. For a negative or
    /// NaN `value` it is `i64::MIN`: every sample takes the float test.
    product_bound: i64,
}

impl Threshold {
    /// The threshold `value` for `layer`.
    pub(super) fn new(value: f32, layer: &Layer) -> Self {
        let size2 = (layer.size * layer.size) as f32;
        // `size^4 <= 27^4`, exact in `f32`.
        let bound = value * (size2 * size2) * (1.0 - 1.0 / 1024.0);
        let product_bound = if value >= 0.0 { bound as i64 } else { i64::MIN };
        Self { value, product_bound }
    }

    /// The threshold on det(H).
    pub(super) fn value(&self) -> f32 {
        self.value
    }
}

/// det(H) of `layer` at the samples `x0, x0 + step, ...` (`step` 1 or 2) of row `y` into `out`
/// (one per element, as many as both `out` and the integral rows allow), except that a sample
/// whose `fxx * fyy` is at most the threshold gets [`BELOW`]: its det(H), no larger, cannot be a
/// maximum above the threshold, and most samples are such (over 90% on real frames at threshold
/// 30), so their `Dxy` (half the taps) is never computed. Bit `j % 8` of `marks[j / 8]` is set
/// for every `out[j]` above the threshold (`marks` is not cleared first). Requires
/// `x0, y >= b + 1` and `threshold` made for `layer`.
pub(super) fn response_row<I: IntegralRows>(
    ii: &I,
    layer: &Layer,
    step: usize,
    (x0, y): (usize, usize),
    threshold: &Threshold,
    (out, marks): (&mut [f32], &mut [u8]),
) {
    let [a, b, c, d, e, f, g, h, i, j] = layer.rows(ii, y);
    let base = x0.saturating_sub(layer.b + 1);
    let xy = XyRows { rows: [g, h, i, j], base, step, l: layer.l, inv_area: layer.inv_area() };
    with_window!(step, layer.l, row_passes([a, b, c, d, e, f], threshold, &xy, (out, marks)));
}

/// [`response_row`] for one window type (lobe `l`) of the `Dxx`/`Dyy` rows (the first six of
/// [`Layer::rows`]), windows from column `xy.base`: two passes, each with few enough rows to
/// keep its values in the Cortex-M4's registers ([`yy_row`], then [`products_row`]).
fn row_passes<'a, T: Window<'a>>(
    l: usize,
    [xt, xb, y0, y1, y2, y3]: [&'a [u16]; 6],
    threshold: &Threshold,
    xy: &XyRows<'_>,
    (out, marks): (&mut [f32], &mut [u8]),
) {
    // The samples whose windows every row holds (both passes then cover the same ones).
    let rows = [xt, xb, y0, y1, y2, y3];
    let n = rows.iter().map(|r| T::iter(r, xy.base).len()).fold(out.len(), usize::min);
    let out = out.get_mut(..n).unwrap_or(&mut []);
    yy_row::<T>(l, [y0, y1, y2, y3], xy.base, out);
    products_row::<T>(l, [xt, xb], threshold, xy, (out, marks));
}

/// Responses not computed because they are at most the threshold (see [`response_row`]).
pub(super) const BELOW: f32 = f32::NEG_INFINITY;

/// What [`finish_block`] needs of a row: the `Dxy` rows of a layer (the last four of
/// [`Layer::rows`]), the first window's column and the sampling step.
struct XyRows<'a> {
    rows: [&'a [u16]; 4],
    base: usize,
    step: usize,
    l: usize,
    inv_area: f32,
}

/// The samples `first + k` of the row of `xy` for every bit `k` of `above`, whose `out[k]`
/// holds `fxx * fyy`: det(H) in their place ([`BELOW`] if the rows do not hold their `Dxy`
/// windows), marked in `marks` where above the threshold `t`. Not inlined: called for few
/// blocks, it would otherwise take registers from the loop of [`products_row`].
#[inline(never)]
fn finish_block(
    xy: &XyRows<'_>,
    (t, first, above): (f32, usize, u32),
    out: &mut [f32],
    marks: &mut [u8],
) {
    with_window!(1, xy.l, finish_block_with(xy, (t, first, above), out, marks));
}

/// [`finish_block`] for one window type (lobe `l`).
fn finish_block_with<'a, T: Window<'a>>(
    l: usize,
    xy: &XyRows<'a>,
    (t, first, mut above): (f32, usize, u32),
    out: &mut [f32],
    marks: &mut [u8],
) {
    while above != 0 {
        let k = above.trailing_zeros() as usize;
        above &= above - 1;
        let Some(o) = out.get_mut(k) else { continue };
        let s = first + k;
        let dxy = second_xy_from::<T>(l, xy.rows, xy.base + s * xy.step);
        *o = dxy.map_or(BELOW, |dxy| det_h(*o, dxy, xy.inv_area));
        if *o > t
            && let Some(m) = marks.get_mut(s / 8)
        {
            *m |= 1 << (s % 8);
        }
    }
}

/// The first pass of [`row_passes`]: the integer `Dyy` of every sample, windows from column
/// `base`, into `out` as bits (for [`products_row`]).
#[inline(always)]
fn yy_row<'a, T: Window<'a>>(l: usize, rows: [&'a [u16]; 4], base: usize, out: &mut [f32]) {
    let [r0, r1, r2, r3] = rows.map(|r| T::iter(r, base));
    for (o, ((a, b), (c, d))) in out.iter_mut().zip(r0.zip(r1).zip(r2.zip(r3))) {
        *o = f32::from_bits(second_yy(l, [a, b, c, d]) as u32);
    }
}

/// Samples per block of [`products_row`]: one bit each in a `u32`.
const BLOCK: usize = 32;

/// The second pass of [`row_passes`]: `Dxx` from its rows, windows from column `xy.base`,
/// with the `Dyy` bits that [`yy_row`] left in `out`, then `fxx * fyy`, then det(H) and the
/// marks for the samples above the threshold.
#[inline(always)]
fn products_row<'a, T: Window<'a>>(
    l: usize,
    [xt, xb]: [&'a [u16]; 2],
    threshold: &Threshold,
    xy: &XyRows<'_>,
    (out, marks): (&mut [f32], &mut [u8]),
) {
    let (t, bound) = (threshold.value, threshold.product_bound);
    // By blocks, the few samples above the threshold noted in a bit mask and their `Dxy` taken
    // after the block: with no call in it, the loop keeps more of its values in registers.
    for (block, out) in out.chunks_mut(BLOCK).enumerate() {
        let first = xy.base + block * BLOCK * T::COLUMNS;
        let windows = T::iter(xt, first).zip(T::iter(xb, first));
        let mut above = 0u32;
        for (k, (o, (xt, xb))) in out.iter_mut().zip(windows).enumerate() {
            let dxx = second_xx(l, [xt, xb]);
            let dyy = o.to_bits() as i32;
            // Most samples stop at the integer test (see `Threshold::product_bound`).
            *o = BELOW;
            if i64::from(dxx) * i64::from(dyy) > bound {
                let p = xx_yy_product((dxx, dyy), xy.inv_area);
                if p > t {
                    *o = p;
                    above |= 1 << k;
                }
            }
        }
        if above != 0 {
            finish_block(xy, (t, block * BLOCK, above), out, marks);
        }
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
    Some((second_xx(l, [a, b]), second_yy(l, [c, d, e, f]), second_xy(l, [g, h, i, j])))
}

/// Integer `Dxx + Dyy` of lobe `l` at the windows starting at column `base` (the `Dxx` and
/// `Dyy` rows of [`Layer::rows`] only).
fn trace_from<'a, T: Window<'a>>(l: usize, rows: [&'a [u16]; 6], base: usize) -> Option<i32> {
    let [a, b, c, d, e, f] = windows_from::<T, 6>(rows, base)?;
    Some(second_xx(l, [a, b]) + second_yy(l, [c, d, e, f]))
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

/// Whether the trace `Dxx + Dyy` (the Laplacian) of `layer` at `(x, y)` is `>= 0`; `None`
/// where [`derivatives_at`] gives none (the `Dxy` rows are not read, but lie within the rows
/// the others span, so the integral rows hold all or none of them).
pub(super) fn laplacian_positive_at<I: IntegralRows>(
    ii: &I,
    layer: &Layer,
    x: usize,
    y: usize,
) -> Option<bool> {
    let [a, b, c, d, e, f, ..] = layer.rows(ii, y);
    let base = x.checked_sub(layer.b + 1)?;
    let trace = with_window!(1, layer.l, trace_from([a, b, c, d, e, f], base))?;
    Some(trace >= 0)
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
