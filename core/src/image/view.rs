//! Borrowed image views with a row stride, and the errors that building one can give.

use core::fmt;

/// Why an image view could not be built or an image operation could not run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ImageError {
    /// Width or height is zero.
    ZeroSize,
    /// The row stride is shorter than the width.
    StrideTooSmall {
        /// Elements per row in the buffer.
        stride: usize,
        /// Pixels per row of the image.
        width: usize,
    },
    /// The buffer holds fewer elements than `stride * (height - 1) + width`.
    BufferTooSmall {
        /// Elements the image needs.
        needed: usize,
        /// Elements the buffer has.
        got: usize,
    },
    /// Two images that must agree in size do not.
    SizeMismatch {
        /// Size the operation expected, `(width, height)`.
        expected: (usize, usize),
        /// Size it was given, `(width, height)`.
        got: (usize, usize),
    },
    /// The depth scale (raw units per metre) is not a finite positive number.
    InvalidDepthScale,
    /// A depth resolution level above [`MAX_DEPTH_LEVEL`].
    InvalidDepthLevel(u8),
}

impl fmt::Display for ImageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::ZeroSize => write!(f, "image width or height is zero"),
            Self::StrideTooSmall { stride, width } => {
                write!(f, "row stride {stride} is shorter than the width {width}")
            }
            Self::BufferTooSmall { needed, got } => {
                write!(f, "image buffer holds {got} elements, {needed} needed")
            }
            Self::SizeMismatch { expected, got } => {
                write!(f, "image is {}x{}, expected {}x{}", got.0, got.1, expected.0, expected.1)
            }
            Self::InvalidDepthScale => write!(f, "depth scale must be finite and positive"),
            Self::InvalidDepthLevel(level) => {
                write!(f, "depth level {level} is above the largest, {MAX_DEPTH_LEVEL}")
            }
        }
    }
}

impl core::error::Error for ImageError {}

/// Checks that a buffer of `len` elements can hold a `width` x `height` image with `stride`.
fn check_layout(len: usize, width: usize, height: usize, stride: usize) -> Result<(), ImageError> {
    if width == 0 || height == 0 {
        return Err(ImageError::ZeroSize);
    }
    if stride < width {
        return Err(ImageError::StrideTooSmall { stride, width });
    }
    let needed = stride
        .checked_mul(height - 1)
        .and_then(|n| n.checked_add(width))
        .ok_or(ImageError::BufferTooSmall { needed: usize::MAX, got: len })?;
    if len < needed {
        return Err(ImageError::BufferTooSmall { needed, got: len });
    }
    Ok(())
}

/// A read-only view of a row-major image whose rows are `stride` elements apart.
///
/// Pixel `(x, y)` is at `data[y * stride + x]`; `x` grows to the right, `y` downwards, origin at the
/// top-left pixel's centre.
#[derive(Debug, Clone, Copy)]
pub struct ImageView<'a, P> {
    data: &'a [P],
    width: usize,
    height: usize,
    stride: usize,
}

impl<'a, P: Copy> ImageView<'a, P> {
    /// A view of `data` as `width` x `height` pixels with rows `stride` elements apart.
    ///
    /// # Errors
    /// [`ImageError::ZeroSize`], [`ImageError::StrideTooSmall`] or [`ImageError::BufferTooSmall`]
    /// when the layout does not fit `data`.
    pub fn new(
        data: &'a [P],
        width: usize,
        height: usize,
        stride: usize,
    ) -> Result<Self, ImageError> {
        check_layout(data.len(), width, height, stride)?;
        Ok(Self { data, width, height, stride })
    }

    /// A view of a tightly packed buffer (`stride == width`).
    ///
    /// # Errors
    /// As [`ImageView::new`].
    pub fn packed(data: &'a [P], width: usize, height: usize) -> Result<Self, ImageError> {
        Self::new(data, width, height, width)
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Elements from the start of one row to the start of the next.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// `(width, height)` in pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The whole buffer: pixel `(x, y)` is `data()[y * stride + x]` for `x < width`,
    /// `y < height` (elements between rows, or past the last one, are not pixels).
    pub fn data(&self) -> &'a [P] {
        self.data
    }

