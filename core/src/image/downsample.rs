//! 2x downsampling of gray and depth images (one pyramid level: VGA to QVGA).
//!
//! Both functions read 2x2 blocks of the source and write one pixel per block; a last odd column or
//! row of the source is dropped (the output size is the floor of half the input size), so output
//! pixel `(x, y)` covers source pixels `(2x..=2x+1, 2y..=2y+1)`.

use super::view::{GrayView, GrayViewMut, ImageError, ImageView, ImageViewMut};

/// Checks that `dst` is `(src.width / 2, src.height / 2)`.
fn check_half_size(src: (usize, usize), dst: (usize, usize)) -> Result<(), ImageError> {
    let expected = (src.0 / 2, src.1 / 2);
    if dst != expected {
        return Err(ImageError::SizeMismatch { expected, got: dst });
    }
    Ok(())
}

/// Calls `block` on every 2x2 block of `src` (as `[[top-left, top-right], [bottom-left,
/// bottom-right]]`) and stores its result in the matching pixel of `dst`: one [`row_pair`] per
/// output row, so the streaming functions below compute exactly what the whole-frame ones do.
///
/// The caller has checked the sizes; rows are walked with iterators, so no pixel access can panic.
fn for_each_block<P: Copy>(
    src: &ImageView<'_, P>,
    dst: &mut ImageViewMut<'_, P>,
    block: impl Fn([[P; 2]; 2]) -> P,
) {
    let mut src_rows = src.rows();
    for out in dst.rows_mut() {
        let (Some(top), Some(bottom)) = (src_rows.next(), src_rows.next()) else {
            return;
        };
        row_pair(top, bottom, out, &block);
    }
}

/// One output row from two source rows: `out[x] = block` of columns `2x, 2x + 1` (a last odd
/// column is dropped; `out` may be shorter than half the rows, then only its pixels are written).
fn row_pair<P: Copy>(top: &[P], bottom: &[P], out: &mut [P], block: impl Fn([[P; 2]; 2]) -> P) {
    let pairs = top.as_chunks::<2>().0.iter().zip(bottom.as_chunks::<2>().0);
    for (o, (&t, &b)) in out.iter_mut().zip(pairs) {
        *o = block([t, b]);
    }
}

/// Checks the row lengths of a streamed row pair: both source rows equally long, `out` exactly
/// half as long (rounded down).
fn check_row_pair(top: usize, bottom: usize, out: usize) -> Result<(), ImageError> {
    if bottom != top {
        return Err(ImageError::SizeMismatch { expected: (top, 1), got: (bottom, 1) });
    }
    check_half_size((top, 2), (out, 1))?;
    if out == 0 {
        return Err(ImageError::ZeroSize);
    }
    Ok(())
}

/// [`downsample_gray_2x`] on a stream: one output row from source rows `2y` (`top`) and `2y + 1`
/// (`bottom`), so a sensor frame can be halved while it arrives, two rows at a time, without ever
/// being held whole. Streaming every row pair of an image gives exactly the output of
/// [`downsample_gray_2x`] (the two share the block rule and are tested against each other).
///
/// # Errors
/// [`ImageError::SizeMismatch`] unless `top` and `bottom` have one length and `out` half of it
/// (rounded down); [`ImageError::ZeroSize`] for rows shorter than 2 pixels.
pub fn downsample_gray_row_pair(
    top: &[u8],
    bottom: &[u8],
    out: &mut [u8],
) -> Result<(), ImageError> {
    check_row_pair(top.len(), bottom.len(), out.len())?;
    row_pair(top, bottom, out, gray_block);
    Ok(())
}

/// [`downsample_depth_2x`] on a stream, as [`downsample_gray_row_pair`] is to
/// [`downsample_gray_2x`]: the same per-block rule, exactly the whole-frame output.
///
/// # Errors
/// As [`downsample_gray_row_pair`].
pub fn downsample_depth_row_pair(
    top: &[u16],
    bottom: &[u16],
    out: &mut [u16],
) -> Result<(), ImageError> {
    check_row_pair(top.len(), bottom.len(), out.len())?;
    row_pair(top, bottom, out, depth_block);
    Ok(())
}

