//! The rolling integral image: the last [`INTEGRAL_RING_ROWS`] rows of a level's integral image,
//! modulo 2^16 (see [`super::filter`] for why that is exact).

use super::filter::{INTEGRAL_RING_ROWS, IntegralRows};

/// Row `y` of the level's integral image lives in slot `y % INTEGRAL_RING_ROWS`; rows are
/// `W` wide, of which a level uses its own width (the second level half of it).
#[derive(Debug, Clone)]
pub(super) struct IntegralRing<const W: usize> {
    rows: [[u16; W]; INTEGRAL_RING_ROWS],
}

impl<const W: usize> IntegralRows for IntegralRing<W> {
    fn row(&self, y: usize) -> &[u16] {
        self.rows.get(y % INTEGRAL_RING_ROWS).map_or(&[], |r| &r[..])
    }
}

impl<const W: usize> IntegralRing<W> {
    /// An empty ring (`const`, so that the detector can initialize a `static`).
    pub(super) const fn new() -> Self {
        Self { rows: [[0; W]; INTEGRAL_RING_ROWS] }
    }

    /// Adds image row `y` (rows must come in order from 0; row 0 starts a new image): integral
    /// row `y` is integral row `y - 1` plus the running sum along image row `y`. Pixels beyond
    /// `W` are ignored.
    pub(super) fn push(&mut self, y: usize, pixels: &[u8]) {
        let pixels = pixels.get(..W).unwrap_or(pixels);
        let (quads, tail) = pixels.as_chunks::<4>();
        // One word per four pixels: the Cortex-M4 adds a byte of it to the running sum in one
        // instruction (`uxtab`), where separate byte loads cost a load and an add each.
        let quads = quads.iter().map(|&q| {
            let w = u32::from_le_bytes(q);
            [w & 0xFF, (w >> 8) & 0xFF, (w >> 16) & 0xFF, w >> 24]
        });
        self.integrate(y, quads, tail.iter().copied());
    }

    /// Adds row `y` of the second pyramid level, the 2x2 means of image rows `top` and `bottom`
    /// (see [`half_row`]), as [`IntegralRing::push`] does.
    pub(super) fn push_half(&mut self, y: usize, top: &[u8], bottom: &[u8]) {
        let n = top.len().min(bottom.len()).min(2 * W);
        let (top, bottom) = (top.get(..n).unwrap_or(&[]), bottom.get(..n).unwrap_or(&[]));
        let (top4, bottom4) = (top.as_chunks::<4>().0, bottom.as_chunks::<4>().0);
        // Two means per word of each row, summed in two 16-bit lanes: a lane's sum `a + b + c + d
        // + 2 <= 1022` never carries into the other, and `>> 2` then the mask leave exactly the
        // two rounded means of `half_row`, in bytes 0 and 2.
        const LANES: u32 = 0x00FF_00FF;
        let pairs = top4.iter().zip(bottom4).map(|(&t, &b)| {
            let (t, b) = (u32::from_le_bytes(t), u32::from_le_bytes(b));
            let sum = (t & LANES) + ((t >> 8) & LANES) + (b & LANES) + ((b >> 8) & LANES);
            let means = ((sum + 0x0002_0002) >> 2) & LANES;
            [means & 0xFF, means >> 16]
        });
        let done = 4 * top4.len();
        let (top, bottom) = (top.get(done..).unwrap_or(&[]), bottom.get(done..).unwrap_or(&[]));
        self.integrate(y, pairs, half_row(top, bottom));
    }

