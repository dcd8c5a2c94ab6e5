//! How well a run's planes match the demo room's (issue 49's demo bar): the room's planar faces
//! as the rendered frames see them ([`true_planes`]), and each face large enough in some frame
//! matched with the run's plane nearest to it, the run's planes moved into the ground truth's
//! world by its first keyframe ([`plane_accuracy`]).
//!
//! Why the first keyframe and not the trajectory's SE(3) alignment: the run's world is that
//! keyframe's camera by construction, so its ground-truth pose moves the planes exactly, and the
//! errors are the planes' and the map's drift. The alignment fitted on a trajectory that barely
//! moves vertically tilts by a few tenths of a degree, a centimetre at a floor two metres from
//! the path: an error of the evaluation, not of the planes.

use nalgebra::{Isometry3, Vector3};
use serde::Serialize;

use crate::run::PlanesReport;
use crate::synth::SyntheticSequence;
use crate::trajectory::Trajectory;

/// A planar face of the room in the ground truth's world: the points `p` with `normal . p +
/// offset_m = 0`.
#[derive(Debug, Clone, PartialEq)]
pub struct TruePlane {
    /// Which face (`floor`, `east wall`, `box 0 face 2`, ...).
    pub name: String,
    /// Unit normal, toward the side the frames saw it from.
    pub normal: Vector3<f64>,
    /// Metres.
    pub offset_m: f64,
    /// The largest share of one of the frames it covered.
    pub largest_fraction: f64,
}

/// The faces the frames `frames` of `sequence` see within `max_depth_m`, each with the largest
/// share of a frame it covered (a ray every `step` pixels).
pub fn true_planes(
    sequence: &SyntheticSequence,
    frames: impl Iterator<Item = usize>,
    step: usize,
    max_depth_m: f64,
) -> Vec<TruePlane> {
    let mut faces: Vec<TruePlane> = Vec::new();
    for i in frames {
        let Some(gt) = sequence.ground_truth(i) else { continue };
        for v in sequence.visible_planes(i, step, max_depth_m) {
            let normal = gt.t_wc.rotation * v.normal_c;
            let offset_m = v.offset_m - normal.dot(&gt.t_wc.translation.vector);
            match faces.iter_mut().find(|f| f.name == v.name) {
                Some(f) => f.largest_fraction = f.largest_fraction.max(v.fraction),
                None => faces.push(TruePlane {
                    name: v.name,
                    normal,
                    offset_m,
                    largest_fraction: v.fraction,
                }),
            }
        }
    }
    faces.sort_by(|a, b| b.largest_fraction.total_cmp(&a.largest_fraction));
    faces
}

/// One face checked (report.json `plane_accuracy.faces`).
#[derive(Debug, Clone, Serialize)]
pub struct FaceMatch {
    /// Which face.
    pub name: String,
    /// The largest share of a frame it covered.
    pub largest_fraction: f64,
    /// Degrees between its normal and the matched plane's (null: not found).
    pub normal_error_deg: Option<f64>,
    /// Metres from the matched plane's centroid to the face's plane (null: not found): the
    /// offset error where the plane was seen, not at the world's origin, where a tenth of a
    /// degree of tilt would add millimetres per metre of lever.
    pub offset_error_m: Option<f64>,
}

/// The run's planes against the room's (report.json `plane_accuracy`).
#[derive(Debug, Clone, Serialize)]
pub struct PlaneAccuracy {
    /// Faces checked: those covering more than this share of some frame.
    pub min_fraction: f64,
    /// Faces found: a run plane within 10 degrees of the face's normal (the one whose centroid
    /// is nearest the face's plane).
    pub found: usize,
    /// Faces checked and not found.
    pub missed: usize,
    /// The largest normal error of the faces found, degrees.
    pub normal_error_deg_max: Option<f64>,
    /// The largest offset error of the faces found, metres.
    pub offset_error_m_max: Option<f64>,
    /// Every face checked.
    pub faces: Vec<FaceMatch>,
}

/// A run plane counts as a face's when their normals are within this many degrees.
const MATCH_DEG: f64 = 10.0;

/// `T_gt_est`: the run's world in the ground truth's, from the run's first keyframe (the first
/// pose of `keyframes`) and the ground-truth pose nearest its timestamp. `None` without either.
pub fn first_keyframe_alignment(keyframes: &Trajectory, gt: &Trajectory) -> Option<Isometry3<f64>> {
    let first = keyframes.poses.first()?;
    let truth = gt.poses.iter().min_by(|a, b| {
        (a.timestamp_s - first.timestamp_s)
            .abs()
            .total_cmp(&(b.timestamp_s - first.timestamp_s).abs())
    })?;
    Some(truth.t_wc * first.t_wc.inverse())
}

