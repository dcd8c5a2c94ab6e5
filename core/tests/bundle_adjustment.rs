//! The bundle adjuster on synthetic problems with known answers: convergence without noise,
//! error reduction with Kinect-like noise, Huber against outliers, fixed variables, segmented
//! (rig) mode, determinism across work quotas, bad input, sizes.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

#[path = "support/ba_synth.rs"]
mod ba_synth;

use std::sync::Mutex;

use ba_synth::{
    LocalBundleAdjuster, SEGMENT_CFG, SegmentedBundleAdjuster, Synth, SynthConfig, segmented,
};
use ferroslam_core::config::SensorModel;
use ferroslam_core::geometry::Pose;
use ferroslam_core::optim::{
    BaError, BaParams, BaStatus, BaSummary, BundleAdjuster, CameraId, PointId, Termination,
    VariableKind,
};
use nalgebra::{Point2, Point3};

/// The adjuster lives in a static, as on the board (`Mutex::new` and `new` are `const`).
static LOCAL: Mutex<LocalBundleAdjuster> = Mutex::new(LocalBundleAdjuster::new());

type Small = BundleAdjuster<16, 40, 512, 4096>;

/// Runs the solve to the end in steps of `quota` units.
fn solve<const R: usize, const C: usize, const P: usize, const O: usize>(
    ba: &mut BundleAdjuster<R, C, P, O>,
    synth: &Synth,
    params: &BaParams,
    quota: u32,
) -> BaSummary {
    ba.start(&synth.camera, params).unwrap();
    loop {
        if let BaStatus::Finished(s) = ba.step(quota).unwrap() {
            return s;
        }
    }
}

/// (camera-centre RMSE m, rotation RMSE rad, point RMSE m) over the free variables.
fn local_errors<const R: usize, const C: usize, const P: usize, const O: usize>(
    ba: &BundleAdjuster<R, C, P, O>,
    synth: &Synth,
    cams: &[CameraId],
    points: &[PointId],
) -> (f64, f64, f64) {
    let (t, r) = synth.pose_rmse(|k| ba.camera_pose(cams[k]).unwrap());
    (t, r, synth.point_rmse(|i| ba.point(points[i]).unwrap()))
}

/// Every output bit of a local problem: camera poses and points.
fn output_bits<const R: usize, const C: usize, const P: usize, const O: usize>(
    ba: &BundleAdjuster<R, C, P, O>,
    cams: &[CameraId],
    points: &[PointId],
) -> Vec<u32> {
    let mut bits = Vec::new();
    for &c in cams {
        let t = ba.camera_pose(c).unwrap();
        bits.extend(t.rotation.coords.iter().map(|x| x.to_bits()));
        bits.extend(t.translation.vector.iter().map(|x| x.to_bits()));
    }
    for &p in points {
        bits.extend(ba.point(p).unwrap().iter().map(|x| x.to_bits()));
    }
    bits
}

#[test]
fn noise_free_converges_to_truth() {
    let cfg = SynthConfig { pixel_noise_px: 0.0, depth_noise_coeff: 0.0, ..SynthConfig::SMALL };
    let synth = Synth::generate(&cfg);
    let mut ba = Box::new(Small::new());
    let f = synth.fill_local(&mut ba).unwrap();
    let before = local_errors(&ba, &synth, &f.cams, &f.points);
    let s = solve(&mut ba, &synth, &BaParams::DEFAULT, u32::MAX);
    let after = local_errors(&ba, &synth, &f.cams, &f.points);
    println!("noise-free: {s:?}\n  before {before:?}\n  after  {after:?}");
    assert_eq!(s.termination, Termination::Converged);
    assert!(before.0 > 0.02 && before.2 > 0.03, "the start is off: {before:?}");
    // Only the storage rounding (1/64 px, 6e-5 /m) is left: 0.1 mm, 0.1 mrad.
    assert!(after.0 < 2e-4 && after.1 < 2e-4 && after.2 < 5e-4, "{after:?}");
    assert!(s.final_cost < 1e-4 * s.initial_cost);
    assert_eq!(s.valid_observations as usize, synth.observation_count());
}

