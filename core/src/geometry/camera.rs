//! The pinhole camera of the paper's Eq. 1-2, with Jacobians, depth back-projection and the
//! intrinsics of a 2x-downsampled image.
//!
//! The paper writes a world point `X_w` in camera `n` as `X_c = R_n X_w - p_n` (Eq. 1) and
//! projects it as `x = fx xc/zc + cx`, `y = fy yc/zc + cy` (Eq. 2). Here that transform is the
//! world-to-camera pose `t_cw` with rotation `R_n` and translation `-p_n`; the pipeline's outputs
//! are its inverse `t_wc` (camera-to-world). Camera axes: x right, y down, z forward (optical axis).
//!
//! Pixel coordinates are in pixels with integer values at pixel centres: pixel `(i, j)` (column,
//! row) covers `[i - 0.5, i + 0.5) x [j - 0.5, j + 0.5)`, and the image spans
//! `[-0.5, width - 0.5) x [-0.5, height - 0.5)`. This is the convention of TUM/OpenCV intrinsics.

use core::fmt;

use nalgebra::{Matrix2x3, Matrix2x6, Matrix3, Point2, Point3};

use super::se3::Pose;
use super::so3::hat;

/// Nearest depth (camera z, metres) that [`PinholeCamera::project`] accepts: points closer than
/// 1 mm, on the camera plane or behind the camera have no projection.
pub const MIN_PROJECTION_DEPTH_M: f32 = 1e-3;

/// Invalid pinhole intrinsics.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum CameraError {
    /// A focal length is zero, negative, NaN or infinite.
    InvalidFocalLength {
        /// Horizontal focal length given, in pixels.
        fx: f32,
        /// Vertical focal length given, in pixels.
        fy: f32,
    },
    /// A principal point coordinate is NaN or infinite.
    InvalidPrincipalPoint {
        /// Horizontal coordinate given, in pixels.
        cx: f32,
        /// Vertical coordinate given, in pixels.
        cy: f32,
    },
    /// The image width or height is zero.
    ZeroSize {
        /// Width given, in pixels.
        width: usize,
        /// Height given, in pixels.
        height: usize,
    },
}

impl fmt::Display for CameraError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::InvalidFocalLength { fx, fy } => {
                write!(f, "focal lengths must be finite and positive, got fx {fx}, fy {fy}")
            }
            Self::InvalidPrincipalPoint { cx, cy } => {
                write!(f, "principal point must be finite, got cx {cx}, cy {cy}")
            }
            Self::ZeroSize { width, height } => {
                write!(f, "image size must be non-zero, got {width}x{height}")
            }
        }
    }
}

impl core::error::Error for CameraError {}

/// A world point projected into a camera, with the Jacobians a pose or structure optimizer needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldProjection {
    /// Pixel coordinates `(u, v)`.
    pub uv: Point2<f32>,
    /// The point in the camera frame, `t_cw * p_w`, in metres.
    pub p_c: Point3<f32>,
    /// `d(uv) / d(xi)` (pixels per metre / per radian) for the left perturbation
    /// `t_cw <- exp(xi) t_cw` with `xi = [rho; phi]`, taken at `xi = 0`.
    pub d_uv_d_xi: Matrix2x6<f32>,
    /// `d(uv) / d(p_w)`, in pixels per metre.
    pub d_uv_d_p_w: Matrix2x3<f32>,
}

/// A world point's projection with the Jacobian with respect to the pose only: the fields of
/// [`WorldProjection`] a pose solver uses
/// ([`PinholeCamera::project_world_with_pose_jacobian`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseProjection {
    /// Pixel coordinates `(u, v)`.
    pub uv: Point2<f32>,
    /// The point in the camera frame, `t_cw * p_w`, in metres.
    pub p_c: Point3<f32>,
    /// `d(uv) / d(xi)` (pixels per metre / per radian) for the left perturbation
    /// `t_cw <- exp(xi) t_cw` with `xi = [rho; phi]`, taken at `xi = 0`.
    pub d_uv_d_xi: Matrix2x6<f32>,
}

