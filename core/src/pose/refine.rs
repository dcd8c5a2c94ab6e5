//! Robust Levenberg-Marquardt on SE(3): reprojection plus inverse-depth residuals, Huber weights,
//! 6x6 normal equations solved by Cholesky, left-perturbation updates.

use nalgebra::{Matrix2x6, Matrix6, UnitQuaternion, Vector2, Vector6};

use super::{Correspondence, InlierMask, PoseError, PoseParams, validate_input};
use crate::geometry::{PinholeCamera, Pose, se3_exp};

/// Fewest correspondences that can determine a pose (six unknowns, two equations each).
pub(super) const MIN_CORRESPONDENCES: usize = 3;

/// Levenberg-Marquardt damping: start, floor and give-up ceiling (multiplies the Hessian's
/// diagonal, Marquardt scaling).
const LAMBDA_INIT: f32 = 1.0e-4;
const LAMBDA_MIN: f32 = 1.0e-7;
const LAMBDA_MAX: f32 = 1.0e6;
/// Relative floor added to each diagonal entry before scaling by lambda, so a parameter the
/// data do not see still gets damped (the conditioning check then rejects the pose).
const DIAG_FLOOR: f32 = 1.0e-6;

/// A pose with its quality figures; only valid poses are returned (see [`refine_pose`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseEstimate {
    /// The estimated world-to-camera pose.
    pub t_cw: Pose,
    /// Per-correspondence inlier flags at `t_cw` (index into the caller's slice), by the
    /// chi-square gates of [`PoseParams`].
    pub inliers: InlierMask,
    /// Number of inliers (`inliers.count()`).
    pub num_inliers: usize,
    /// Root mean square reprojection error over the inliers, pixels.
    pub rms_reprojection_px: f32,
    /// Levenberg-Marquardt solves done, over all rounds.
    pub iterations: u32,
    /// Whether the last round ended on a step below the thresholds rather than on its
    /// iteration cap.
    pub converged: bool,
    /// Largest translation standard deviation (inverse Hessian over the inliers), metres.
    pub sigma_translation_m: f32,
    /// Largest rotation standard deviation, radians.
    pub sigma_rotation_rad: f32,
}

/// The whitened residuals of one correspondence and their Jacobians for a left perturbation.
struct Terms {
    /// Reprojection error over `pixel_sigma_px`.
    e: Vector2<f32>,
    /// `d(e)/d(xi)`.
    j: Matrix2x6<f32>,
    /// Inverse-depth error over `depth_noise_coeff_per_m`, with its `d/d(xi)`.
    depth: Option<(f32, Vector6<f32>)>,
}

/// Huber weight and loss of a squared whitened residual `s2` for threshold `delta`:
/// `rho = s2` inside, `2 delta s - delta^2` outside; `w = rho'(s2)`.
fn huber(s2: f32, delta: f32) -> (f32, f32) {
    if s2 <= delta * delta {
        (1.0, s2)
    } else {
        let s = ferroslam_fpu::sqrtf(s2);
        (delta / s, 2.0 * delta * s - delta * delta)
    }
}

/// `h += J^T J w` on the upper triangle (`a <= b`) only; [`mirror_upper`] fills the rest once.
///
/// Each entry gets `(j0a j0b + j1a j1b) w`, the order in which nalgebra evaluates
/// `h += j.transpose() * j * w`, so the result is the same bits as that expression at a third of
/// its work: 21 entries instead of 36, without the 6 x 6 temporaries. The lower triangle would
/// receive the same values (products commute), so mirroring at the end gives the full matrix.
fn add_jtj_upper(h: &mut Matrix6<f32>, j: &Matrix2x6<f32>, w: f32) {
    for b in 0..6 {
        let (j0b, j1b) = (j[(0, b)], j[(1, b)]);
        for a in 0..=b {
            h[(a, b)] += (j[(0, a)] * j0b + j[(1, a)] * j1b) * w;
        }
    }
}

