//! Bilinear samples of a template image at the 16.16 fixed-point positions of a warped grid:
//! one checked read at a time ([`sample_each`]), or through a copy of the pixels the grid reads
//! ([`Window`]), with the same values bit for bit.

use super::GRAY_OFFSET;
use crate::matching::affine::{Mat2, mat_apply};

/// One in 16.16 fixed point.
const FIXED_ONE: f32 = 65536.0;

/// The 16.16 fixed-point positions of the `S x S` template grid `centre + a_inv q` (margin
/// included): the start of each row and the step along a row, the map's first column. A row's
/// samples then step in integers (no float-to-integer conversion per sample, the same on every
/// target). [`Template::warp`](super::Template) checks the grid's corners in floating point
/// first; they lie at most 0.5 px inside `0..w - 1`, so the 1/65536 px rounding of a step, times
/// 14 steps, cannot leave the image.
pub(super) fn fixed_grid<const S: usize>(
    centre: (f32, f32),
    a_inv: &Mat2,
) -> ([(i32, i32); S], (i32, i32)) {
    let fixed = |v: f32| libm::roundf(v * FIXED_ONE) as i32;
    let m = (S / 2) as f32;
    let starts = core::array::from_fn(|j| {
        let (dx, dy) = mat_apply(a_inv, (-m, j as f32 - m));
        (fixed(centre.0 + dx), fixed(centre.1 + dy))
    });
    (starts, (fixed(a_inv[0][0]), fixed(a_inv[1][0])))
}

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
pub(super) fn sample_each<const S: usize>(
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
pub(super) struct Window {
    rows: [[u8; WINDOW_SIDE]; WINDOW_SIDE + 2],
}

impl Window {
    /// All zero, to be filled by [`Self::sample`].
    pub(super) const EMPTY: Self = Self { rows: [[0; WINDOW_SIDE]; WINDOW_SIDE + 2] };

    /// Fills `out` with the bilinear samples of `data` (rows `stride` apart) at the 16.16
    /// fixed-point positions `starts[j] + k step` (row `j`, column `k`), minus the gray offset,
    /// through a copy of the pixels they read; `false` (and `out` untouched) when those pixels
    /// do not fit a window or its rows leave the buffer, for [`sample_each`]. The values are those
    /// of [`sample_each`], bit for bit: the same pixels, the same [`lerp_fixed`]; only the
    /// per-sample bounds checks of [`bilinear_fixed`] are gone, with the copy paid once.
    pub(super) fn sample<const S: usize>(
        &mut self,
        data: &[u8],
        stride: usize,
        starts: &[(i32, i32); S],
        step: (i32, i32),
        out: &mut [[f32; S]; S],
    ) -> bool {
        // A row's positions move linearly, so its extremes are its ends (the wrapping product
        // matches the samples' wrapping steps).
        let span_x = (S as i32 - 1).wrapping_mul(step.0);
        let span_y = (S as i32 - 1).wrapping_mul(step.1);
        let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (i32::MAX, i32::MIN, i32::MAX, i32::MIN);
        for &(x, y) in starts {
            let (x_end, y_end) = (x.wrapping_add(span_x), y.wrapping_add(span_y));
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matching::patch_tracker::test_images::noise_image;

    /// The window's samples equal the checked ones bit for bit, on a 16 x 16 template and on a
    /// larger image; warps whose pixels do not fit a window, or leave the image, are refused.
    #[test]
    fn window_samples_equal_checked_ones() {
        const S: usize = 11;
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
                    let (starts, step) = fixed_grid::<S>(centre, a_inv);
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
            let (starts, step) = fixed_grid::<S>(centre, a_inv);
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
}
