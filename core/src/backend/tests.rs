//! Back-end tests.
//!
//! Test code only: this file is compiled under #[cfg(test)] (see the `mod` line that includes it).
//!
//! The split of a step into [`Backend::advance_solve`] and [`Backend::finish_solve`] is checked on
//! real frames in the workspace tests (`slam_determinism`: the back end on its own thread gives
//! the sequential bits) and by the firmware replay; here, its edges.

extern crate std;

use super::{BackendError, BackendParams, BackendStatus, BoardBackend};
use crate::geometry::PinholeCamera;
use crate::map::BoardMap;

fn camera() -> PinholeCamera {
    PinholeCamera::new(260.0, 260.0, 160.0, 120.0, 320, 240).unwrap_or_else(|_| unreachable!())
}

#[test]
fn with_no_solve_under_way_there_is_no_solve_job() {
    let (mut backend, mut map) = (BoardBackend::new(), BoardMap::new());
    assert!(backend.solve_job().is_none());
    assert_eq!(backend.advance_solve(5_000), Ok(false));
    assert_eq!(backend.finish_solve(&mut map), None);
    assert_eq!(backend.stats().steps, 0, "nothing was charged as a step");
    // An empty map gives no problem to build: the step stays idle.
    assert_eq!(backend.step(&mut map, &camera(), 5_000), Ok(BackendStatus::Idle));
    assert!(!backend.is_busy());
}

/// The sensor model reaches both solvers but for its depth noise: bundle adjustment keeps its
/// own; the default model gives the default weighting.
#[test]
fn the_sensor_model_reaches_both_solvers_but_for_depth_noise() {
    let default = crate::config::SensorModel::DEFAULT;
    assert_eq!(BackendParams::DEFAULT.with_sensor(default), BackendParams::DEFAULT);
    assert_eq!(BackendParams::DEFAULT.local.sensor.depth_noise_coeff_per_m, 6.0e-4);
    let sensor = crate::config::SensorModel {
        depth_noise_coeff_per_m: 2.0e-4,
        pixel_sigma_px: 0.5,
        depth_max_m: 3.0,
        ..default
    };
    let p = BackendParams::DEFAULT.with_sensor(sensor);
    for ba in [p.local, p.global] {
        assert_eq!(ba.sensor.depth_noise_coeff_per_m, 6.0e-4);
        assert_eq!((ba.sensor.pixel_sigma_px, ba.sensor.depth_max_m), (0.5, 3.0));
    }
    assert!(p.is_valid());
}

#[test]
fn advance_solve_checks_the_parameters_like_step() {
    let params = BackendParams { segment_keyframes: 0, ..BackendParams::DEFAULT };
    assert!(!params.is_valid());
    let mut backend = BoardBackend::with_params(params);
    assert_eq!(backend.advance_solve(5_000), Err(BackendError::InvalidParams));
    let mut map = BoardMap::new();
    assert_eq!(backend.step(&mut map, &camera(), 5_000), Err(BackendError::InvalidParams));
}

