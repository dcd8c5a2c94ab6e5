//! Filling the adjuster and reading it back: rigs, cameras, points and observations added before
//! a solve, their estimates and residuals after it.

use nalgebra::{Point2, Point3};

use super::model::StoredObservation;
use super::problem::stored_pose;
use super::solver::BundleAdjuster;
use super::solver_state::Phase;
use super::{BaError, CameraId, ObservationId, PointId, RigId, VariableKind};
use crate::geometry::Pose;

/// The residuals of one observation at the current estimate (see
/// [`BundleAdjuster::observation_residual`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ObservationResidual {
    /// Squared whitened reprojection error (chi-square, 2 DOF): pixels^2 over `pixel_sigma_px^2`.
    pub chi2_reprojection: f32,
    /// Squared whitened inverse-depth error (chi-square, 1 DOF), when a depth was measured.
    pub chi2_depth: Option<f32>,
}

impl<const R: usize, const C: usize, const P: usize, const O: usize> BundleAdjuster<R, C, P, O> {
    /// Refuses input once a solve has started (until [`Self::clear`]).
    fn check_idle(&self) -> Result<(), BaError> {
        if self.state.phase == Phase::Idle { Ok(()) } else { Err(BaError::Busy) }
    }

    /// Adds a rig: a pose variable `t_sw` (world to rig) that one or more cameras hang from
    /// (segmented global BA: a segment's pose). A `fixed` rig is never changed.
    ///
    /// # Errors
    /// [`BaError::Busy`] during a solve, [`BaError::InvalidPose`] when not finite or the
    /// rotation is not unit, [`BaError::Full`] at capacity `R`.
    pub fn add_rig(&mut self, t_sw: &Pose, fixed: bool) -> Result<RigId, BaError> {
        self.check_idle()?;
        let stored = stored_pose(t_sw)?;
        let p = &mut self.problem;
        let i = usize::from(p.n_rigs);
        let (Some(slot), Some(flag)) = (p.rig_pose.get_mut(i), p.rig_fixed.get_mut(i)) else {
            return Err(BaError::Full { kind: VariableKind::Rig, capacity: R });
        };
        (*slot, *flag) = (stored, fixed);
        p.n_rigs += 1;
        Ok(RigId(i as u16))
    }

    /// Adds a camera (a keyframe) on `rig` with the fixed rig-to-camera offset `t_cs`: its pose
    /// is `t_cw = t_cs t_sw`.
    ///
    /// # Errors
    /// [`BaError::Busy`], [`BaError::UnknownRig`], [`BaError::InvalidPose`], [`BaError::Full`].
    pub fn add_camera(&mut self, rig: RigId, t_cs: &Pose) -> Result<CameraId, BaError> {
        self.check_idle()?;
        if rig.0 >= self.problem.n_rigs {
            return Err(BaError::UnknownRig { index: rig.index() });
        }
        let stored = stored_pose(t_cs)?;
        let p = &mut self.problem;
        let i = usize::from(p.n_cams);
        let (Some(slot), Some(r)) = (p.cam_offset.get_mut(i), p.cam_rig.get_mut(i)) else {
            return Err(BaError::Full { kind: VariableKind::Camera, capacity: C });
        };
        (*slot, *r) = (stored, rig.0);
        p.n_cams += 1;
        Ok(CameraId(i as u16))
    }

    /// Adds a keyframe of local BA: a rig at `t_cw` (world to camera) with one camera at the
    /// identity offset. Its [`Self::camera_pose`] is then its rig's pose, bit for bit.
    ///
    /// # Errors
    /// Those of [`Self::add_rig`] and [`Self::add_camera`] (capacity `R` or `C`).
    pub fn add_keyframe(&mut self, t_cw: &Pose, fixed: bool) -> Result<CameraId, BaError> {
        if usize::from(self.problem.n_cams) >= C {
            return Err(BaError::Full { kind: VariableKind::Camera, capacity: C });
        }
        let rig = self.add_rig(t_cw, fixed)?;
        self.add_camera(rig, &Pose::identity())
    }

