//! What a run's MCAP file holds: the run's results as Foxglove messages, each on its
//! [`Topic`] at its time.

use std::f64::consts::{FRAC_PI_2, PI};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde_json::Value;

use super::foxglove::{self, Primitive, Rgba, Time};
use super::schemas::Schema;
use crate::eval::EvalReport;
use crate::page::ground_truth_in_run_world;
use crate::run::{ArRun, CUBE_SIDE_M, OBJECT_COLOURS, PlanesReport, TrackingRun};
use crate::trajectory::Trajectory;

/// The frame everything is in: the run's world, its first keyframe's camera.
pub const WORLD: &str = "world";
/// The camera's frame, which [`Topic::Transforms`] places in [`WORLD`].
pub const CAMERA: &str = "camera";
/// The name of the log lines' source.
const LOG_NAME: &str = "ferroslam";

/// A topic of the file, and the Foxglove type of its messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Topic {
    /// `/camera/pose`: each posed frame's final pose (CameraTrajectory.txt's).
    CameraPose,
    /// `/tf`: the same pose as the transform `world` -> `camera`.
    Transforms,
    /// `/camera/online_pose`: each frame's pose as the front end output it then.
    OnlinePose,
    /// `/groundtruth/pose`: the ground truth matched to a pose, aligned into the run's world.
    GroundTruthPose,
    /// `/trajectory`: every final pose, once.
    Trajectory,
    /// `/groundtruth/trajectory`: every aligned ground-truth pose, once.
    GroundTruthTrajectory,
    /// `/map/points`: the map's points over the run, once.
    MapPoints,
    /// `/map/points_newest`: the points new in the last keyframe, once.
    NewestPoints,
    /// `/map/keyframes`: an arrow along each keyframe's optical axis, at its frame.
    Keyframes,
    /// `/map/planes`: each plane as a thin square, once.
    Planes,
    /// `/ar/anchors`: each object as a cube where placed, at its frame; removed when removed.
    Anchors,
    /// `/events`: relocalizations, loops closed, anchor script steps.
    Events,
}

impl Topic {
    /// Every topic, in the order their channels are declared.
    pub const ALL: [Self; 12] = [
        Self::CameraPose,
        Self::Transforms,
        Self::OnlinePose,
        Self::GroundTruthPose,
        Self::Trajectory,
        Self::GroundTruthTrajectory,
        Self::MapPoints,
        Self::NewestPoints,
        Self::Keyframes,
        Self::Planes,
        Self::Anchors,
        Self::Events,
    ];

    /// The topic's name.
    pub fn name(self) -> &'static str {
        match self {
            Self::CameraPose => "/camera/pose",
            Self::Transforms => "/tf",
            Self::OnlinePose => "/camera/online_pose",
            Self::GroundTruthPose => "/groundtruth/pose",
            Self::Trajectory => "/trajectory",
            Self::GroundTruthTrajectory => "/groundtruth/trajectory",
            Self::MapPoints => "/map/points",
            Self::NewestPoints => "/map/points_newest",
            Self::Keyframes => "/map/keyframes",
            Self::Planes => "/map/planes",
            Self::Anchors => "/ar/anchors",
            Self::Events => "/events",
        }
    }

    /// The Foxglove type of its messages.
    pub fn schema(self) -> Schema {
        match self {
            Self::CameraPose | Self::OnlinePose | Self::GroundTruthPose => Schema::PoseInFrame,
            Self::Transforms => Schema::FrameTransform,
            Self::Trajectory | Self::GroundTruthTrajectory => Schema::PosesInFrame,
            Self::MapPoints | Self::NewestPoints => Schema::PointCloud,
            Self::Keyframes | Self::Planes | Self::Anchors => Schema::SceneUpdate,
            Self::Events => Schema::Log,
        }
    }
}

/// One message: its topic, log time and body.
#[derive(Debug, Clone)]
pub struct Message {
    /// Where it goes.
    pub topic: Topic,
    /// Its log time (and publish time).
    pub time: Time,
    /// Its JSON.
    pub body: Value,
}

