//! The measurement model, the same as tracking's (see [`crate::tracking`]): per observation a
//! whitened reprojection residual `(project(t_cw p_w) - uv) / pixel_sigma_px` (2 DOF) and, with a
//! measured depth, a whitened inverse-depth residual `(1/z_pred - 1/z_meas) /
//! depth_noise_coeff_per_m` (1 DOF), each block with its own Huber weight; and how observations
//! are stored compactly.
//!
//! # Jacobians
//!
//! With `p_c = t_cw p_w` and `a_k` the gradient of whitened residual row `k` with respect to
//! `p_c` (`d e / d p_c`, one row per residual), the Jacobian row of a left camera perturbation
//! `t_cw <- exp(xi) t_cw` is `[a_k; p_c x a_k]` (because `d p_c = rho + phi x p_c`), and of the
//! world point `R_cw^T a_k`. A rig perturbation `T_s <- exp(xi) T_s` of a camera `t_cw = t_cs T_s`
//! is the camera perturbation `Ad(t_cs) xi`.

use super::BaParams;
use super::linalg::{PoseMatrix, Vec3, Vec6, cross3};
use crate::geometry::{MIN_PROJECTION_DEPTH_M, PinholeCamera};

/// Quantization of stored pixel coordinates: `1/32` pixel.
const UV_STEPS_PER_PX: f32 = 32.0;
/// Stored pixel coordinates are offset by this many pixels so that `u >= -1` is representable.
const UV_OFFSET_PX: f32 = 1.0;
/// Quantization of stored inverse depth: `2^-13` per metre.
const INV_DEPTH_STEPS_PER_INV_M: f32 = 8192.0;

/// Smallest storable pixel coordinate, pixels.
pub const MIN_OBSERVATION_PX: f32 = -UV_OFFSET_PX;
/// Largest storable pixel coordinate, pixels (`65535 / 32 - 1`).
pub const MAX_OBSERVATION_PX: f32 = 65535.0 / UV_STEPS_PER_PX - UV_OFFSET_PX;
/// Nearest storable measured depth, metres (inverse depth at most `65535 * 2^-13` per metre).
pub const MIN_OBSERVATION_DEPTH_M: f32 = INV_DEPTH_STEPS_PER_INV_M / 65535.0;

/// One observation as stored: 8 bytes. Pixel coordinates in 1/32 pixel (rounding error at most
/// 1/64 pixel), measured inverse depth in `2^-13` per metre (0 = no depth; rounding error at
/// most `6.1e-5` per metre, 2% of the default inverse-depth sigma), the observing camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct StoredObservation {
    u_q: u16,
    v_q: u16,
    inv_depth_q: u16,
    pub(super) camera: u16,
}

impl StoredObservation {
    pub(super) const EMPTY: Self = Self { u_q: 0, v_q: 0, inv_depth_q: 0, camera: 0 };

    /// The observation, or `Err(true)` for a pixel and `Err(false)` for a depth that is not
    /// finite or not storable.
    pub(super) fn encode(camera: u16, u: f32, v: f32, depth_m: Option<f32>) -> Result<Self, bool> {
        let uv = |x: f32| {
            let q = libm::roundf((x + UV_OFFSET_PX) * UV_STEPS_PER_PX);
            // NaN and infinities fail the range test; the cast is then exact.
            (0.0..=65535.0).contains(&q).then_some(q as u16)
        };
        let (Some(u_q), Some(v_q)) = (uv(u), uv(v)) else { return Err(true) };
        let inv_depth_q = match depth_m {
            None => 0,
            Some(d) => {
                let q = libm::roundf(INV_DEPTH_STEPS_PER_INV_M / d);
                let storable = d > 0.0 && (1.0..=65535.0).contains(&q);
                if !storable {
                    return Err(false);
                }
                q as u16
            }
        };
        Ok(Self { u_q, v_q, inv_depth_q, camera })
    }

    /// The stored pixel `(u, v)` (exact: the scale is a power of two).
    pub(super) fn uv(&self) -> (f32, f32) {
        let d = |q: u16| f32::from(q) * (1.0 / UV_STEPS_PER_PX) - UV_OFFSET_PX;
        (d(self.u_q), d(self.v_q))
    }

