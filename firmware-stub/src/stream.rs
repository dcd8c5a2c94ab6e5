//! The board's frame store: one QVGA gray image and its depth at half that resolution (the QVGA
//! profile's depth level 1), filled two sensor rows at a time while a VGA frame arrives, so that
//! no VGA frame is ever held (a VGA gray + depth pair is 921,600 bytes, more than the reference
//! board's budget for everything).
//!
//! Each pair of sensor rows `2y, 2y + 1` becomes QVGA gray row `y` through the core's streaming
//! downsampler ([`downsample_gray_row_pair`]); the depth rows are halved the same way
//! ([`downsample_depth_row_pair`]) into a one-row buffer, and each pair of those halved rows again
//! into depth row `y / 2`. That is exactly what the whole-frame functions give on the host (the
//! sensor frame halved, then its depth halved once more: `ferroslam-sim`'s `coarsen_depth`;
//! tested below), in 39,040 bytes of depth instead of 153,600.

use ferroslam_core::config::{QVGA, QvgaDepthBuffer, QvgaGrayBuffer, capacity};
use ferroslam_core::frame::RgbdFrame;
use ferroslam_core::image::{
    DepthView, GrayView, ImageError, ImageView, downsample_depth_row_pair, downsample_gray_row_pair,
};

/// Widest sensor row the board streams, pixels (VGA).
pub const MAX_SENSOR_WIDTH: usize = capacity::MAX_WIDTH;
/// Tallest sensor frame the board streams, pixels (VGA).
pub const MAX_SENSOR_HEIGHT: usize = capacity::MAX_HEIGHT;

/// Pixels of the half-resolution frame of the largest sensor (QVGA).
const HALF_PIXELS: usize = (MAX_SENSOR_WIDTH / 2) * (MAX_SENSOR_HEIGHT / 2);

/// The depth level of the store: one depth reading per 2 x 2 gray pixels.
const DEPTH_LEVEL: u8 = QVGA.depth_level;

/// A QVGA gray image and its 160 x 120 depth, the only frame storage of the board (76,800 +
/// 38,400 bytes, and the 640-byte depth row being halved). Zeroed by [`HalfFrame::new`]
/// (`const`, so it can initialize a `static` in `.bss`).
#[derive(Debug)]
pub struct HalfFrame {
    gray: QvgaGrayBuffer,
    depth: QvgaDepthBuffer,
    /// The last even half-resolution depth row, waiting for the odd row below it.
    depth_row: [u16; MAX_SENSOR_WIDTH / 2],
    /// The half-resolution row `depth_row` holds, if any.
    depth_row_index: Option<usize>,
    /// Size of the gray frame stored (half the sensor's), pixels.
    size: (usize, usize),
}

impl Default for HalfFrame {
    fn default() -> Self {
        Self::new()
    }
}

impl HalfFrame {
    /// An empty (all zero) frame store.
    pub const fn new() -> Self {
        Self {
            gray: [0; HALF_PIXELS],
            depth: [0; HALF_PIXELS >> (2 * DEPTH_LEVEL)],
            depth_row: [0; MAX_SENSOR_WIDTH / 2],
            depth_row_index: None,
            size: (0, 0),
        }
    }

    /// Starts a frame of a `sensor_width` x `sensor_height` sensor: the stored gray frame will
    /// be half that, rounded down, its depth half the gray frame, rounded down.
    ///
    /// # Errors
    /// [`ImageError::SizeMismatch`] for a sensor larger than VGA, [`ImageError::ZeroSize`] for one
    /// with a side shorter than 4 pixels (its depth would be empty).
    pub fn start(&mut self, sensor_width: usize, sensor_height: usize) -> Result<(), ImageError> {
        if sensor_width > MAX_SENSOR_WIDTH || sensor_height > MAX_SENSOR_HEIGHT {
            return Err(ImageError::SizeMismatch {
                expected: (MAX_SENSOR_WIDTH, MAX_SENSOR_HEIGHT),
                got: (sensor_width, sensor_height),
            });
        }
        let size = (sensor_width / 2, sensor_height / 2);
        if size.0 >> DEPTH_LEVEL == 0 || size.1 >> DEPTH_LEVEL == 0 {
            return Err(ImageError::ZeroSize);
        }
        self.size = size;
        self.depth_row_index = None;
        Ok(())
    }