    /// Adds a point `p_w` (world, metres). A `fixed` point (a reference landmark) is never
    /// changed; its observations still constrain the poses. Its observations must follow it.
    ///
    /// # Errors
    /// [`BaError::Busy`], [`BaError::InvalidPoint`] when not finite, [`BaError::Full`].
    pub fn add_point(&mut self, p_w: &Point3<f32>, fixed: bool) -> Result<PointId, BaError> {
        self.check_idle()?;
        if !(p_w.x.is_finite() && p_w.y.is_finite() && p_w.z.is_finite()) {
            return Err(BaError::InvalidPoint);
        }
        let p = &mut self.problem;
        let i = usize::from(p.n_points);
        let n_obs = p.n_obs;
        let (Some(slot), Some(flag), Some(end)) =
            (p.point.get_mut(i), p.point_fixed.get_mut(i), p.point_end.get_mut(i))
        else {
            return Err(BaError::Full { kind: VariableKind::Point, capacity: P });
        };
        (*slot, *flag, *end) = ([p_w.x, p_w.y, p_w.z], fixed, n_obs);
        p.n_points += 1;
        Ok(PointId(i as u16))
    }

    /// Adds the observation of `point` by `camera` at pixel `uv` (pixel-centre convention, as
    /// [`PinholeCamera`](crate::geometry::PinholeCamera)) with the measured depth `depth_m`
    /// (camera z, metres) if any. `point` must be the last point added: a point's observations
    /// are stored together.
    ///
    /// Stored in 8 bytes: `uv` rounded to 1/32 pixel, the inverse depth to `2^-13` per metre
    /// (see [`MIN_OBSERVATION_DEPTH_M`](super::MIN_OBSERVATION_DEPTH_M)).
    ///
    /// # Errors
    /// [`BaError::Busy`], [`BaError::ObservationNotGrouped`] when `point` is not the last point,
    /// [`BaError::UnknownCamera`], [`BaError::InvalidPixel`] outside
    /// `[MIN_OBSERVATION_PX, MAX_OBSERVATION_PX]` or not finite, [`BaError::InvalidDepth`] not
    /// finite, not positive or nearer than `MIN_OBSERVATION_DEPTH_M`, [`BaError::Full`].
    pub fn add_observation(
        &mut self,
        point: PointId,
        camera: CameraId,
        uv: Point2<f32>,
        depth_m: Option<f32>,
    ) -> Result<ObservationId, BaError> {
        self.check_idle()?;
        let p = &mut self.problem;
        if p.n_points == 0 || point.0 != p.n_points - 1 {
            return Err(BaError::ObservationNotGrouped { point: point.index() });
        }
        if camera.0 >= p.n_cams {
            return Err(BaError::UnknownCamera { index: camera.index() });
        }
        let obs = StoredObservation::encode(camera.0, uv.x, uv.y, depth_m).map_err(|pixel| {
            if pixel {
                BaError::InvalidPixel { u: uv.x, v: uv.y }
            } else {
                BaError::InvalidDepth { depth_m: depth_m.unwrap_or(f32::NAN) }
            }
        })?;
        let i = usize::from(p.n_obs);
        let (Some(slot), Some(end)) = (p.obs.get_mut(i), p.point_end.get_mut(point.index())) else {
            return Err(BaError::Full { kind: VariableKind::Observation, capacity: O });
        };
        *slot = obs;
        p.n_obs += 1;
        *end = p.n_obs;
        Ok(ObservationId(i as u16))
    }

    /// Adds a point `p_w` with `slots` observations to be given later, in any order, by
    /// [`Self::set_observation`] (for callers whose observations are not grouped by point, such
    /// as keyframes' lists). Every slot must then be set before [`Self::start`]; a slot left
    /// unset would read as an observation by camera 0 at pixel `MIN_OBSERVATION_PX`.
    ///
    /// # Errors
    /// Those of [`Self::add_point`]; [`BaError::Full`] when the slots do not fit.
    pub fn add_point_with_slots(
        &mut self,
        p_w: &Point3<f32>,
        fixed: bool,
        slots: usize,
    ) -> Result<PointId, BaError> {
        let room = O - usize::from(self.problem.n_obs);
        if slots > room {
            return Err(BaError::Full { kind: VariableKind::Observation, capacity: O });
        }
        let id = self.add_point(p_w, fixed)?;
        let p = &mut self.problem;
        // `slots <= O - n_obs` and `O <= 65,535`: the sum fits u16.
        p.n_obs += slots as u16;
        if let Some(end) = p.point_end.get_mut(id.index()) {
            *end = p.n_obs;
        }
        Ok(id)
    }