#[test]
fn realistic_noise_reduces_error() {
    let synth = Synth::generate(&SynthConfig::REALISTIC);
    let mut ba = LOCAL.lock().unwrap();
    let f = synth.fill_local(&mut ba).unwrap();
    let before = local_errors(&ba, &synth, &f.cams, &f.points);
    let s = solve(&mut ba, &synth, &BaParams::DEFAULT, u32::MAX);
    let after = local_errors(&ba, &synth, &f.cams, &f.points);
    println!(
        "realistic ({} obs): {s:?}\n  before {before:?}\n  after  {after:?}",
        synth.observation_count()
    );
    assert_eq!(s.termination, Termination::Converged);
    // 3.4 cm, 0.87 deg and 5 cm at the start; the optimum with this noise is near 2.3 mm,
    // 0.08 deg and 7 mm.
    assert!(after.0 < 0.1 * before.0 && after.0 < 0.004, "translation {before:?} -> {after:?}");
    assert!(after.1 < 0.15 * before.1 && after.1 < 0.002, "rotation {before:?} -> {after:?}");
    assert!(after.2 < 0.2 * before.2 && after.2 < 0.01, "points {before:?} -> {after:?}");
    // The cost is near its expectation: about one per whitened residual (0.7 px noise at 1 px
    // sigma: 0.49 per pixel residual; depth noise below its sigma).
    let residuals = synth.observation_count() as f32 * 2.9;
    assert!(s.final_cost < 0.5 * residuals, "{}", s.final_cost);
}

#[test]
fn huber_down_weights_outliers() {
    let cfg = SynthConfig { outlier_fraction: 0.05, ..SynthConfig::REALISTIC };
    let synth = Synth::generate(&cfg);
    let mut ba = LOCAL.lock().unwrap();
    let sensor = SensorModel { huber_delta_px: 1.0e4, ..SensorModel::DEFAULT };
    let least_squares = BaParams { sensor, ..BaParams::DEFAULT };
    let mut errors = Vec::new();
    for params in [least_squares, BaParams::DEFAULT] {
        let f = synth.fill_local(&mut ba).unwrap();
        let s = solve(&mut ba, &synth, &params, u32::MAX);
        errors.push(local_errors(&ba, &synth, &f.cams, &f.points));
        println!("delta {} px: {s:?} -> {:?}", params.sensor.huber_delta_px, errors.last());
    }
    let (ls, huber) = (errors[0], errors[1]);
    assert!(huber.0 < 0.6 * ls.0 && huber.2 < 0.6 * ls.2, "Huber {huber:?} LS {ls:?}");
    assert!(huber.0 < 0.006 && huber.2 < 0.02, "{huber:?}");
    // After the robust solve (the last one) the chi-square gates separate outliers.
    let f_ids = synth.fill_local(&mut ba);
    let f = f_ids.unwrap();
    solve(&mut ba, &synth, &BaParams::DEFAULT, u32::MAX);
    let (mut flagged_out, mut flagged_in) = (0usize, 0usize);
    for (&id, &outlier) in f.obs.iter().zip(&f.outlier) {
        let r = ba.observation_residual(id).unwrap();
        let flagged = r.chi2_reprojection > 5.991 || r.chi2_depth.is_some_and(|d| d > 3.841);
        flagged_out += usize::from(outlier && flagged);
        flagged_in += usize::from(!outlier && flagged);
    }
    let n_out = f.outlier.iter().filter(|&&o| o).count();
    let n_in = f.outlier.len() - n_out;
    println!("flagged {flagged_out}/{n_out} outliers, {flagged_in}/{n_in} inliers");
    assert!(n_out > 200);
    assert!(flagged_out as f64 > 0.95 * n_out as f64);
    assert!((flagged_in as f64) < 0.10 * n_in as f64);
}