    /// Size of the stored (half-resolution) gray frame, pixels.
    pub fn size(&self) -> (usize, usize) {
        self.size
    }

    /// Size of the stored depth, pixels (half the gray frame's, rounded down).
    pub fn depth_size(&self) -> (usize, usize) {
        (self.size.0 >> DEPTH_LEVEL, self.size.1 >> DEPTH_LEVEL)
    }

    /// Stores sensor gray rows `2 * row`, `2 * row + 1` as half-resolution row `row`.
    ///
    /// # Errors
    /// [`ImageError::SizeMismatch`] when `row` is past the frame or the rows are not the sensor's
    /// width.
    pub fn put_gray_rows(
        &mut self,
        row: usize,
        top: &[u8],
        bottom: &[u8],
    ) -> Result<(), ImageError> {
        let out = row_slice(&mut self.gray, self.size, row)?;
        downsample_gray_row_pair(top, bottom, out)
    }

    /// Takes sensor depth rows `2 * row`, `2 * row + 1`: halved, an even `row` waits for the odd
    /// one after it, and the two are halved again into depth row `row / 2`. Rows come in order,
    /// as a sensor sends them: an odd `row` whose even row was not put just before, and the last
    /// row of a frame with an odd half height, store nothing.
    ///
    /// # Errors
    /// As [`HalfFrame::put_gray_rows`].
    pub fn put_depth_rows(
        &mut self,
        row: usize,
        top: &[u16],
        bottom: &[u16],
    ) -> Result<(), ImageError> {
        let (w, h) = self.size;
        if row >= h {
            return Err(ImageError::SizeMismatch { expected: self.size, got: (w, row + 1) });
        }
        if row.is_multiple_of(2) {
            // Checked before anything is written: on an error the waiting row is kept.
            downsample_depth_row_pair(
                top,
                bottom,
                self.depth_row.get_mut(..w).unwrap_or_default(),
            )?;
            self.depth_row_index = Some(row);
            return Ok(());
        }
        let mut half = [0u16; MAX_SENSOR_WIDTH / 2];
        let half = half.get_mut(..w).unwrap_or_default();
        downsample_depth_row_pair(top, bottom, half)?;
        if self.depth_row_index.take() != Some(row - 1) {
            return Ok(());
        }
        let size = self.depth_size();
        let out = row_slice(&mut self.depth, size, row / 2)?;
        downsample_depth_row_pair(self.depth_row.get(..w).unwrap_or_default(), half, out)
    }

    /// The stored frame as the core's [`RgbdFrame`], its depth at level 1 (rows not yet put
    /// hold the previous frame's or zeros).
    ///
    /// # Errors
    /// [`ImageError::ZeroSize`] before [`HalfFrame::start`]; [`ImageError::InvalidDepthScale`].
    pub fn frame(&self, timestamp_s: f64, depth_scale: f32) -> Result<RgbdFrame<'_>, ImageError> {
        let (w, h) = self.size;
        let gray = GrayView::packed(self.gray.get(..w * h).unwrap_or_default(), w, h)?;
        let (wd, hd) = self.depth_size();
        let raw = ImageView::packed(self.depth.get(..wd * hd).unwrap_or_default(), wd, hd)?;
        let depth = DepthView::with_level(raw, depth_scale, DEPTH_LEVEL)?;
        Ok(RgbdFrame { timestamp_s, gray, depth })
    }
}