/// `h += jd jd^T w` on the upper triangle for a depth Jacobian, whose entries 0, 1 and 5 are zero
/// by construction (see [`Problem::terms`]): only the `{2, 3, 4}` block changes. The skipped
/// products are signed zeros, and adding a zero leaves every entry as it was (no entry is ever
/// `-0`: the sums start at `+0`, and round-to-nearest never gives `-0` from a sum with a `+0` or
/// from an exact cancellation), so the result is the same bits as `h += jd * jd.transpose() * w`.
fn add_depth_upper(h: &mut Matrix6<f32>, jd: &Vector6<f32>, w: f32) {
    for b in 2..5 {
        for a in 2..=b {
            h[(a, b)] += jd[a] * jd[b] * w;
        }
    }
}

/// Copies the upper triangle of `h` onto its lower triangle.
fn mirror_upper(h: &mut Matrix6<f32>) {
    for b in 0..6 {
        for a in 0..b {
            h[(b, a)] = h[(a, b)];
        }
    }
}

/// The normal equations `H xi = -g` at one pose, and the (robust) cost there.
struct Normal {
    h: Matrix6<f32>,
    g: Vector6<f32>,
    cost: f32,
    used: usize,
}

/// One problem: the camera, the caller's correspondences and the tunables.
struct Problem<'a> {
    camera: &'a PinholeCamera,
    corrs: &'a [Correspondence],
    params: &'a PoseParams,
}

