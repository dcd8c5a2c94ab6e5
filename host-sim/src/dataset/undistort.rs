//! Undistorting frames: a colour camera's lens distortion (see [`Distortion`]) removed as the
//! frames are decoded, so the core, which models a pinhole camera, gets pinhole frames.
//!
//! Why it matters: TUM RGB-D's Freiburg 1 and 2 sensors deliver images that are not undistorted,
//! and TUM publishes their intrinsics together with the distortion that goes with them (see
//! [`super::Calibration::preset`]). With Freiburg 1's coefficients a point halfway from the
//! centre to the image corner sits about 3 pixels (VGA) from where the pinhole model puts it,
//! and at the corner more than 10: a systematic error of the size of a tracked feature's whole
//! error budget, which bundle adjustment cannot average away. A camera on the board is meant to
//! deliver rectified images (most RGB-D sensors do it in hardware), which is what this module
//! computes on the host.
//!
//! Method: the inverse map, computed once per dataset. Every pixel `(u, v)` of the undistorted
//! image (the same size and pinhole intrinsics as the sensor's) is sent to the normalized point
//! `((u - cx) / fx, (v - cy) / fy)`, distorted, and projected back: the raw pixel it came from.
//! - Gray: bilinear interpolation there, rounded half up to 8 bits. A source outside the raw
//!   image takes the nearest border pixel (no artificial black edge for the detector to find).
//! - Depth: the nearest raw sample, never a blend (a blend across an object's edge would be a
//!   depth no surface has); 0, "no reading", outside the raw image. Only depth that comes
//!   registered to the raw colour image (a sensor's own registration, as TUM's) is remapped;
//!   depth that the reader registers itself ([`super::registration`]) is projected with the
//!   pinhole intrinsics and is therefore already in the undistorted image's geometry.
//!
//! Deterministic: the map is plain `f64` arithmetic in a fixed order, the sampling integer.
//!
//! Measured: the demo's 300 frames (`ferroslam-sim demo`'s default path) written out in TUM
//! layout, and the same frames distorted with Freiburg 1's coefficients (OpenCV's `remap`: gray
//! bilinear, depth nearest; a script, not committed), replayed with `ferroslam-sim replay`
//! (QVGA, the Kinect tunables of a replay, so not the demo's own figures). ATE RMSE:
//!
//! | frames | odometry | SLAM |
//! | --- | --- | --- |
//! | pinhole (as rendered) | 4.6 mm | 5.8 mm |
//! | distorted, distortion ignored (the `tum1` preset before it carried the distortion) | 9.4 mm | 24.0 mm |
//! | distorted, distortion removed here | 6.1 mm | 7.0 mm |
//!
//! What is left after removing it (1.2-1.5 mm) is the two resamplings' blur and the corners of
//! the image that the raw frame does not cover.

use super::calibration::{Calibration, Distortion};

/// Fixed-point bits of a source position's fraction (1/256 pixel).
const FRACTION_BITS: u32 = 8;
const ONE: u32 = 1 << FRACTION_BITS;

/// Where one undistorted pixel comes from in the raw image.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Source {
    /// Top-left raw pixel of the bilinear quad, clamped into the image (border replicated).
    x0: u16,
    y0: u16,
    /// The fractions towards `x0 + 1` and `y0 + 1`, in 1/256 pixel (0 on a clamped axis).
    fx: u16,
    fy: u16,
    /// The nearest raw pixel's index, or `None` outside the raw image.
    nearest: Option<u32>,
}

/// The undistortion of one sensor's frames (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Undistorter {
    width: usize,
    height: usize,
    sources: Vec<Source>,
}

impl Undistorter {
    /// The undistortion for frames of `calibration` (its size, intrinsics and distortion);
    /// `None` when it has no distortion (the frames are left as they are, bit for bit).
    pub fn new(calibration: &Calibration) -> Option<Self> {
        let d = calibration.distortion;
        if d.is_none() {
            return None;
        }
        let (w, h) = (calibration.width as usize, calibration.height as usize);
        let [fx, fy, cx, cy] =
            [calibration.fx, calibration.fy, calibration.cx, calibration.cy].map(f64::from);
        let mut sources = Vec::with_capacity(w * h);
        for v in 0..h {
            for u in 0..w {
                let (x, y) = ((u as f64 - cx) / fx, (v as f64 - cy) / fy);
                let (xd, yd) = d.distort(x, y);
                sources.push(Source::at((fx * xd + cx, fy * yd + cy), (w, h)));
            }
        }
        Some(Self { width: w, height: h, sources })
    }