/// The messages of `run` (with `evaluation`'s ground truth), in no particular order. What holds
/// for the whole run (trajectories, points, planes) is stamped with the first pose's time, so
/// that a player shows it all through playback.
pub fn messages(run: &TrackingRun, evaluation: Option<&EvalReport>) -> Vec<Message> {
    let first = run.camera.poses.first().map(|p| p.timestamp_s);
    let start = Time::from_seconds(
        first.or_else(|| run.per_frame.first().map(|f| f.timestamp_s)).unwrap_or(0.0),
    );
    let mut out = Vec::new();
    let mut push = |topic, time, body| out.push(Message { topic, time, body });
    for p in &run.camera.poses {
        let time = Time::from_seconds(p.timestamp_s);
        push(Topic::CameraPose, time, foxglove::pose_in_frame(time, WORLD, &p.t_wc));
        push(Topic::Transforms, time, foxglove::frame_transform(time, WORLD, CAMERA, &p.t_wc));
    }
    for p in &run.online.poses {
        let time = Time::from_seconds(p.timestamp_s);
        push(Topic::OnlinePose, time, foxglove::pose_in_frame(time, WORLD, &p.t_wc));
    }
    let trajectory = |poses: &Trajectory| {
        foxglove::poses_in_frame(start, WORLD, poses.poses.iter().map(|p| &p.t_wc))
    };
    if !run.camera.is_empty() {
        push(Topic::Trajectory, start, trajectory(&run.camera));
    }
    if let Some(e) = evaluation {
        let gt = Trajectory::new(ground_truth_in_run_world(e));
        for p in &gt.poses {
            let time = Time::from_seconds(p.timestamp_s);
            push(Topic::GroundTruthPose, time, foxglove::pose_in_frame(time, WORLD, &p.t_wc));
        }
        push(Topic::GroundTruthTrajectory, start, trajectory(&gt));
    }
    if let Some(cloud) = &run.map_points {
        push(Topic::MapPoints, start, foxglove::point_cloud(start, WORLD, &cloud.points));
        push(Topic::NewestPoints, start, foxglove::point_cloud(start, WORLD, &cloud.newest));
    }
    for (i, k) in run.keyframes.poses.iter().enumerate() {
        let time = Time::from_seconds(k.timestamp_s);
        let entity = foxglove::entity(time, WORLD, &format!("keyframe-{i}"), &keyframe_arrow(k));
        push(Topic::Keyframes, time, foxglove::scene_update(time, vec![entity], &[]));
    }
    if let Some(planes) = &run.planes {
        push(Topic::Planes, start, plane_update(start, planes));
    }
    let frame_time =
        |index: usize| Time::from_seconds(run.per_frame.get(index).map_or(0.0, |f| f.timestamp_s));
    if let Some(ar) = &run.ar {
        for (time, body) in anchor_updates(ar, frame_time) {
            push(Topic::Anchors, time, body);
        }
    }
    for (time, body) in events(run, frame_time) {
        push(Topic::Events, time, body);
    }
    out
}

/// A keyframe's colour (the report page's orange).
const KEYFRAME_COLOUR: Rgba = [1.0, 0.6, 0.0, 1.0];
/// A keyframe arrow's length, metres.
const KEYFRAME_ARROW_M: f64 = 0.1;
/// A plane's colour (the report page's translucent blue).
const PLANE_COLOUR: Rgba = [0.5, 0.69, 1.0, 0.35];
/// A plane square's side and thickness, metres (the page's square around the centroid).
const PLANE_SIZE_M: [f64; 3] = [0.4, 0.4, 0.005];

/// An arrow from keyframe `k`'s camera centre along its optical axis (camera z; a Foxglove
/// arrow points along its pose's x).
fn keyframe_arrow(k: &crate::trajectory::StampedPose) -> Primitive {
    let x_to_z = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -FRAC_PI_2);
    let pose = Isometry3::from_parts(k.t_wc.translation, k.t_wc.rotation * x_to_z);
    Primitive::Arrow { pose, length_m: KEYFRAME_ARROW_M, color: KEYFRAME_COLOUR }
}

/// The rotation taking z to the unit vector `axis`.
fn z_onto(axis: [f32; 3]) -> UnitQuaternion<f64> {
    let axis = Vector3::new(f64::from(axis[0]), f64::from(axis[1]), f64::from(axis[2]));
    UnitQuaternion::rotation_between(&Vector3::z(), &axis)
        .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), PI))
}

fn translation(p: [f32; 3]) -> Translation3<f64> {
    Translation3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))
}

/// Every plane as a thin square about its centroid, across its normal.
fn plane_update(time: Time, planes: &PlanesReport) -> Value {
    let entities = planes
        .planes
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let pose = Isometry3::from_parts(translation(p.centroid_m), z_onto(p.normal));
            let square = Primitive::Cube { pose, size_m: PLANE_SIZE_M, color: PLANE_COLOUR };
            foxglove::entity(time, WORLD, &format!("plane-{i}"), &square)
        })
        .collect();
    foxglove::scene_update(time, entities, &[])
}

