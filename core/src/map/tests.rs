//! Map unit tests.
//!
//! Test code only: this file is compiled under #[cfg(test)] (see the `mod` line that includes it).

use nalgebra::Point3;

use super::*;

fn pose() -> Pose {
    Pose::identity()
}

#[test]
fn observations_round_trip_within_their_quantization() {
    let mut m: Map<4, 8> = Map::new();
    let kf = m.add_keyframe(pose(), 0.0).unwrap();
    let lm = m.add_landmark(Point3::new(0.0, 0.0, 1.0), kf).unwrap();
    let o = Observation::new(lm, (123.456, 7.89), Some(2.3456)).unwrap();
    let (u, v) = o.uv();
    assert!((u - 123.456).abs() <= 1.0 / 64.0 && (v - 7.89).abs() <= 1.0 / 64.0);
    assert!((o.depth_m().unwrap() - 2.3456).abs() <= 1.25e-4);
    assert_eq!(Observation::new(lm, (1.0, 1.0), Some(f32::NAN)).unwrap().depth_m(), None);
    assert_eq!(Observation::new(lm, (1.0, 1.0), Some(-1.0)).unwrap().depth_m(), None);
    assert_eq!(Observation::new(lm, (1.0, 1.0), Some(99.0)).unwrap().depth_m(), None);
    assert!(Observation::new(lm, (-1.0, 1.0), None).is_none());
    assert!(Observation::new(lm, (f32::NAN, 1.0), None).is_none());
    assert!(Observation::new(lm, (3000.0, 1.0), None).is_none());
    assert_eq!(core::mem::size_of::<Observation>(), 10);
}

#[test]
fn full_arenas_are_errors_and_retiring_frees_room() {
    let mut m: Map<2, 3> = Map::new();
    let k0 = m.add_keyframe(pose(), 0.0).unwrap();
    let k1 = m.add_keyframe(pose(), 1.0).unwrap();
    assert_eq!(m.add_keyframe(pose(), 2.0), Err(MapError::KeyFramesFull));
    let a = m.add_landmark(Point3::new(0.0, 0.0, 1.0), k0).unwrap();
    let b = m.add_landmark(Point3::new(1.0, 0.0, 1.0), k0).unwrap();
    let c = m.add_landmark(Point3::new(2.0, 0.0, 1.0), k1).unwrap();
    assert_eq!(m.add_landmark(Point3::origin(), k1), Err(MapError::LandmarksFull));
    for (kf, lm) in [(k0, a), (k0, b), (k1, b), (k1, c)] {
        m.add_observation(kf, Observation::new(lm, (1.0, 2.0), None).unwrap()).unwrap();
    }
    assert_eq!(m.landmark(b).unwrap().num_observations, 2);
    // Retiring k0 orphans `a` (removed) but not `b` (k1 still sees it).
    assert_eq!(m.retire_oldest_keyframe(|_| false), Some(k0));
    assert!(m.keyframe(k0).is_none() && m.landmark(a).is_none());
    assert_eq!(m.landmark(b).unwrap().num_observations, 1);
    assert_eq!(m.num_keyframes(), 1);
    assert_eq!(m.num_landmarks(), 2);
    let k2 = m.add_keyframe(pose(), 2.0).unwrap();
    assert_eq!(m.keyframe(k2).unwrap().seq, 2);
    assert_eq!(m.oldest_keyframe(), Some(k1));
    // A kept orphan survives.
    assert_eq!(m.retire_oldest_keyframe(|id| id == c), Some(k1));
    assert!(m.landmark(c).is_some() && m.landmark(b).is_none());
    let stale = Observation::new(a, (1.0, 1.0), None).unwrap();
    assert_eq!(m.add_observation(k2, stale), Err(MapError::UnknownId));
    m.clear();
    assert_eq!((m.num_keyframes(), m.num_landmarks()), (0, 0));
}