#[test]
fn fixed_variables_stay_bit_exact() {
    let cfg = SynthConfig { fixed_keyframes: 3, fixed_point_fraction: 0.3, ..SynthConfig::SMALL };
    let synth = Synth::generate(&cfg);
    let mut ba = Box::new(Small::new());
    let f = synth.fill_local(&mut ba).unwrap();
    let s = solve(&mut ba, &synth, &BaParams::DEFAULT, u32::MAX);
    assert_eq!(s.termination, Termination::Converged);
    let bits = |t: &Pose| {
        let mut v: Vec<u32> = t.rotation.coords.iter().map(|x| x.to_bits()).collect();
        v.extend(t.translation.vector.iter().map(|x| x.to_bits()));
        v
    };
    let mut moved = 0;
    for (k, &c) in f.cams.iter().enumerate() {
        let now = ba.camera_pose(c).unwrap();
        if synth.fixed_keyframe[k] {
            assert_eq!(bits(&now), bits(&synth.start_t_cw[k]), "keyframe {k}");
        } else {
            moved += usize::from(bits(&now) != bits(&synth.start_t_cw[k]));
        }
    }
    for (i, &p) in f.points.iter().enumerate() {
        let now = ba.point(p).unwrap();
        if synth.fixed_point[i] {
            let start = synth.start_p_w[i];
            assert!(now.iter().zip(start.iter()).all(|(a, b)| a.to_bits() == b.to_bits()));
        }
    }
    assert_eq!(moved, cfg.keyframes - 3);
    assert!(synth.fixed_point.iter().filter(|&&f| f).count() > 20);
}

#[test]
fn segmented_mode_recovers_segment_poses() {
    let mut ba = Box::new(SegmentedBundleAdjuster::new());
    // Noise-free: back to the truth.
    let cfg = SynthConfig { pixel_noise_px: 0.0, depth_noise_coeff: 0.0, ..SEGMENT_CFG };
    let seg = segmented(&cfg, 5, ba.as_mut()).unwrap();
    let before = seg.rig_error(|r| ba.rig_pose(r).unwrap());
    let s = solve(&mut ba, &seg.synth, &BaParams::DEFAULT, u32::MAX);
    let after = seg.rig_error(|r| ba.rig_pose(r).unwrap());
    println!("segments, noise-free: {before} -> {after} m, {s:?}");
    assert_eq!(s.termination, Termination::Converged);
    assert!(before > 0.01 && after < 3e-4, "{before} -> {after}");
    assert!(seg.synth.point_rmse(|i| ba.point(seg.filled.points[i]).unwrap()) < 5e-4);
    // Inside a segment the relative poses are those given, whatever the rig did.
    for k in 0..cfg.keyframes {
        let (c, c0) = (seg.filled.cams[k], seg.filled.cams[5 * (k / 5)]);
        let rel = ba.camera_pose(c).unwrap() * ba.camera_pose(c0).unwrap().inverse();
        let want = seg.synth.true_t_cw[k] * seg.synth.true_t_cw[5 * (k / 5)].inverse();
        assert!((rel.translation.vector - want.translation.vector).norm() < 1e-5);
        assert!(rel.rotation.angle_to(&want.rotation) < 1e-5);
        assert_eq!(ba.camera_rig(c), Some(seg.rigs[k / 5]));
    }
    // With noise: the segment poses are still pulled close to the truth.
    let seg = segmented(&SEGMENT_CFG, 5, ba.as_mut()).unwrap();
    let before = seg.rig_error(|r| ba.rig_pose(r).unwrap());
    let s = solve(&mut ba, &seg.synth, &BaParams::DEFAULT, u32::MAX);
    let after = seg.rig_error(|r| ba.rig_pose(r).unwrap());
    println!("segments, noisy: {before} -> {after} m, {s:?}");
    assert!(after < 0.15 * before && after < 0.004, "{before} -> {after}");
}

