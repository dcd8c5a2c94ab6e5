//! [`OwnedFrame`]: an RGB-D frame that owns its pixels, as the dataset reader decodes it and the
//! synthetic renderer draws it; [`OwnedFrame::view`] lends it to the core as an [`RgbdFrame`].

use ferroslam_core::frame::RgbdFrame;
use ferroslam_core::image::{
    DepthView, GrayView, GrayViewMut, ImageError, ImageView, ImageViewMut, downsample_depth_2x,
    downsample_gray_2x,
};

/// An RGB-D frame that owns its pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct OwnedFrame {
    /// Capture time in seconds on the recording's clock (a dataset's colour timestamp).
    pub timestamp_s: f64,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// 8-bit gray, row-major, `width * height` samples.
    pub gray: Vec<u8>,
    /// Raw depth, row-major, `(width >> depth_level) * (height >> depth_level)` samples;
    /// `raw / depth_scale` metres, 0 = no reading.
    pub depth: Vec<u16>,
    /// One depth sample per `2^depth_level x 2^depth_level` pixels (see the core's
    /// [`DepthView`]).
    pub depth_level: u8,
    /// Raw depth units per metre.
    pub depth_scale: f32,
}

impl OwnedFrame {
    /// A 0x0 frame at time 0, to be filled by a renderer or decoder that reuses buffers.
    pub fn empty(depth_scale: f32) -> Self {
        Self {
            timestamp_s: 0.0,
            width: 0,
            height: 0,
            gray: Vec::new(),
            depth: Vec::new(),
            depth_level: 0,
            depth_scale,
        }
    }

    /// The frame as the core's borrowed [`RgbdFrame`].
    ///
    /// # Errors
    /// An [`ImageError`] when the buffers do not hold `width * height` samples or the depth scale is
    /// not finite and positive (never for a decoded or rendered frame).
    pub fn view(&self) -> Result<RgbdFrame<'_>, ImageError> {
        let gray = GrayView::packed(&self.gray, self.width, self.height)?;
        let (w, h) = self.depth_size();
        let raw = ImageView::packed(&self.depth, w, h)?;
        let depth = DepthView::with_level(raw, self.depth_scale, self.depth_level)?;
        Ok(RgbdFrame { timestamp_s: self.timestamp_s, gray, depth })
    }

    /// The depth image's size, depth samples: the image's shifted right by `depth_level`.
    pub fn depth_size(&self) -> (usize, usize) {
        (self.width >> self.depth_level, self.height >> self.depth_level)
    }

    /// Halves the depth `levels` more times with the core's 2x2 downsampler (each sample a real
    /// reading of its block), keeping the gray image: the frame store of a board that keeps its
    /// depth coarser than its gray image.
    ///
    /// # Errors
    /// An [`ImageError`] when the level would pass the core's
    /// [`MAX_DEPTH_LEVEL`](ferroslam_core::image::MAX_DEPTH_LEVEL) or a side would be empty.
    /// The frame is unchanged on an error.
    pub fn coarsen_depth(&mut self, levels: u8) -> Result<(), ImageError> {
        let last = self.depth_level.saturating_add(levels);
        if last > ferroslam_core::image::MAX_DEPTH_LEVEL {
            return Err(ImageError::InvalidDepthLevel(last));
        }
        if levels > 0 && (self.width >> last == 0 || self.height >> last == 0) {
            return Err(ImageError::ZeroSize);
        }
        for _ in 0..levels {
            let level = self.depth_level + 1;
            let (w, h) = self.depth_size();
            let (w2, h2) = (self.width >> level, self.height >> level);
            let mut out = vec![0; w2 * h2];
            downsample_depth_2x(
                &ImageView::packed(&self.depth, w, h)?,
                &mut ImageViewMut::packed(&mut out, w2, h2)?,
            )?;
            self.depth = out;
            self.depth_level = level;
        }
        Ok(())
    }

    /// Depth at pixel `(x, y)` in metres (the reading of the depth sample holding it), `None`
    /// outside the image or without a reading.
    pub fn depth_m(&self, x: usize, y: usize) -> Option<f64> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let (w, _) = self.depth_size();
        let (x, y) = (x >> self.depth_level, y >> self.depth_level);
        match self.depth.get(y * w + x) {
            Some(0) | None => None,
            Some(&d) => Some(f64::from(d) / f64::from(self.depth_scale)),
        }
    }
}

/// `frame` halved `levels` times by the core's 2x2 downsamplers (gray: rounded mean; depth: a real
/// sample of each block, never a blend across an edge), as the firmware brings sensor frames to
/// the processing profile. `levels == 0` copies the frame.
///
/// # Errors
/// An [`ImageError`] when a level would be empty (a side shorter than 2 pixels).
pub fn halve_frame(frame: &RgbdFrame<'_>, levels: u8) -> Result<OwnedFrame, ImageError> {
    let (gray, depth) = (frame.gray, frame.depth.raw());
    let mut out = if levels == 0 {
        OwnedFrame {
            timestamp_s: frame.timestamp_s,
            width: gray.width(),
            height: gray.height(),
            gray: gray.rows().flatten().copied().collect(),
            depth: depth.rows().flatten().copied().collect(),
            depth_level: frame.depth.level(),
            depth_scale: frame.depth.depth_scale(),
        }
    } else {
        halve_once(frame)?
    };
    for _ in 1..levels {
        let next = halve_once(&out.view()?)?;
        out = next;
    }
    Ok(out)
}

