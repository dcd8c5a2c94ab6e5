//! AR in a run (`--ar`, `--anchors`, issue 49): virtual objects placed, scaled and removed
//! ([`ArPlan`]: the paper's two objects on the two largest planes of the first tracked frame
//! that shows two, each at the pixel of its plane's centroid; or a user's script), moved by loop
//! corrections with the map they were placed in (`ferroslam_core::ar::Anchors`),
//! then drawn in every frame at the pixel the frame's output pose projects it to (what the board
//! would draw), and, on every [`OVERLAY_EVERY`]th frame, over the camera image as a wireframe
//! cube standing on its plane, hidden where the real depth is nearer.

use ferroslam_core::ar::{
    Anchor, AnchorCommand, AnchorError, Anchors, FramePlanes, PlacingFrame, PlaneDetector,
    PlaneParams,
};
use ferroslam_core::frame::RgbdFrame;
use ferroslam_core::geometry::{PinholeCamera, Pose};
use ferroslam_core::map::KeyFrameId;
use ferroslam_core::system::{ProfileTypes, Slam};
use ferroslam_core::tracking::FrameResult;
use nalgebra::Point3;
use serde::Serialize;

use crate::anchor_script::{AnchorScript, ScriptStep};
use crate::plane_truth::PixelStats;

/// The paper's objects: two, at their own size.
const OBJECTS: u16 = 2;

/// Frames between two overlay images kept (the preview's frame step).
const OVERLAY_EVERY: usize = 3;

/// An object's cube side at scale 1, metres.
pub const CUBE_SIDE_M: f32 = 0.15;

/// Its colours, by object id (red, blue, then green).
pub const OBJECT_COLOURS: [[u8; 3]; 3] = [[230, 40, 40], [40, 90, 240], [40, 200, 60]];

/// Which objects a run places.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum ArPlan {
    /// The paper's two objects, on the two largest planes of the first tracked frame showing two.
    #[default]
    Paper,
    /// A user's script (`--anchors FILE`).
    Script(AnchorScript),
}

/// An output frame as the anchors see it.
#[derive(Debug, Clone, Copy)]
pub(super) struct ArFrame {
    /// Frame index, 0-based as played.
    pub index: usize,
    /// Its output camera-to-world pose.
    pub t_wc: Pose,
    /// Whether it was tracked (a lost frame places nothing).
    pub tracked: bool,
    /// The keyframe it was tracked against.
    pub reference: Option<KeyFrameId>,
    /// The correction a loop closed in this frame moved the active map by.
    pub loop_correction: Option<Pose>,
}

/// Places the objects, applies the script, then records where each frame draws them.
#[derive(Debug)]
pub(super) struct ArRecorder {
    detector: Box<PlaneDetector>,
    params: PlaneParams,
    plan: ArPlan,
    /// Script steps applied so far.
    applied: usize,
    anchors: Anchors,
    drawings: Drawings,
}

impl ArRecorder {
    /// Detection with the sensor model `params` holds, placing as `plan` says.
    pub(super) fn new(params: PlaneParams, plan: ArPlan) -> Self {
        Self {
            detector: Box::new(PlaneDetector::new()),
            params,
            plan,
            applied: 0,
            anchors: Anchors::new(),
            drawings: Drawings::default(),
        }
    }

    /// Frame `f` was output: moves the anchors with a loop correction (`in_map`: whether the
    /// active map holds a keyframe), applies what the plan says for this frame, then records
    /// where the frame draws every placed object.
    pub(super) fn frame(
        &mut self,
        f: &ArFrame,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        in_map: impl Fn(KeyFrameId) -> bool,
    ) {
        if let Some(correction) = &f.loop_correction {
            self.anchors.correct(correction, in_map);
        }
        // The frame's planes, detected once when the plan has something to do in it.
        let wanted = match &self.plan {
            ArPlan::Script(script) => {
                script.steps.get(self.applied).is_some_and(|s| s.frame <= f.index)
            }
            ArPlan::Paper => self.drawings.run.anchors.is_empty() && f.tracked,
        };
        let mut planes = FramePlanes::new();
        let detected =
            wanted && self.detector.detect(&frame.depth, cam, &self.params, &mut planes).is_ok();
        let commands = self.commands(f, detected.then_some(&planes), cam);
        if !commands.is_empty() {
            let placing = PlacingFrame {
                depth: &frame.depth,
                cam,
                t_wc: &f.t_wc,
                planes: &planes,
                reference: f.reference,
            };
            let usable = (f.tracked && detected).then_some(&placing);
            // Tried on a copy: the paper's objects are placed together or not at all.
            let mut anchors = self.anchors.clone();
            let results: Vec<_> = commands.iter().map(|(c, _)| anchors.apply(c, usable)).collect();
            if matches!(self.plan, ArPlan::Script(_)) || results.iter().all(Result::is_ok) {
                self.anchors = anchors;
                for ((command, line), result) in commands.iter().zip(results) {
                    self.record(f.index, command, *line, result, frame);
                }
            }
        }
        if !self.drawings.draw(self.anchors.iter(), &f.t_wc, cam) {
            return;
        }
        let run = &mut self.drawings.run;
        if (f.index - run.frame).is_multiple_of(OVERLAY_EVERY) {
            let shown: Vec<Anchor> = self.anchors.iter().copied().collect();
            run.overlays.push((f.index, overlay(frame, cam, &f.t_wc, &shown)));
        }
    }