#[test]
fn results_do_not_depend_on_the_work_quota() {
    let cfg = SynthConfig { outlier_fraction: 0.05, ..SynthConfig::SMALL };
    let synth = Synth::generate(&cfg);
    let mut runs = Vec::new();
    for quota in [1, 1000, u32::MAX] {
        let mut ba = Box::new(Small::new());
        let f = synth.fill_local(&mut ba).unwrap();
        ba.start(&synth.camera, &BaParams::DEFAULT).unwrap();
        let mut steps = 0u64;
        let summary = loop {
            let before = ba.summary().work_units;
            let status = ba.step(quota).unwrap();
            // No step exceeds its quota.
            assert!(ba.summary().work_units - before <= u64::from(quota));
            steps += 1;
            if let BaStatus::Finished(s) = status {
                break s;
            }
        };
        println!("quota {quota}: {steps} steps, {summary:?}");
        runs.push((output_bits(&ba, &f.cams, &f.points), summary));
    }
    assert_eq!(runs[0].1.termination, Termination::Converged);
    assert!(runs[0].1.work_units > 50_000, "quota 1 really took many steps");
    for run in &runs[1..] {
        assert_eq!(run.0, runs[0].0);
        assert_eq!(run.1, runs[0].1);
    }
    // Segmented mode too (offsets, rig runs), split at an odd quota.
    let mut bits = Vec::new();
    for quota in [7, u32::MAX] {
        let mut ba = Box::new(SegmentedBundleAdjuster::new());
        let seg = segmented(&SynthConfig { points: 200, ..SEGMENT_CFG }, 5, ba.as_mut()).unwrap();
        solve(&mut ba, &seg.synth, &BaParams::DEFAULT, quota);
        bits.push(output_bits(&ba, &seg.filled.cams, &seg.filled.points));
    }
    assert_eq!(bits[0], bits[1]);
}

#[test]
fn without_fixed_variables_the_damping_holds_the_gauge() {
    let cfg =
        SynthConfig { fixed_keyframes: 0, fixed_point_fraction: 0.0, ..SynthConfig::REALISTIC };
    let synth = Synth::generate(&cfg);
    let mut ba = LOCAL.lock().unwrap();
    // The default solve, and a much tighter one as the reference optimum.
    let tight = BaParams {
        pcg_max_iterations: 100,
        pcg_relative_tolerance: 1e-3,
        function_tolerance: 1e-7,
        max_iterations: 30,
        ..BaParams::DEFAULT
    };
    let mut solutions = Vec::new();
    for params in [BaParams::DEFAULT, tight] {
        let f = synth.fill_local(&mut ba).unwrap();
        let s = solve(&mut ba, &synth, &params, u32::MAX);
        println!("gauge free: {s:?}");
        assert_eq!(s.termination, Termination::Converged);
        assert!(s.final_cost < 0.05 * s.initial_cost);
        // Poses relative to keyframe 0: the gauge (a rigid motion of everything) drops out.
        let t0 = ba.camera_pose(f.cams[0]).unwrap();
        let rel: Vec<Pose> =
            f.cams.iter().map(|&c| ba.camera_pose(c).unwrap() * t0.inverse()).collect();
        solutions.push((s.final_cost, rel));
    }
    let ((cost, rel), (cost_ref, rel_ref)) = (&solutions[0], &solutions[1]);
    assert!((cost - cost_ref).abs() < 1e-4 * cost_ref);
    let mut worst_vs_ref = 0.0f32;
    let mut worst_vs_truth = 0.0f32;
    for k in 1..cfg.keyframes {
        let truth = synth.true_t_cw[k] * synth.true_t_cw[0].inverse();
        let d = |a: &Pose, b: &Pose| (a.translation.vector - b.translation.vector).norm();
        worst_vs_ref = worst_vs_ref.max(d(&rel[k], &rel_ref[k]));
        worst_vs_truth = worst_vs_truth.max(d(&rel[k], &truth));
    }
    // Unanchored, the optimum itself drifts by about 2 cm over the 3.2 m of the window.
    println!(
        "relative translation: {worst_vs_ref} m from the reference, {worst_vs_truth} m from the truth"
    );
    assert!(worst_vs_ref < 1e-3 && worst_vs_truth < 0.03);
}

