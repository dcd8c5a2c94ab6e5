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

/// A 16-bit depth image view with its scale: `raw / depth_scale` is the depth in metres along the
/// camera's optical (z) axis, and a raw 0 means "no reading".
#[derive(Debug, Clone, Copy)]
pub struct DepthView<'a> {
    raw: ImageView<'a, u16>,
    depth_scale: f32,
}

impl<'a> DepthView<'a> {
    /// A depth view over raw samples with `depth_scale` raw units per metre (1000 for millimetres,
    /// 5000 for the TUM benchmark).
    ///
    /// # Errors
    /// [`ImageError::InvalidDepthScale`] when the scale is not finite and positive.
    pub fn new(raw: ImageView<'a, u16>, depth_scale: f32) -> Result<Self, ImageError> {
        if !(depth_scale.is_finite() && depth_scale > 0.0) {
            return Err(ImageError::InvalidDepthScale);
        }
        Ok(Self { raw, depth_scale })
    }

    /// The raw samples.
    pub fn raw(&self) -> ImageView<'a, u16> {
        self.raw
    }

    /// Raw units per metre.
    pub fn depth_scale(&self) -> f32 {
        self.depth_scale
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.raw.width()
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.raw.height()
    }

    /// `(width, height)` in pixels.
    pub fn size(&self) -> (usize, usize) {
        self.raw.size()
    }

    /// Depth at `(x, y)` in metres, or `None` outside the image or where the sensor gave no reading.
    pub fn depth_m(&self, x: usize, y: usize) -> Option<f32> {
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
        let (x0, y0) = (u as usize, v as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (u - x0 as f32, v - y0 as f32);
        let d = [
            self.depth_m(x0, y0)?,
            self.depth_m(x1, y0)?,
            self.depth_m(x0, y1)?,
            self.depth_m(x1, y1)?,
        ];
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
