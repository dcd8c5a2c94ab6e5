//! AR in a run (`--ar`, issue 49): the paper's two objects placed on the two largest planes of
//! the first tracked frame that shows two, each at the pixel of its plane's centroid, then drawn
//! in every later frame at the pixel the frame's output pose projects it to (what the board
//! would draw), and, on every [`OVERLAY_EVERY`]th frame, over the camera image as a wireframe
//! cube standing on its plane, hidden where the real depth is nearer.

use ferroslam_core::ar::{Anchor, FramePlanes, PlaneDetector, PlaneParams};
use ferroslam_core::frame::RgbdFrame;
use ferroslam_core::geometry::{PinholeCamera, Pose};
use nalgebra::Point3;
use serde::Serialize;

/// The paper's objects: two, at their own size.
const OBJECTS: u16 = 2;

/// Frames between two overlay images kept (the preview's frame step).
const OVERLAY_EVERY: usize = 3;

/// An object's cube side at scale 1, metres.
const CUBE_SIDE_M: f32 = 0.15;

/// Its colours, by object id (red, blue, then green).
const COLOURS: [[u8; 3]; 3] = [[230, 40, 40], [40, 90, 240], [40, 200, 60]];

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
            if (index - run.frame).is_multiple_of(OVERLAY_EVERY) {
                let overlay = overlay(frame, cam, t_wc, &run.anchors);
                run.overlays.push((index, overlay));
            }
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
            let depth_m = frame.depth.depth_at(uv.x, uv.y, Anchor::MAX_RELATIVE_STEP)?;
            anchors.push(PlacedAnchor {
                object,
                pixel: [uv.x, uv.y],
                depth_m,
                position_m: anchor.p_w,
                up: anchor.up_w,
                anchor,
            });
        }
        Some(ArRun { frame: index, anchors, drawn: Vec::new(), overlays: Vec::new() })
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
    /// Every third frame from `frame` on: its index and its camera image with the
    /// objects drawn.
    #[serde(skip)]
    pub overlays: Vec<(usize, image::RgbImage)>,
}

/// `frame`'s gray image with each anchor drawn as a wireframe cube standing on its plane (side
/// [`CUBE_SIDE_M`] x its scale), seen from `t_wc`; an edge's pixel is hidden where the frame's
/// depth there is more than 2 cm nearer than the cube.
fn overlay(
    frame: &RgbdFrame<'_>,
    cam: &PinholeCamera,
    t_wc: &Pose,
    anchors: &[PlacedAnchor],
) -> image::RgbImage {
    let (w, h) = frame.gray.size();
    let mut img = image::RgbImage::from_fn(w as u32, h as u32, |x, y| {
        let g = frame.gray.get(x as usize, y as usize).unwrap_or(0);
        image::Rgb([g, g, g])
    });
    let t_cw = t_wc.inverse();
    for a in anchors {
        let colour = COLOURS[usize::from(a.anchor.object) % COLOURS.len()];
        let up = nalgebra::Vector3::from(a.anchor.up_w);
        // Any direction across the plane, then the third axis.
        let across = if up.x.abs() < 0.9 { nalgebra::Vector3::x() } else { nalgebra::Vector3::y() };
        let e1 = up.cross(&across).normalize();
        let e2 = up.cross(&e1);
        let s = CUBE_SIDE_M * a.anchor.scale;
        let base = nalgebra::Vector3::from(a.anchor.p_w);
        let corner = |i: usize| {
            let (x, y, z) = ((i & 1) as f32 - 0.5, ((i >> 1) & 1) as f32 - 0.5, (i >> 2) as f32);
            Point3::from(base + e1 * (x * s) + e2 * (y * s) + up * (z * s))
        };
        for (i, j) in CUBE_EDGES {
            let (p, q) = (t_cw * corner(i), t_cw * corner(j));
            // Enough steps for a pixel each along the longest edge a QVGA frame shows.
            for k in 0..=64 {
                let p_c = p + (q - p) * (k as f32 / 64.0);
                let Some(uv) = cam.project(&p_c) else { continue };
                if !cam.in_image(&uv, 0.0) {
                    continue;
                }
                let hidden = frame
                    .depth
                    .depth_at(uv.x, uv.y, Anchor::MAX_RELATIVE_STEP)
                    .is_some_and(|z| z < p_c.z - 0.02);
                if !hidden {
                    img.put_pixel(uv.x.round() as u32, uv.y.round() as u32, image::Rgb(colour));
                }
            }
        }
    }
    img
}

/// A cube's 12 edges between its corners `x + 2 y + 4 z` (`x, y, z` in 0 and 1).
const CUBE_EDGES: [(usize, usize); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];
