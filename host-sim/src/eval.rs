//! Trajectory accuracy: ATE and RPE, computed as evo 1.38.1 computes them.
//!
//! [`evaluate`] takes a ground truth and an estimate (both camera to world, metres, seconds) and
//! gives an [`EvalReport`]:
//!
//! - **association** ([`associate`]): evo's `associate_trajectories` with `--t_max_diff max_dt_s`
//!   (nearest timestamp of the longer trajectory for each pose of the shorter one);
//! - **ATE** = `evo_ape tum GT EST -a --t_max_diff max_dt_s`: the estimate's positions are aligned
//!   onto the ground truth's by a rigid SE(3) Umeyama fit without scale
//!   ([`ferroslam_core::geometry::align_rigid`], f64), then the error of each match is the distance
//!   between aligned estimate and ground-truth positions (m);
//! - **RPE per frame** = `evo_rpe tum GT EST --delta 1 --delta_unit f --t_max_diff max_dt_s` with
//!   `--pose_relation trans_part` (m) and `--pose_relation angle_deg` (degrees), see [`rpe::per_frame`];
//! - **RPE per second**: TUM's `evaluate_rpe.py --fixed_delta --delta 1 --delta_unit s` applied to the
//!   matched poses, see [`rpe::per_delta_seconds`] (m/s and deg/s, i.e. error over a ~1 s interval).
//!
//! Statistics follow evo ([`ErrorStats`]). `tests/tests/eval_evo.rs` checks every number against
//! values evo produced on real trajectories (`tests/fixtures/evo/`).

pub mod associate;
pub mod rpe;
pub mod stats;

use std::fmt;
use std::path::Path;

use nalgebra::{Isometry3, Point3};
use serde::Serialize;

pub use self::associate::MatchIndices;
pub use self::rpe::RpeSample;
pub use self::stats::ErrorStats;
use crate::trajectory::{StampedPose, Trajectory, TrajectoryError};

/// The association window evo users pass for TUM-like data (`--t_max_diff 0.02`), in seconds.
pub const DEFAULT_MAX_DT_S: f64 = 0.02;

/// Fewest matched poses the SE(3) alignment accepts (three non-collinear positions fix a rotation).
pub const MIN_MATCHES_FOR_ALIGNMENT: usize = 3;

/// The interval of the per-second RPE, in seconds.
pub const RPE_DELTA_S: f64 = 1.0;

/// Why an evaluation could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EvalError {
    /// A trajectory file could not be read.
    #[error("cannot read trajectory: {source}")]
    Read {
        /// The reader's error (names file and line).
        #[from]
        source: TrajectoryError,
    },
    /// The association window is negative or not finite.
    #[error("invalid max time difference {max_dt_s} s (must be finite and >= 0)")]
    InvalidMaxDt {
        /// The window given, in seconds.
        max_dt_s: f64,
    },
    /// A trajectory has no poses.
    #[error("the {which} trajectory has no poses")]
    Empty {
        /// `"ground-truth"` or `"estimated"`.
        which: &'static str,
    },
    /// A trajectory's timestamps are not finite and strictly increasing.
    #[error("the {which} trajectory's timestamps are not strictly increasing at pose {index}")]
    NotIncreasing {
        /// `"ground-truth"` or `"estimated"`.
        which: &'static str,
        /// 0-based index of the first offending pose.
        index: usize,
    },
    /// No timestamps could be associated.
    #[error(
        "no matching timestamps between ground truth ({gt_poses} poses) and estimate ({est_poses} \
         poses) with max time difference {max_dt_s} s"
    )]
    NoMatches {
        /// Ground-truth pose count.
        gt_poses: usize,
        /// Estimated pose count.
        est_poses: usize,
        /// The association window, in seconds.
        max_dt_s: f64,
    },
    /// Too few matches for the alignment.
    #[error("only {matched} matched poses; the alignment needs at least {required}")]
    TooFewMatches {
        /// Matched pose count.
        matched: usize,
        /// [`MIN_MATCHES_FOR_ALIGNMENT`].
        required: usize,
    },
    /// The alignment failed (e.g. all matched positions on a line).
    #[error("trajectory alignment failed: {source}")]
    Alignment {
        /// The core's error.
        source: ferroslam_core::geometry::AlignError,
    },
}

/// RPE statistics of one kind (per frame or per second).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RpeStats {
    /// Number of pose pairs compared.
    pub pairs: usize,
    /// Translation error: metres per pair (per frame) or metres per second (per second).
    pub trans: ErrorStats,
    /// Rotation error: degrees per pair (per frame) or degrees per second (per second).
    pub rot: ErrorStats,
}

