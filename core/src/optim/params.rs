//! Tunables of bundle adjustment.

use crate::tracking::PoseParams;

/// Tunables of [`BundleAdjuster`](super::BundleAdjuster), with their units.
///
/// The first three are the measurement model and should equal tracking's
/// ([`Self::from_pose_params`]) so that the front end and the back end weigh the same data alike.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BaParams {
    /// Standard deviation of an observed pixel position, pixels. Residuals are divided by it.
    pub pixel_sigma_px: f32,
    /// Depth noise coefficient `c` of `sigma_z = c z^2`, per metre: the standard deviation of the
    /// inverse-depth residual, in 1/m (see [`PoseParams::depth_noise_coeff_per_m`]).
    pub depth_noise_coeff_per_m: f32,
    /// Huber threshold on the reprojection error, pixels; the depth term uses the same threshold
    /// in standard deviations (`huber_delta_px / pixel_sigma_px`), as tracking does.
    pub huber_delta_px: f32,
    /// Levenberg-Marquardt solves at most (accepted or rejected).
    pub max_iterations: u32,
    /// Conjugate-gradient iterations per solve at most.
    pub pcg_max_iterations: u32,
    /// A solve stops once the preconditioned residual norm `sqrt(r^T M^-1 r)` falls below this
    /// fraction of its initial value (an inexact Newton step; LM iterates on).
    pub pcg_relative_tolerance: f32,
    /// Converged when an accepted step lowers the cost by less than this fraction.
    pub function_tolerance: f32,
    /// Converged when, in an accepted step, every pose moves less than this (metres) and
    /// [`Self::min_step_rotation_rad`], and every point less than [`Self::min_step_point_m`].
    pub min_step_translation_m: f32,
    /// Convergence: rotation part of a pose step, radians.
    pub min_step_rotation_rad: f32,
    /// Convergence: length of a point step, metres.
    pub min_step_point_m: f32,
    /// Initial Levenberg-Marquardt damping (multiplies the Hessian's diagonal, Marquardt
    /// scaling); divided by 10 after an accepted step, multiplied by 10 after a rejected one,
    /// within `[1e-7, 1e6]` (beyond the ceiling the solve ends as stalled).
    pub lambda_init: f32,
}

impl BaParams {
    /// The defaults, usable in `const` contexts (what [`Default`] gives). The model fields are
    /// [`PoseParams::DEFAULT`]'s.
    pub const DEFAULT: Self = Self {
        pixel_sigma_px: PoseParams::DEFAULT.pixel_sigma_px,
        depth_noise_coeff_per_m: PoseParams::DEFAULT.depth_noise_coeff_per_m,
        huber_delta_px: PoseParams::DEFAULT.huber_delta_px,
        max_iterations: 10,
        pcg_max_iterations: 25,
        pcg_relative_tolerance: 5.0e-2,
        function_tolerance: 1.0e-5,
        min_step_translation_m: 1.0e-5,
        min_step_rotation_rad: 1.0e-5,
        min_step_point_m: 1.0e-5,
        lambda_init: 1.0e-4,
    };

    /// [`Self::DEFAULT`] with tracking's measurement model (pixel sigma, depth noise, Huber).
    pub const fn from_pose_params(pose: &PoseParams) -> Self {
        Self {
            pixel_sigma_px: pose.pixel_sigma_px,
            depth_noise_coeff_per_m: pose.depth_noise_coeff_per_m,
            huber_delta_px: pose.huber_delta_px,
            ..Self::DEFAULT
        }
    }

    /// Whether every value is in range: sigmas, thresholds and tolerances finite and positive
    /// (the relative PCG tolerance below 1), at least one iteration of each kind, the initial
    /// damping finite and positive.
    pub fn is_valid(&self) -> bool {
        let pos = |x: f32| x.is_finite() && x > 0.0;
        pos(self.pixel_sigma_px)
            && pos(self.depth_noise_coeff_per_m)
            && pos(self.huber_delta_px)
            && pos(self.pcg_relative_tolerance)
            && self.pcg_relative_tolerance < 1.0
            && pos(self.function_tolerance)
            && pos(self.min_step_translation_m)
            && pos(self.min_step_rotation_rad)
            && pos(self.min_step_point_m)
            && pos(self.lambda_init)
            && self.max_iterations > 0
            && self.pcg_max_iterations > 0
    }
}

impl Default for BaParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_follow_tracking() {
        assert!(BaParams::DEFAULT.is_valid());
        let pose = PoseParams { pixel_sigma_px: 0.7, ..PoseParams::DEFAULT };
        let p = BaParams::from_pose_params(&pose);
        assert_eq!(p.pixel_sigma_px, 0.7);
        assert_eq!(p.huber_delta_px, pose.huber_delta_px);
        for bad in [
            BaParams { pixel_sigma_px: f32::NAN, ..BaParams::DEFAULT },
            BaParams { pcg_relative_tolerance: 1.0, ..BaParams::DEFAULT },
            BaParams { max_iterations: 0, ..BaParams::DEFAULT },
            BaParams { lambda_init: 0.0, ..BaParams::DEFAULT },
        ] {
            assert!(!bad.is_valid());
        }
    }
}
