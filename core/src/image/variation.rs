//! The image variation of the paper's Eq. 3: per pixel `v_m`, the largest absolute gray difference
//! between pixel `m` and its 8 neighbours `N(m)`, and the total variation `W(I) = sum_m v_m`.
//!
//! Border pixels: `N(m)` holds only the neighbours that exist inside the image (5 on an edge, 3 in
//! a corner, none in a 1x1 image, whose `v_m` is 0 as the maximum over an empty set of absolute
//! differences). No padding is invented, so a constant image has `W(I) = 0` everywhere.
//!
//! Computation: `max_s |I(m) - I(s)| = max(max_s I(s) - I(m), I(m) - min_s I(s))`, and the centre
//! may join the maximum and minimum without changing the result (its own difference is 0). So `v_m`
//! is the largest distance from `I(m)` to the max or min of its (clipped) 3x3 window. A row is
//! processed by sliding per-column maxima and minima along it; a missing neighbour row or column is
//! replaced by the centre's own, which clips the window without a branch per pixel.

use super::view::{GrayView, GrayViewMut, ImageError};

/// The vertical extent of one column of the 3x3 window: its max, min, and centre sample.
///
/// Held as `u32` so that the hot loop works on whole registers (no byte extraction on the
/// Cortex-M).
#[derive(Clone, Copy)]
struct Column {
    hi: u32,
    lo: u32,
    centre: u32,
}

impl Column {
    /// The column of the three samples `above`, `centre`, `below`.
    #[inline(always)]
    fn new(above: u8, centre: u8, below: u8) -> Self {
        let (a, c, b) = (u32::from(above), u32::from(centre), u32::from(below));
        Self { hi: a.max(c).max(b), lo: a.min(c).min(b), centre: c }
    }
}

/// `v_m` of the centre column's pixel, from the window's left, centre and right columns.
#[inline(always)]
fn window_variation(left: Column, mid: Column, right: Column) -> u32 {
    let hi = left.hi.max(mid.hi).max(right.hi);
    let lo = left.lo.min(mid.lo).min(right.lo);
    // The window holds the centre, so lo <= centre <= hi and neither difference wraps.
    hi.wrapping_sub(mid.centre).max(mid.centre.wrapping_sub(lo))
}

/// Emits `v_m` (0..=255) for each pixel of `centre`, left to right. `above` and `below` are the
/// neighbour rows, or `centre` itself where the image has no such row; all three have the same
/// length.
#[inline(always)]
fn row_variation(above: &[u8], centre: &[u8], below: &[u8], mut emit: impl FnMut(u32)) {
    let mut columns =
        above.iter().zip(centre).zip(below).map(|((&a, &c), &b)| Column::new(a, c, b));
    let Some(mut mid) = columns.next() else {
        return;
    };
    // The first pixel has no left neighbour: its own column stands in for it.
    let mut left = mid;
    for right in columns {
        emit(window_variation(left, mid, right));
        left = mid;
        mid = right;
    }
    // Likewise the last pixel has no right neighbour.
    emit(window_variation(left, mid, mid));
}

/// Calls `f(y, above, centre, below)` for every row `y` of `img`, top to bottom, with the image's
/// missing rows above the first and below the last replaced by the centre row.
fn for_each_row_triple<'a>(img: &GrayView<'a>, mut f: impl FnMut(&'a [u8], &'a [u8], &'a [u8])) {
    let mut rows = img.rows();
    let Some(mut centre) = rows.next() else {
        return;
    };
    let mut above = centre;
    loop {
        let next = rows.next();
        f(above, centre, next.unwrap_or(centre));
        match next {
            Some(n) => {
                above = centre;
                centre = n;
            }
            None => return,
        }
    }
}

/// The variation `v_m` of the pixel `(x, y)` (paper Eq. 3): the largest `|I(m) - I(s)|` over the
/// neighbours `s` of the 8-neighbourhood that lie inside the image, in gray levels. `None` outside
/// the image; 0 for the single pixel of a 1x1 image.
pub fn variation(img: &GrayView<'_>, x: usize, y: usize) -> Option<u8> {
    let centre = img.get(x, y)?;
    let mut v = 0u8;
    for ny in y.saturating_sub(1)..=y.saturating_add(1) {
        for nx in x.saturating_sub(1)..=x.saturating_add(1) {
            // Pixels past the right or bottom edge give `None`; the centre gives 0.
            if let Some(s) = img.get(nx, ny) {
                v = v.max(centre.abs_diff(s));
            }
        }
    }
    Some(v)
}

/// The total variation `W(I) = sum over all pixels m of v_m` (paper Eq. 3), in gray levels.
///
/// Row by row, with no per-pixel bounds checks: about 8 min/max operations per pixel. Never
/// overflows: `W(I) <= 255 * width * height`.
pub fn total_variation(img: &GrayView<'_>) -> u64 {
    let mut total = 0u64;
    for_each_row_triple(img, |above, centre, below| {
        let mut row_sum = 0u32;
        // A row sum is at most 255 * width, which fits u32 for any row shorter than 16 million
        // pixels; summing per row in u32 keeps the inner loop in 32-bit registers on the Cortex-M.
        row_variation(above, centre, below, |v| row_sum = row_sum.wrapping_add(v));
        total += u64::from(row_sum);
    });
    total
}

