//! [`Observation`]: a keyframe's measurement of a landmark, in 10 bytes.

use super::LandmarkId;

/// Pixel coordinates are stored in units of 1/32 pixel.
const UV_UNITS_PER_PX: f32 = 32.0;
/// Depth is stored in units of 1/4 mm (up to 16.38 m); 0 means "no depth".
const DEPTH_UNITS_PER_M: f32 = 4000.0;

/// Where a keyframe saw a landmark: the pixel (1/32 px resolution, up to 2047 px) and the measured
/// depth (1/4 mm resolution, up to 16.38 m), if any.
///
/// The quantization errors (at most 1/64 px and 1/8 mm) are far below the measurement noise of
/// a QVGA feature (~0.1 px) and of a Kinect-class depth (millimetres).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Observation {
    /// The landmark observed.
    pub landmark: LandmarkId,
    u: u16,
    v: u16,
    depth: u16,
}

impl Observation {
    /// An observation of `landmark` at pixel `(u, v)` with optional depth `depth_m`. Returns
    /// `None` when the pixel is negative, not finite or beyond 2047 px; a depth that is not finite,
    /// not positive or beyond 16.38 m is stored as "no depth".
    pub fn new(landmark: LandmarkId, (u, v): (f32, f32), depth_m: Option<f32>) -> Option<Self> {
        let q = |x: f32| -> Option<u16> {
            let s = libm::roundf(x * UV_UNITS_PER_PX);
            // NaN fails the comparison.
            (s >= 0.0 && s <= f32::from(u16::MAX)).then_some(s as u16)
        };
        let depth = depth_m
            .map(|d| libm::roundf(d * DEPTH_UNITS_PER_M))
            .filter(|d| *d >= 1.0 && *d <= f32::from(u16::MAX))
            .map_or(0, |d| d as u16);
        Some(Self { landmark, u: q(u)?, v: q(v)?, depth })
    }

    /// The pixel, as stored.
    pub fn uv(&self) -> (f32, f32) {
        (f32::from(self.u) / UV_UNITS_PER_PX, f32::from(self.v) / UV_UNITS_PER_PX)
    }

    /// The measured depth in metres, as stored, if any.
    pub fn depth_m(&self) -> Option<f32> {
        (self.depth > 0).then(|| f32::from(self.depth) / DEPTH_UNITS_PER_M)
    }
}