    /// Row `y` (exactly `width` pixels), or `None` past the last row.
    pub fn row(&self, y: usize) -> Option<&'a [P]> {
        if y >= self.height {
            return None;
        }
        let start = y * self.stride;
        self.data.get(start..start + self.width)
    }

    /// The rows from top to bottom, each exactly `width` pixels.
    pub fn rows(&self) -> impl Iterator<Item = &'a [P]> + 'a {
        let (width, stride) = (self.width, self.stride);
        let data = self.data;
        (0..self.height).filter_map(move |y| data.get(y * stride..y * stride + width))
    }

    /// Pixel `(x, y)`, or `None` outside the image.
    pub fn get(&self, x: usize, y: usize) -> Option<P> {
        if x >= self.width {
            return None;
        }
        self.row(y).and_then(|r| r.get(x).copied())
    }
}

/// A writable view of a row-major image whose rows are `stride` elements apart.
#[derive(Debug)]
pub struct ImageViewMut<'a, P> {
    data: &'a mut [P],
    width: usize,
    height: usize,
    stride: usize,
}

impl<'a, P: Copy> ImageViewMut<'a, P> {
    /// A writable view of `data` as `width` x `height` pixels with rows `stride` elements apart.
    ///
    /// # Errors
    /// As [`ImageView::new`].
    pub fn new(
        data: &'a mut [P],
        width: usize,
        height: usize,
        stride: usize,
    ) -> Result<Self, ImageError> {
        check_layout(data.len(), width, height, stride)?;
        Ok(Self { data, width, height, stride })
    }

    /// A writable view of a tightly packed buffer (`stride == width`).
    ///
    /// # Errors
    /// As [`ImageView::new`].
    pub fn packed(data: &'a mut [P], width: usize, height: usize) -> Result<Self, ImageError> {
        Self::new(data, width, height, width)
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// `(width, height)` in pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Row `y` for writing (exactly `width` pixels), or `None` past the last row.
    pub fn row_mut(&mut self, y: usize) -> Option<&mut [P]> {
        if y >= self.height {
            return None;
        }
        let start = y * self.stride;
        self.data.get_mut(start..start + self.width)
    }

    /// The rows from top to bottom for writing, each exactly `width` pixels.
    pub fn rows_mut(&mut self) -> impl Iterator<Item = &mut [P]> + '_ {
        let width = self.width;
        // `check_layout` guarantees `height` chunks, the last one possibly shorter than `stride`
        // but never shorter than `width`; `get_mut` keeps that a checked fact, not a panic.
        self.data.chunks_mut(self.stride).take(self.height).filter_map(move |r| r.get_mut(..width))
    }

    /// A read-only view of the same pixels.
    pub fn as_view(&self) -> ImageView<'_, P> {
        ImageView { data: self.data, width: self.width, height: self.height, stride: self.stride }
    }
}

/// An 8-bit gray image view (0 = black, 255 = white).
pub type GrayView<'a> = ImageView<'a, u8>;

/// A writable 8-bit gray image view.
pub type GrayViewMut<'a> = ImageViewMut<'a, u8>;

/// Largest [`DepthView`] level: one depth pixel per 4 x 4 image pixels.
pub const MAX_DEPTH_LEVEL: u8 = 2;

/// A 16-bit depth image view with its scale: `raw / depth_scale` is the depth in metres along the
/// camera's optical (z) axis, and a raw 0 means "no reading".
///
/// The depth may be coarser than the gray image it goes with: at level `l` one depth pixel covers
/// `2^l x 2^l` image pixels (image pixel `(x, y)` lies in depth pixel `(x >> l, y >> l)`), as
/// [`downsample_depth_2x`](super::downsample_depth_2x) applied `l` times makes it. Every accessor
/// takes and gives **image** pixels, so the pipeline reads depth the same way at any level. Level 1
/// holds the depth in a quarter of the memory: the reference board keeps level 1
/// ([`QVGA`](crate::config::QVGA)`.depth_level`; the trade-off: docs/decisions.md, "Board RAM:
/// depth level, map and BA capacities").
///
/// The depth may also be finer than the image: [`DepthView::for_coarser_image`] reads the same
/// depth for an image halved once more (a front end tracking on a pyramid level above the
/// depth's), where one image pixel covers `2 x 2` depth pixels.
#[derive(Debug, Clone, Copy)]
pub struct DepthView<'a> {
    raw: ImageView<'a, u16>,
    depth_scale: f32,
    level: u8,
    /// Halvings of the image beyond the depth's (at most one of `level` and `finer` is not 0).
    finer: u8,
}

