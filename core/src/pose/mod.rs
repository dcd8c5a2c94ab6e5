//! The reusable pose estimator: robust SE(3) pose estimation from 2D-3D (and depth)
//! correspondences, RANSAC on minimal sets, the constant-velocity motion model, and the rotation
//! re-estimated on small blurry images. It knows nothing of maps or frames; the front end
//! ([`crate::tracking`]) feeds it.
//!
//! # Pipeline
//!
//! 1. [`MotionModel::predict`] extrapolates `t_cw` from the last two tracked poses.
//! 2. [`refine_pose`] polishes a prediction against [`Correspondence`]s (map point `p_w`,
//!    observed pixel, optional measured depth) with robust Levenberg-Marquardt on SE(3).
//! 3. When the prediction is poor, [`ransac_pose`] hypothesizes poses from minimal sets of three
//!    depth-carrying correspondences (3D-3D, [`align_rigid`](crate::geometry::align_rigid)),
//!    scores them by reprojection inliers and refines the best. [`track_pose`] chains 2 and 3.
//!
//! # Model
//!
//! Each correspondence contributes a whitened reprojection residual
//! `(project(t_cw p_w) - uv) / pixel_sigma_px` (2 DOF) and, when its depth is known, a whitened
//! inverse-depth residual `(1/z_pred - 1/z_meas) / depth_noise_coeff_per_m` (1 DOF). Depth
//! sensors of the Kinect class have `sigma_z = c z^2` (Khoshelham and Elberink 2012, `c` about
//! 1.4e-3 per metre); since `d(1/z) = dz / z^2`, the inverse depth has the *constant* standard
//! deviation `c`, which is why the residual is in inverse depth. Each block gets its own Huber
//! weight. Pose updates are left perturbations `t_cw <- exp(xi) t_cw`, `xi = [rho; phi]`,
//! matching [`PinholeCamera::project_world_with_jacobians`](crate::geometry::PinholeCamera).
//!
//! # Memory
//!
//! Nothing is stored per correspondence while optimizing: every iteration recomputes residuals
//! from the caller's slice. Inlier flags are an [`InlierMask`] bitset (64 bytes for
//! [`MAX_CORRESPONDENCES`] = 512). Peak stack of [`track_pose`] is estimated (from type sizes,
//! not measured on the target) at under 2 KB: a few 6x6 f32 matrices (144 bytes each), three
//! masks and two [`PoseEstimate`]s (120 bytes each).
//!
//! # Determinism
//!
//! f32 `+ - * /` only (no `mul_add`), square roots through `ferroslam_fpu` (correctly rounded,
//! the same bits everywhere), logarithms through `libm`, exp/log of SE(3) through
//! [`geometry`](crate::geometry), correspondences visited in slice order, random numbers from a
//! caller-seeded [`TrackingRng`].

use core::fmt;

use nalgebra::{Point2, Point3};

use crate::config::capacity;

mod inlier_mask;
mod motion;
mod params;
mod ransac;
mod refine;
pub mod small_image_rotation;

#[cfg(test)]
mod tests;

pub use inlier_mask::InlierMask;
pub use motion::{MotionModel, predict_constant_velocity};
pub use params::PoseParams;
pub use ransac::{TrackingRng, ransac_pose, track_pose};
pub use refine::{PoseEstimate, refine_pose};

/// Most correspondences one pose estimate takes: one per feature of a frame.
pub const MAX_CORRESPONDENCES: usize = capacity::MAX_FEATURES_PER_FRAME;

/// A map point matched to an observation in the current frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Correspondence {
    /// The landmark in the world (reference) frame, metres.
    pub p_w: Point3<f32>,
    /// Where it is observed in the current image, pixels (pixel-centre convention).
    pub uv: Point2<f32>,
    /// The current frame's depth (camera z, metres) at `uv`, if measured. Must be finite and
    /// positive when present: map a sensor's 0 (no reading) to `None`.
    pub depth_m: Option<f32>,
}

impl Correspondence {
    /// Whether every coordinate is finite and the depth, if any, finite and positive.
    pub fn is_valid(&self) -> bool {
        let p = &self.p_w;
        let depth_ok = self.depth_m.is_none_or(|d| d.is_finite() && d > 0.0);
        p.x.is_finite()
            && p.y.is_finite()
            && p.z.is_finite()
            && self.uv.x.is_finite()
            && self.uv.y.is_finite()
            && depth_ok
    }
}

/// Why no pose (or prediction) was produced.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum PoseError {
    /// Fewer usable correspondences than the estimate needs.
    TooFewCorrespondences {
        /// Usable correspondences (in front of the camera, or with depth for RANSAC).
        count: usize,
        /// Minimum needed.
        required: usize,
    },
    /// More correspondences than [`MAX_CORRESPONDENCES`].
    TooManyCorrespondences {
        /// Number given.
        count: usize,
    },
    /// A correspondence holds a NaN or infinite coordinate, or a depth that is not positive.
    InvalidCorrespondence {
        /// Index of the first bad correspondence.
        index: usize,
    },
    /// A [`PoseParams`] value is out of range (see [`PoseParams::is_valid`]).
    InvalidParams,
    /// The pose is not determined: the normal equations are singular or the pose uncertainty
    /// exceeds the limits of [`PoseParams`] (points coincident, collinear or too few).
    Degenerate,
    /// The refined pose explains too few correspondences.
    TooFewInliers {
        /// Inliers at the final pose.
        inliers: usize,
        /// [`PoseParams::min_inliers`].
        required: usize,
    },
    /// RANSAC found no hypothesis with enough inliers.
    NoConsensus {
        /// Inliers of the best hypothesis.
        best_inliers: usize,
    },
    /// The motion model's timestamps do not increase strictly, or are not finite.
    TimestampsNotIncreasing {
        /// The earlier timestamp, seconds.
        earlier_s: f64,
        /// The later timestamp, seconds.
        later_s: f64,
    },
}

impl fmt::Display for PoseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooFewCorrespondences { count, required } => {
                write!(f, "{count} usable correspondences, need {required}")
            }
            Self::TooManyCorrespondences { count } => {
                write!(f, "{count} correspondences exceed the capacity {MAX_CORRESPONDENCES}")
            }
            Self::InvalidCorrespondence { index } => {
                write!(f, "correspondence {index} is not finite or has a non-positive depth")
            }
            Self::InvalidParams => write!(f, "pose estimation parameters out of range"),
            Self::Degenerate => write!(f, "the pose is not determined by the correspondences"),
            Self::TooFewInliers { inliers, required } => {
                write!(f, "{inliers} inliers, need {required}")
            }
            Self::NoConsensus { best_inliers } => {
                write!(f, "no RANSAC consensus: best hypothesis has {best_inliers} inliers")
            }
            Self::TimestampsNotIncreasing { earlier_s, later_s } => {
                write!(f, "timestamps must increase: {earlier_s} s then {later_s} s")
            }
        }
    }
}

impl core::error::Error for PoseError {}

/// Checks the slice length and every correspondence.
fn validate_input(correspondences: &[Correspondence]) -> Result<(), PoseError> {
    if correspondences.len() > MAX_CORRESPONDENCES {
        return Err(PoseError::TooManyCorrespondences { count: correspondences.len() });
    }
    match correspondences.iter().position(|c| !c.is_valid()) {
        Some(index) => Err(PoseError::InvalidCorrespondence { index }),
        None => Ok(()),
    }
}