/// Pinhole intrinsics (no distortion) and image size, validated on construction.
///
/// `fx, fy`: focal lengths in pixels; `cx, cy`: principal point in pixels (pixel-centre
/// convention, see the module documentation); `width, height`: image size in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PinholeCamera {
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    width: usize,
    height: usize,
}

impl PinholeCamera {
    /// A camera with focal lengths `fx, fy` and principal point `cx, cy` (pixels) for
    /// `width` x `height` images.
    ///
    /// # Errors
    /// [`CameraError::InvalidFocalLength`] unless both focal lengths are finite and positive,
    /// [`CameraError::InvalidPrincipalPoint`] if `cx` or `cy` is not finite,
    /// [`CameraError::ZeroSize`] if `width` or `height` is zero.
    pub fn new(
        fx: f32,
        fy: f32,
        cx: f32,
        cy: f32,
        width: usize,
        height: usize,
    ) -> Result<Self, CameraError> {
        let focal_ok = |f: f32| f.is_finite() && f > 0.0;
        if !focal_ok(fx) || !focal_ok(fy) {
            return Err(CameraError::InvalidFocalLength { fx, fy });
        }
        if !cx.is_finite() || !cy.is_finite() {
            return Err(CameraError::InvalidPrincipalPoint { cx, cy });
        }
        if width == 0 || height == 0 {
            return Err(CameraError::ZeroSize { width, height });
        }
        Ok(Self { fx, fy, cx, cy, width, height })
    }

    /// Horizontal focal length, pixels.
    pub fn fx(&self) -> f32 {
        self.fx
    }

    /// Vertical focal length, pixels.
    pub fn fy(&self) -> f32 {
        self.fy
    }

    /// Horizontal principal point, pixels.
    pub fn cx(&self) -> f32 {
        self.cx
    }

    /// Vertical principal point, pixels.
    pub fn cy(&self) -> f32 {
        self.cy
    }

    /// Image width, pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Image height, pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The intrinsics of the image downsampled by 2x2 means (odd last row or column dropped).
    ///
    /// Output pixel `i` averages input pixels `2i` and `2i + 1`, so its centre lies at input
    /// coordinate `2i + 0.5`: `u = 2 u' + 0.5`, hence `u' = (u + 0.5) / 2 - 0.5`. Applied to Eq. 2
    /// this gives `fx' = fx / 2` and `cx' = (cx + 0.5) / 2 - 0.5` (not `cx / 2`, which would
    /// shift every projection by a quarter pixel); likewise for `y`.
    ///
    /// # Errors
    /// [`CameraError::ZeroSize`] when the image is 1 pixel wide or tall.
    pub fn downscaled_2x(&self) -> Result<Self, CameraError> {
        let half = |c: f32| (c + 0.5) * 0.5 - 0.5;
        Self::new(
            self.fx * 0.5,
            self.fy * 0.5,
            half(self.cx),
            half(self.cy),
            self.width / 2,
            self.height / 2,
        )
    }

    /// Eq. 2 with `1 / z`: the pixel and the reciprocal depth, or `None` when the point is not
    /// in front of the camera or the result is not finite.
    fn project_inner(&self, p_c: &Point3<f32>) -> Option<(Point2<f32>, f32)> {
        // NaN depth is rejected too (not greater).
        if p_c.z.partial_cmp(&MIN_PROJECTION_DEPTH_M) != Some(core::cmp::Ordering::Greater) {
            return None;
        }
        let inv_z = 1.0 / p_c.z;
        let uv =
            Point2::new(self.fx * (p_c.x * inv_z) + self.cx, self.fy * (p_c.y * inv_z) + self.cy);
        (uv.x.is_finite() && uv.y.is_finite()).then_some((uv, inv_z))
    }

    /// The pixel `(u, v)` of the camera-frame point `p_c` (metres) by Eq. 2.
    ///
    /// `None` when `p_c.z <= MIN_PROJECTION_DEPTH_M` (behind or too close to the camera) or a
    /// coordinate is not finite. The pixel may lie outside the image: see [`Self::in_image`].
    pub fn project(&self, p_c: &Point3<f32>) -> Option<Point2<f32>> {
        self.project_inner(p_c).map(|(uv, _)| uv)
    }

