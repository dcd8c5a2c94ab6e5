//! The rolling integral image: the last [`INTEGRAL_RING_ROWS`] rows of a level's integral image,
//! modulo 2^16 (see [`super::filter`] for why that is exact).

use super::filter::{INTEGRAL_RING_ROWS, IntegralRows};

/// Row `y` of the level's integral image lives in slot `y % INTEGRAL_RING_ROWS`; rows are
/// `W` wide, of which a level uses its own width (the second level half of it).
#[derive(Debug)]
pub(super) struct IntegralRing<const W: usize> {
    rows: [[u16; W]; INTEGRAL_RING_ROWS],
    /// Column sums of every image row added so far (modulo 2^16).
    column_sums: [u16; W],
}

impl<const W: usize> IntegralRows for IntegralRing<W> {
    fn row(&self, y: usize) -> &[u16] {
        self.rows.get(y % INTEGRAL_RING_ROWS).map_or(&[], |r| &r[..])
    }
}

impl<const W: usize> IntegralRing<W> {
    /// An empty ring (`const`, so that the detector can initialize a `static`).
    pub(super) const fn new() -> Self {
        Self { rows: [[0; W]; INTEGRAL_RING_ROWS], column_sums: [0; W] }
    }

    /// Adds image row `y` (rows must come in order from 0; row 0 starts a new image). Pixels
    /// beyond `W` are ignored.
    pub(super) fn push(&mut self, y: usize, pixels: impl Iterator<Item = u8>) {
        if y == 0 {
            self.column_sums.fill(0);
        }
        let Some(dst) = self.rows.get_mut(y % INTEGRAL_RING_ROWS) else { return };
        let mut acc = 0u16;
        for ((d, cs), p) in dst.iter_mut().zip(self.column_sums.iter_mut()).zip(pixels) {
            *cs = cs.wrapping_add(u16::from(p));
            acc = acc.wrapping_add(*cs);
            *d = acc;
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