impl<'a> DepthView<'a> {
    /// A depth view over raw samples with `depth_scale` raw units per metre (1000 for millimetres,
    /// 5000 for the TUM benchmark), one depth pixel per image pixel.
    ///
    /// # Errors
    /// [`ImageError::InvalidDepthScale`] when the scale is not finite and positive.
    pub fn new(raw: ImageView<'a, u16>, depth_scale: f32) -> Result<Self, ImageError> {
        Self::with_level(raw, depth_scale, 0)
    }

    /// A depth view whose pixels each cover `2^level x 2^level` image pixels (see the type's
    /// documentation).
    ///
    /// # Errors
    /// [`ImageError::InvalidDepthScale`] when the scale is not finite and positive;
    /// [`ImageError::InvalidDepthLevel`] when `level` is above [`MAX_DEPTH_LEVEL`].
    pub fn with_level(
        raw: ImageView<'a, u16>,
        depth_scale: f32,
        level: u8,
    ) -> Result<Self, ImageError> {
        if !(depth_scale.is_finite() && depth_scale > 0.0) {
            return Err(ImageError::InvalidDepthScale);
        }
        if level > MAX_DEPTH_LEVEL {
            return Err(ImageError::InvalidDepthLevel(level));
        }
        Ok(Self { raw, depth_scale, level, finer: 0 })
    }

    /// This depth read for an image `levels` halvings coarser than the one it goes with (image
    /// pixel `(x, y)` of the coarser image is pixel `(2^levels (x + 0.5) - 0.5, ...)` of this
    /// one's); `None` when that is more than one halving finer than the image.
    pub fn for_coarser_image(self, levels: u8) -> Option<Self> {
        let (level, finer) =
            if levels <= self.level { (self.level - levels, 0) } else { (0, levels - self.level) };
        (finer <= 1).then_some(Self { level, finer, ..self })
    }

