//! The problem a [`BundleAdjuster`](super::BundleAdjuster) holds: rigs, cameras, points and
//! observations in fixed arrays (`variables.rs` fills it and reads the results).

use super::BaError;
use super::linalg::{PoseMatrix, StoredPose, Vec3};
use super::model::StoredObservation;
use crate::geometry::Pose;

/// The variables and data, in insertion order. Observations are stored grouped by point (the
/// observations of point `l` are `point_end[l - 1]..point_end[l]`), which is what the Schur
/// elimination visits.
#[derive(Debug, Clone)]
pub(super) struct Problem<const R: usize, const C: usize, const P: usize, const O: usize> {
    /// `T_s`: the rig's world-to-rig pose (for a keyframe of local BA, its `t_cw`).
    pub(super) rig_pose: [StoredPose; R],
    pub(super) rig_fixed: [bool; R],
    pub(super) n_rigs: u16,
    /// `t_cs`: rig-to-camera offset of each camera; its pose is `t_cw = t_cs T_s`.
    pub(super) cam_offset: [StoredPose; C],
    pub(super) cam_rig: [u16; C],
    pub(super) n_cams: u16,
    /// `p_w`, metres.
    pub(super) point: [Vec3; P],
    pub(super) point_fixed: [bool; P],
    /// One past the point's last observation.
    pub(super) point_end: [u16; P],
    pub(super) n_points: u16,
    pub(super) obs: [StoredObservation; O],
    pub(super) n_obs: u16,
}

impl<const R: usize, const C: usize, const P: usize, const O: usize> Problem<R, C, P, O> {
    pub(super) const fn new() -> Self {
        Self {
            rig_pose: [StoredPose::IDENTITY; R],
            rig_fixed: [false; R],
            n_rigs: 0,
            cam_offset: [StoredPose::IDENTITY; C],
            cam_rig: [0; C],
            n_cams: 0,
            point: [[0.0; 3]; P],
            point_fixed: [false; P],
            point_end: [0; P],
            n_points: 0,
            obs: [StoredObservation::EMPTY; O],
            n_obs: 0,
        }
    }

    /// The observation indices of point `l`.
    pub(super) fn obs_range(&self, l: usize) -> (usize, usize) {
        let start = match l.checked_sub(1) {
            Some(prev) => self.point_end.get(prev).copied().unwrap_or(0),
            None => 0,
        };
        (usize::from(start), usize::from(self.point_end.get(l).copied().unwrap_or(0)))
    }

    /// The rig of camera `c`, as an index.
    pub(super) fn rig_of(&self, c: usize) -> usize {
        usize::from(self.cam_rig.get(c).copied().unwrap_or(0))
    }

    /// `t_cw = t_cs T_s` of camera `c` with its rig at `t_s`, as a matrix. An identity offset is
    /// skipped, so a keyframe's camera is its rig's pose bit for bit.
    pub(super) fn camera_matrix(&self, c: usize, t_s: &StoredPose) -> PoseMatrix {
        match self.cam_offset.get(c) {
            Some(offset) if !offset.is_identity() => {
                PoseMatrix::from_pose(&(offset.to_pose() * t_s.to_pose()))
            }
            _ => PoseMatrix::from_pose(&t_s.to_pose()),
        }
    }

    /// The offset of camera `c` as a matrix, `None` when it is the identity.
    pub(super) fn offset_matrix(&self, c: usize) -> Option<PoseMatrix> {
        let offset = self.cam_offset.get(c)?;
        (!offset.is_identity()).then(|| PoseMatrix::from_pose(&offset.to_pose()))
    }
}

/// Checks that `pose` is finite with a unit quaternion (to 1e-3), and stores it.
pub(super) fn stored_pose(pose: &Pose) -> Result<StoredPose, BaError> {
    let stored = StoredPose::from_pose(pose);
    let norm = pose.rotation.coords.norm();
    let unit = (norm - 1.0).abs() <= 1e-3;
    if !stored.is_finite() || !unit {
        return Err(BaError::InvalidPose);
    }
    Ok(stored)
}