    /// The stored measured inverse depth, per metre.
    pub(super) fn inv_depth(&self) -> Option<f32> {
        (self.inv_depth_q != 0)
            .then(|| f32::from(self.inv_depth_q) * (1.0 / INV_DEPTH_STEPS_PER_INV_M))
    }
}

/// Huber weight and loss of a squared whitened residual `s2` for threshold `delta`:
/// `rho = s2` inside, `2 delta s - delta^2` outside; `w = rho'(s2)` (as tracking's).
pub(super) fn huber(s2: f32, delta: f32) -> (f32, f32) {
    if s2 <= delta * delta {
        (1.0, s2)
    } else {
        let s = ferroslam_fpu::sqrtf(s2);
        (delta / s, 2.0 * delta * s - delta * delta)
    }
}

/// One whitened residual row: `a = d e / d p_c`, the residual `e`, its Huber weight `w`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Row {
    pub(super) a: Vec3,
    pub(super) e: f32,
    pub(super) w: f32,
}

/// An observation linearized: the point in the camera, 2 or 3 rows, the robust cost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Terms {
    pub(super) p_c: Vec3,
    pub(super) rows: [Row; 3],
    pub(super) n_rows: usize,
    pub(super) cost: f32,
    /// Unweighted squared whitened errors: reprojection (2 DOF) and inverse depth (1 DOF, 0
    /// without depth).
    pub(super) chi2: (f32, f32),
}

impl Terms {
    /// The rows in use.
    pub(super) fn rows(&self) -> &[Row] {
        self.rows.get(..self.n_rows).unwrap_or(&[])
    }
}

/// The camera-perturbation Jacobian row `[a; p_c x a]` of a residual row.
pub(super) fn pose_row(p_c: &Vec3, a: &Vec3) -> Vec6 {
    let c = cross3(p_c, a);
    [a[0], a[1], a[2], c[0], c[1], c[2]]
}

/// The intrinsics and noise model in the form the per-observation arithmetic uses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Model {
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    inv_sigma_px: f32,
    inv_depth_coeff: f32,
    huber_delta: f32,
}

impl Model {
    pub(super) const EMPTY: Self = Self {
        fx: 1.0,
        fy: 1.0,
        cx: 0.0,
        cy: 0.0,
        inv_sigma_px: 1.0,
        inv_depth_coeff: 1.0,
        huber_delta: 1.0,
    };

    /// The model of `camera` and `params` (which the caller has validated).
    pub(super) fn new(camera: &PinholeCamera, params: &BaParams) -> Self {
        Self {
            fx: camera.fx(),
            fy: camera.fy(),
            cx: camera.cx(),
            cy: camera.cy(),
            inv_sigma_px: 1.0 / params.sensor.pixel_sigma_px,
            inv_depth_coeff: 1.0 / params.sensor.depth_noise_coeff_per_m,
            huber_delta: params.sensor.huber_delta_px / params.sensor.pixel_sigma_px,
        }
    }