impl RpeStats {
    fn from_samples(samples: &[RpeSample]) -> Option<Self> {
        let trans: Vec<f64> = samples.iter().map(|s| s.trans_m).collect();
        let rot: Vec<f64> = samples.iter().map(|s| s.rot_deg).collect();
        Some(Self {
            pairs: samples.len(),
            trans: ErrorStats::from_errors(&trans)?,
            rot: ErrorStats::from_errors(&rot)?,
        })
    }
}

/// The rigid transform that maps the estimate's world frame onto the ground truth's (`T_gt_est`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AlignmentSummary {
    /// Translation in metres.
    pub translation_m: [f64; 3],
    /// Rotation as a unit quaternion `(qx, qy, qz, qw)`.
    pub quaternion_xyzw: [f64; 4],
}

/// One matched pose with its absolute error, for plots.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchedPose {
    /// The ground-truth pose (camera to world, ground-truth world).
    pub gt: StampedPose,
    /// The estimated pose as read (camera to world, estimate's world).
    pub est: StampedPose,
    /// The estimated pose mapped into the ground-truth world by the alignment.
    pub est_aligned_t_wc: Isometry3<f64>,
    /// Distance between the aligned estimate's and the ground truth's camera centres, in metres.
    pub ate_m: f64,
}

/// The result of [`evaluate`]. The summary serializes to JSON; [`EvalReport::matches`] and the RPE
/// samples (one entry per pose) are skipped so `--json` output stays small.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EvalReport {
    /// Poses in the ground truth.
    pub gt_poses: usize,
    /// Poses in the estimate.
    pub est_poses: usize,
    /// Matched pose pairs (a pose of the longer trajectory may appear in more than one).
    pub matched_poses: usize,
    /// The association window used, in seconds.
    pub max_dt_s: f64,
    /// Absolute trajectory error after SE(3) alignment, in metres.
    pub ate: ErrorStats,
    /// RPE between consecutive matches (m and degrees).
    pub rpe_per_frame: RpeStats,
    /// RPE over ~1 s (m/s and deg/s); `None` when no pair ~1 s apart exists.
    pub rpe_per_second: Option<RpeStats>,
    /// `T_gt_est`, the alignment applied to the estimate.
    pub alignment: AlignmentSummary,
    /// Every match, in association order, with its aligned estimate and error.
    #[serde(skip)]
    pub matches: Vec<MatchedPose>,
    /// Per-pair errors of the per-frame RPE.
    #[serde(skip)]
    pub rpe_per_frame_samples: Vec<RpeSample>,
    /// Per-pair errors of the per-second RPE.
    #[serde(skip)]
    pub rpe_per_second_samples: Vec<RpeSample>,
}

/// Reads two TUM files and evaluates the estimate against the ground truth (see [`evaluate`]).
pub fn run_eval(gt_path: &Path, est_path: &Path, max_dt_s: f64) -> Result<EvalReport, EvalError> {
    let gt = Trajectory::read_tum(gt_path)?;
    let est = Trajectory::read_tum(est_path)?;
    evaluate(&gt, &est, max_dt_s)
}

fn check_input(traj: &Trajectory, which: &'static str) -> Result<(), EvalError> {
    if traj.is_empty() {
        return Err(EvalError::Empty { which });
    }
    traj.check_increasing().map_err(|index| EvalError::NotIncreasing { which, index })
}