    /// [`Self::project`] with the Jacobian `d(u, v) / d(p_c)` (2x3, pixels per metre):
    /// `[[fx/z, 0, -fx x/z^2], [0, fy/z, -fy y/z^2]]`.
    pub fn project_with_jacobian(
        &self,
        p_c: &Point3<f32>,
    ) -> Option<(Point2<f32>, Matrix2x3<f32>)> {
        let (uv, inv_z) = self.project_inner(p_c)?;
        let (fx_z, fy_z) = (self.fx * inv_z, self.fy * inv_z);
        #[rustfmt::skip]
        let jac = Matrix2x3::new(
            fx_z, 0.0, -fx_z * (p_c.x * inv_z),
            0.0, fy_z, -fy_z * (p_c.y * inv_z),
        );
        Some((uv, jac))
    }

    /// The camera-frame point (metres) seen at pixel `(u, v)` with z-depth `depth_m`, the
    /// inverse of Eq. 2 (RGB-D sensors give the depth along the optical axis, not the range).
    ///
    /// Pure arithmetic: the caller rejects invalid depths (a sensor's 0 = no reading, NaN) first;
    /// whatever `depth_m` is, the result has `z == depth_m`.
    pub fn back_project(&self, u: f32, v: f32, depth_m: f32) -> Point3<f32> {
        Point3::new((u - self.cx) / self.fx * depth_m, (v - self.cy) / self.fy * depth_m, depth_m)
    }

    /// [`Self::back_project`] with the Jacobian `d(p_c) / d(u, v, depth_m)` (3x3; columns in
    /// that order: metres per pixel, metres per pixel, metres per metre).
    pub fn back_project_with_jacobian(
        &self,
        u: f32,
        v: f32,
        depth_m: f32,
    ) -> (Point3<f32>, Matrix3<f32>) {
        let (xn, yn) = ((u - self.cx) / self.fx, (v - self.cy) / self.fy);
        let p = Point3::new(xn * depth_m, yn * depth_m, depth_m);
        #[rustfmt::skip]
        let jac = Matrix3::new(
            depth_m / self.fx, 0.0, xn,
            0.0, depth_m / self.fy, yn,
            0.0, 0.0, 1.0,
        );
        (p, jac)
    }

    /// Whether pixel `uv` lies at least `border` pixels inside the outermost pixel centres:
    /// `border <= u <= width - 1 - border`, likewise for `v`; false for NaN.
    ///
    /// With `border = 0` the four neighbours of a bilinear lookup exist; a square patch of
    /// half-size `r` pixels around `uv` fits with `border = r`.
    pub fn in_image(&self, uv: &Point2<f32>, border: f32) -> bool {
        // Image sizes are far below 2^24, so the conversions are exact.
        let max_u = self.width as f32 - 1.0 - border;
        let max_v = self.height as f32 - 1.0 - border;
        uv.x >= border && uv.x <= max_u && uv.y >= border && uv.y <= max_v
    }

    /// The pixel of the world point `p_w` (metres) seen from `t_cw` (world-to-camera), as
    /// [`Self::project`] of `t_cw * p_w`.
    pub fn project_world(&self, t_cw: &Pose, p_w: &Point3<f32>) -> Option<Point2<f32>> {
        self.project(&(t_cw * p_w))
    }

    /// [`Self::project_world`] with the Jacobians with respect to a left perturbation of the
    /// pose (`t_cw <- exp(xi) t_cw`, `xi = [rho; phi]`) and with respect to the world point.
    ///
    /// With `J = d(uv)/d(p_c)`: `d(uv)/d(xi) = J [I, -[p_c]x]` and `d(uv)/d(p_w) = J R_cw`.
    /// `None` in the cases of [`Self::project`].
    pub fn project_world_with_jacobians(
        &self,
        t_cw: &Pose,
        p_w: &Point3<f32>,
    ) -> Option<WorldProjection> {
        let PoseProjection { uv, p_c, d_uv_d_xi } =
            self.project_world_with_pose_jacobian(t_cw, p_w)?;
        // The translation columns of `d(uv)/d(xi)` are `J` itself.
        let j = d_uv_d_xi.fixed_columns::<3>(0);
        let d_uv_d_p_w = j * t_cw.rotation.to_rotation_matrix().into_inner();
        Some(WorldProjection { uv, p_c, d_uv_d_xi, d_uv_d_p_w })
    }

