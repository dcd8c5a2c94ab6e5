//! The planes of a SLAM run (issue 49): the core's plane detector on every keyframe's depth, the
//! planes kept in each keyframe's frame, then moved into the world by the keyframes' final poses
//! and merged ([`ferroslam_core::ar::PlaneMap`]), so they follow bundle adjustment and loops.

use std::collections::HashMap;

use ferroslam_core::ar::{
    FramePlanes, PlaneDetector, PlaneError, PlaneMap, PlaneMergeParams, PlaneParams,
};
use ferroslam_core::frame::RgbdFrame;
use ferroslam_core::geometry::{PinholeCamera, Pose};
use ferroslam_core::map::KeyFrameId;
use ferroslam_core::system::OnlinePlanes;
use serde::Serialize;

/// Each keyframe's planes, in its camera's frame, as the run makes them.
#[derive(Debug)]
pub(super) struct KeyframePlanes {
    detector: Box<PlaneDetector>,
    params: PlaneParams,
    /// In the order the keyframes were made.
    seen: Vec<(KeyFrameId, FramePlanes)>,
}

impl KeyframePlanes {
    /// Detection with the sensor model `params` holds.
    pub(super) fn new(params: PlaneParams) -> Self {
        Self { detector: Box::new(PlaneDetector::new()), params, seen: Vec::new() }
    }

    /// Detects the planes of keyframe `kf`, made of `frame` (seen by `cam`).
    ///
    /// # Errors
    /// The detector's: a frame the camera does not fit.
    pub(super) fn observe(
        &mut self,
        kf: KeyFrameId,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
    ) -> Result<(), PlaneError> {
        let mut planes = FramePlanes::new();
        self.detector.detect(&frame.depth, cam, &self.params, &mut planes)?;
        self.seen.push((kf, planes));
        Ok(())
    }

    /// The world's planes, each keyframe's moved by its pose in `keyframe_pose` (a keyframe
    /// without one is left out) and merged, largest support first; `online` the ones SLAM found
    /// as it ran.
    pub(super) fn report(
        &self,
        keyframe_pose: &HashMap<KeyFrameId, (f64, Pose)>,
        online: &OnlinePlanes,
    ) -> PlanesReport {
        let mut map = PlaneMap::new();
        let merge = PlaneMergeParams::DEFAULT;
        let mut used = 0;
        for (kf, planes) in &self.seen {
            let Some((_, t_wk)) = keyframe_pose.get(kf) else { continue };
            used += 1;
            for p in planes {
                map.observe(&p.transformed(t_wk), &merge);
            }
        }
        let mut planes: Vec<PlaneReport> = map
            .planes()
            .iter()
            .map(|m| PlaneReport {
                normal: m.plane.normal,
                offset_m: m.plane.offset_m,
                centroid_m: m.plane.centroid,
                rms_m: m.plane.rms_m,
                largest_frame_fraction: m.plane.frame_fraction(),
                observations: m.observations,
                samples: m.plane.samples,
            })
            .collect();
        planes.sort_by_key(|p| std::cmp::Reverse(p.samples));
        let board = OnlinePlanesReport {
            detections: online.detections(),
            planes: online.map().planes().len(),
            dropped: online.map().dropped(),
            fingerprint: online.fingerprint(),
        };
        PlanesReport { keyframes: used, dropped: map.dropped(), planes, online: board }
    }
}

/// The planes of a run (report.json `planes`), in the world frame of its trajectory.
#[derive(Debug, Clone, Serialize)]
pub struct PlanesReport {
    /// Keyframes whose planes were merged.
    pub keyframes: usize,
    /// Plane observations dropped because the plane map was full.
    pub dropped: u32,
    /// The planes, most supported first.
    pub planes: Vec<PlaneReport>,
    /// The planes SLAM found as it ran, as a board has them.
    pub online: OnlinePlanesReport,
}

/// The planes SLAM found as it ran ([`OnlinePlanes`]): each keyframe's surroundings detected on
/// a later cheap frame and merged at its output pose, as the firmware does.
#[derive(Debug, Clone, Serialize)]
pub struct OnlinePlanesReport {
    /// Frames the detector ran on.
    pub detections: u32,
    /// Planes kept.
    pub planes: usize,
    /// Observations dropped because the plane map was full.
    pub dropped: u32,
    /// FNV-1a over the kept planes' bits ([`OnlinePlanes::fingerprint`]): the firmware's must be
    /// the same.
    pub fingerprint: u32,
}

/// One plane of the world: the points `p` with `normal . p + offset_m = 0` (metres).
#[derive(Debug, Clone, Serialize)]
pub struct PlaneReport {
    /// Unit normal, toward the side it was seen from.
    pub normal: [f32; 3],
    /// Offset, metres.
    pub offset_m: f32,
    /// Mean of its points, metres.
    pub centroid_m: [f32; 3],
    /// RMS distance of its points to it, metres.
    pub rms_m: f32,
    /// The largest share of a keyframe it covered.
    pub largest_frame_fraction: f32,
    /// Keyframes it was seen in.
    pub observations: u16,
    /// Depth samples it was fitted on.
    pub samples: u32,
}