/// A keyframe made while a segmented global BA solves (and the landmark it hosts) was not in the
/// problem; the write-back moves both with their segment, so the newest keyframe keeps its pose
/// relative to the segment it grew from and still sees its landmark where it measured it.
#[test]
fn global_ba_moves_what_was_made_during_the_solve_with_its_segment() {
    use nalgebra::{Point3, Translation3, UnitQuaternion, Vector3};

    use super::BaKind;
    use crate::geometry::Pose;
    use crate::map::{KeyFrameId, Observation};

    let cam = camera();
    // Cameras 0.1 m apart along x, looking along +z; landmarks 2-3 m ahead.
    let truth = |i: u32| Pose::translation(0.1 * i as f32, 0.0, 0.0);
    let points: [Point3<f32>; 48] = core::array::from_fn(|j| {
        let (c, r) = ((j % 8) as f32, (j / 8) as f32);
        Point3::new(-0.8 + 0.25 * c, -0.5 + 0.2 * r, 2.0 + 0.1 * ((j * 7) % 10) as f32)
    });
    // Segment 1 (keyframes 2 and 3, and the one made during the solve) drifted by `drift`.
    let drift = Pose::from_parts(
        Translation3::new(0.02, -0.01, 0.015),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.01),
    );
    let believed = |i: u32| if i >= 2 { drift * truth(i) } else { truth(i) };
    let observe = |map: &mut BoardMap, kf: KeyFrameId, i: u32, lm, p_w: &Point3<f32>| {
        let p_c = truth(i).inverse() * p_w;
        let uv = cam.project(&p_c).unwrap_or_else(|| unreachable!("every point is in view"));
        let obs = Observation::new(lm, (uv.x, uv.y), Some(p_c.z));
        map.add_observation(kf, obs.unwrap_or_else(|| unreachable!())).unwrap();
    };
    let mut map = BoardMap::new();
    let kfs: [KeyFrameId; 4] =
        core::array::from_fn(|i| map.add_keyframe(believed(i as u32), i as f64).unwrap());
    for p in &points {
        let lm = map.add_landmark(*p, kfs[0]).unwrap();
        for (i, &kf) in kfs.iter().enumerate() {
            observe(&mut map, kf, i as u32, lm, p);
        }
    }
    let params = BackendParams { segment_keyframes: 2, ..BackendParams::DEFAULT };
    let mut backend = BoardBackend::with_params(params);
    backend.keyframe_added(kfs[3], 3);
    backend.pending = None; // no local BA first: the global one is due
    assert_eq!(backend.step(&mut map, &cam, 5_000), Ok(BackendStatus::Built(BaKind::Global)));

    // While it solves, the front end makes keyframe 4 (segment 2, not in the problem) and a
    // landmark hosted by it, both in segment 1's drifted world.
    let kf4 = map.add_keyframe(believed(4), 4.0).unwrap();
    let p_new = drift * Point3::new(0.3, 0.1, 2.5);
    let lm_new = map.add_landmark(p_new, kf4).unwrap();
    observe(&mut map, kf4, 4, lm_new, &(drift.inverse() * p_new));
    backend.keyframe_added(kf4, 4);
    let relative = |map: &BoardMap| {
        let (k3, k4) = (map.keyframe(kfs[3]).unwrap(), map.keyframe(kf4).unwrap());
        k3.t_wc.inverse() * k4.t_wc
    };
    let seen_from_4 = |map: &BoardMap| {
        map.keyframe(kf4).unwrap().t_wc.inverse() * map.landmark(lm_new).unwrap().p_w
    };
    let (relative_before, seen_before) = (relative(&map), seen_from_4(&map));
    let k3_before = map.keyframe(kfs[3]).unwrap().t_wc;

    let mut finished = false;
    for _ in 0..1_000 {
        match backend.step(&mut map, &cam, 5_000) {
            Ok(BackendStatus::Finished(BaKind::Global, _)) => {
                finished = true;
                break;
            }
            Ok(BackendStatus::Solving(BaKind::Global)) => {}
            other => panic!("unexpected step {other:?}"),
        }
    }
    assert!(finished, "the global BA finished");
    assert_eq!(backend.stats().global_runs, 1);
    let k3_after = map.keyframe(kfs[3]).unwrap().t_wc;
    let moved = (k3_after.translation.vector - k3_before.translation.vector).norm();
    assert!(moved > 0.01, "segment 1 moved back toward the truth ({moved} m)");
    let error = (k3_after.translation.vector - truth(3).translation.vector).norm();
    assert!(error < 0.005, "segment 1 is within 5 mm of the truth ({error} m)");
    let r = relative(&map);
    assert!((r.translation.vector - relative_before.translation.vector).norm() < 1e-4);
    assert!(r.rotation.angle_to(&relative_before.rotation) < 1e-4);
    assert!((seen_from_4(&map) - seen_before).norm() < 1e-4);
}

/// The host-scale back end on a map larger than the board's: 100 keyframes (the board holds 32)
/// that all see the same 100 landmarks, whose arena slots lie past the board's 1,024. The window
/// around the newest keyframe stops at the type's cap of 65 keyframes, the next 31 observers are
/// its fixed neighbours (96 rigs), and the solve pulls the window's drifted poses back.
#[test]
fn host_backend_fills_a_65_keyframe_window_in_a_large_map() {
    // The map (1 MB) and the back end are built on the stack before being boxed in a debug build.
    let run = std::thread::Builder::new().stack_size(16 << 20).spawn(fill_a_65_keyframe_window);
    run.unwrap().join().unwrap();
}

