//! The planes SLAM finds as it runs ([`OnlinePlanes`]), on the board as on a host: each
//! keyframe's surroundings once, on a later frame, merged into a world plane map at that frame's
//! pose. (The host's report builds its planes again at the end of a run from the keyframes'
//! final poses; these are what a board has while it runs, for anchors placed on it.)

use heapless::Vec;

use crate::ar::{
    FramePlanes, MAX_MAP_PLANES, Plane, PlaneDetector, PlaneError, PlaneMap, PlaneMergeParams,
    PlaneParams,
};
use crate::config::SensorModel;
use crate::frame::RgbdFrame;
use crate::geometry::{PinholeCamera, Pose};
use crate::map::Fnv1a;
use crate::tracking::FrameResult;

/// Frames after a keyframe before its planes are looked for, at the earliest: the first cheap
/// frame after a keyframe asks the place memory whether it closes a loop, so the planes take a
/// later one and the two costs never add up on one frame.
pub const PLANE_FRAMES_AFTER_KEYFRAME: u8 = 2;

/// The world's planes found while SLAM runs (see the module documentation): after each keyframe,
/// the first frame at least [`PLANE_FRAMES_AFTER_KEYFRAME`] frames later that the front end
/// tracked in its cheapest way (one final stage from the prediction: no guides, no small-image
/// rotation, no detection) and that closed no loop runs the plane detector on its depth; its
/// planes are moved into the world by its output pose and merged into the [`PlaneMap`]. A
/// keyframe made before such a frame came starts the wait again. Cost: one detection per
/// keyframe at most (about 7.5-9 M Cortex-M4 instructions), on the frames that cost least;
/// the detector's 18 KB are on the stack only then. A loop's correction moves the planes found
/// since tracking last restarted, as it moves that track's keyframes ([`PlaneMap::correct`]);
/// bundle adjustment moves no plane (a plane stays where its frame's output pose put it).
#[derive(Debug, Clone, Default)]
pub struct OnlinePlanes {
    map: PlaneMap,
    /// Frames since the keyframe whose planes are due (`None`: none due).
    due: Option<u8>,
    /// Detections run.
    detections: u32,
}

impl OnlinePlanes {
    /// No planes, none due (`const`, for a `static`).
    pub const fn new() -> Self {
        Self { map: PlaneMap::new(), due: None, detections: 0 }
    }

    /// The world's planes so far.
    pub fn map(&self) -> &PlaneMap {
        &self.map
    }

    /// Starts again from `map`, the planes a saved map held ([`PlaneMap::restored`]), none due.
    pub(super) fn restore(&mut self, map: PlaneMap) {
        *self = Self { map, ..Self::new() };
    }

    /// The world's planes in the frame of a camera at `t_wc` (camera to world), in the order
    /// kept: what an anchor placed in that camera's frame stands on. Cost: one transform per
    /// plane; about 1.3 KB on the caller's stack.
    pub fn seen_from(&self, t_wc: &Pose) -> Vec<Plane, MAX_MAP_PLANES> {
        let t_cw = t_wc.inverse();
        self.map.planes().iter().map(|m| m.plane.transformed(&t_cw)).collect()
    }

    /// Frames the detector ran on.
    pub fn detections(&self) -> u32 {
        self.detections
    }

    /// FNV-1a over every kept plane's fields (their bits, in order) and observation count: what
    /// a board and a host replay of the same frames compare.
    pub fn fingerprint(&self) -> u32 {
        let mut hash = Fnv1a::default();
        for m in self.map.planes() {
            let p = &m.plane;
            let floats = [p.normal, [p.offset_m, p.rms_m, 0.0], p.centroid];
            floats.iter().flatten().for_each(|f| hash.add(&f.to_bits().to_le_bytes()));
            hash.add(&p.cells.to_le_bytes());
            hash.add(&p.samples.to_le_bytes());
            hash.add(&m.observations.to_le_bytes());
        }
        hash.value()
    }

    /// Takes `frame` (seen by `cam`, depth noise `sensor`) as tracking left it (`result`): a
    /// keyframe makes planes due; a due frame that qualifies (see [`OnlinePlanes`]) detects them.
    pub(super) fn after_frame(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        sensor: &SensorModel,
        result: &FrameResult,
    ) {
        if result.reinitialized {
            self.map.restart_track();
        }
        if let Some(closure) = &result.loop_closure {
            self.map.correct(&closure.correction, &PlaneMergeParams::DEFAULT);
        }
        if result.keyframe.is_some() {
            self.due = Some(0);
            return;
        }
        let Some(frames) = self.due else { return };
        let frames = frames.saturating_add(1);
        self.due = Some(frames);
        let w = &result.work;
        let cheapest = w.final_stages <= 1 && w.guide_runs == 0 && !w.rotation_estimated;
        let cheap = result.tracked && cheapest && !w.detected && result.loop_closure.is_none();
        if frames < PLANE_FRAMES_AFTER_KEYFRAME || !cheap {
            return;
        }
        self.due = None;
        self.detections = self.detections.saturating_add(1);
        let mut planes = FramePlanes::new();
        if detect(frame, cam, sensor, &mut planes).is_ok() {
            let merge = PlaneMergeParams::DEFAULT;
            for plane in &planes {
                self.map.observe(&plane.transformed(&result.t_wc), &merge);
            }
        }
    }
}

/// The planes of `frame` into `planes`, with a detector on this call's stack: kept out of line,
/// so its 18 KB are stacked only while it runs, above the frame loop rather than the tracker's
/// deepest calls.
#[inline(never)]
fn detect(
    frame: &RgbdFrame<'_>,
    cam: &PinholeCamera,
    sensor: &SensorModel,
    planes: &mut FramePlanes,
) -> Result<(), PlaneError> {
    let mut detector = const { PlaneDetector::new() };
    let params = PlaneParams { sensor: *sensor, ..PlaneParams::DEFAULT };
    detector.detect(&frame.depth, cam, &params, planes)
}