    /// Integral row `y` from the level's row `y`, given as groups of `N` pixel values (each
    /// `<= 255`, at most `W / N` groups) followed by the pixels after the last group.
    fn integrate<const N: usize>(
        &mut self,
        y: usize,
        groups: impl ExactSizeIterator<Item = [u32; N]>,
        tail: impl Iterator<Item = u8>,
    ) {
        let slot = y % INTEGRAL_RING_ROWS;
        let prev_slot = (y + INTEGRAL_RING_ROWS - 1) % INTEGRAL_RING_ROWS;
        // Split the ring so that the previous row can be read while the new one is written.
        let (dst, prev) = if prev_slot < slot {
            let (head, tail) = self.rows.split_at_mut(slot);
            (tail.first_mut(), head.get(prev_slot))
        } else {
            let (head, tail) = self.rows.split_at_mut(prev_slot);
            (head.get_mut(slot), tail.first())
        };
        let Some(dst) = dst else { return };
        let done = N * groups.len();
        // Row 0 has no row above: its integral row is the running sum alone (once per image, so
        // the simple loop is enough).
        let Some(prev) = prev.filter(|_| y > 0) else {
            let pixels = groups.flat_map(|q| q.map(|v| v as u8)).chain(tail);
            let mut acc = 0u16;
            for (d, p) in dst.iter_mut().zip(pixels) {
                acc = acc.wrapping_add(u16::from(p));
                *d = acc;
            }
            return;
        };
        // The running sum is kept in a `u32` and truncated on store: the stored value is the
        // same modulo 2^16 as with wrapping `u16` arithmetic.
        let mut acc = 0u32;
        let rows = dst.as_chunks_mut::<N>().0.iter_mut().zip(prev.as_chunks::<N>().0);
        for ((d, a), p) in rows.zip(groups) {
            for ((d, &a), p) in d.iter_mut().zip(a).zip(p) {
                acc = acc.wrapping_add(p);
                *d = u32::from(a).wrapping_add(acc) as u16;
            }
        }
        let rest = dst.get_mut(done..).unwrap_or(&mut []).iter_mut();
        for ((d, &a), p) in rest.zip(prev.get(done..).unwrap_or(&[])).zip(tail) {
            acc = acc.wrapping_add(u32::from(p));
            *d = u32::from(a).wrapping_add(acc) as u16;
        }
    }
}

/// Row `j` of the second pyramid level: the 2x2 means of image rows `top` and `bottom`, rounded
/// half up as [`crate::image::downsample_gray_2x`] does (a last odd column is dropped).
pub(super) fn half_row<'a>(top: &'a [u8], bottom: &'a [u8]) -> impl Iterator<Item = u8> + 'a {
    let pairs = top.as_chunks::<2>().0.iter().zip(bottom.as_chunks::<2>().0);
    pairs.map(|(&[a, b], &[c, d])| {
        let sum = u16::from(a) + u16::from(b) + u16::from(c) + u16::from(d) + 2;
        // sum <= 1022, so sum / 4 <= 255: the conversion is exact.
        (sum / 4) as u8
    })
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    /// The integral row of `pixels` (truncated to `w`) over `prev`, the scalar way.
    fn reference(prev: Option<&[u16]>, pixels: impl Iterator<Item = u8>, w: usize) -> Vec<u16> {
        let mut acc = 0u16;
        let row = pixels.take(w).enumerate().map(|(x, p)| {
            acc = acc.wrapping_add(u16::from(p));
            acc.wrapping_add(prev.map_or(0, |r| r[x]))
        });
        row.collect()
    }

    /// Both levels' rows, at widths around the groups of four (and beyond `W`), over more rows
    /// than the ring holds and bright enough to wrap modulo 2^16.
    #[test]
    fn rows_match_the_scalar_running_sum() {
        const W: usize = 21;
        for width in 0..=2 * W + 3 {
            // Bright pseudo-random pixels: every rounding case of the means, and sums that wrap.
            let pixel = |x: usize, y: usize| {
                let h = (x * 7919 + y * 104_729 + width * 31).wrapping_mul(2_654_435_761);
                (128 + (h >> 13) % 128) as u8
            };
            let image: Vec<Vec<u8>> =
                (0..40).map(|y| (0..width).map(|x| pixel(x, y)).collect()).collect();
            let (mut full, mut half) = (IntegralRing::<W>::new(), IntegralRing::<W>::new());
            let (mut full_prev, mut half_prev): (Vec<u16>, Vec<u16>) = (Vec::new(), Vec::new());
            for (y, row) in image.iter().enumerate() {
                full.push(y, row);
                let prev = (y > 0).then_some(&full_prev[..]);
                let expected = reference(prev, row.iter().copied(), W);
                assert_eq!(&full.row(y)[..expected.len()], &expected[..], "{width} px, row {y}");
                full_prev = full.row(y).to_vec();
                if y % 2 == 1 {
                    let (top, bottom) = (&image[y - 1], row);
                    let j = y / 2;
                    half.push_half(j, top, bottom);
                    let prev = (j > 0).then_some(&half_prev[..]);
                    let expected = reference(prev, half_row(top, bottom), W);
                    assert_eq!(&half.row(j)[..expected.len()], &expected[..], "{width} px, {j}");
                    half_prev = half.row(j).to_vec();
                }
            }
        }
    }
}