/// Writes `v_m` of every pixel of `img` into the same pixel of `dst` (gray levels; used to choose
/// well-textured regions of interest).
///
/// # Errors
/// [`ImageError::SizeMismatch`] unless `dst` has the size of `img`.
pub fn variation_map(img: &GrayView<'_>, dst: &mut GrayViewMut<'_>) -> Result<(), ImageError> {
    if dst.size() != img.size() {
        return Err(ImageError::SizeMismatch { expected: img.size(), got: dst.size() });
    }
    let mut out_rows = dst.rows_mut();
    for_each_row_triple(img, |above, centre, below| {
        if let Some(out) = out_rows.next() {
            let mut out = out.iter_mut();
            row_variation(above, centre, below, |v| {
                if let Some(o) = out.next() {
                    // v_m <= 255 (see `window_variation`).
                    *o = u8::try_from(v).unwrap_or(u8::MAX);
                }
            });
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::TestRng;

    /// Eq. 3 straight from the definition, for comparison.
    fn reference_total(img: &GrayView<'_>) -> u64 {
        let mut t = 0;
        for y in 0..img.height() {
            for x in 0..img.width() {
                t += u64::from(variation(img, x, y).unwrap());
            }
        }
        t
    }

    #[test]
    fn three_by_three_by_hand() {
        #[rustfmt::skip]
        let px = [
            10, 20, 30,
            40, 50, 60,
            70, 80, 90,
        ];
        let img = GrayView::packed(&px, 3, 3).unwrap();
        // v_m by hand, e.g. (2,0) = 30: neighbours 20, 50, 60 -> max |30 - s| = 30;
        // (0,0) = 10: neighbours 20, 40, 50 -> 40; centre 50: |50 - 10| = |50 - 90| = 40.
        #[rustfmt::skip]
        let expected = [
            40, 40, 30,
            40, 40, 40,
            30, 40, 40,
        ];
        let mut map = [0u8; 9];
        variation_map(&img, &mut GrayViewMut::packed(&mut map, 3, 3).unwrap()).unwrap();
        assert_eq!(map, expected);
        for (i, &e) in expected.iter().enumerate() {
            assert_eq!(variation(&img, i % 3, i / 3), Some(e));
        }
        assert_eq!(total_variation(&img), 340);
        assert_eq!(variation(&img, 3, 0), None);
        assert_eq!(variation(&img, 0, 3), None);
    }

    #[test]
    fn step_edge() {
        // Two rows of 0 0 255 255: only the two columns at the edge vary, by 255 each.
        let px = [0, 0, 255, 255, 0, 0, 255, 255];
        let img = GrayView::packed(&px, 4, 2).unwrap();
        assert_eq!(total_variation(&img), 4 * 255);
        let mut map = [9u8; 8];
        variation_map(&img, &mut GrayViewMut::packed(&mut map, 4, 2).unwrap()).unwrap();
        assert_eq!(map, [0, 255, 255, 0, 0, 255, 255, 0]);
    }

    #[test]
    fn stride_padding_is_not_a_neighbour() {
        // 2x2 image with stride 3; the padding (255) would dominate every v_m if it were read.
        let px = [0, 10, 255, 20, 30];
        let img = GrayView::new(&px, 2, 2, 3).unwrap();
        // (0,0): max(10, 20, 30) = 30; (1,0)=10: max(10, 10, 20) = 20; (0,1)=20: 20; (1,1)=30: 30.
        assert_eq!(total_variation(&img), 100);
        let mut map = [0u8, 0, 7, 0, 0, 7];
        variation_map(&img, &mut GrayViewMut::new(&mut map, 2, 2, 3).unwrap()).unwrap();
        assert_eq!(map, [30, 20, 7, 20, 30, 7]);
    }

    #[test]
    fn degenerate_shapes() {
        let one = GrayView::packed(&[77], 1, 1).unwrap();
        assert_eq!(variation(&one, 0, 0), Some(0));
        assert_eq!(total_variation(&one), 0);
        let col = GrayView::packed(&[0, 100, 50], 1, 3).unwrap();
        // v = 100, max(100, 50) = 100, 50.
        assert_eq!(total_variation(&col), 250);
        let row = GrayView::packed(&[0, 100, 50], 3, 1).unwrap();
        assert_eq!(total_variation(&row), 250);
        let flat = GrayView::packed(&[9u8; 20], 5, 4).unwrap();
        assert_eq!(total_variation(&flat), 0);
    }

    #[test]
    fn matches_the_definition_on_pseudo_random_images() {
        let mut rng = TestRng::new(0x1234_5678);
        let buf: [u8; 13 * 9] = core::array::from_fn(|_| (rng.next_u32() >> 24) as u8);
        for (w, h, stride) in [(13, 9, 13), (7, 5, 11), (2, 9, 13), (13, 1, 13), (1, 1, 1)] {
            let img = GrayView::new(&buf, w, h, stride).unwrap();
            assert_eq!(total_variation(&img), reference_total(&img), "{w}x{h}/{stride}");
        }
    }

    #[test]
    fn map_size_must_match() {
        let px = [0u8; 6];
        let img = GrayView::packed(&px, 3, 2).unwrap();
        let mut map = [0u8; 6];
        let mut dst = GrayViewMut::packed(&mut map, 2, 3).unwrap();
        assert_eq!(
            variation_map(&img, &mut dst),
            Err(ImageError::SizeMismatch { expected: (3, 2), got: (2, 3) })
        );
    }
}