/// The entity id of AR object `object`: a place replaces its cube.
fn object_id(object: u16) -> String {
    format!("object-{object}")
}

/// A cube per placement (side [`CUBE_SIDE_M`] x scale, standing on its plane, in the object's
/// colour), at its placing frame's time; a deletion per removal done.
fn anchor_updates(ar: &ArRun, frame_time: impl Fn(usize) -> Time) -> Vec<(Time, Value)> {
    let mut out = Vec::new();
    for a in &ar.anchors {
        let time = frame_time(a.frame);
        let side = foxglove::short(CUBE_SIDE_M * a.scale);
        let up = Vector3::new(f64::from(a.up[0]), f64::from(a.up[1]), f64::from(a.up[2]));
        let centre = translation(a.position_m).vector + up * (side / 2.0);
        let pose = Isometry3::from_parts(centre.into(), z_onto(a.up));
        let [r, g, b] = OBJECT_COLOURS[usize::from(a.object) % OBJECT_COLOURS.len()];
        let color = [f32::from(r) / 255.0, f32::from(g) / 255.0, f32::from(b) / 255.0, 1.0];
        let cube = Primitive::Cube { pose, size_m: [side; 3], color };
        let entity = foxglove::entity(time, WORLD, &object_id(a.object), &cube);
        out.push((time, foxglove::scene_update(time, vec![entity], &[])));
    }
    for e in ar.events.iter().filter(|e| e.refused.is_none()) {
        if let ferroslam_core::ar::AnchorCommand::Remove { object } = e.command {
            let time = frame_time(e.frame);
            out.push((time, foxglove::scene_update(time, Vec::new(), &[object_id(object)])));
        }
    }
    out
}

/// A log line per relocalization, loop closed and anchor script step (a refused step is a
/// warning).
fn events(run: &TrackingRun, frame_time: impl Fn(usize) -> Time) -> Vec<(Time, Value)> {
    let mut out = Vec::new();
    for (i, f) in run.per_frame.iter().enumerate() {
        let time = Time::from_seconds(f.timestamp_s);
        for (happened, what) in [
            (f.relocalized, "relocalized in a remembered place"),
            (f.loop_closed, "loop closed: the map moved onto the place"),
        ] {
            if happened {
                let message = format!("frame {i}: {what}");
                out.push((time, foxglove::log(time, foxglove::INFO, LOG_NAME, &message)));
            }
        }
    }
    for e in run.ar.iter().flat_map(|ar| &ar.events) {
        let time = frame_time(e.frame);
        // The report's words for the command.
        let command = serde_json::to_value(e).ok();
        let command = command.as_ref().and_then(|v| v["command"].as_str()).unwrap_or("");
        let (level, outcome) = match &e.refused {
            None => (foxglove::INFO, "done".to_owned()),
            Some(why) => (foxglove::WARNING, format!("refused ({why})")),
        };
        let message =
            format!("frame {}: anchor script line {}: {command}: {outcome}", e.frame, e.line);
        out.push((time, foxglove::log(time, level, LOG_NAME, &message)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trajectory::StampedPose;

    /// A keyframe's arrow points along its camera's optical axis.
    #[test]
    fn keyframe_arrows_point_along_the_optical_axis() {
        let t_wc = Isometry3::new(Vector3::new(1.0, 2.0, 3.0), Vector3::new(0.3, -0.2, 0.9));
        let Primitive::Arrow { pose, .. } = keyframe_arrow(&StampedPose { timestamp_s: 1.0, t_wc })
        else {
            panic!("an arrow")
        };
        let along = pose.rotation * Vector3::x();
        assert!((along - t_wc.rotation * Vector3::z()).norm() < 1e-12);
        assert_eq!(pose.translation, t_wc.translation);
    }

    /// A plane's square lies across its normal, even a normal along -z.
    #[test]
    fn plane_squares_lie_across_their_normal() {
        for normal in [[0.0, 0.6, 0.8], [0.0, 0.0, -1.0], [0.0, 0.0, 1.0]] {
            let q = z_onto(normal);
            let n = Vector3::new(f64::from(normal[0]), f64::from(normal[1]), f64::from(normal[2]));
            assert!((q * Vector3::z() - n).norm() < 1e-6, "{normal:?}");
        }
    }

    /// Every topic's messages have a Foxglove type.
    #[test]
    fn topics_have_foxglove_schemas() {
        for topic in Topic::ALL {
            assert!(topic.schema().name().starts_with("foxglove."));
            assert!(topic.name().starts_with('/'));
        }
    }
}