/// Evaluates `est` against `gt` (both camera to world, metres, seconds, strictly increasing
/// timestamps), associating timestamps within `max_dt_s` seconds; see the [module docs](self).
pub fn evaluate(gt: &Trajectory, est: &Trajectory, max_dt_s: f64) -> Result<EvalReport, EvalError> {
    if !max_dt_s.is_finite() || max_dt_s < 0.0 {
        return Err(EvalError::InvalidMaxDt { max_dt_s });
    }
    check_input(gt, "ground-truth")?;
    check_input(est, "estimated")?;
    let pairs: Vec<(StampedPose, StampedPose)> =
        associate::associate(&gt.timestamps_s(), &est.timestamps_s(), max_dt_s)
            .into_iter()
            .filter_map(|m| Some((*gt.poses.get(m.gt)?, *est.poses.get(m.est)?)))
            .collect();
    if pairs.is_empty() {
        return Err(EvalError::NoMatches { gt_poses: gt.len(), est_poses: est.len(), max_dt_s });
    }
    if pairs.len() < MIN_MATCHES_FOR_ALIGNMENT {
        return Err(EvalError::TooFewMatches {
            matched: pairs.len(),
            required: MIN_MATCHES_FOR_ALIGNMENT,
        });
    }

    let est_points: Vec<Point3<f64>> = pairs.iter().map(|(_, e)| position(&e.t_wc)).collect();
    let gt_points: Vec<Point3<f64>> = pairs.iter().map(|(g, _)| position(&g.t_wc)).collect();
    let t_gt_est = ferroslam_core::geometry::align_rigid(&est_points, &gt_points)
        .map_err(|source| EvalError::Alignment { source })?;

    let matches: Vec<MatchedPose> = pairs
        .iter()
        .map(|&(gt, est)| {
            let est_aligned_t_wc = t_gt_est * est.t_wc;
            let ate_m = (est_aligned_t_wc.translation.vector - gt.t_wc.translation.vector).norm();
            MatchedPose { gt, est, est_aligned_t_wc, ate_m }
        })
        .collect();
    let ate_errors: Vec<f64> = matches.iter().map(|m| m.ate_m).collect();

    let gt_poses: Vec<Isometry3<f64>> = pairs.iter().map(|(g, _)| g.t_wc).collect();
    let est_poses: Vec<Isometry3<f64>> = pairs.iter().map(|(_, e)| e.t_wc).collect();
    let stamps: Vec<f64> = pairs.iter().map(|(_, e)| e.timestamp_s).collect();
    let per_frame = rpe::per_frame(&gt_poses, &est_poses, &stamps);
    let per_second = rpe::per_delta_seconds(&gt_poses, &est_poses, &stamps, RPE_DELTA_S);

    let matched = matches.len();
    let too_few = || EvalError::TooFewMatches { matched, required: MIN_MATCHES_FOR_ALIGNMENT };
    Ok(EvalReport {
        gt_poses: gt.len(),
        est_poses: est.len(),
        matched_poses: matched,
        max_dt_s,
        ate: ErrorStats::from_errors(&ate_errors).ok_or_else(too_few)?,
        rpe_per_frame: RpeStats::from_samples(&per_frame).ok_or_else(too_few)?,
        rpe_per_second: RpeStats::from_samples(&per_second),
        alignment: summarize(&t_gt_est),
        matches,
        rpe_per_frame_samples: per_frame,
        rpe_per_second_samples: per_second,
    })
}

fn position(t_wc: &Isometry3<f64>) -> Point3<f64> {
    Point3::from(t_wc.translation.vector)
}

fn summarize(t: &Isometry3<f64>) -> AlignmentSummary {
    let v = t.translation.vector;
    let q = t.rotation.quaternion();
    AlignmentSummary { translation_m: [v.x, v.y, v.z], quaternion_xyzw: [q.i, q.j, q.k, q.w] }
}

impl EvalReport {
    /// Estimate timestamps (s) and ATE (m) of every match, for an error-over-time plot.
    pub fn ate_over_time(&self) -> (Vec<f64>, Vec<f64>) {
        self.matches.iter().map(|m| (m.est.timestamp_s, m.ate_m)).unzip()
    }
}

fn stats_row(f: &mut fmt::Formatter<'_>, label: &str, s: &ErrorStats) -> fmt::Result {
    writeln!(
        f,
        "{label:<22}{:>11.6}{:>11.6}{:>11.6}{:>11.6}{:>11.6}{:>11.6}",
        s.rmse, s.mean, s.median, s.std, s.min, s.max
    )
}

impl fmt::Display for EvalReport {
    /// A human-readable table (evo-compatible ATE with SE(3) alignment, RPE per frame and per second).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "matched poses: {} (ground truth {}, estimate {}, max |dt| {} s)",
            self.matched_poses, self.gt_poses, self.est_poses, self.max_dt_s
        )?;
        writeln!(
            f,
            "{:<22}{:>11}{:>11}{:>11}{:>11}{:>11}{:>11}",
            "", "rmse", "mean", "median", "std", "min", "max"
        )?;
        stats_row(f, "ATE [m]", &self.ate)?;
        stats_row(f, "RPE/frame trans [m]", &self.rpe_per_frame.trans)?;
        stats_row(f, "RPE/frame rot [deg]", &self.rpe_per_frame.rot)?;
        match &self.rpe_per_second {
            Some(s) => {
                stats_row(f, "RPE/s trans [m/s]", &s.trans)?;
                stats_row(f, "RPE/s rot [deg/s]", &s.rot)?;
            }
            None => writeln!(f, "RPE/s: no pose pairs ~{RPE_DELTA_S} s apart")?,
        }
        writeln!(
            f,
            "ATE: SE(3) Umeyama alignment without scale (as evo_ape -a); RPE/frame: {} pairs; RPE/s: {} pairs",
            self.rpe_per_frame.pairs,
            self.rpe_per_second.map_or(0, |s| s.pairs)
        )
    }
}

#[cfg(test)]
mod tests;