/// `frame` halved once (its depth too, so the depth keeps its level).
fn halve_once(frame: &RgbdFrame<'_>) -> Result<OwnedFrame, ImageError> {
    let (width, height) = (frame.gray.width() / 2, frame.gray.height() / 2);
    let raw = frame.depth.raw();
    let (dw, dh) = (raw.width() / 2, raw.height() / 2);
    let mut gray = vec![0; width * height];
    let mut depth = vec![0; dw * dh];
    downsample_gray_2x(&frame.gray, &mut GrayViewMut::packed(&mut gray, width, height)?)?;
    downsample_depth_2x(&raw, &mut ImageViewMut::packed(&mut depth, dw, dh)?)?;
    Ok(OwnedFrame {
        timestamp_s: frame.timestamp_s,
        width,
        height,
        gray,
        depth,
        depth_level: frame.depth.level(),
        depth_scale: frame.depth.depth_scale(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn view_checks_buffer_sizes() {
        let f = OwnedFrame {
            timestamp_s: 1.5,
            width: 2,
            height: 2,
            gray: vec![1, 2, 3, 4],
            depth: vec![0, 1000, 2000, 3000],
            depth_level: 0,
            depth_scale: 1000.0,
        };
        let v = f.view().unwrap();
        assert_eq!(v.timestamp_s, 1.5);
        assert_eq!(v.depth.depth_m(1, 1), Some(3.0));
        let short = OwnedFrame { depth: vec![0; 3], ..f.clone() };
        assert!(short.view().is_err());
        assert!(OwnedFrame { depth_scale: f32::NAN, ..f }.view().is_err());
    }

    #[test]
    fn coarser_depth_keeps_the_gray_and_reads_in_image_pixels() {
        let gray: Vec<u8> = (0..64).map(|i| i as u8).collect();
        let depth: Vec<u16> = (0..64).map(|i| 1000 + (i % 8) as u16).collect();
        let mut f = OwnedFrame {
            timestamp_s: 0.0,
            width: 8,
            height: 8,
            gray: gray.clone(),
            depth,
            depth_level: 0,
            depth_scale: 1000.0,
        };
        f.coarsen_depth(1).unwrap();
        assert_eq!((f.gray.clone(), f.depth.len(), f.depth_size()), (gray, 16, (4, 4)));
        let v = f.view().unwrap();
        assert_eq!((v.depth.size(), v.depth.level()), ((8, 8), 1));
        // Columns 6 and 7 (1006 and 1007 mm) make depth column 3: the mean of its middle two.
        assert_eq!(f.depth_m(7, 0), Some(1.006));
        assert_eq!(v.depth.depth_m(7, 0), Some(1.006));
        // Halving keeps the level; past the core's largest level is an error.
        let h = halve_frame(&v, 1).unwrap();
        assert_eq!((h.width, h.depth_level, h.depth_size()), (4, 1, (2, 2)));
        assert_eq!(f.coarsen_depth(2), Err(ImageError::InvalidDepthLevel(3)));
        assert_eq!(f.depth_level, 1, "unchanged on an error");
    }

    #[test]
    fn halving_twice_gives_a_quarter_size_frame_of_real_samples() {
        let gray: Vec<u8> = (0..64).map(|i| i as u8).collect();
        let depth: Vec<u16> =
            (0..64).map(|i| if i % 3 == 0 { 0 } else { 1000 + i as u16 }).collect();
        let f = OwnedFrame {
            timestamp_s: 2.0,
            width: 8,
            height: 8,
            gray,
            depth,
            depth_level: 0,
            depth_scale: 5000.0,
        };
        let q = halve_frame(&f.view().unwrap(), 2).unwrap();
        assert_eq!((q.width, q.height, q.timestamp_s, q.depth_scale), (2, 2, 2.0, 5000.0));
        // One surface (1000 to 1063 raw) with holes: a block of four valid samples may give the
        // mean of its middle two, which lies on that surface, near a sample.
        let near_a_sample =
            |d: &u16| f.depth.iter().any(|s| *s != 0 && u32::from(s.abs_diff(*d)) * 32 <= 1000);
        assert!(q.depth.iter().all(near_a_sample), "{:?}", q.depth);
        // Two surfaces (1.0 m and 3.0 m in a checkerboard of 1 x 1 pixel squares): every sample is
        // one of the two, never a blend between them.
        let depth: Vec<u16> =
            (0..64).map(|i| if (i + i / 8) % 2 == 0 { 1000 } else { 3000 }).collect();
        let edges = OwnedFrame { depth, ..f.clone() };
        let q = halve_frame(&edges.view().unwrap(), 2).unwrap();
        assert!(q.depth.iter().all(|d| [1000, 3000].contains(d)), "{:?}", q.depth);
        assert_eq!(halve_frame(&f.view().unwrap(), 0).unwrap(), f);
        let tiny = OwnedFrame { width: 1, height: 1, gray: vec![0], depth: vec![0], ..f };
        assert!(halve_frame(&tiny.view().unwrap(), 1).is_err());
    }
}
