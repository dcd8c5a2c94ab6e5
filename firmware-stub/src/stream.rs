//! The board's frame store: one QVGA gray + depth pair, filled two sensor rows at a time while a
//! VGA frame arrives, so that no VGA frame is ever held (a VGA gray + depth pair is 921,600 bytes,
//! more than the reference board's budget for everything).
//!
//! Each pair of sensor rows `2y, 2y + 1` becomes QVGA row `y` through the core's streaming
//! downsamplers ([`downsample_gray_row_pair`], [`downsample_depth_row_pair`]), which give exactly
//! what the whole-frame functions give on the host (tested in the core).

use ferroslam_core::config::{QvgaDepthBuffer, QvgaGrayBuffer, capacity};
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

/// A QVGA gray + depth frame, the only frame storage of the board (230,400 bytes). Zeroed by
/// [`HalfFrame::new`] (`const`, so it can initialize a `static` in `.bss`).
#[derive(Debug)]
pub struct HalfFrame {
    gray: QvgaGrayBuffer,
    depth: QvgaDepthBuffer,
    /// Size of the frame stored (half the sensor's), pixels.
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
        Self { gray: [0; HALF_PIXELS], depth: [0; HALF_PIXELS], size: (0, 0) }
    }

    /// Starts a frame of a `sensor_width` x `sensor_height` sensor: the stored frame will be half
    /// that, rounded down.
    ///
    /// # Errors
    /// [`ImageError::SizeMismatch`] for a sensor larger than VGA, [`ImageError::ZeroSize`] for one
    /// with a side shorter than 2 pixels.
    pub fn start(&mut self, sensor_width: usize, sensor_height: usize) -> Result<(), ImageError> {
        if sensor_width > MAX_SENSOR_WIDTH || sensor_height > MAX_SENSOR_HEIGHT {
            return Err(ImageError::SizeMismatch {
                expected: (MAX_SENSOR_WIDTH, MAX_SENSOR_HEIGHT),
                got: (sensor_width, sensor_height),
            });
        }
        let size = (sensor_width / 2, sensor_height / 2);
        if size.0 == 0 || size.1 == 0 {
            return Err(ImageError::ZeroSize);
        }
        self.size = size;
        Ok(())
    }

    /// Size of the stored (half-resolution) frame, pixels.
    pub fn size(&self) -> (usize, usize) {
        self.size
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

    /// Stores sensor depth rows `2 * row`, `2 * row + 1` as half-resolution row `row`.
    ///
    /// # Errors
    /// As [`HalfFrame::put_gray_rows`].
    pub fn put_depth_rows(
        &mut self,
        row: usize,
        top: &[u16],
        bottom: &[u16],
    ) -> Result<(), ImageError> {
        let out = row_slice(&mut self.depth, self.size, row)?;
        downsample_depth_row_pair(top, bottom, out)
    }

    /// The stored frame as the core's [`RgbdFrame`] (rows not yet put hold the previous frame's
    /// or zeros).
    ///
    /// # Errors
    /// [`ImageError::ZeroSize`] before [`HalfFrame::start`]; [`ImageError::InvalidDepthScale`].
    pub fn frame(&self, timestamp_s: f64, depth_scale: f32) -> Result<RgbdFrame<'_>, ImageError> {
        let (w, h) = self.size;
        let n = w * h;
        let gray = GrayView::packed(self.gray.get(..n).unwrap_or_default(), w, h)?;
        let raw = ImageView::packed(self.depth.get(..n).unwrap_or_default(), w, h)?;
        Ok(RgbdFrame { timestamp_s, gray, depth: DepthView::new(raw, depth_scale)? })
    }
}

/// Row `row` of a packed half-resolution buffer of `size`.
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
        let src = GrayView::packed(&gray, w, h).unwrap();
        downsample_gray_2x(&src, &mut GrayViewMut::packed(&mut g, 320, 240).unwrap()).unwrap();
        let src = ImageView::packed(&depth, w, h).unwrap();
        downsample_depth_2x(&src, &mut ImageViewMut::packed(&mut d, 320, 240).unwrap()).unwrap();
        assert!(f.gray.rows().flatten().copied().eq(g.iter().copied()));
        assert!(f.depth.raw().rows().flatten().copied().eq(d.iter().copied()));
        assert_eq!((f.timestamp_s, f.depth.depth_scale()), (1.5, 1000.0));
    }

    #[test]
    fn bad_sizes_and_rows_are_errors() {
        let mut store = Box::new(HalfFrame::new());
        assert!(store.frame(0.0, 1.0).is_err(), "no frame before start");
        assert!(store.start(642, 480).is_err());
        assert!(store.start(1, 480).is_err());
        store.start(4, 4).unwrap();
        assert_eq!(store.size(), (2, 2));
        assert!(store.put_gray_rows(2, &[0; 4], &[0; 4]).is_err(), "row past the frame");
        assert!(store.put_gray_rows(0, &[0; 6], &[0; 6]).is_err(), "row of the wrong width");
        assert!(store.put_depth_rows(1, &[1; 4], &[1; 4]).is_ok());
        assert!(store.frame(0.0, f32::NAN).is_err());
    }
}