impl Problem<'_> {
    /// Residuals of `c` at `t_cw`; `None` when `p_w` does not project (behind the camera).
    /// Always inlined, with the projection it calls, for the same reason as the BA's
    /// observation terms (`optim::model`): returned from calls, the structures were copied
    /// through the stack.
    #[inline(always)]
    fn terms(&self, t_cw: &Pose, c: &Correspondence) -> Option<Terms> {
        let proj = self.camera.project_world_with_pose_jacobian(t_cw, &c.p_w)?;
        let inv_sigma = 1.0 / self.params.sensor.pixel_sigma_px;
        let e = (proj.uv - c.uv) * inv_sigma;
        let j = proj.d_uv_d_xi * inv_sigma;
        let depth = c.depth_m.map(|d_m| {
            let inv_c = 1.0 / self.params.sensor.depth_noise_coeff_per_m;
            // Projection guarantees z > MIN_PROJECTION_DEPTH_M.
            let p = proj.p_c;
            let inv_z = 1.0 / p.z;
            let r = (inv_z - 1.0 / d_m) * inv_c;
            // d(1/z)/d(xi) = -(1/z^2) dz/d(xi), dz/d(xi) = [0, 0, 1, y, -x, 0] (left perturbation).
            let k = -(inv_z * inv_z) * inv_c;
            (r, Vector6::new(0.0, 0.0, k, k * p.y, -(k * p.x), 0.0))
        });
        Some(Terms { e, j, depth })
    }

    /// Normal equations over the `active` correspondences at `t_cw`, Huber-weighted when
    /// `robust` (else plain least squares, for the covariance).
    fn accumulate(&self, t_cw: &Pose, active: &InlierMask, robust: bool) -> Normal {
        let delta = if robust {
            self.params.sensor.huber_delta_px / self.params.sensor.pixel_sigma_px
        } else {
            f32::INFINITY
        };
        let mut n = Normal { h: Matrix6::zeros(), g: Vector6::zeros(), cost: 0.0, used: 0 };
        for (i, c) in self.corrs.iter().enumerate() {
            if !active.contains(i) {
                continue;
            }
            let Some(t) = self.terms(t_cw, c) else { continue };
            let (w, rho) = huber(t.e.norm_squared(), delta);
            add_jtj_upper(&mut n.h, &t.j, w);
            n.g += t.j.transpose() * t.e * w;
            n.cost += rho;
            if let Some((r, jd)) = t.depth {
                let (w, rho) = huber(r * r, delta);
                add_depth_upper(&mut n.h, &jd, w);
                n.g += jd * (r * w);
                n.cost += rho;
            }
            n.used += 1;
        }
        mirror_upper(&mut n.h);
        n
    }

    /// Inlier flags of every correspondence at `t_cw`, and the sum of squared reprojection
    /// errors over the inliers (pixels^2).
    fn classify(&self, t_cw: &Pose) -> (InlierMask, f32) {
        let mut mask = InlierMask::new();
        let mut sum_sq_px = 0.0;
        let sigma2 = self.params.sensor.pixel_sigma_px * self.params.sensor.pixel_sigma_px;
        for (i, c) in self.corrs.iter().enumerate() {
            let Some(t) = self.terms(t_cw, c) else { continue };
            let chi2 = t.e.norm_squared();
            let depth_ok = t.depth.is_none_or(|(r, _)| r * r <= self.params.chi2_depth);
            if chi2 <= self.params.chi2_reprojection && depth_ok {
                mask.insert(i);
                sum_sq_px += chi2 * sigma2;
            }
        }
        (mask, sum_sq_px)
    }

    /// One round of Levenberg-Marquardt over `active` from `t_cw`: the refined pose, whether a
    /// small step ended it, and the number of solves (added to `iterations`).
    fn lm_round(
        &self,
        mut t_cw: Pose,
        active: &InlierMask,
        iterations: &mut u32,
    ) -> Result<(Pose, bool), PoseError> {
        let mut lin = self.accumulate(&t_cw, active, true);
        if lin.used < MIN_CORRESPONDENCES {
            return Err(PoseError::TooFewCorrespondences {
                count: lin.used,
                required: MIN_CORRESPONDENCES,
            });
        }
        let mut lambda = LAMBDA_INIT;
        for _ in 0..self.params.max_iterations {
            *iterations += 1;
            let Some(step) = solve_damped(&lin, lambda) else {
                lambda *= 10.0;
                if lambda > LAMBDA_MAX {
                    return Err(PoseError::Degenerate);
                }
                continue;
            };
            let small = step.fixed_rows::<3>(0).norm() < self.params.min_step_translation_m
                && step.fixed_rows::<3>(3).norm() < self.params.min_step_rotation_rad;
            let candidate = compose_left(&step, &t_cw);
            let cand = self.accumulate(&candidate, active, true);
            if cand.cost <= lin.cost && cand.used >= MIN_CORRESPONDENCES {
                t_cw = candidate;
                lin = cand;
                lambda = (lambda * 0.1).max(LAMBDA_MIN);
            } else {
                lambda *= 10.0;
            }
            // A tiny step, accepted or not, means the minimum is reached to f32 precision.
            if small || lambda > LAMBDA_MAX {
                return Ok((t_cw, small));
            }
        }
        Ok((t_cw, false))
    }

    /// Largest translation and rotation standard deviations at `t_cw` over `inliers`, from the
    /// diagonal of the inverse of the unweighted Hessian; `None` when it is singular.
    fn sigmas(&self, t_cw: &Pose, inliers: &InlierMask) -> Option<(f32, f32)> {
        let lin = self.accumulate(t_cw, inliers, false);
        let cov = lin.h.cholesky()?.inverse();
        let d = cov.diagonal();
        let max3 = |a: f32, b: f32, c: f32| a.max(b).max(c);
        let var_t = max3(d.x, d.y, d.z);
        let var_r = max3(d.w, d.a, d.b);
        let ok = var_t.is_finite() && var_r.is_finite() && var_t >= 0.0 && var_r >= 0.0;
        ok.then(|| (ferroslam_fpu::sqrtf(var_t), ferroslam_fpu::sqrtf(var_r)))
    }
}