/// Row `row` of a packed buffer of `size`.
fn row_slice<P>(buf: &mut [P], size: (usize, usize), row: usize) -> Result<&mut [P], ImageError> {
    let (w, h) = size;
    let bad = ImageError::SizeMismatch { expected: size, got: (w, row + 1) };
    if row >= h {
        return Err(bad);
    }
    buf.get_mut(row * w..(row + 1) * w).ok_or(bad)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferroslam_core::image::{
        GrayViewMut, ImageViewMut, downsample_depth_2x, downsample_gray_2x,
    };
    use std::boxed::Box;
    use std::vec::Vec;

    #[test]
    fn a_streamed_frame_equals_the_whole_frame_halving() {
        let (w, h) = (640, 480);
        let gray: Vec<u8> = (0..w * h).map(|i| (i * 7 % 251) as u8).collect();
        let depth: Vec<u16> =
            (0..w * h).map(|i| if i % 5 == 0 { 0 } else { (i % 4000) as u16 }).collect();
        let mut store = Box::new(HalfFrame::new());
        store.start(w, h).unwrap();
        for y in 0..h / 2 {
            let rows = |k: usize| (2 * y + k) * w..(2 * y + k + 1) * w;
            store.put_gray_rows(y, &gray[rows(0)], &gray[rows(1)]).unwrap();
            store.put_depth_rows(y, &depth[rows(0)], &depth[rows(1)]).unwrap();
        }
        let f = store.frame(1.5, 1000.0).unwrap();
        let mut g = std::vec![0u8; 320 * 240];
        let mut d = std::vec![0u16; 320 * 240];
        let mut d2 = std::vec![0u16; 160 * 120];
        let src = GrayView::packed(&gray, w, h).unwrap();
        downsample_gray_2x(&src, &mut GrayViewMut::packed(&mut g, 320, 240).unwrap()).unwrap();
        let src = ImageView::packed(&depth, w, h).unwrap();
        downsample_depth_2x(&src, &mut ImageViewMut::packed(&mut d, 320, 240).unwrap()).unwrap();
        let src = ImageView::packed(&d, 320, 240).unwrap();
        downsample_depth_2x(&src, &mut ImageViewMut::packed(&mut d2, 160, 120).unwrap()).unwrap();
        assert!(f.gray.rows().flatten().copied().eq(g.iter().copied()));
        assert_eq!((f.depth.raw().size(), f.depth.level()), ((160, 120), 1));
        assert!(f.depth.raw().rows().flatten().copied().eq(d2.iter().copied()));
        assert_eq!((f.timestamp_s, f.depth.depth_scale()), (1.5, 1000.0));
    }

    #[test]
    fn depth_rows_out_of_order_store_nothing() {
        let mut store = Box::new(HalfFrame::new());
        store.start(8, 8).unwrap();
        assert_eq!((store.size(), store.depth_size()), ((4, 4), (2, 2)));
        // Row 1 without row 0 just before it: no depth row is made.
        store.put_depth_rows(1, &[500; 8], &[500; 8]).unwrap();
        assert!(store.frame(0.0, 1000.0).unwrap().depth.raw().rows().flatten().all(|&d| d == 0));
        store.put_depth_rows(0, &[700; 8], &[700; 8]).unwrap();
        store.put_depth_rows(1, &[700; 8], &[700; 8]).unwrap();
        let f = store.frame(0.0, 1000.0).unwrap();
        assert_eq!(f.depth.raw().row(0), Some(&[700u16, 700][..]));
        assert_eq!(f.depth.raw().row(1), Some(&[0u16, 0][..]));
    }

    #[test]
    fn bad_sizes_and_rows_are_errors() {
        let mut store = Box::new(HalfFrame::new());
        assert!(store.frame(0.0, 1.0).is_err(), "no frame before start");
        assert!(store.start(642, 480).is_err());
        assert!(store.start(1, 480).is_err());
        assert!(store.start(2, 480).is_err(), "its depth would be empty");
        store.start(4, 4).unwrap();
        assert_eq!((store.size(), store.depth_size()), ((2, 2), (1, 1)));
        assert!(store.put_gray_rows(2, &[0; 4], &[0; 4]).is_err(), "row past the frame");
        assert!(store.put_gray_rows(0, &[0; 6], &[0; 6]).is_err(), "row of the wrong width");
        assert!(store.put_depth_rows(1, &[1; 4], &[1; 4]).is_ok());
        assert!(store.frame(0.0, f32::NAN).is_err());
    }
}