    /// Where undistorted pixel `(u, v)` comes from in the raw image, pixels (with the border
    /// clamping of the gray samples); `None` outside the image.
    pub fn source_of(&self, u: usize, v: usize) -> Option<(f32, f32)> {
        if u >= self.width {
            return None;
        }
        let s = self.sources.get(v * self.width + u)?;
        let f = |i: u16, frac: u16| f32::from(i) + f32::from(frac) / ONE as f32;
        Some((f(s.x0, s.fx), f(s.y0, s.fy)))
    }

    /// The undistorted gray image of `raw` (row-major, the calibrated size); a `raw` of another
    /// length gives an all-zero image (the decoder checks sizes before this is called).
    pub fn gray(&self, raw: &[u8]) -> Vec<u8> {
        if raw.len() != self.width * self.height {
            return vec![0; self.sources.len()];
        }
        let w = self.width;
        let px = |x: usize, y: usize| u32::from(raw.get(y * w + x).copied().unwrap_or(0));
        let mut out = Vec::with_capacity(self.sources.len());
        for s in &self.sources {
            let (x0, y0) = (usize::from(s.x0), usize::from(s.y0));
            // A clamped axis has a zero fraction, so its second pixel weighs nothing: clamp it.
            let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(self.height - 1));
            let (fx, fy) = (u32::from(s.fx), u32::from(s.fy));
            let top = px(x0, y0) * (ONE - fx) + px(x1, y0) * fx;
            let bottom = px(x0, y1) * (ONE - fx) + px(x1, y1) * fx;
            // At most 255 * 2^16: the rounded quotient is at most 255.
            let sum = top * (ONE - fy) + bottom * fy;
            let value = (sum + ONE * ONE / 2) >> (2 * FRACTION_BITS);
            out.push(u8::try_from(value).unwrap_or(u8::MAX));
        }
        out
    }

    /// The undistorted depth image of `raw` (raw units, 0 = no reading; the calibrated size),
    /// nearest sample; a `raw` of another length gives an all-zero image.
    pub fn depth(&self, raw: &[u16]) -> Vec<u16> {
        if raw.len() != self.width * self.height {
            return vec![0; self.sources.len()];
        }
        let at = |s: &Source| s.nearest.and_then(|i| raw.get(i as usize).copied()).unwrap_or(0);
        self.sources.iter().map(at).collect()
    }
}

impl Source {
    /// The source at raw position `(x, y)` of an image `w` x `h` (at most 65,535 pixels a side,
    /// which the calibration's `u32` sizes of real sensors never approach).
    fn at((x, y): (f64, f64), (w, h): (usize, usize)) -> Self {
        let inside = |c: f64, n: usize| c >= -0.5 && c < n as f64 - 0.5;
        let nearest = (inside(x, w) && inside(y, h))
            .then(|| ((y + 0.5).floor() as usize * w + (x + 0.5).floor() as usize) as u32);
        let (x0, fx) = quad_axis(x, w);
        let (y0, fy) = quad_axis(y, h);
        Self { x0, y0, fx, fy, nearest }
    }
}

/// The quad's first pixel and fraction along one axis of `n` pixels for position `c`, clamped
/// into `0..=n - 1` (a NaN, from a distortion that folds the image, clamps to 0).
fn quad_axis(c: f64, n: usize) -> (u16, u16) {
    let last = n.saturating_sub(1) as f64;
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, last) };
    let fixed = (c * f64::from(ONE)).round();
    let (i, frac) = ((fixed / f64::from(ONE)).floor(), fixed % f64::from(ONE));
    // A fraction that rounds up to the last pixel's right edge stays on the last pixel.
    if i >= last { (last as u16, 0) } else { (i as u16, frac as u16) }
}

impl Distortion {
    /// No distortion.
    pub const NONE: Self = Self { k1: 0.0, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0 };

    /// Whether every coefficient is zero (a pinhole camera).
    pub fn is_none(&self) -> bool {
        [self.k1, self.k2, self.p1, self.p2, self.k3].iter().all(|&k| k == 0.0)
    }