/// The step `xi` solving `(H + lambda diag(H + floor)) xi = -g`; `None` if not positive
/// definite or not finite.
fn solve_damped(lin: &Normal, lambda: f32) -> Option<Vector6<f32>> {
    let diag = lin.h.diagonal();
    let floor = diag.max() * DIAG_FLOOR;
    let mut damped = lin.h;
    for (i, d) in diag.iter().enumerate() {
        if let Some(x) = damped.get_mut((i, i)) {
            *x += lambda * (*d + floor);
        }
    }
    let step = damped.cholesky()?.solve(&(-lin.g));
    step.iter().all(|x| x.is_finite()).then_some(step)
}

/// `exp(xi) t_cw`, with the rotation re-normalized so repeated updates do not drift.
fn compose_left(xi: &Vector6<f32>, t_cw: &Pose) -> Pose {
    let mut t = se3_exp(xi) * t_cw;
    t.rotation = UnitQuaternion::new_normalize(t.rotation.into_inner());
    t
}

/// Refines `t_cw_init` (world-to-camera) against `correspondences` by robust
/// Levenberg-Marquardt.
///
/// `active` restricts the first round to a subset (e.g. RANSAC inliers); `None` uses all.
/// [`PoseParams::refine_rounds`] rounds of at most [`PoseParams::max_iterations`] solves each;
/// after each round every correspondence is re-classified by the chi-square gates and the next
/// round uses the inliers only. Cost per solve: two passes over the correspondences (one
/// projection with Jacobians each). Stack: a few 6x6 matrices and two [`InlierMask`]s.
///
/// # Errors
/// [`PoseError::TooManyCorrespondences`], [`PoseError::InvalidCorrespondence`] (NaN, infinite
/// or non-positive depth), [`PoseError::InvalidParams`], [`PoseError::TooFewCorrespondences`]
/// (fewer than 3 projecting), [`PoseError::TooFewInliers`] (below
/// [`PoseParams::min_inliers`]), [`PoseError::Degenerate`] (singular or ill-conditioned
/// normal equations: the returned pose would not be determined).
pub fn refine_pose(
    camera: &PinholeCamera,
    correspondences: &[Correspondence],
    t_cw_init: &Pose,
    active: Option<&InlierMask>,
    params: &PoseParams,
) -> Result<PoseEstimate, PoseError> {
    validate_input(correspondences)?;
    if !params.is_valid() {
        return Err(PoseError::InvalidParams);
    }
    if correspondences.len() < MIN_CORRESPONDENCES {
        return Err(PoseError::TooFewCorrespondences {
            count: correspondences.len(),
            required: MIN_CORRESPONDENCES,
        });
    }
    let problem = Problem { camera, corrs: correspondences, params };
    let min_inliers = params.min_inliers as usize;
    let mut active = active.copied().unwrap_or_else(|| InlierMask::first(correspondences.len()));
    let (mut t_cw, mut iterations, mut converged) = (*t_cw_init, 0, false);
    for round in 0..params.refine_rounds {
        if round > 0 {
            active = problem.classify(&t_cw).0;
            if active.count() < min_inliers.max(MIN_CORRESPONDENCES) {
                let inliers = active.count();
                return Err(PoseError::TooFewInliers { inliers, required: min_inliers });
            }
        }
        (t_cw, converged) = problem.lm_round(t_cw, &active, &mut iterations)?;
    }
    let (inliers, sum_sq_px) = problem.classify(&t_cw);
    let num_inliers = inliers.count();
    if num_inliers < min_inliers.max(MIN_CORRESPONDENCES) {
        return Err(PoseError::TooFewInliers { inliers: num_inliers, required: min_inliers });
    }
    let (sigma_t, sigma_r) = problem.sigmas(&t_cw, &inliers).ok_or(PoseError::Degenerate)?;
    if sigma_t > params.max_sigma_translation_m || sigma_r > params.max_sigma_rotation_rad {
        return Err(PoseError::Degenerate);
    }
    Ok(PoseEstimate {
        t_cw,
        inliers,
        num_inliers,
        // num_inliers >= 3 and far below 2^24: the conversion is exact.
        rms_reprojection_px: ferroslam_fpu::sqrtf(sum_sq_px / num_inliers as f32),
        iterations,
        converged,
        sigma_translation_m: sigma_t,
        sigma_rotation_rad: sigma_r,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SensorModel;
    use nalgebra::{Point2, Point3, Translation3, Vector3};

    /// The inverse-depth and reprojection Jacobians match central differences of the residuals
    /// under left perturbations (f32, step 1e-3, tolerance 1% plus an absolute floor).
    #[test]
    fn jacobians_match_numeric_differences() {
        let camera = PinholeCamera::new(525.0, 525.0, 319.5, 239.5, 640, 480).unwrap();
        let sensor = SensorModel { depth_noise_coeff_per_m: 0.01, ..SensorModel::DEFAULT };
        let params = PoseParams { sensor, ..PoseParams::default() };
        let corrs = [Correspondence {
            p_w: Point3::new(0.4, -0.3, 2.5),
            uv: Point2::new(300.0, 200.0),
            depth_m: Some(2.2),
        }];
        let problem = Problem { camera: &camera, corrs: &corrs, params: &params };
        let t_cw = Pose::from_parts(
            Translation3::new(0.1, 0.05, -0.2),
            UnitQuaternion::from_scaled_axis(Vector3::new(0.1, -0.15, 0.05)),
        );
        let at = |xi: &Vector6<f32>| problem.terms(&(se3_exp(xi) * t_cw), &corrs[0]).unwrap();
        let t0 = at(&Vector6::zeros());
        let (_, jd) = t0.depth.unwrap();
        let h = 1e-3;
        for k in 0..6 {
            let mut d = Vector6::zeros();
            d[k] = h;
            let (p, m) = (at(&d), at(&-d));
            let num_d = (p.depth.unwrap().0 - m.depth.unwrap().0) / (2.0 * h);
            assert!((num_d - jd[k]).abs() <= 1e-3 + 0.01 * jd[k].abs(), "depth {k}");
            let num_e = (p.e - m.e) / (2.0 * h);
            for r in 0..2 {
                let a = t0.j[(r, k)];
                assert!((num_e[r] - a).abs() <= 1e-2 + 0.01 * a.abs(), "uv {r} {k}");
            }
        }
    }

    #[test]
    fn huber_is_quadratic_inside_and_linear_outside() {
        assert_eq!(huber(1.0, 2.0), (1.0, 1.0));
        assert_eq!(huber(16.0, 2.0), (0.5, 12.0));
    }

    /// The symmetric, sparse Hessian updates give the same bits as the nalgebra expressions they
    /// replace (`h += j^T j w` and `h += jd jd^T w`), over random Jacobians of mixed signs and
    /// magnitudes, accumulated over many terms as in [`Problem::accumulate`].
    #[test]
    fn hessian_updates_are_bit_identical_to_the_dense_products() {
        let mut rng = crate::test_rng::TestRng::new(7);
        let mut val = |scale: f64| (rng.uniform(-1.0, 1.0) * scale) as f32;
        let (mut dense, mut sparse) = (Matrix6::<f32>::zeros(), Matrix6::<f32>::zeros());
        for i in 0..500 {
            let scale = [1.0e-3, 1.0, 400.0][i % 3];
            let j = Matrix2x6::from_fn(|_, _| val(scale));
            let w = val(1.0).abs();
            dense += j.transpose() * j * w;
            add_jtj_upper(&mut sparse, &j, w);
            let k = val(scale);
            let jd = Vector6::new(0.0, 0.0, k, k * val(2.0), -(k * val(2.0)), 0.0);
            dense += jd * jd.transpose() * w;
            add_depth_upper(&mut sparse, &jd, w);
        }
        mirror_upper(&mut sparse);
        for (d, s) in dense.iter().zip(sparse.iter()) {
            assert_eq!(d.to_bits(), s.to_bits(), "{d} vs {s}");
        }
    }
}