    /// [`Self::project_world_with_jacobians`] without `d(uv)/d(p_w)`, for a solver that moves
    /// only the pose (tracking): the same values, bit for bit, without the rotation matrix and the
    /// product that only a point update needs. Always inlined: the pose solver calls it per
    /// correspondence and iteration, and a call returns the projection through the stack.
    #[inline(always)]
    pub fn project_world_with_pose_jacobian(
        &self,
        t_cw: &Pose,
        p_w: &Point3<f32>,
    ) -> Option<PoseProjection> {
        let p_c = t_cw * p_w;
        let (uv, j) = self.project_with_jacobian(&p_c)?;
        // exp(xi) p_c = p_c + rho + phi x p_c to first order, so d(p_c)/d(phi) = -[p_c]x.
        let d_phi = -(j * hat(&p_c.coords));
        #[rustfmt::skip]
        let d_uv_d_xi = Matrix2x6::new(
            j.m11, j.m12, j.m13, d_phi.m11, d_phi.m12, d_phi.m13,
            j.m21, j.m22, j.m23, d_phi.m21, d_phi.m22, d_phi.m23,
        );
        Some(PoseProjection { uv, p_c, d_uv_d_xi })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::test_support::random_vector3;
    use crate::test_rng::TestRng;

    /// TUM freiburg1 intrinsics at VGA.
    fn fr1() -> PinholeCamera {
        PinholeCamera::new(517.3, 516.5, 318.6, 255.3, 640, 480).unwrap()
    }

    #[test]
    fn constructor_rejects_bad_intrinsics() {
        let bad_focal = [0.0, -1.0, f32::NAN, f32::INFINITY];
        for f in bad_focal {
            let e = PinholeCamera::new(f, 500.0, 320.0, 240.0, 640, 480).unwrap_err();
            assert!(matches!(e, CameraError::InvalidFocalLength { .. }));
            let e = PinholeCamera::new(500.0, f, 320.0, 240.0, 640, 480).unwrap_err();
            assert!(matches!(e, CameraError::InvalidFocalLength { .. }));
        }
        for c in [f32::NAN, f32::NEG_INFINITY] {
            let e = PinholeCamera::new(500.0, 500.0, c, 240.0, 640, 480).unwrap_err();
            assert!(matches!(e, CameraError::InvalidPrincipalPoint { .. }));
            let e = PinholeCamera::new(500.0, 500.0, 320.0, c, 640, 480).unwrap_err();
            assert!(matches!(e, CameraError::InvalidPrincipalPoint { .. }));
        }
        assert_eq!(
            PinholeCamera::new(500.0, 500.0, 320.0, 240.0, 0, 480),
            Err(CameraError::ZeroSize { width: 0, height: 480 })
        );
        assert!(PinholeCamera::new(500.0, 500.0, 320.0, 240.0, 640, 0).is_err());
        let mut text = heapless::String::<96>::new();
        core::fmt::write(
            &mut text,
            format_args!("{}", CameraError::ZeroSize { width: 0, height: 1 }),
        )
        .unwrap();
        assert_eq!(text.as_str(), "image size must be non-zero, got 0x1");
    }

    #[test]
    fn projection_follows_eq_2_and_rejects_points_behind() {
        let cam = fr1();
        let uv = cam.project(&Point3::new(0.5, -0.25, 2.0)).unwrap();
        assert_eq!(uv, Point2::new(517.3 * 0.25 + 318.6, 516.5 * -0.125 + 255.3));
        for z in [0.0, -1.0, MIN_PROJECTION_DEPTH_M, f32::NAN] {
            assert_eq!(cam.project(&Point3::new(0.1, 0.1, z)), None);
        }
        assert_eq!(cam.project(&Point3::new(f32::INFINITY, 0.0, 1.0)), None);
        assert_eq!(cam.project(&Point3::new(0.0, f32::NAN, 1.0)), None);
        // project and project_with_jacobian agree to the bit.
        let p = Point3::new(0.3, 0.7, 1.3);
        assert_eq!(cam.project(&p), cam.project_with_jacobian(&p).map(|(uv, _)| uv));
    }

    #[test]
    fn paper_eq_1_maps_to_t_cw() {
        // X_c = R_n X_w - p_n is t_cw = (R_n, -p_n).
        let r_n = nalgebra::UnitQuaternion::from_euler_angles(0.1f32, -0.2, 0.3);
        let p_n = nalgebra::Vector3::new(0.5f32, -1.0, 0.25);
        let t_cw = Pose::from_parts((-p_n).into(), r_n);
        let x_w = Point3::new(1.0f32, 2.0, 3.0);
        let x_c = r_n * x_w - p_n;
        assert!((t_cw * x_w - x_c).norm() < 1e-6);
        let cam = fr1();
        assert_eq!(cam.project_world(&t_cw, &x_w), cam.project(&(t_cw * x_w)));
    }

    #[test]
    fn back_projection_round_trips() {
        let cam = fr1();
        let mut rng = TestRng::new(20);
        for _ in 0..2000 {
            let (u, v) = (rng.uniform(-0.5, 639.5) as f32, rng.uniform(-0.5, 479.5) as f32);
            let d = rng.uniform(0.2, 8.0) as f32;
            let p = cam.back_project(u, v, d);
            assert_eq!(p.z, d);
            assert_eq!(p, cam.back_project_with_jacobian(u, v, d).0);
            let uv = cam.project(&p).unwrap();
            // A few ulp of a coordinate of up to 640 pixels.
            assert!((uv.x - u).abs() < 2e-4 && (uv.y - v).abs() < 2e-4, "{u} {v} {d}: {uv}");
        }
    }

    #[test]
    fn in_image_uses_pixel_centres_and_border() {
        let cam = fr1();
        assert!(cam.in_image(&Point2::new(0.0, 0.0), 0.0));
        assert!(cam.in_image(&Point2::new(639.0, 479.0), 0.0));
        assert!(!cam.in_image(&Point2::new(639.01, 100.0), 0.0));
        assert!(!cam.in_image(&Point2::new(-0.01, 100.0), 0.0));
        assert!(cam.in_image(&Point2::new(3.0, 476.0), 3.0));
        assert!(!cam.in_image(&Point2::new(2.9, 100.0), 3.0));
        assert!(!cam.in_image(&Point2::new(100.0, 476.1), 3.0));
        assert!(!cam.in_image(&Point2::new(f32::NAN, 100.0), 0.0));
    }

    #[test]
    fn downscaled_intrinsics_match_2x2_mean_pixels() {
        let cam = fr1();
        let half = cam.downscaled_2x().unwrap();
        assert_eq!((half.width(), half.height()), (320, 240));
        assert_eq!((half.fx(), half.fy()), (517.3 / 2.0, 516.5 / 2.0));
        // A point seen at input pixel u is seen at output coordinate (u - 0.5) / 2: the centre of
        // output pixel i is the midpoint of input pixels 2i and 2i+1.
        let mut rng = TestRng::new(21);
        for _ in 0..200 {
            let p = Point3::from(
                random_vector3(&mut rng, -1.0, 1.0).cast::<f32>() + nalgebra::Vector3::z() * 2.0,
            );
            let (full, small) = (cam.project(&p).unwrap(), half.project(&p).unwrap());
            assert!((small.x - (full.x - 0.5) / 2.0).abs() < 1e-4);
            assert!((small.y - (full.y - 0.5) / 2.0).abs() < 1e-4);
        }
        let odd =
            PinholeCamera::new(100.0, 100.0, 1.0, 1.0, 3, 5).unwrap().downscaled_2x().unwrap();
        assert_eq!((odd.width(), odd.height(), odd.cx()), (1, 2, 0.25));
        let one = PinholeCamera::new(100.0, 100.0, 0.0, 0.0, 1, 5).unwrap();
        assert!(matches!(one.downscaled_2x(), Err(CameraError::ZeroSize { .. })));
    }
}