/// The gray of one 2x2 block: the rounded mean (see [`downsample_gray_2x`]).
fn gray_block([[a, b], [c, d]]: [[u8; 2]; 2]) -> u8 {
    let sum = u16::from(a) + u16::from(b) + u16::from(c) + u16::from(d) + 2;
    // sum <= 4 * 255 + 2, so sum / 4 <= 255: the conversion never saturates.
    u8::try_from(sum / 4).unwrap_or(u8::MAX)
}

/// Halves a gray image: each output pixel is the mean of its 2x2 source block, rounded half up,
/// `(a + b + c + d + 2) / 4` in integers (exact and identical on every target).
///
/// # Errors
/// [`ImageError::SizeMismatch`] unless `dst` is `(src.width / 2, src.height / 2)` (rounded down); a
/// source one pixel wide or high therefore always fails, since views are never empty.
pub fn downsample_gray_2x(src: &GrayView<'_>, dst: &mut GrayViewMut<'_>) -> Result<(), ImageError> {
    check_half_size(src.size(), dst.size())?;
    for_each_block(src, dst, gray_block);
    Ok(())
}

/// The depth of one 2x2 block: the median of its valid (non-zero) raw samples where they lie on
/// one surface, else the valid sample nearest to it; 0 if none.
///
/// Case by case, with `s` the valid samples sorted ascending (nearest to the camera first):
/// - none valid: 0 (no reading);
/// - one: `s[0]`, the only measurement;
/// - two: the median is their mean, equally far from both; the tie goes to the smaller `s[0]`, the
///   surface nearer to the camera. At an object edge the nearer surface is the one that occludes
///   the other, so it is what the coarse pixel's ray meets first, and keeping it keeps thin
///   foreground structures (table legs, edges) that a far-wins rule would erase;
/// - three: the median `s[1]` is itself a sample;
/// - four: the median is `(s[1] + s[2]) / 2` (rounded down). When `s[1]` and `s[2]` are within
///   1/32 of `s[1]` of each other (3%: 6 cm at 2 m, beyond any one surface's depth change across
///   a VGA pixel but for grazing views) they are taken to be one surface, and the median is the
///   output: it is what the block's centre sees on a plane. Otherwise the block straddles an
///   edge, and the tie between `s[1]` and `s[2]` goes to the smaller, `s[1]`, as for two.
///
/// So the output is a real measurement (`s[(n - 1) / 2]`) or, on one surface only, the mean of
/// the two middle ones: never an average across samples on different surfaces (which would
/// invent a point floating between foreground and background). Keeping `s[1]` on smooth blocks
/// too (the rule before this one) put every slanted surface nearer to the camera by up to half
/// the depth step of a full-resolution pixel. Why: docs/decisions.md, "Depth halving keeps the
/// median on one surface".
fn depth_block([[a, b], [c, d]]: [[u16; 2]; 2]) -> u16 {
    let n = u8::from(a != 0) + u8::from(b != 0) + u8::from(c != 0) + u8::from(d != 0);
    if n == 4 {
        // All valid: no shift needed. The two middle samples are the larger pair minimum and the
        // smaller pair maximum (`s[0]` and `s[3]` are the other two), in some order.
        let ((p, q), (r, t)) = ordered_pairs([a, b, c, d]);
        let (m, k) = (p.max(r), q.min(t));
        let (s1, s2) = (m.min(k), m.max(k));
        if u32::from(s2 - s1) * 32 <= u32::from(s1) {
            // Fits a u16: the mean of two u16.
            return ((u32::from(s1) + u32::from(s2)) / 2) as u16;
        }
        return s1;
    }
    // Shifting every sample down by one (wrapping) sends "no reading" (0) to u16::MAX and keeps
    // the order of valid samples, so invalid samples sort last: the first `n` of the sorted block
    // are exactly the valid samples, in order. Shifting back up maps an all-invalid block to 0.
    let (s0, s1) = two_smallest([a, b, c, d].map(|v| v.wrapping_sub(1)));
    let pick = if n >= 3 { s1 } else { s0 };
    pick.wrapping_add(1)
}

