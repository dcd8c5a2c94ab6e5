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