/// Matches every face of `truth` over `min_fraction` with the run's `planes` moved into the
/// ground truth's world by `t_gt_est`.
pub fn plane_accuracy(
    truth: &[TruePlane],
    planes: &PlanesReport,
    t_gt_est: &Isometry3<f64>,
    min_fraction: f64,
) -> PlaneAccuracy {
    let (r, t) = (t_gt_est.rotation, t_gt_est.translation.vector);
    // Each plane's normal and centroid in the ground truth's world.
    let moved: Vec<(Vector3<f64>, Vector3<f64>)> = planes
        .planes
        .iter()
        .map(|p| {
            let n = r * Vector3::from(p.normal).cast::<f64>();
            (n, r * Vector3::from(p.centroid_m).cast::<f64>() + t)
        })
        .collect();
    let faces: Vec<FaceMatch> = truth
        .iter()
        .filter(|f| f.largest_fraction > min_fraction)
        .map(|f| {
            let angle = |n: &Vector3<f64>| n.dot(&f.normal).clamp(-1.0, 1.0).acos().to_degrees();
            let apart = |c: &Vector3<f64>| (f.normal.dot(c) + f.offset_m).abs();
            let best = moved
                .iter()
                .filter(|(n, _)| angle(n) < MATCH_DEG)
                .min_by(|a, b| apart(&a.1).total_cmp(&apart(&b.1)));
            FaceMatch {
                name: f.name.clone(),
                largest_fraction: f.largest_fraction,
                normal_error_deg: best.map(|(n, _)| angle(n)),
                offset_error_m: best.map(|(_, c)| apart(c)),
            }
        })
        .collect();
    let found: Vec<&FaceMatch> = faces.iter().filter(|f| f.normal_error_deg.is_some()).collect();
    let max = |v: fn(&FaceMatch) -> Option<f64>| found.iter().filter_map(|f| v(f)).reduce(f64::max);
    PlaneAccuracy {
        min_fraction,
        found: found.len(),
        missed: faces.len() - found.len(),
        normal_error_deg_max: max(|f| f.normal_error_deg),
        offset_error_m_max: max(|f| f.offset_error_m),
        faces,
    }
}

/// Order statistics of pixel errors.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct PixelStats {
    /// Median, pixels (numpy's: the mean of the middle two of an even count).
    pub median: f64,
    /// 95th percentile (nearest rank), pixels.
    pub p95: f64,
    /// Largest, pixels.
    pub max: f64,
    /// Errors counted.
    pub count: usize,
}

impl PixelStats {
    fn of(mut values: Vec<f64>) -> Self {
        values.sort_by(f64::total_cmp);
        let n = values.len();
        if n == 0 {
            return Self::default();
        }
        // Nearest rank: the smallest value with at least 95% of the values at or below it.
        let rank = (0.95 * n as f64).ceil() as usize;
        Self {
            median: crate::eval::stats::median_of_sorted(&values).unwrap_or(f64::NAN),
            p95: values[rank.clamp(1, n) - 1],
            max: values[n - 1],
            count: n,
        }
    }
}

/// How far from where they belong a run drew its objects (report.json `ar`, with `--ar` or
/// `--anchors`): per frame from the first placing one on, per placed object, the pixel the
/// frame's output pose draws it at against the pixel the true point under its placing pixel
/// projects to with the frame's true pose (processing resolution; frames where that point is
/// outside the image or behind the camera are not counted; occlusion is not modelled).
#[derive(Debug, Clone, Serialize)]
pub struct ArAccuracy {
    /// The frame (0-based, as played) the first object was placed in.
    pub frame: usize,
    /// Placements (an object placed again counts again).
    pub objects: usize,
    /// The placements: object, frame, pixel, where it stood.
    pub anchors: Vec<crate::run::PlacedAnchor>,
    /// The `--anchors` script's steps as applied, with their outcomes.
    pub events: Vec<crate::run::ArEvent>,
    /// The script applied as the board applies it (on the world's planes SLAM found as it ran),
    /// `None` for the paper's objects.
    pub online: Option<crate::run::OnlineAnchorsReport>,
    /// Pixel error of every object in every frame counted (`None`: no ground truth).
    pub error_px: Option<PixelStats>,
    /// Frame-to-frame jitter: how much an object's error moved between consecutive frames,
    /// pixels (`None`: no ground truth).
    pub jitter_px: Option<PixelStats>,
}

impl ArAccuracy {
    /// This accuracy with the board's anchors (`online`, when the run has them) measured by
    /// `measure` too: their pixel error and jitter.
    pub fn with_online(mut self, measure: impl Fn(&crate::run::ArRun) -> Self) -> Self {
        if let Some(online) = &mut self.online {
            let board = measure(&online.drawings);
            (online.error_px, online.jitter_px) = (board.error_px, board.jitter_px);
        }
        self
    }

    /// `ar`'s placements and events, without a truth to measure them against.
    pub fn unmeasured(ar: &crate::run::ArRun) -> Self {
        Self {
            frame: ar.frame,
            objects: ar.anchors.len(),
            anchors: ar.anchors.clone(),
            events: ar.events.clone(),
            online: ar.online.clone(),
            error_px: None,
            jitter_px: None,
        }
    }
}