    /// The raw samples, in depth pixels.
    pub fn raw(&self) -> ImageView<'a, u16> {
        self.raw
    }

    /// Raw units per metre.
    pub fn depth_scale(&self) -> f32 {
        self.depth_scale
    }

    /// The level: one depth pixel per `2^level x 2^level` image pixels.
    pub fn level(&self) -> u8 {
        self.level
    }

    /// Width of the image it covers, image pixels (`2^level` times the raw width).
    pub fn width(&self) -> usize {
        (self.raw.width() << self.level) >> self.finer
    }

    /// Height of the image it covers, image pixels.
    pub fn height(&self) -> usize {
        (self.raw.height() << self.level) >> self.finer
    }

    /// `(width, height)` of the image it covers, image pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width(), self.height())
    }

    /// Depth at image pixel `(x, y)` in metres (the reading of the depth pixel holding it), or
    /// `None` outside the image or where the sensor gave no reading.
    pub fn depth_m(&self, x: usize, y: usize) -> Option<f32> {
        if self.finer > 0 {
            // The depth pixel at the image pixel's centre, rounded down and right: (2x + 0.5).
            return self.raw_m(x << self.finer, y << self.finer);
        }
        self.raw_m(x >> self.level, y >> self.level)
    }

    /// Depth at depth pixel `(x, y)`, metres.
    fn raw_m(&self, x: usize, y: usize) -> Option<f32> {
        match self.raw.get(x, y) {
            Some(0) | None => None,
            Some(d) => Some(f32::from(d) / self.depth_scale),
        }
    }

    /// Depth at the sub-pixel position `(u, v)` (pixel centres at integers), metres: the bilinear
    /// interpolation of the four surrounding readings when all four exist and lie within
    /// `max_relative_step` of each other (one surface); otherwise the nearest pixel's reading
    /// when the four are not one surface (an edge: no blend across it), or `None` when a
    /// reading is missing or `(u, v)` is outside the image or not finite.
    ///
    /// A feature's position is sub-pixel; its depth taken at the rounded pixel instead would be
    /// off by up to half a pixel's depth gradient (on a floor seen at a grazing angle, centimetres
    /// at QVGA), a bias that pose estimation and bundle adjustment would then trust.
    pub fn depth_at(&self, u: f32, v: f32, max_relative_step: f32) -> Option<f32> {
        let (w, h) = self.size();
        // NaN fails the comparisons; the casts below only see values inside the image.
        if !(u >= 0.0 && v >= 0.0 && u <= (w - 1) as f32 && v <= (h - 1) as f32) {
            return None;
        }
        // Image pixel centre `u` is depth coordinate `(u + 0.5) / 2^l - 0.5`; the half depth
        // pixel at each border has no neighbour beyond it and takes the border's reading.
        let (u, v) = if self.finer > 0 {
            let s = f32::from(1u8 << self.finer);
            let (wd, hd) = self.raw.size();
            let at = |p: f32, n: usize| ((p + 0.5) * s - 0.5).clamp(0.0, (n - 1) as f32);
            (at(u, wd), at(v, hd))
        } else if self.level == 0 {
            (u, v)
        } else {
            let s = 1.0 / f32::from(1u8 << self.level);
            let (wd, hd) = self.raw.size();
            let at = |p: f32, n: usize| ((p + 0.5) * s - 0.5).clamp(0.0, (n - 1) as f32);
            (at(u, wd), at(v, hd))
        };
        let (w, h) = self.raw.size();
        let (x0, y0) = (u as usize, v as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (u - x0 as f32, v - y0 as f32);
        let d =
            [self.raw_m(x0, y0)?, self.raw_m(x1, y0)?, self.raw_m(x0, y1)?, self.raw_m(x1, y1)?];
        let (lo, hi) =
            d.iter().fold((f32::INFINITY, 0.0f32), |(lo, hi), &z| (lo.min(z), hi.max(z)));
        if hi - lo > max_relative_step * lo {
            // Not one surface: the nearest reading (the corner the position is closest to).
            let k = usize::from(fx >= 0.5) + 2 * usize::from(fy >= 0.5);
            return d.get(k).copied();
        }
        let top = d[0] + fx * (d[1] - d[0]);
        let bottom = d[2] + fx * (d[3] - d[2]);
        Some(top + fy * (bottom - top))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_errors_are_reported() {
        let buf = [0u8; 10];
        assert_eq!(GrayView::new(&buf, 0, 1, 1).unwrap_err(), ImageError::ZeroSize);
        assert_eq!(
            GrayView::new(&buf, 4, 2, 3).unwrap_err(),
            ImageError::StrideTooSmall { stride: 3, width: 4 }
        );
        assert_eq!(
            GrayView::new(&buf, 4, 3, 4).unwrap_err(),
            ImageError::BufferTooSmall { needed: 12, got: 10 }
        );
        // The last row needs only `width` elements, not a full stride.
        assert!(GrayView::new(&buf, 4, 2, 6).is_ok());
    }

    #[test]
    fn strided_rows_skip_padding() {
        let buf = [1u8, 2, 9, 3, 4, 9];
        let v = GrayView::new(&buf, 2, 2, 3).unwrap();
        assert_eq!(v.row(1), Some(&[3u8, 4][..]));
        assert_eq!(v.rows().count(), 2);
        assert_eq!(v.get(1, 1), Some(4));
        assert_eq!(v.get(2, 0), None);
        assert_eq!(v.get(0, 2), None);
    }

    #[test]
    fn a_coarser_depth_reads_in_image_pixels() {
        // A slanted plane, z = 1 + 0.01 x + 0.02 y metres at image pixel (x, y), sampled at the
        // centres of 2 x 2 blocks (what halving a plane gives) into an 8 x 6 depth image for a
        // 16 x 12 image.
        let plane = |x: f32, y: f32| 1.0 + 0.01 * x + 0.02 * y;
        let mut raw = [0u16; 8 * 6];
        for (k, r) in raw.iter_mut().enumerate() {
            let (x, y) = ((k % 8) as f32 * 2.0 + 0.5, (k / 8) as f32 * 2.0 + 0.5);
            *r = libm::roundf(plane(x, y) * 10_000.0) as u16;
        }
        let view = ImageView::packed(&raw, 8, 6).unwrap();
        let d = DepthView::with_level(view, 10_000.0, 1).unwrap();
        assert_eq!((d.size(), d.level()), ((16, 12), 1));
        // Whole pixels read the depth pixel holding them.
        assert_eq!(d.depth_m(5, 3), Some(f32::from(raw[8 + 2]) / 10_000.0));
        assert_eq!(d.depth_m(16, 0), None);
        // Sub-pixel reads interpolate the plane in image pixels, up to the samples' rounding.
        for (u, v) in [(1.0, 1.0), (4.25, 7.5), (10.0, 2.75), (13.5, 9.0)] {
            let z = d.depth_at(u, v, 0.1).unwrap();
            assert!((z - plane(u, v)).abs() < 2e-4, "({u}, {v}): {z} vs {}", plane(u, v));
        }
        // The whole image is covered: its last pixel and the half depth pixel at each border.
        assert!(d.depth_at(15.0, 11.0, 0.1).is_some());
        assert!(d.depth_at(0.0, 0.0, 0.1).is_some());
        assert_eq!(d.depth_at(15.5, 0.0, 0.1), None);
        assert_eq!(
            DepthView::with_level(view, 1.0, MAX_DEPTH_LEVEL + 1).unwrap_err(),
            ImageError::InvalidDepthLevel(MAX_DEPTH_LEVEL + 1)
        );
    }

    #[test]
    fn a_finer_depth_reads_in_the_coarser_image_s_pixels() {
        // A slanted plane, z = 1 + 0.01 x + 0.02 y metres at depth pixel (x, y) of a 16 x 12
        // depth image, read for an 8 x 6 image: its pixel (u, v) is depth pixel (2u + 0.5, ...).
        let plane = |x: f32, y: f32| 1.0 + 0.01 * x + 0.02 * y;
        let mut raw = [0u16; 16 * 12];
        for (k, r) in raw.iter_mut().enumerate() {
            *r = (plane((k % 16) as f32, (k / 16) as f32) * 10_000.0).round() as u16;
        }
        let view = ImageView::packed(&raw, 16, 12).unwrap();
        let full = DepthView::new(view, 10_000.0).unwrap();
        let coarse = full.for_coarser_image(1).unwrap();
        assert_eq!(coarse.size(), (8, 6));
        for (u, v) in [(0.0f32, 0.0f32), (3.25, 2.5), (6.9, 4.1)] {
            let z = coarse.depth_at(u, v, 0.5).unwrap();
            let (x, y) = (2.0 * u + 0.5, 2.0 * v + 0.5);
            assert!((z - plane(x, y)).abs() < 2e-4, "({u}, {v}): {z} vs {}", plane(x, y));
            assert_eq!(z, full.depth_at(x, y, 0.5).unwrap());
        }
        assert_eq!(coarse.depth_m(3, 2), full.depth_m(6, 4));
        assert_eq!(coarse.depth_at(7.5, 0.0, 0.5), None, "outside the coarser image");
        // A level-1 depth read for an image halved once more is a plain view of it.
        let half = DepthView::with_level(view, 10_000.0, 1).unwrap();
        let same = half.for_coarser_image(1).unwrap();
        assert_eq!((same.level(), same.size()), (0, (16, 12)));
        assert!(full.for_coarser_image(2).is_none(), "two halvings finer: not supported");
    }

    #[test]
    fn level_zero_is_the_plain_view() {
        let raw = [1000u16, 2000, 3000, 4000];
        let view = ImageView::packed(&raw, 2, 2).unwrap();
        let (a, b) = (
            DepthView::new(view, 1000.0).unwrap(),
            DepthView::with_level(view, 1000.0, 0).unwrap(),
        );
        assert_eq!(a.size(), b.size());
        assert_eq!(a.depth_at(0.3, 0.6, 10.0), b.depth_at(0.3, 0.6, 10.0));
        assert_eq!(a.depth_at(0.3, 0.6, 10.0), Some(1.0 + 0.3 + 2.0 * 0.6));
    }

    #[test]
    fn depth_zero_is_no_reading() {
        let raw = [0u16, 5000];
        let d = DepthView::new(ImageView::packed(&raw, 2, 1).unwrap(), 5000.0).unwrap();
        assert_eq!(d.depth_m(0, 0), None);
        assert_eq!(d.depth_m(1, 0), Some(1.0));
        let raw_view = ImageView::packed(&raw, 2, 1).unwrap();
        assert!(DepthView::new(raw_view, f32::NAN).is_err());
        assert!(DepthView::new(raw_view, 0.0).is_err());
    }
}