#[test]
fn bad_input_is_refused_with_errors() {
    let mut ba = Box::new(BundleAdjuster::<2, 2, 2, 3>::new());
    let cam = ba_synth::qvga_camera();
    assert_eq!(ba.step(10), Err(BaError::NotStarted));
    let nan_pose = Pose::from_parts(
        nalgebra::Translation3::new(f32::NAN, 0.0, 0.0),
        nalgebra::UnitQuaternion::identity(),
    );
    assert_eq!(ba.add_keyframe(&nan_pose, false), Err(BaError::InvalidPose));
    let k0 = ba.add_keyframe(&Pose::identity(), true).unwrap();
    let r1 = ba.add_rig(&Pose::identity(), false).unwrap();
    let k1 = ba.add_camera(r1, &Pose::identity()).unwrap();
    let full = BaError::Full { kind: VariableKind::Camera, capacity: 2 };
    assert_eq!(ba.add_camera(r1, &Pose::identity()), Err(full));
    assert_eq!(ba.add_keyframe(&Pose::identity(), false), Err(full));
    let p_nan = Point3::new(0.0, f32::NAN, 1.0);
    assert_eq!(ba.add_point(&p_nan, false), Err(BaError::InvalidPoint));
    let p = ba.add_point(&Point3::new(0.0, 0.0, 2.0), false).unwrap();
    let uv = Point2::new(160.0, 120.0);
    for bad in [f32::NAN, f32::INFINITY, -2.0, 5000.0] {
        let e = ba.add_observation(p, k0, Point2::new(bad, 1.0), None);
        assert!(matches!(e, Err(BaError::InvalidPixel { .. })), "{bad}");
    }
    for bad in [0.0, -1.0, f32::NAN, 0.05] {
        let e = ba.add_observation(p, k0, uv, Some(bad));
        assert!(matches!(e, Err(BaError::InvalidDepth { .. })), "{bad}");
    }
    ba.add_observation(p, k0, uv, Some(2.0)).unwrap();
    ba.add_observation(p, k1, uv, None).unwrap();
    let q = ba.add_point(&Point3::new(0.1, 0.0, 2.0), false).unwrap();
    assert_eq!(
        ba.add_observation(p, k0, uv, None),
        Err(BaError::ObservationNotGrouped { point: 0 })
    );
    ba.add_observation(q, k0, uv, None).unwrap();
    let full = BaError::Full { kind: VariableKind::Observation, capacity: 3 };
    assert_eq!(ba.add_observation(q, k1, uv, None), Err(full));
    let full = BaError::Full { kind: VariableKind::Point, capacity: 2 };
    assert_eq!(ba.add_point(&Point3::origin(), true), Err(full));
    let sensor = SensorModel { pixel_sigma_px: -1.0, ..SensorModel::DEFAULT };
    let bad_params = BaParams { sensor, ..BaParams::DEFAULT };
    assert_eq!(ba.start(&cam, &bad_params), Err(BaError::InvalidParams));
    ba.start(&cam, &BaParams::DEFAULT).unwrap();
    assert_eq!(ba.add_point(&Point3::origin(), false), Err(BaError::Busy));
    assert!(matches!(ba.step(u32::MAX), Ok(BaStatus::Finished(_))));
    // Error messages are readable.
    assert_eq!(BaError::Busy.to_string(), "a solve is under way: clear the adjuster first");
    ba.clear();
    assert_eq!(ba.counts(), (0, 0, 0, 0));
    assert_eq!(ba.camera_pose(k0), None);
    assert!(ba.add_keyframe(&Pose::identity(), false).is_ok());
}

