//! AR in a run (`--ar`, issue 49): the paper's two objects placed on the two largest planes of
//! the first tracked frame that shows two, each at the pixel of its plane's centroid, then drawn
//! in every later frame at the pixel the frame's output pose projects it to (what the board
//! would draw).

use ferroslam_core::ar::{Anchor, FramePlanes, PlaneDetector, PlaneParams};
use ferroslam_core::frame::RgbdFrame;
use ferroslam_core::geometry::{PinholeCamera, Pose};
use nalgebra::Point3;
use serde::Serialize;

/// The paper's objects: two, at their own size.
const OBJECTS: u16 = 2;

/// Places the objects once, then records where each frame draws them.
#[derive(Debug)]
pub(super) struct ArRecorder {
    detector: Box<PlaneDetector>,
    params: PlaneParams,
    run: Option<ArRun>,
}

impl ArRecorder {
    /// Detection with the sensor model `params` holds.
    pub(super) fn new(params: PlaneParams) -> Self {
        Self { detector: Box::new(PlaneDetector::new()), params, run: None }
    }

    /// Frame `index` (0-based, as played) was output at `t_wc`, tracked or not: places the
    /// objects when none are yet and the frame is `tracked` and shows two planes, then records
    /// where the frame draws them.
    pub(super) fn frame(
        &mut self,
        index: usize,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        t_wc: &Pose,
        tracked: bool,
    ) {
        if self.run.is_none() && tracked {
            self.run = self.place(index, frame, cam, t_wc);
        }
        if let Some(run) = &mut self.run {
            run.drawn.push(run.anchors.iter().map(|a| a.anchor.pixel(t_wc, cam)).collect());
        }
    }

    fn place(
        &mut self,
        index: usize,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        t_wc: &Pose,
    ) -> Option<ArRun> {
        let mut planes = FramePlanes::new();
        self.detector.detect(&frame.depth, cam, &self.params, &mut planes).ok()?;
        if planes.len() < usize::from(OBJECTS) {
            return None;
        }
        let mut anchors = Vec::new();
        for (object, plane) in (0..OBJECTS).zip(&planes) {
            let uv = cam.project(&Point3::from(plane.centroid))?;
            let anchor =
                Anchor::place(object, 1.0, (uv.x, uv.y), &frame.depth, cam, t_wc, &planes).ok()?;
            // Read as `Anchor::place` read it (it placed the object, so there is a reading).
            let depth_m = frame.depth.depth_at(uv.x, uv.y, 0.05)?;
            anchors.push(PlacedAnchor {
                object,
                pixel: [uv.x, uv.y],
                depth_m,
                position_m: anchor.p_w,
                up: anchor.up_w,
                anchor,
            });
        }
        Some(ArRun { frame: index, anchors, drawn: Vec::new() })
    }

    /// What was placed and drawn (`None`: no frame showed two planes).
    pub(super) fn finish(self) -> Option<ArRun> {
        self.run
    }
}

/// An object placed, and the pixel it was placed at.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct PlacedAnchor {
    /// The object's id.
    pub object: u16,
    /// The pixel of the placing frame, at the processing resolution.
    pub pixel: [f32; 2],
    /// The placing frame's depth at that pixel, metres.
    pub depth_m: f32,
    /// Where it stands in the run's world frame, metres.
    pub position_m: [f32; 3],
    /// Its up: the plane's normal in the run's world frame.
    pub up: [f32; 3],
    /// The anchor itself.
    #[serde(skip)]
    pub anchor: Anchor,
}

/// The objects of an AR run and where every frame from the placing one on drew them.
#[derive(Debug, Clone, Serialize)]
pub struct ArRun {
    /// The frame (0-based, as played) the objects were placed in.
    pub frame: usize,
    /// The objects.
    pub anchors: Vec<PlacedAnchor>,
    /// Per frame from `frame` on, per object: the pixel drawn (`None`: behind the camera).
    #[serde(skip)]
    pub drawn: Vec<Vec<Option<[f32; 2]>>>,
}