/// [`ArAccuracy`] of `ar`, a run of `sequence`'s frames from `skip_frames` on seen by `cam`: the
/// truth under each placing pixel is where the renderer's ray from the true pose of its placing
/// frame meets the room.
pub fn ar_accuracy(
    sequence: &SyntheticSequence,
    skip_frames: usize,
    ar: &crate::run::ArRun,
    cam: &ferroslam_core::geometry::PinholeCamera,
) -> ArAccuracy {
    let truth = ar
        .anchors
        .iter()
        .map(|a| sequence.cast_ray(skip_frames + a.frame, &ray(cam, a.pixel)))
        .collect();
    let first = skip_frames + ar.frame;
    accuracy(ar, cam, truth, |j| sequence.ground_truth(first + j).map(|g| g.t_wc))
}

/// [`ArAccuracy`] of `ar` against a recording's ground truth `gt` (camera-to-world poses, the
/// nearest within `max_dt_s` of each frame's timestamp in `timestamps_s`, the run's frames in
/// order): the truth under each placing pixel is its placing frame's depth there, seen from
/// that frame's true pose (an object whose placing frame has no ground truth is not measured).
pub fn ar_accuracy_with_gt(
    ar: &crate::run::ArRun,
    cam: &ferroslam_core::geometry::PinholeCamera,
    gt: &Trajectory,
    timestamps_s: &[f64],
    max_dt_s: f64,
) -> ArAccuracy {
    let stamps: Vec<f64> = gt.poses.iter().map(|p| p.timestamp_s).collect();
    let pose_at = |frame: usize| {
        let t = *timestamps_s.get(frame)?;
        let i = crate::eval::rpe::find_closest_index(&stamps, t);
        gt.poses.get(i).filter(|p| (p.timestamp_s - t).abs() <= max_dt_s).map(|p| p.t_wc)
    };
    let truth = ar
        .anchors
        .iter()
        .map(|a| {
            let seen = ray(cam, a.pixel) * f64::from(a.depth_m);
            pose_at(a.frame).map(|t_wc| t_wc * nalgebra::Point3::from(seen))
        })
        .collect();
    accuracy(ar, cam, truth, |j| pose_at(ar.frame + j))
}

/// The camera-frame ray (z = 1) of `pixel`.
fn ray(cam: &ferroslam_core::geometry::PinholeCamera, pixel: [f32; 2]) -> Vector3<f64> {
    let (fx, fy) = (f64::from(cam.fx()), f64::from(cam.fy()));
    let (cx, cy) = (f64::from(cam.cx()), f64::from(cam.cy()));
    Vector3::new((f64::from(pixel[0]) - cx) / fx, (f64::from(pixel[1]) - cy) / fy, 1.0)
}

/// The errors of `ar`'s drawings against `truth` (each object's true world point) seen from
/// `true_pose(j)` (the true camera-to-world pose of the `j`-th frame from the placing one).
fn accuracy(
    ar: &crate::run::ArRun,
    cam: &ferroslam_core::geometry::PinholeCamera,
    truth: Vec<Option<nalgebra::Point3<f64>>>,
    true_pose: impl Fn(usize) -> Option<nalgebra::Isometry3<f64>>,
) -> ArAccuracy {
    let (fx, fy) = (f64::from(cam.fx()), f64::from(cam.fy()));
    let (cx, cy) = (f64::from(cam.cx()), f64::from(cam.cy()));
    let (w, h) = (cam.width() as f64, cam.height() as f64);
    let (mut errors, mut jitter) = (Vec::new(), Vec::new());
    let mut last: Vec<Option<Vector3<f64>>> = vec![None; ar.anchors.len()];
    for (j, drawn) in ar.drawn.iter().enumerate() {
        let t_wc = true_pose(j);
        for (k, (p, d)) in truth.iter().zip(drawn).enumerate() {
            let error = p.zip(*d).zip(t_wc).and_then(|((p, d), t_wc)| {
                let p_c = t_wc.inverse_transform_point(&p);
                if p_c.z <= 0.0 {
                    return None;
                }
                let (u, v) = (fx * p_c.x / p_c.z + cx, fy * p_c.y / p_c.z + cy);
                let inside = u >= 0.0 && v >= 0.0 && u <= w - 1.0 && v <= h - 1.0;
                inside.then(|| Vector3::new(f64::from(d[0]) - u, f64::from(d[1]) - v, 0.0))
            });
            if let Some(e) = error {
                errors.push(e.norm());
                if let Some(Some(before)) = last.get(k) {
                    jitter.push((e - before).norm());
                }
            }
            if let Some(slot) = last.get_mut(k) {
                *slot = error;
            }
        }
    }
    ArAccuracy {
        error_px: Some(PixelStats::of(errors)),
        jitter_px: Some(PixelStats::of(jitter)),
        ..ArAccuracy::unmeasured(ar)
    }
}