    /// The observation `obs` of the world point `p_w` (metres) by the camera `t_cw`; `None` when
    /// the point is not in front of the camera (z at most [`MIN_PROJECTION_DEPTH_M`]) or the
    /// projection is not finite, like [`PinholeCamera::project`].
    ///
    /// Always inlined: called, its 88-byte `Option<Terms>` went through the stack and was copied
    /// out (`__aeabi_memcpy4`). Why: docs/decisions.md, "Observation terms inlined".
    #[inline(always)]
    pub(super) fn terms(
        &self,
        t_cw: &PoseMatrix,
        p_w: &Vec3,
        obs: &StoredObservation,
    ) -> Option<Terms> {
        let p_c = t_cw.transform(p_w);
        let z = p_c[2];
        // NaN is rejected too (not greater).
        let in_front = z > MIN_PROJECTION_DEPTH_M;
        if !in_front {
            return None;
        }
        let inv_z = 1.0 / z;
        let (xn, yn) = (p_c[0] * inv_z, p_c[1] * inv_z);
        let (u, v) = (self.fx * xn + self.cx, self.fy * yn + self.cy);
        if !u.is_finite() || !v.is_finite() {
            return None;
        }
        let (u_m, v_m) = obs.uv();
        let s = self.inv_sigma_px;
        let (e_u, e_v) = ((u - u_m) * s, (v - v_m) * s);
        let chi2_uv = e_u * e_u + e_v * e_v;
        let (w, rho_uv) = huber(chi2_uv, self.huber_delta);
        let (fx_z, fy_z) = (self.fx * inv_z, self.fy * inv_z);
        let row_u = Row { a: [fx_z * s, 0.0, -(fx_z * xn) * s], e: e_u, w };
        let row_v = Row { a: [0.0, fy_z * s, -(fy_z * yn) * s], e: e_v, w };
        let mut terms = Terms {
            p_c,
            rows: [row_u, row_v, Row { a: [0.0; 3], e: 0.0, w: 0.0 }],
            n_rows: 2,
            cost: rho_uv,
            chi2: (chi2_uv, 0.0),
        };
        if let Some(inv_z_m) = obs.inv_depth() {
            let k = self.inv_depth_coeff;
            let e = (inv_z - inv_z_m) * k;
            let (w, rho) = huber(e * e, self.huber_delta);
            // d(1/z)/d(p_c) = [0, 0, -1/z^2].
            terms.rows[2] = Row { a: [0.0, 0.0, -(inv_z * inv_z) * k], e, w };
            terms.n_rows = 3;
            terms.cost = rho_uv + rho;
            terms.chi2.1 = e * e;
        }
        Some(terms)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SensorModel;
    use crate::geometry::{Pose, se3_exp};
    use nalgebra::{Point3, Translation3, UnitQuaternion, Vector3, Vector6};

    fn camera() -> PinholeCamera {
        PinholeCamera::new(262.5, 262.5, 159.75, 119.75, 320, 240).unwrap()
    }

    fn model() -> Model {
        let sensor = SensorModel { depth_noise_coeff_per_m: 0.01, ..SensorModel::DEFAULT };
        let params = BaParams { sensor, ..BaParams::DEFAULT };
        Model::new(&camera(), &params)
    }

    fn t_cw() -> Pose {
        Pose::from_parts(
            Translation3::new(0.1, 0.05, -0.2),
            UnitQuaternion::from_scaled_axis(Vector3::new(0.1, -0.15, 0.05)),
        )
    }

    /// Whitened residuals (2 or 3) of `obs` at `t_cw`, `p_w`.
    fn residuals(t_cw: &Pose, p_w: &Vec3, obs: &StoredObservation) -> [f32; 3] {
        let t = model().terms(&PoseMatrix::from_pose(t_cw), p_w, obs).unwrap();
        [t.rows[0].e, t.rows[1].e, t.rows[2].e]
    }

    #[test]
    fn encoding_round_trips_within_its_resolution() {
        let o = StoredObservation::encode(7, 123.456, -0.5, Some(2.345)).unwrap();
        let (u, v) = o.uv();
        assert!((u - 123.456).abs() <= 1.0 / 64.0 && v == -0.5);
        assert!((o.inv_depth().unwrap() - 1.0 / 2.345).abs() <= 1.0 / 16384.0);
        assert_eq!(o.camera, 7);
        assert_eq!(StoredObservation::encode(0, 10.0, 10.0, None).unwrap().inv_depth(), None);
        for bad in [f32::NAN, f32::INFINITY, -1.5, 2100.0] {
            assert_eq!(StoredObservation::encode(0, bad, 10.0, None), Err(true));
            assert_eq!(StoredObservation::encode(0, 10.0, bad, None), Err(true));
        }
        for bad in [0.0, -1.0, f32::NAN, f32::INFINITY, 0.1, 1e9] {
            assert_eq!(StoredObservation::encode(0, 10.0, 10.0, Some(bad)), Err(false), "{bad}");
        }
        assert!(StoredObservation::encode(0, MAX_OBSERVATION_PX, MIN_OBSERVATION_PX, None).is_ok());
        assert!(StoredObservation::encode(0, 1.0, 1.0, Some(MIN_OBSERVATION_DEPTH_M)).is_ok());
    }

    #[test]
    fn residuals_agree_with_the_camera_and_tracking() {
        let cam = camera();
        let p_w = Point3::new(0.4f32, -0.3, 2.5);
        let obs = StoredObservation::encode(0, 180.25, 100.5, Some(2.2)).unwrap();
        let t = model().terms(&PoseMatrix::from_pose(&t_cw()), &p_w.coords.into(), &obs).unwrap();
        let proj = cam.project_world_with_jacobians(&t_cw(), &p_w).unwrap();
        assert!((t.rows[0].e - (proj.uv.x - 180.25)).abs() < 1e-4);
        assert!((t.rows[1].e - (proj.uv.y - 100.5)).abs() < 1e-4);
        let depth_e = (1.0 / proj.p_c.z - obs.inv_depth().unwrap()) / 0.01;
        assert!((t.rows[2].e - depth_e).abs() < 1e-3);
        // The pose rows are the camera's d(uv)/d(xi); the point rows its d(uv)/d(p_w).
        let m = PoseMatrix::from_pose(&t_cw());
        for k in 0..2 {
            let row = pose_row(&t.p_c, &t.rows[k].a);
            for (j, r) in row.iter().enumerate() {
                assert!((r - proj.d_uv_d_xi[(k, j)]).abs() < 1e-3, "{k} {j}");
            }
            let lw = m.rotate_back(&t.rows[k].a);
            for (j, l) in lw.iter().enumerate() {
                assert!((l - proj.d_uv_d_p_w[(k, j)]).abs() < 1e-3);
            }
        }
        // Behind the camera, NaN: no terms.
        let behind = [0.0, 0.0, -1.0];
        assert!(model().terms(&PoseMatrix::IDENTITY, &behind, &obs).is_none());
        assert!(model().terms(&PoseMatrix::IDENTITY, &[f32::NAN, 0.0, 1.0], &obs).is_none());
    }

    /// Analytic Jacobians of all three residuals against central differences: camera (left
    /// perturbation), rig behind an offset (`Ad(t_cs)`), and world point.
    #[test]
    fn jacobians_match_numeric_differences() {
        let obs = StoredObservation::encode(0, 150.0, 110.0, Some(2.0)).unwrap();
        let t_cs = Pose::from_parts(
            Translation3::new(0.05, -0.1, 0.02),
            UnitQuaternion::from_scaled_axis(Vector3::new(0.02, 0.3, -0.1)),
        );
        let t_sw = t_cs.inverse() * t_cw();
        let offset = PoseMatrix::from_pose(&t_cs);
        for p_w in [[0.4f32, -0.3, 2.5], [-0.8, 0.5, 1.2], [0.05, 0.02, 4.0]] {
            let t = model().terms(&PoseMatrix::from_pose(&t_cw()), &p_w, &obs).unwrap();
            let h = 1e-3f32;
            for k in 0..6 {
                let mut d = Vector6::zeros();
                d[k] = h;
                let cam = |d: &Vector6<f32>| residuals(&(se3_exp(d) * t_cw()), &p_w, &obs);
                let rig = |d: &Vector6<f32>| residuals(&(t_cs * se3_exp(d) * t_sw), &p_w, &obs);
                let (cp, cm, rp, rm) = (cam(&d), cam(&-d), rig(&d), rig(&-d));
                for r in 0..3 {
                    let analytic_cam = pose_row(&t.p_c, &t.rows[r].a);
                    let mut e = [0.0; 6];
                    e[k] = 1.0;
                    let analytic_rig =
                        crate::optim::linalg::dot6(&analytic_cam, &offset.adjoint(&e));
                    let num_cam = (cp[r] - cm[r]) / (2.0 * h);
                    let num_rig = (rp[r] - rm[r]) / (2.0 * h);
                    let tol = |a: f32| 2e-2 + 0.01 * a.abs();
                    assert!((num_cam - analytic_cam[k]).abs() <= tol(analytic_cam[k]), "{r} {k}");
                    assert!((num_rig - analytic_rig).abs() <= tol(analytic_rig), "rig {r} {k}");
                }
            }
            let m = PoseMatrix::from_pose(&t_cw());
            for k in 0..3 {
                let (mut pp, mut pm) = (p_w, p_w);
                pp[k] += 1e-3;
                pm[k] -= 1e-3;
                let (a, b) = (residuals(&t_cw(), &pp, &obs), residuals(&t_cw(), &pm, &obs));
                for r in 0..3 {
                    let analytic = m.rotate_back(&t.rows[r].a)[k];
                    let num = (a[r] - b[r]) / 2e-3;
                    assert!((num - analytic).abs() <= 2e-2 + 0.01 * analytic.abs(), "pt {r} {k}");
                }
            }
        }
    }

    #[test]
    fn huber_is_quadratic_inside_and_linear_outside() {
        assert_eq!(huber(1.0, 2.0), (1.0, 1.0));
        assert_eq!(huber(16.0, 2.0), (0.5, 12.0));
    }
}
