//! Tunables of bundle adjustment.

use crate::config::SensorModel;

/// Tunables of [`BundleAdjuster`](super::BundleAdjuster), with their units.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BaParams {
    /// The sensor's measurement model, the one tracking takes: the pixel sigma, the Huber
    /// threshold and the depth noise whiten the residuals (the back end gives its own depth
    /// noise: `BackendParams::with_sensor`).
    pub sensor: SensorModel,
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
    /// The defaults, usable in `const` contexts (what [`Default`] gives), with the default
    /// [`SensorModel`].
    pub const DEFAULT: Self = Self {
        sensor: SensorModel::DEFAULT,
        max_iterations: 10,
        pcg_max_iterations: 25,
        pcg_relative_tolerance: 5.0e-2,
        function_tolerance: 1.0e-5,
        min_step_translation_m: 1.0e-5,
        min_step_rotation_rad: 1.0e-5,
        min_step_point_m: 1.0e-5,
        lambda_init: 1.0e-4,
    };

    /// Whether every value is in range: sigmas, thresholds and tolerances finite and positive
    /// (the relative PCG tolerance below 1), at least one iteration of each kind, the initial
    /// damping finite and positive.
    pub fn is_valid(&self) -> bool {
        let pos = |x: f32| x.is_finite() && x > 0.0;
        self.sensor.is_valid()
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
    fn defaults_are_valid_and_share_tracking_s_sensor_model() {
        assert!(BaParams::DEFAULT.is_valid());
        assert_eq!(BaParams::DEFAULT.sensor, crate::pose::PoseParams::DEFAULT.sensor);
        let blind = SensorModel { pixel_sigma_px: f32::NAN, ..SensorModel::DEFAULT };
        for bad in [
            BaParams { sensor: blind, ..BaParams::DEFAULT },
            BaParams { pcg_relative_tolerance: 1.0, ..BaParams::DEFAULT },
            BaParams { max_iterations: 0, ..BaParams::DEFAULT },
            BaParams { lambda_init: 0.0, ..BaParams::DEFAULT },
        ] {
            assert!(!bad.is_valid());
        }
    }
}