    /// The commands of frame `f`, with their script lines (the paper's plan: the two objects on
    /// the two largest of the frame's `planes`, once a tracked frame shows two).
    fn commands(
        &mut self,
        f: &ArFrame,
        planes: Option<&FramePlanes>,
        cam: &PinholeCamera,
    ) -> Vec<(AnchorCommand, Option<usize>)> {
        match &self.plan {
            ArPlan::Script(script) => {
                let due = script.steps[self.applied..].iter().take_while(|s| s.frame <= f.index);
                let commands: Vec<_> = due.map(|s| (s.command, Some(s.line))).collect();
                self.applied += commands.len();
                commands
            }
            ArPlan::Paper if !self.drawings.run.anchors.is_empty() || !f.tracked => Vec::new(),
            ArPlan::Paper => {
                let Some(planes) = planes.filter(|p| p.len() >= usize::from(OBJECTS)) else {
                    return Vec::new();
                };
                (0..OBJECTS)
                    .zip(planes)
                    .filter_map(|(object, plane)| {
                        let uv = cam.project(&Point3::from(plane.centroid))?;
                        Some((
                            AnchorCommand::Place { object, pixel: [uv.x, uv.y], scale: 1.0 },
                            None,
                        ))
                    })
                    .collect()
            }
        }
    }

    /// Records `command`'s outcome: a new entry for a place, the entry's end for a remove or a
    /// move, an event for a script step.
    fn record(
        &mut self,
        index: usize,
        command: &AnchorCommand,
        line: Option<usize>,
        result: Result<Anchor, AnchorError>,
        frame: &RgbdFrame<'_>,
    ) {
        if let Some(line) = line {
            let refused = result.as_ref().err().map(|e| format!("{e:?}"));
            self.drawings.run.events.push(ArEvent {
                frame: index,
                line,
                command: *command,
                refused,
            });
        }
        if let Ok(anchor) = result {
            self.drawings.applied(index, command, &anchor, frame);
        }
    }

    /// What was placed and drawn (`None`: nothing placed and no script step).
    pub(super) fn finish(self) -> Option<ArRun> {
        let run = self.drawings.run;
        (!run.anchors.is_empty() || !run.events.is_empty()).then_some(run)
    }
}

/// An object placed, and the pixel it was placed at.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct PlacedAnchor {
    /// The object's id.
    pub object: u16,
    /// The frame (0-based, as played) it was placed in.
    pub frame: usize,
    /// The pixel of the placing frame, at the processing resolution.
    pub pixel: [f32; 2],
    /// The placing frame's depth at that pixel, metres.
    pub depth_m: f32,
    /// Where it stood when placed, in the run's world frame, metres.
    pub position_m: [f32; 3],
    /// Its up: the plane's normal in the run's world frame.
    pub up: [f32; 3],
    /// Its scale when placed.
    pub scale: f32,
}

/// A script step as applied.
#[derive(Debug, Clone, Serialize)]
pub struct ArEvent {
    /// The frame it was applied in (0-based, as played).
    pub frame: usize,
    /// Its line in the script.
    pub line: usize,
    /// What it asked.
    #[serde(serialize_with = "command_text")]
    pub command: AnchorCommand,
    /// Why nothing changed (an `AnchorError`'s name), `None` when done.
    pub refused: Option<String>,
}

fn command_text<S: serde::Serializer>(c: &AnchorCommand, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(&match *c {
        AnchorCommand::Place { object, pixel: [u, v], scale } => {
            format!("place {object} at ({u:.2}, {v:.2}) px, scale {scale}")
        }
        AnchorCommand::Scale { object, scale } => format!("scale {object} to {scale}"),
        AnchorCommand::Remove { object } => format!("remove {object}"),
    })
}