#[test]
fn degenerate_problems_end_without_panicking() {
    let cam = ba_synth::qvga_camera();
    let mut ba = Box::new(Small::new());
    let run = |ba: &mut Small| {
        ba.start(&cam, &BaParams::DEFAULT).unwrap();
        match ba.step(u32::MAX).unwrap() {
            BaStatus::Finished(s) => s,
            BaStatus::Running => panic!("an unbounded step finishes"),
        }
    };
    // Empty.
    assert_eq!(run(&mut ba).termination, Termination::NothingToOptimize);
    // All fixed: nothing moves.
    let synth = Synth::generate(&SynthConfig {
        fixed_keyframes: 10,
        fixed_point_fraction: 1.0,
        ..SynthConfig::SMALL
    });
    let f = synth.fill_local(&mut ba).unwrap();
    let start = output_bits(&ba, &f.cams, &f.points);
    assert_eq!(run(&mut ba).termination, Termination::NothingToOptimize);
    assert_eq!(output_bits(&ba, &f.cams, &f.points), start);
    // One free keyframe, one point seen once without depth, one point behind the camera, a
    // free keyframe that sees nothing, and a cluster of coincident points.
    ba.clear();
    let k0 = ba.add_keyframe(&Pose::identity(), false).unwrap();
    let lonely = ba.add_keyframe(&Pose::identity(), false).unwrap();
    let p = ba.add_point(&Point3::new(0.1, 0.1, 2.0), false).unwrap();
    ba.add_observation(p, k0, Point2::new(170.0, 130.0), None).unwrap();
    let behind = ba.add_point(&Point3::new(0.0, 0.0, -1.0), false).unwrap();
    ba.add_observation(behind, k0, Point2::new(160.0, 120.0), Some(1.0)).unwrap();
    for i in 0..20 {
        let q = ba.add_point(&Point3::new(0.3, -0.2, 3.0), false).unwrap();
        let uv = Point2::new(190.0 + (i % 3) as f32, 100.0 - (i % 5) as f32);
        ba.add_observation(q, k0, uv, Some(3.0 + 0.01 * i as f32)).unwrap();
    }
    let s = run(&mut ba);
    println!("degenerate: {s:?}");
    assert!(s.final_cost.is_finite() && s.final_cost <= s.initial_cost);
    assert_eq!(s.valid_observations, 21, "the point behind the camera stays out");
    assert_eq!(ba.camera_pose(lonely), Some(Pose::identity()));
    let t = ba.camera_pose(k0).unwrap();
    assert!(t.translation.vector.iter().all(|x| x.is_finite()));
    assert!(ba.point(p).unwrap().iter().all(|x| x.is_finite()));
    // Extreme but finite input: no panic, the estimate stays finite.
    ba.clear();
    let k = ba.add_keyframe(&Pose::identity(), false).unwrap();
    for z in [1e30f32, 1e-30, 3.0e38] {
        let q = ba.add_point(&Point3::new(z, z, z), false).unwrap();
        ba.add_observation(q, k, Point2::new(1.0, 1.0), Some(1.0)).unwrap();
    }
    let s = run(&mut ba);
    println!("extreme: {s:?}");
    assert!(ba.camera_pose(k).unwrap().translation.vector.iter().all(|x| x.is_finite()));
}

#[test]
fn restart_continues_from_the_estimate() {
    let synth = Synth::generate(&SynthConfig::SMALL);
    let mut ba = Box::new(Small::new());
    synth.fill_local(&mut ba).unwrap();
    let first = solve(&mut ba, &synth, &BaParams::DEFAULT, u32::MAX);
    let second = solve(&mut ba, &synth, &BaParams::DEFAULT, u32::MAX);
    assert_eq!(second.initial_cost, first.final_cost);
    assert!(second.final_cost <= second.initial_cost);
    assert!(second.iterations <= 2, "{second:?}");
}

#[test]
fn sizes_are_as_documented() {
    use std::mem::size_of;
    println!(
        "local {} segmented {}",
        size_of::<LocalBundleAdjuster>(),
        size_of::<SegmentedBundleAdjuster>()
    );
    assert_eq!(size_of::<LocalBundleAdjuster>(), 124_328);
    assert_eq!(size_of::<SegmentedBundleAdjuster>(), 99_504);
}
