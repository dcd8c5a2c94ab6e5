//! Unit tests of [`super::evaluate`] on synthetic trajectories (the evo comparison on real data is
//! in `tests/tests/eval_evo.rs`).

use super::*;
use crate::trajectory::StampedPose;
use nalgebra::{Translation3, UnitQuaternion, Vector3};

fn pose(t: f64, x: f64, y: f64, z: f64, yaw: f64) -> StampedPose {
    StampedPose {
        timestamp_s: t,
        t_wc: Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), yaw),
        ),
    }
}

fn circle(n: usize, dt: f64) -> Trajectory {
    Trajectory::new(
        (0..n)
            .map(|i| {
                let a = i as f64 * 0.05;
                pose(i as f64 * dt, a.cos(), 0.1 * a.sin(), a.sin(), a)
            })
            .collect(),
    )
}

#[test]
fn rigidly_moved_copy_has_zero_error() {
    let gt = circle(100, 1.0 / 30.0);
    let offset = Isometry3::from_parts(
        Translation3::new(3.0, -1.0, 0.5),
        UnitQuaternion::from_euler_angles(0.3, -0.2, 1.0),
    );
    let est = Trajectory::new(
        gt.poses
            .iter()
            .map(|p| StampedPose { timestamp_s: p.timestamp_s + 0.005, t_wc: offset * p.t_wc })
            .collect(),
    );
    let r = evaluate(&gt, &est, DEFAULT_MAX_DT_S).unwrap();
    assert_eq!(r.matched_poses, 100);
    assert!(r.ate.max < 1e-9, "{r}");
    assert!(r.rpe_per_frame.trans.max < 1e-9 && r.rpe_per_frame.rot.max < 1e-6);
    let s = r.rpe_per_second.unwrap();
    assert!(s.trans.max < 1e-9 && s.rot.max < 1e-6);
    assert_eq!(r.rpe_per_frame.pairs, 99);
    // TUM rule: i -> i + 30 (1 s at 30 Hz), kept unless it lands on the last match (index 99).
    assert_eq!(s.pairs, 69);
    let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        r.alignment.quaternion_xyzw[3],
        r.alignment.quaternion_xyzw[0],
        r.alignment.quaternion_xyzw[1],
        r.alignment.quaternion_xyzw[2],
    ));
    assert!(q.angle_to(&offset.rotation.inverse()) < 1e-9);
}

#[test]
fn constant_offset_error_is_measured() {
    let gt = circle(60, 0.1);
    // Every other estimate pose moved 1 cm along +y: not removable by a rigid alignment.
    let est = Trajectory::new(
        gt.poses
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let mut q = *p;
                if i.is_multiple_of(2) {
                    q.t_wc.translation.vector.y += 0.01;
                }
                q
            })
            .collect(),
    );
    let r = evaluate(&gt, &est, DEFAULT_MAX_DT_S).unwrap();
    assert!((r.ate.rmse - 0.005).abs() < 1e-4, "{r}");
    assert!((r.rpe_per_frame.trans.mean - 0.01).abs() < 1e-9);
    let (t, e) = r.ate_over_time();
    assert_eq!((t.len(), e.len()), (60, 60));
}

#[test]
fn errors_for_bad_inputs() {
    let gt = circle(10, 0.1);
    let empty = Trajectory::default();
    assert!(matches!(evaluate(&gt, &empty, 0.02), Err(EvalError::Empty { which: "estimated" })));
    assert!(matches!(evaluate(&empty, &gt, 0.02), Err(EvalError::Empty { which: "ground-truth" })));
    assert!(matches!(evaluate(&gt, &gt, -1.0), Err(EvalError::InvalidMaxDt { .. })));
    assert!(matches!(evaluate(&gt, &gt, f64::NAN), Err(EvalError::InvalidMaxDt { .. })));
    let late = Trajectory::new(
        gt.poses.iter().map(|p| StampedPose { timestamp_s: p.timestamp_s + 100.0, ..*p }).collect(),
    );
    assert!(matches!(evaluate(&gt, &late, 0.02), Err(EvalError::NoMatches { .. })));
    let two = Trajectory::new(gt.poses[..2].to_vec());
    assert!(matches!(
        evaluate(&gt, &two, 0.02),
        Err(EvalError::TooFewMatches { matched: 2, required: 3 })
    ));
    let line = Trajectory::new((0..5).map(|i| pose(i as f64, i as f64, 0.0, 0.0, 0.0)).collect());
    assert!(matches!(evaluate(&line, &line, 0.02), Err(EvalError::Alignment { .. })));
    let mut unsorted = gt.clone();
    unsorted.poses.swap(3, 4);
    assert!(matches!(
        evaluate(&gt, &unsorted, 0.02),
        Err(EvalError::NotIncreasing { which: "estimated", index: 4 })
    ));
}

#[test]
fn report_json_is_small_and_display_is_a_table() {
    let gt = circle(50, 0.1);
    let r = evaluate(&gt, &gt, DEFAULT_MAX_DT_S).unwrap();
    let json = serde_json::to_value(&r).unwrap();
    assert_eq!(json["matched_poses"], 50);
    assert!(json["ate"]["rmse"].is_number());
    assert!(json["rpe_per_second"]["trans"]["mean"].is_number());
    assert!(json.get("matches").is_none());
    let text = r.to_string();
    assert!(text.contains("ATE [m]") && text.contains("RPE/s trans [m/s]"), "{text}");
}

#[test]
fn short_trajectory_has_no_per_second_rpe() {
    let gt = circle(10, 0.05);
    let r = evaluate(&gt, &gt, DEFAULT_MAX_DT_S).unwrap();
    assert!(r.rpe_per_second.is_none());
    assert!(r.to_string().contains("no pose pairs"));
}