/// The objects of an AR run and where every frame from the first placing one on drew them.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ArRun {
    /// The frame (0-based, as played) the first object was placed in.
    pub frame: usize,
    /// Every placement, in order (an object placed again is a new entry; the old one is no
    /// longer drawn).
    pub anchors: Vec<PlacedAnchor>,
    /// The script's steps as applied, with their outcomes (empty for the paper's objects).
    pub events: Vec<ArEvent>,
    /// Per frame from `frame` on, per entry of `anchors`: the pixel drawn (`None`: behind the
    /// camera, not placed yet, removed or moved).
    #[serde(skip)]
    pub drawn: Vec<Vec<Option<[f32; 2]>>>,
    /// Every third frame from `frame` on: its index and its camera image with the
    /// objects drawn.
    #[serde(skip)]
    pub overlays: Vec<(usize, image::RgbImage)>,
    /// The script applied as the board applies it (`None` for the paper's objects): each
    /// command through `Slam::command` in its frame, on the world's planes found so far.
    pub online: Option<OnlineAnchorsReport>,
}

/// Where each placed object is drawn, frame by frame: the placements and drawings of an
/// [`ArRun`], kept the same way for the host's anchors and the board's.
#[derive(Debug, Default)]
struct Drawings {
    run: ArRun,
    /// The entry of [`ArRun::anchors`] each placed object is drawn as, by object.
    entries: Vec<(u16, usize)>,
}

impl Drawings {
    /// `command`, applied in frame `index` (`frame`), gave `anchor`: a place is a new entry,
    /// drawn from now on in place of the object's earlier one; a remove ends the object's.
    fn applied(
        &mut self,
        index: usize,
        command: &AnchorCommand,
        anchor: &Anchor,
        frame: &RgbdFrame<'_>,
    ) {
        let object = command.object();
        match *command {
            AnchorCommand::Place { pixel: [u, v], .. } => {
                if self.run.anchors.is_empty() {
                    self.run.frame = index;
                }
                let depth_m = frame.depth.depth_at(u, v, Anchor::MAX_RELATIVE_STEP).unwrap_or(0.0);
                let entry = self.run.anchors.len();
                self.run.anchors.push(PlacedAnchor {
                    object,
                    frame: index,
                    pixel: [u, v],
                    depth_m,
                    position_m: anchor.p_w,
                    up: anchor.up_w,
                    scale: anchor.scale,
                });
                self.entries.retain(|(o, _)| *o != object);
                self.entries.push((object, entry));
            }
            AnchorCommand::Scale { .. } => {}
            AnchorCommand::Remove { .. } => self.entries.retain(|(o, _)| *o != object),
        }
    }

    /// Records where a frame at `t_wc` draws `anchors` (each as its object's entry); `false`,
    /// recording nothing, before the first placement.
    fn draw<'a>(
        &mut self,
        anchors: impl Iterator<Item = &'a Anchor>,
        t_wc: &Pose,
        cam: &PinholeCamera,
    ) -> bool {
        if self.run.anchors.is_empty() {
            return false;
        }
        let mut drawn = vec![None; self.run.anchors.len()];
        for a in anchors {
            if let Some(&(_, entry)) = self.entries.iter().find(|(o, _)| *o == a.object) {
                drawn[entry] = a.pixel(t_wc, cam);
            }
        }
        self.run.drawn.push(drawn);
        true
    }
}

/// A script's commands applied as the board applies those it receives on its serial link: each
/// through the SLAM system (`Slam::command`) in its frame, right after the front end, on the
/// world's planes found so far (no detection on the frame). `cargo xtask firmware-replay
/// --anchors` compares the board's with these.
#[derive(Debug)]
pub(super) struct OnlineAnchors {
    steps: Vec<ScriptStep>,
    next: usize,
    report: OnlineAnchorsReport,
    drawings: Drawings,
}

/// The anchors a script gave through the SLAM system, as the board applies the commands it
/// receives: what the board has.
#[derive(Debug, Clone, Default, Serialize)]
pub struct OnlineAnchorsReport {
    /// Commands applied.
    pub applied: usize,
    /// Commands refused, in order.
    pub refused: Vec<RefusedCommand>,
    /// The anchors at the end, in the order their objects were first placed.
    pub anchors: Vec<OnlineAnchor>,
    /// FNV-1a over them (`Anchors::fingerprint`), as the firmware logs it.
    pub fingerprint: u32,
    /// The placements and where each frame drew them (measured as the host's anchors are:
    /// `error_px`, `jitter_px`).
    #[serde(skip)]
    pub drawings: Box<ArRun>,
    /// Pixel error of every object in every frame counted (`None`: not measured).
    pub error_px: Option<PixelStats>,
    /// Frame-to-frame jitter of that error (`None`: not measured).
    pub jitter_px: Option<PixelStats>,
}

