//! The bundle adjuster on synthetic problems with known answers: convergence without noise,
//! error reduction with Kinect-like noise, Huber against outliers, fixed variables, segmented
//! (rig) mode, determinism across work quotas, bad input, sizes.

#[path = "support/ba_synth.rs"]
mod ba_synth;

use std::sync::Mutex;

use ba_synth::{Synth, SynthConfig, perturb, Rng};
use ferroslam_core::geometry::Pose;
use ferroslam_core::optim::{
    BaError, BaParams, BaStatus, BaSummary, BundleAdjuster, LocalBundleAdjuster, Termination,
};

/// The adjuster lives in a static, as on the board (`Mutex::new` and `new` are `const`).
static LOCAL: Mutex<LocalBundleAdjuster> = Mutex::new(LocalBundleAdjuster::new());

type Small = BundleAdjuster<16, 16, 256, 2048>;

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

fn local_errors<const R: usize, const C: usize, const P: usize, const O: usize>(
    ba: &BundleAdjuster<R, C, P, O>,
    synth: &Synth,
    cams: &[ferroslam_core::optim::CameraId],
    points: &[ferroslam_core::optim::PointId],
) -> (f64, f64, f64) {
    let (t, r) = synth.pose_rmse(|k| ba.camera_pose(cams[k]).unwrap());
    (t, r, synth.point_rmse(|i| ba.point(points[i]).unwrap()))
}

#[test]
fn noise_free_converges_to_truth() {
    let cfg = SynthConfig { pixel_noise_px: 0.0, depth_noise_coeff: 0.0, ..SynthConfig::SMALL };
    let synth = Synth::generate(&cfg);
    let mut ba = Box::new(Small::new());
    let (cams, points) = synth.fill_local(&mut ba).unwrap();
    let before = local_errors(&ba, &synth, &cams, &points);
    let params = BaParams { max_iterations: 30, ..BaParams::DEFAULT };
    let s = solve(&mut ba, &synth, &params, u32::MAX);
    let after = local_errors(&ba, &synth, &cams, &points);
    println!("noise-free: {s:?}\n  before {before:?}\n  after  {after:?}");
    assert_eq!(s.termination, Termination::Converged);
    // Only the storage rounding (1/64 px, 6e-5 /m) is left.
    assert!(after.0 < 2e-4 && after.1 < 2e-4 && after.2 < 5e-4, "{after:?}");
    assert!(s.final_cost < 1e-2 * s.initial_cost);
}

#[test]
fn realistic_noise_reduces_error() {
    let synth = Synth::generate(&SynthConfig::REALISTIC);
    let mut ba = LOCAL.lock().unwrap();
    let (cams, points) = synth.fill_local(&mut ba).unwrap();
    let before = local_errors(&ba, &synth, &cams, &points);
    let s = solve(&mut ba, &synth, &BaParams::DEFAULT, u32::MAX);
    let after = local_errors(&ba, &synth, &cams, &points);
    println!(
        "realistic ({} obs): {s:?}\n  before {before:?}\n  after  {after:?}",
        synth.observation_count()
    );
    assert!(after.0 < 0.2 * before.0, "translation {before:?} -> {after:?}");
    assert!(after.1 < 0.3 * before.1, "rotation {before:?} -> {after:?}");
    assert!(after.2 < 0.3 * before.2, "points {before:?} -> {after:?}");
}