/// The smallest and second smallest of four values (`s[0]` and `s[1]` of the sorted block), with
/// 7 min/max operations instead of a full 10-operation sort: after ordering the pairs `(a, b)` and
/// `(c, d)`, the smallest is the smaller pair minimum, and the second smallest is the larger pair
/// minimum unless the smallest's partner is smaller still, i.e. `min(max(p, r), min(q, t))`.
fn two_smallest(block: [u16; 4]) -> (u16, u16) {
    let ((p, q), (r, t)) = ordered_pairs(block);
    (p.min(r), p.max(r).min(q.min(t)))
}

/// The pairs `(a, b)` and `(c, d)` each in ascending order: the first step of both selections
/// above.
#[inline(always)]
fn ordered_pairs([a, b, c, d]: [u16; 4]) -> ((u16, u16), (u16, u16)) {
    ((a.min(b), a.max(b)), (c.min(d), c.max(d)))
}

/// Halves a raw depth image (`0` = no reading) without inventing depth across object edges: each
/// output sample is the median of its 2x2 block's valid samples when that median lies on one
/// surface, else the valid sample nearest to it (nearer surface on ties), or 0 when the block has
/// no valid sample. The raw units (and so the depth scale) are unchanged.
///
/// Rule, with `s` the block's valid samples sorted ascending: none valid gives 0; one gives it;
/// two give the smaller (their mean is the median, equally far from both; the nearer surface wins
/// because it occludes the farther one and thin foreground objects survive); three give the middle
/// one; four give `(s[1] + s[2]) / 2` when `s[1]` and `s[2]` differ by at most `s[1] / 32` (one
/// surface), else `s[1]` (an edge: the tie broken to the smaller).
///
/// # Errors
/// [`ImageError::SizeMismatch`] unless `dst` is `(src.width / 2, src.height / 2)` (rounded down).
pub fn downsample_depth_2x(
    src: &ImageView<'_, u16>,
    dst: &mut ImageViewMut<'_, u16>,
) -> Result<(), ImageError> {
    check_half_size(src.size(), dst.size())?;
    for_each_block(src, dst, depth_block);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::TestRng;

    fn gray_2x(src: &[u8], w: usize, h: usize) -> [u8; 4] {
        let mut out = [0u8; 4];
        let s = GrayView::packed(src, w, h).unwrap();
        let (ow, oh) = (w / 2, h / 2);
        let mut d = GrayViewMut::packed(&mut out[..ow * oh], ow, oh).unwrap();
        downsample_gray_2x(&s, &mut d).unwrap();
        out
    }

    #[test]
    fn gray_is_rounded_mean_of_blocks() {
        // Blocks: (1+2+5+6+2)/4 = 4, (3+4+7+8+2)/4 = 6.
        assert_eq!(gray_2x(&[1, 2, 3, 4, 5, 6, 7, 8], 4, 2)[..2], [4, 6]);
        // Mean 0.5 rounds up to 1, 0.25 down to 0, 1.25 to 1, 1.75 to 2; white stays white.
        assert_eq!(gray_2x(&[0, 0, 0, 1, 0, 2, 0, 0], 4, 2)[..2], [1, 0]);
        assert_eq!(gray_2x(&[1, 1, 1, 2, 1, 2, 2, 2], 4, 2)[..2], [1, 2]);
        assert_eq!(gray_2x(&[255; 4], 2, 2)[0], 255);
    }

    #[test]
    fn gray_odd_sizes_drop_last_column_and_row() {
        // 5x3 -> 2x1: column 4 and row 2 (all 200) are ignored.
        #[rustfmt::skip]
        let src = [
            0, 4, 8, 8, 200,
            4, 0, 8, 8, 200,
            200, 200, 200, 200, 200,
        ];
        assert_eq!(gray_2x(&src, 5, 3)[..2], [2, 8]);
    }

    #[test]
    fn gray_respects_strides_of_both_views() {
        // 4x2 source with stride 6 (padding 99), 2x1 output with stride 3 (padding kept).
        let src = [1, 2, 3, 4, 99, 99, 5, 6, 7, 8];
        let s = GrayView::new(&src, 4, 2, 6).unwrap();
        let mut out = [0u8, 0, 77];
        let mut d = GrayViewMut::new(&mut out, 2, 1, 3).unwrap();
        downsample_gray_2x(&s, &mut d).unwrap();
        assert_eq!(out, [4, 6, 77]);
    }

    #[test]
    fn wrong_output_size_is_an_error() {
        let src = [0u8; 12];
        let s = GrayView::packed(&src, 4, 3).unwrap();
        let mut out = [0u8; 4];
        let mut d = GrayViewMut::packed(&mut out, 2, 2).unwrap();
        assert_eq!(
            downsample_gray_2x(&s, &mut d),
            Err(ImageError::SizeMismatch { expected: (2, 1), got: (2, 2) })
        );
        let dsrc = [0u16; 12];
        let ds = ImageView::packed(&dsrc, 4, 3).unwrap();
        let mut dout = [0u16; 1];
        let mut dd = ImageViewMut::packed(&mut dout, 1, 1).unwrap();
        assert!(downsample_depth_2x(&ds, &mut dd).is_err());
    }

    fn depth_of(block: [u16; 4]) -> u16 {
        let s = ImageView::packed(&block, 2, 2).unwrap();
        let mut out = [0xBEEFu16];
        let mut d = ImageViewMut::packed(&mut out, 1, 1).unwrap();
        downsample_depth_2x(&s, &mut d).unwrap();
        out[0]
    }

    #[test]
    fn depth_blocks_without_enough_readings() {
        assert_eq!(depth_of([0, 0, 0, 0]), 0);
        assert_eq!(depth_of([0, 0, 1234, 0]), 1234);
        // A valid reading at the top of the raw range is not mistaken for "invalid".
        assert_eq!(depth_of([0, u16::MAX, 0, 0]), u16::MAX);
    }

    #[test]
    fn depth_edge_block_outputs_a_real_sample() {
        // Foreground at 1.0 m, background at 3.0 m (raw mm). Averages would be 2000 (two and two)
        // or 1500/2500: none of them lies on a surface.
        for block in [[1000, 3000, 1000, 3000], [3000, 1000, 1000, 3000]] {
            assert_eq!(depth_of(block), 1000);
        }
        // Two valid, different surfaces: the nearer one, never 2000.
        assert_eq!(depth_of([0, 3000, 1000, 0]), 1000);
        // Three valid: the median sample, whichever surface has the majority.
        assert_eq!(depth_of([3000, 0, 1000, 3000]), 3000);
        assert_eq!(depth_of([1000, 1010, 0, 3000]), 1010);
        // Four valid on one surface (a slanted plane, or noise): the median, the mean of the two
        // middle samples rounded down, which need not be a sample.
        assert_eq!(depth_of([1003, 1001, 1002, 1004]), 1002);
        assert_eq!(depth_of([1006, 1000, 1004, 1002]), 1003);
        // The middle two just within 1/32 of the lower one (32 * 31 <= 1000) are one surface;
        // just beyond it (32 * 32 > 1000), an edge: the nearer middle sample.
        assert_eq!(depth_of([1000, 1000, 1031, 1031]), 1015);
        assert_eq!(depth_of([1000, 1000, 1032, 1032]), 1000);
        // Three on the background, one foreground: a background sample (median 3000.5, tie to the
        // smaller), not a blend.
        assert_eq!(depth_of([3000, 3002, 1000, 3001]), 3000);
        for block in [[1000, 3000, 1000, 3000], [0, 3000, 1000, 0], [3000, 3002, 1000, 3001]] {
            assert!(block.contains(&depth_of(block)));
        }
    }

    #[test]
    fn two_smallest_of_every_order() {
        let v = [3u16, 1, 4, 2];
        assert_eq!(two_smallest([5, 5, 1, 5]), (1, 5));
        assert_eq!(two_smallest([2, 9, 2, 9]), (2, 2));
        for i in 0..24usize {
            // Each of the 24 permutations of 1..=4, by Lehmer code.
            let mut pool = [v[0], v[1], v[2], v[3]];
            pool.sort_unstable();
            let mut rest: heapless::Vec<u16, 4> = pool.iter().copied().collect();
            let mut perm = [0u16; 4];
            let mut code = i;
            for (k, slot) in perm.iter_mut().enumerate() {
                let f = [6, 2, 1, 1][k];
                *slot = rest.remove(code / f);
                code %= f;
            }
            assert_eq!(two_smallest(perm), (1, 2), "{perm:?}");
        }
    }

    #[test]
    fn streaming_row_pairs_gives_exactly_the_whole_frame_output() {
        extern crate std;
        use std::vec::Vec;
        // Even and odd sizes, with stride padding, gray of every level and depth with holes and
        // the extreme raw values.
        for (w, h, seed) in [(640, 480, 1), (7, 5, 2), (2, 2, 3), (33, 8, 4), (320, 3, 5)] {
            let stride = w + 3;
            let mut rng = TestRng::new(seed);
            let mut next = || rng.next_u32();
            let gray: Vec<u8> = (0..stride * h).map(|_| next() as u8).collect();
            let depth: Vec<u16> = (0..stride * h)
                .map(|_| match next() % 8 {
                    0 | 1 => 0,
                    2 => u16::MAX,
                    _ => next() as u16,
                })
                .collect();
            let (ow, oh) = (w / 2, h / 2);
            let g = GrayView::new(&gray, w, h, stride).unwrap();
            let d = ImageView::new(&depth, w, h, stride).unwrap();
            let mut whole_g = std::vec![0u8; ow * oh];
            let mut whole_d = std::vec![0u16; ow * oh];
            downsample_gray_2x(&g, &mut GrayViewMut::packed(&mut whole_g, ow, oh).unwrap())
                .unwrap();
            downsample_depth_2x(&d, &mut ImageViewMut::packed(&mut whole_d, ow, oh).unwrap())
                .unwrap();
            let mut streamed_g = std::vec![0u8; ow * oh];
            let mut streamed_d = std::vec![0u16; ow * oh];
            for y in 0..oh {
                let out = y * ow..(y + 1) * ow;
                let (top, bottom) = (g.row(2 * y).unwrap(), g.row(2 * y + 1).unwrap());
                downsample_gray_row_pair(top, bottom, &mut streamed_g[out.clone()]).unwrap();
                let (top, bottom) = (d.row(2 * y).unwrap(), d.row(2 * y + 1).unwrap());
                downsample_depth_row_pair(top, bottom, &mut streamed_d[out]).unwrap();
            }
            assert_eq!(streamed_g, whole_g, "{w}x{h}");
            assert_eq!(streamed_d, whole_d, "{w}x{h}");
        }
    }

    #[test]
    fn row_pairs_of_the_wrong_length_are_errors() {
        let mut out = [0u8; 2];
        assert!(downsample_gray_row_pair(&[0; 4], &[0; 5], &mut out).is_err());
        assert!(downsample_gray_row_pair(&[0; 6], &[0; 6], &mut out).is_err());
        assert!(downsample_gray_row_pair(&[0; 5], &[0; 5], &mut out).is_ok(), "odd column dropped");
        assert!(downsample_depth_row_pair(&[0; 1], &[0; 1], &mut [0; 0]).is_err());
    }

    #[test]
    fn depth_respects_strides() {
        // 4x2 source, stride 5, padding 7; blocks: {0,0,0,0} -> 0, {2000,0,1000,0} -> 1000.
        let src = [0u16, 0, 2000, 0, 7, 0, 0, 1000, 0];
        let s = ImageView::new(&src, 4, 2, 5).unwrap();
        let mut out = [9u16; 2];
        let mut d = ImageViewMut::packed(&mut out, 2, 1).unwrap();
        downsample_depth_2x(&s, &mut d).unwrap();
        assert_eq!(out, [0, 1000]);
    }
}
