//! Tunables of pose estimation.

use crate::config::SensorModel;

/// Tunables of [`refine_pose`](super::refine_pose), [`ransac_pose`](super::ransac_pose) and
/// [`track_pose`](super::track_pose), with their units.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseParams {
    /// The sensor's measurement model: the pixel sigma, the Huber threshold and the tracker's
    /// depth noise (`depth_noise_coeff_per_m`) whiten the residuals.
    pub sensor: SensorModel,
    /// Inlier gate on the whitened squared reprojection error (chi-square, 2 DOF): 5.991 is the
    /// 95% quantile.
    pub chi2_reprojection: f32,
    /// Inlier gate on the whitened squared inverse-depth error (chi-square, 1 DOF): 3.841 is the
    /// 95% quantile. An inlier passes both gates (the depth one only when depth is known).
    pub chi2_depth: f32,
    /// Levenberg-Marquardt solves per refinement round.
    pub max_iterations: u32,
    /// Refinement rounds: after each, inliers are re-classified by the chi-square gates and the
    /// next round optimizes over the inliers only (outliers get weight zero).
    pub refine_rounds: u32,
    /// Convergence: a step whose translation is below this (metres) and rotation below
    /// [`Self::min_step_rotation_rad`] ends the round.
    pub min_step_translation_m: f32,
    /// Convergence: rotation part of a step, radians.
    pub min_step_rotation_rad: f32,
    /// RANSAC hypotheses at most.
    pub ransac_iterations: u32,
    /// RANSAC stops early once an all-inlier minimal set has been drawn with this probability,
    /// given the best inlier ratio so far (in `(0, 1)`).
    pub ransac_confidence: f32,
    /// Fewest inliers of a valid pose.
    pub min_inliers: u32,
    /// [`track_pose`](super::track_pose) falls back to RANSAC when refining the prediction keeps
    /// fewer than this fraction of the correspondences as inliers.
    pub min_inlier_ratio: f32,
    /// A valid pose has every translation standard deviation (from the inverse Hessian over the
    /// inliers) at most this, metres.
    pub max_sigma_translation_m: f32,
    /// A valid pose has every rotation standard deviation at most this, radians.
    pub max_sigma_rotation_rad: f32,
}

impl PoseParams {
    /// The defaults, usable in `const` contexts (what [`Default`] gives).
    pub const DEFAULT: Self = Self {
        sensor: SensorModel::DEFAULT,
        chi2_reprojection: 5.991,
        chi2_depth: 3.841,
        max_iterations: 10,
        refine_rounds: 3,
        min_step_translation_m: 1.0e-5,
        min_step_rotation_rad: 1.0e-5,
        ransac_iterations: 128,
        ransac_confidence: 0.999,
        min_inliers: 15,
        min_inlier_ratio: 0.5,
        max_sigma_translation_m: 0.05,
        max_sigma_rotation_rad: 0.035,
    };
}

impl Default for PoseParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl PoseParams {
    /// Whether every value is in range: sigmas, thresholds and limits finite and positive,
    /// at least one iteration and round, confidence and ratio in `[0, 1)` (confidence > 0).
    pub fn is_valid(&self) -> bool {
        let pos = |x: f32| x.is_finite() && x > 0.0;
        self.sensor.is_valid()
            && pos(self.chi2_reprojection)
            && pos(self.chi2_depth)
            && pos(self.min_step_translation_m)
            && pos(self.min_step_rotation_rad)
            && pos(self.max_sigma_translation_m)
            && pos(self.max_sigma_rotation_rad)
            && self.max_iterations > 0
            && self.refine_rounds > 0
            && self.ransac_confidence > 0.0
            && self.ransac_confidence < 1.0
            && self.min_inlier_ratio >= 0.0
            && self.min_inlier_ratio < 1.0
    }
}