    /// Sets slot `slot` of `point` (added by [`Self::add_point_with_slots`]) to the observation
    /// by `camera` at pixel `uv` with the measured depth `depth_m`, if any (see
    /// [`Self::add_observation`] for the encoding). A depth that cannot be stored is dropped
    /// (the pixel is kept): a slot is never left unset by a bad depth.
    ///
    /// # Errors
    /// [`BaError::Busy`], [`BaError::UnknownCamera`], [`BaError::InvalidPixel`], or
    /// [`BaError::Full`] naming the point's slots when `slot` is past them or `point` unknown.
    pub fn set_observation(
        &mut self,
        point: PointId,
        slot: usize,
        camera: CameraId,
        uv: Point2<f32>,
        depth_m: Option<f32>,
    ) -> Result<ObservationId, BaError> {
        self.check_idle()?;
        let p = &self.problem;
        if camera.0 >= p.n_cams {
            return Err(BaError::UnknownCamera { index: camera.index() });
        }
        let (start, end) = p.obs_range(point.index());
        let i = start + slot;
        if point.0 >= p.n_points || i >= end {
            return Err(BaError::Full { kind: VariableKind::Observation, capacity: end - start });
        }
        let obs = StoredObservation::encode(camera.0, uv.x, uv.y, depth_m)
            .or_else(|pixel| {
                if pixel {
                    Err(())
                } else {
                    StoredObservation::encode(camera.0, uv.x, uv.y, None).map_err(|_| ())
                }
            })
            .map_err(|()| BaError::InvalidPixel { u: uv.x, v: uv.y })?;
        if let Some(o) = self.problem.obs.get_mut(i) {
            *o = obs;
        }
        // `i < O <= 65,535`.
        Ok(ObservationId(i as u16))
    }

    /// The rig's current pose `t_sw` (world to rig); `None` for an unknown id.
    pub fn rig_pose(&self, rig: RigId) -> Option<Pose> {
        (rig.0 < self.problem.n_rigs)
            .then(|| self.problem.rig_pose.get(rig.index()).map(|p| p.to_pose()))
            .flatten()
    }

    /// The camera's current pose `t_cw = t_cs t_sw` (world to camera); `None` for an unknown id.
    pub fn camera_pose(&self, camera: CameraId) -> Option<Pose> {
        let p = &self.problem;
        if camera.0 >= p.n_cams {
            return None;
        }
        let t_sw = p.rig_pose.get(p.rig_of(camera.index()))?.to_pose();
        match p.cam_offset.get(camera.index()) {
            Some(offset) if !offset.is_identity() => Some(offset.to_pose() * t_sw),
            _ => Some(t_sw),
        }
    }

    /// The rig camera `camera` hangs from; `None` for an unknown id.
    pub fn camera_rig(&self, camera: CameraId) -> Option<RigId> {
        (camera.0 < self.problem.n_cams)
            .then(|| self.problem.cam_rig.get(camera.index()).map(|&r| RigId(r)))
            .flatten()
    }

    /// The point's current position `p_w` (world, metres); `None` for an unknown id.
    pub fn point(&self, point: PointId) -> Option<Point3<f32>> {
        (point.0 < self.problem.n_points)
            .then(|| self.problem.point.get(point.index()).map(|p| Point3::new(p[0], p[1], p[2])))
            .flatten()
    }

    /// The whitened squared errors of one observation at the current estimate, for outlier
    /// culling with tracking's chi-square gates. `None` for an unknown id, before
    /// [`Self::start`], or when the point is not in front of the camera.
    pub fn observation_residual(&self, obs: ObservationId) -> Option<ObservationResidual> {
        let p = &self.problem;
        if obs.0 >= p.n_obs || self.state.phase == Phase::Idle {
            return None;
        }
        // The owning point: the first whose end lies past the observation.
        let n_points = usize::from(p.n_points);
        let l = p.point_end.get(..n_points)?.partition_point(|&end| end <= obs.0);
        let o = p.obs.get(obs.index())?;
        let c = usize::from(o.camera);
        let t_cw = p.camera_matrix(c, p.rig_pose.get(p.rig_of(c))?);
        let t = self.state.model.terms(&t_cw, p.point.get(l)?, o)?;
        Some(ObservationResidual {
            chi2_reprojection: t.chi2.0,
            chi2_depth: (t.n_rows == 3).then_some(t.chi2.1),
        })
    }

    /// Rigs, cameras, points and observations held.
    pub fn counts(&self) -> (usize, usize, usize, usize) {
        let p = &self.problem;
        (p.n_rigs.into(), p.n_cams.into(), p.n_points.into(), p.n_obs.into())
    }
}