fn fill_a_65_keyframe_window() {
    use std::boxed::Box;

    use nalgebra::{Point3, Translation3, UnitQuaternion, Vector3};

    use super::{BaKind, HostBackend};
    use crate::config::HOST_MAP;
    use crate::config::capacity::LOCAL_WINDOW_MAX;
    use crate::geometry::Pose;
    use crate::map::{HostMap, KeyFrameId, Observation};

    const KEYFRAMES: u32 = 100;
    let cam = camera();
    // Cameras 3 mm apart along x, looking along +z at landmarks 2-3 m ahead.
    let truth = |i: u32| Pose::translation(0.003 * i as f32, 0.0, 0.0);
    let points: [Point3<f32>; 100] = core::array::from_fn(|j| {
        let (c, r) = ((j % 10) as f32, (j / 10) as f32);
        Point3::new(-0.6 + 0.13 * c, -0.6 + 0.13 * r, 2.0 + 0.1 * ((j * 7) % 10) as f32)
    });
    // The 40 newest keyframes drifted a little.
    let drift = Pose::from_parts(
        Translation3::new(0.004, -0.003, 0.002),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.002),
    );
    let believed = |i: u32| if i >= 60 { drift * truth(i) } else { truth(i) };
    let mut map: Box<HostMap> = Box::default();
    let kfs: std::vec::Vec<KeyFrameId> =
        (0..KEYFRAMES).map(|i| map.add_keyframe(believed(i), f64::from(i)).unwrap()).collect();
    // Landmarks nobody observes take the first 1,100 slots.
    for _ in 0..1_100 {
        map.add_landmark(Point3::new(0.0, 0.0, 2.0), kfs[0]).unwrap();
    }
    for p in &points {
        let lm = map.add_landmark(*p, kfs[0]).unwrap();
        assert!(lm.0.index() >= 1_100, "past the board's landmark slots");
        for (i, &kf) in (0..KEYFRAMES).zip(&kfs) {
            let p_c = truth(i).inverse() * p;
            let uv = cam.project(&p_c).unwrap_or_else(|| unreachable!("every point is in view"));
            let obs = Observation::new(lm, (uv.x, uv.y), Some(p_c.z)).unwrap();
            map.add_observation(kf, obs).unwrap();
        }
    }
    let newest = KEYFRAMES - 1;
    let error = |map: &HostMap| {
        let k = map.keyframe(kfs[newest as usize]).unwrap();
        (k.t_wc.translation.vector - truth(newest).translation.vector).norm()
    };
    let before = error(&map);
    let mut backend: Box<HostBackend> = Box::default();
    backend.keyframe_added(kfs[newest as usize], newest);
    assert_eq!(backend.step(&mut map, &cam, 5_000), Ok(BackendStatus::Built(BaKind::Local)));
    assert_eq!(backend.stats().window_sizes[LOCAL_WINDOW_MAX], 1, "a window of 65 keyframes");
    assert_eq!(backend.cameras.len(), HOST_MAP.ba_rigs, "65 in the window, 31 fixed neighbours");
    assert_eq!(backend.points.len(), points.len());
    let mut finished = false;
    for _ in 0..10_000 {
        match backend.step(&mut map, &cam, 5_000) {
            Ok(BackendStatus::Finished(BaKind::Local, _)) => {
                finished = true;
                break;
            }
            Ok(BackendStatus::Solving(BaKind::Local)) => {}
            other => panic!("unexpected step {other:?}"),
        }
    }
    assert!(finished, "the local BA finished");
    let after = error(&map);
    assert!(
        after < 0.25 * before,
        "the newest keyframe moved toward the truth: {before} -> {after} m"
    );
}

/// The window grows by one covisibility level at a time: in a chain of keyframes where each
/// shares landmarks only with its neighbours, the newest keyframe's window holds it and one more
/// keyframe per level, and `u8::MAX` levels take the whole chain (the window stops when no
/// keyframe joins).
#[test]
fn each_covisibility_level_adds_the_next_keyframe_of_a_chain() {
    use nalgebra::Point3;

    use super::BaKind;
    use crate::config::capacity::MAX_KEYFRAMES;
    use crate::geometry::Pose;
    use crate::map::{KeyFrameId, Observation};

    const KEYFRAMES: usize = 12;
    const SHARED: usize = 12;
    let cam = camera();
    let window_of = |levels: u8| {
        let mut map = std::boxed::Box::new(BoardMap::new());
        let kfs: std::vec::Vec<KeyFrameId> = (0..KEYFRAMES)
            .map(|i| map.add_keyframe(Pose::translation(0.01 * i as f32, 0.0, 0.0), i as f64))
            .collect::<Result<_, _>>()
            .unwrap();
        // Link i joins keyframes i and i + 1 with its own landmarks, seen by those two only.
        for link in 0..KEYFRAMES - 1 {
            for j in 0..SHARED {
                let p = Point3::new(-0.5 + 0.08 * j as f32, -0.2 + 0.04 * link as f32, 2.5);
                let lm = map.add_landmark(p, kfs[link]).unwrap();
                for &k in &kfs[link..=link + 1] {
                    let t_cw = map.keyframe(k).unwrap().t_wc.inverse();
                    let p_c = t_cw * p;
                    let uv = cam.project(&p_c).unwrap();
                    let obs = Observation::new(lm, (uv.x, uv.y), Some(p_c.z)).unwrap();
                    map.add_observation(k, obs).unwrap();
                }
            }
        }
        let params = BackendParams { window_levels: levels, ..BackendParams::DEFAULT };
        let mut backend = std::boxed::Box::new(BoardBackend::with_params(params));
        let newest = KEYFRAMES - 1;
        backend.keyframe_added(kfs[newest], newest as u32);
        assert_eq!(backend.step(&mut map, &cam, 5_000), Ok(BackendStatus::Built(BaKind::Local)));
        let sizes = &backend.stats().window_sizes;
        let built: std::vec::Vec<usize> = (0..sizes.len()).filter(|&n| sizes[n] > 0).collect();
        assert_eq!(built.len(), 1, "one window built: {built:?}");
        built[0]
    };
    const { assert!(KEYFRAMES <= MAX_KEYFRAMES) };
    assert_eq!(window_of(1), 2);
    assert_eq!(window_of(2), 3, "the default");
    assert_eq!(window_of(5), 6);
    assert_eq!(window_of(u8::MAX), KEYFRAMES, "the whole chain");
}
