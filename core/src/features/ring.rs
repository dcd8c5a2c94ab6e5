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
    pub(super) fn push(&mut self, y: usize, pixels: impl Iterator<Item = u8>) {
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
        let mut acc = 0u16;
        match prev {
            Some(prev) if y > 0 => {
                for ((d, &above), p) in dst.iter_mut().zip(prev.iter()).zip(pixels) {
                    acc = acc.wrapping_add(u16::from(p));
                    *d = above.wrapping_add(acc);
                }
            }
            _ => {
                for (d, p) in dst.iter_mut().zip(pixels) {
                    acc = acc.wrapping_add(u16::from(p));
                    *d = acc;
                }
            }
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