    /// The distorted normalized point of the undistorted one `(x, y)` (OpenCV's model):
    /// `r^2 = x^2 + y^2`, `radial = 1 + k1 r^2 + k2 r^4 + k3 r^6`,
    /// `x_d = x radial + 2 p1 x y + p2 (r^2 + 2 x^2)`, `y_d = y radial + p1 (r^2 + 2 y^2) + 2 p2 x y`.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let [k1, k2, p1, p2, k3] = [self.k1, self.k2, self.p1, self.p2, self.k3].map(f64::from);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        (xd, yd)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn calibration(distortion: Distortion) -> Calibration {
        Calibration { distortion, ..Calibration::preset("tum3").unwrap_or_else(|e| panic!("{e}")) }
    }

    #[test]
    fn no_distortion_changes_nothing() {
        assert_eq!(Undistorter::new(&calibration(Distortion::NONE)), None);
    }

    /// The map against OpenCV's: `cv2.initUndistortRectifyMap(K, d, None, K, (640, 480),
    /// cv2.CV_32FC1)` (opencv-python-headless, OpenCV 5.0.0) with TUM's Freiburg 1 calibration
    /// (K from `fx fy cx cy` 517.3 516.5 318.6 255.3, `d` 0.2624 -0.9531 -0.0054 0.0026 1.1633):
    /// the source positions of a few pixels, printed by OpenCV to 3 decimals.
    #[test]
    fn the_map_is_opencvs() {
        let c = Calibration::preset("tum1").unwrap_or_else(|e| panic!("{e}"));
        let u = Undistorter::new(&c).unwrap_or_else(|| panic!("tum1 has distortion"));
        for [pu, pv, ex, ey] in OPENCV_TUM1 {
            let (x, y) = u.source_of(pu as usize, pv as usize).unwrap_or_else(|| panic!("{pu}"));
            // The map's fraction is 1/256 pixel.
            let tol = 0.5 / 256.0 + 1e-3;
            assert!((x - ex).abs() <= tol && (y - ey).abs() <= tol, "{pu} {pv}: {x} {y}");
        }
    }

    /// `[u, v, x, y]`: undistorted pixel, raw source (clamped into the image as the gray samples
    /// clamp it; OpenCV gives (-0.595, 476.391) for the sixth and (667.255, -23.592) for the
    /// seventh, outside the image).
    const OPENCV_TUM1: [[f32; 4]; 7] = [
        [100.0, 80.0, 94.757, 74.659],
        [320.0, 240.0, 320.002, 239.989],
        [500.0, 400.0, 504.351, 402.692],
        [600.0, 450.0, 608.635, 454.345],
        [200.0, 300.0, 198.842, 300.299],
        [10.0, 470.0, 0.0, 476.391],
        [639.0, 0.0, 639.0, 0.0],
    ];

    #[test]
    fn gray_is_bilinear_and_clamped_depth_nearest_and_zero_outside() {
        // A strong radial distortion that moves points outwards (`k1 > 0`), so that the
        // undistorted image's corners come from outside the raw image.
        let d = Distortion { k1: 0.5, ..Distortion::NONE };
        let c = Calibration {
            fx: 10.0,
            fy: 10.0,
            cx: 9.5,
            cy: 7.5,
            width: 20,
            height: 16,
            ..calibration(d)
        };
        let u = Undistorter::new(&c).unwrap_or_else(|| panic!("distorted"));
        // A ramp along x is reproduced exactly by bilinear interpolation, up to the rounding.
        let raw: Vec<u8> = (0..20 * 16).map(|i| (i % 20) as u8 * 10).collect();
        let gray = u.gray(&raw);
        let depth_raw: Vec<u16> = (0..20 * 16).map(|i| 1000 + i as u16).collect();
        let depth = u.depth(&depth_raw);
        for v in 0..16 {
            for x in 0..20 {
                let (sx, _) = u.source_of(x, v).unwrap_or_else(|| panic!("{x} {v}"));
                let expected = (sx * 10.0 + 0.5).floor();
                assert_eq!(f32::from(gray[v * 20 + x]), expected, "{x} {v}");
                let (xd, yd) = d.distort((x as f64 - 9.5) / 10.0, (v as f64 - 7.5) / 10.0);
                let (rx, ry) = (10.0 * xd + 9.5, 10.0 * yd + 7.5);
                let inside = (-0.5..19.5).contains(&rx) && (-0.5..15.5).contains(&ry);
                let want = if inside {
                    depth_raw[(ry + 0.5).floor() as usize * 20 + (rx + 0.5).floor() as usize]
                } else {
                    0
                };
                assert_eq!(depth[v * 20 + x], want, "{x} {v}");
            }
        }
        // The corners come from outside: depth 0, gray clamped to the border.
        assert_eq!(u.source_of(0, 0), Some((0.0, 0.0)));
        assert_eq!(depth[0], 0);
        assert_eq!(gray[0], raw[0]);
        assert_eq!(u.gray(&[0; 3]), vec![0; 320]);
        assert_eq!(u.depth(&[0; 3]), vec![0; 320]);
    }
}