/// A command [`OnlineAnchors`] refused.
#[derive(Debug, Clone, Serialize)]
pub struct RefusedCommand {
    /// The frame it was applied in (0-based, as played).
    pub frame: usize,
    /// Its script line.
    pub line: usize,
    /// Why: an `AnchorError`'s name.
    pub error: String,
    /// The error's code (`AnchorError::code`): the detail of the board's fault message.
    pub code: u32,
}

/// An anchor at the end of a run, in the world frame.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct OnlineAnchor {
    /// The object's id.
    pub object: u16,
    /// Where it stands, metres.
    pub position_m: [f32; 3],
    /// Its up.
    pub up: [f32; 3],
    /// Its scale.
    pub scale: f32,
}

impl OnlineAnchors {
    /// The board's way for `plan`'s steps (`None` for the paper's objects, which the host places
    /// on each frame's own planes).
    pub(super) fn new(plan: &ArPlan) -> Option<Self> {
        match plan {
            ArPlan::Script(s) => Some(Self {
                steps: s.steps.clone(),
                next: 0,
                report: OnlineAnchorsReport::default(),
                drawings: Drawings::default(),
            }),
            ArPlan::Paper => None,
        }
    }

    /// Applies the steps of frame `index` (and any earlier not applied) to `slam`, which has
    /// just processed `frame` with `result`, then records where the frame draws the anchors.
    pub(super) fn frame<P: ProfileTypes>(
        &mut self,
        index: usize,
        slam: &mut Slam<P>,
        (frame, cam, result): (&RgbdFrame<'_>, &PinholeCamera, &FrameResult),
    ) {
        while let Some(step) = self.steps.get(self.next).filter(|s| s.frame <= index) {
            match slam.command(&step.command, frame, cam, result) {
                Ok(anchor) => {
                    self.report.applied += 1;
                    self.drawings.applied(index, &step.command, &anchor, frame);
                }
                Err(e) => self.report.refused.push(RefusedCommand {
                    frame: index,
                    line: step.line,
                    error: format!("{e:?}"),
                    code: e.code(),
                }),
            }
            self.next += 1;
        }
        self.drawings.draw(slam.anchors().iter(), &result.t_wc, cam);
    }

    /// The report, with `slam`'s anchors at the end.
    pub(super) fn finish<P: ProfileTypes>(mut self, slam: &Slam<P>) -> OnlineAnchorsReport {
        let anchors = slam.anchors();
        self.report.anchors = anchors
            .iter()
            .map(|a| OnlineAnchor {
                object: a.object,
                position_m: a.p_w,
                up: a.up_w,
                scale: a.scale,
            })
            .collect();
        self.report.fingerprint = anchors.fingerprint();
        self.report.drawings = Box::new(self.drawings.run);
        self.report
    }
}

/// `frame`'s gray image with each anchor drawn as a wireframe cube standing on its plane (side
/// [`CUBE_SIDE_M`] x its scale), seen from `t_wc`; an edge's pixel is hidden where the frame's
/// depth there is more than 2 cm nearer than the cube.
fn overlay(
    frame: &RgbdFrame<'_>,
    cam: &PinholeCamera,
    t_wc: &Pose,
    anchors: &[Anchor],
) -> image::RgbImage {
    let (w, h) = frame.gray.size();
    let mut img = image::RgbImage::from_fn(w as u32, h as u32, |x, y| {
        let g = frame.gray.get(x as usize, y as usize).unwrap_or(0);
        image::Rgb([g, g, g])
    });
    let t_cw = t_wc.inverse();
    for a in anchors {
        let colour = OBJECT_COLOURS[usize::from(a.object) % OBJECT_COLOURS.len()];
        let up = nalgebra::Vector3::from(a.up_w);
        // Any direction across the plane, then the third axis.
        let across = if up.x.abs() < 0.9 { nalgebra::Vector3::x() } else { nalgebra::Vector3::y() };
        let e1 = up.cross(&across).normalize();
        let e2 = up.cross(&e1);
        let s = CUBE_SIDE_M * a.scale;
        let base = nalgebra::Vector3::from(a.p_w);
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
