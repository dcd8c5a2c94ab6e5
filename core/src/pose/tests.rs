//! Known-answer tests of pose estimation on synthetic scenes.
//!
//! Test code only: this file is compiled under #[cfg(test)] (see the `mod` line that includes it).

extern crate std;
use nalgebra::{Point2, Point3, Translation3, UnitQuaternion, Vector3, Vector6};

use super::*;
use crate::geometry::{PinholeCamera, Pose, se3_exp};
use crate::test_rng::TestRng;

/// True depth noise coefficient of the synthetic sensor (Kinect v1), per metre.
const SENSOR_DEPTH_COEFF: f32 = 1.4e-3;

fn camera() -> PinholeCamera {
    PinholeCamera::new(525.0, 525.0, 319.5, 239.5, 640, 480).unwrap()
}

/// About 10 degrees of rotation and 0.3 m of translation.
fn truth() -> Pose {
    let axis = Vector3::new(1.0, 2.0, -1.0).normalize();
    Pose::from_parts(
        Translation3::new(0.2, -0.15, 0.16),
        UnitQuaternion::from_scaled_axis(axis * 10f32.to_radians()),
    )
}

/// `truth()` moved by about 5 cm and 3 degrees.
fn perturbed() -> Pose {
    let d = 0.05 / 3f32.sqrt();
    let r = 3f32.to_radians() / 3f32.sqrt();
    se3_exp(&Vector6::new(d, -d, d, r, r, -r)) * truth()
}

/// Translation (m) and rotation (deg) of `a` relative to `b`.
fn pose_error(a: &Pose, b: &Pose) -> (f32, f32) {
    let e = a * b.inverse();
    (e.translation.vector.norm(), e.rotation.angle().to_degrees())
}

struct Scene {
    corrs: heapless::Vec<Correspondence, MAX_CORRESPONDENCES>,
    outliers: InlierMask,
}

/// `n` points 1-4 m in front of the true camera over the whole image; pixel noise `noise_px`
/// (standard deviation), depth on a fraction `depth_fraction` of them (with Kinect noise when
/// `noise_px > 0`), and every correspondence with `i % 10 < outlier_tenths` replaced by a random
/// pixel (and random depth).
fn scene(n: usize, noise_px: f32, depth_fraction: f32, outlier_tenths: usize, seed: u64) -> Scene {
    let cam = camera();
    let t_wc = truth().inverse();
    let mut g = TestRng::new(seed);
    let mut s = Scene { corrs: heapless::Vec::new(), outliers: InlierMask::new() };
    for i in 0..n {
        let (u, v, z) =
            (g.uniform_f32(5.0, 634.0), g.uniform_f32(5.0, 474.0), g.uniform_f32(1.0, 4.0));
        let p_w = t_wc * cam.back_project(u, v, z);
        let mut uv = Point2::new(u + noise_px * g.normal_f32(), v + noise_px * g.normal_f32());
        let depth_noise =
            if noise_px > 0.0 { SENSOR_DEPTH_COEFF * z * z * g.normal_f32() } else { 0.0 };
        let mut depth_m = (g.unit_f32() < depth_fraction).then_some(z + depth_noise);
        if i % 10 < outlier_tenths {
            uv = Point2::new(g.uniform_f32(0.0, 639.0), g.uniform_f32(0.0, 479.0));
            depth_m = depth_m.map(|_| g.uniform_f32(1.0, 4.0));
            s.outliers.insert(i);
        }
        s.corrs.push(Correspondence { p_w, uv, depth_m }).unwrap();
    }
    s
}

/// Fraction of correspondences whose inlier flag matches the truth.
fn flag_accuracy(est: &PoseEstimate, s: &Scene) -> f32 {
    let right = (0..s.corrs.len()).filter(|&i| est.inliers.contains(i) != s.outliers.contains(i));
    right.count() as f32 / s.corrs.len() as f32
}

#[test]
fn noiseless_pose_is_recovered_from_a_perturbed_guess() {
    for depth_fraction in [0.0, 0.5, 1.0] {
        let s = scene(100, 0.0, depth_fraction, 0, 7);
        let est =
            refine_pose(&camera(), &s.corrs, &perturbed(), None, &PoseParams::default()).unwrap();
        let (dt, dr) = pose_error(&est.t_cw, &truth());
        std::eprintln!("noiseless depth {depth_fraction}: {dt:e} m {dr:e} deg {est:?}");
        assert!(dt < 1e-3 && dr < 0.05, "{dt} m, {dr} deg");
        assert_eq!(est.num_inliers, 100);
        assert!(est.rms_reprojection_px < 0.01 && est.converged);
    }
}

#[test]
fn noisy_pose_is_within_millimetres() {
    for depth_fraction in [0.0, 0.7] {
        let s = scene(200, 0.5, depth_fraction, 0, 11);
        let est =
            refine_pose(&camera(), &s.corrs, &perturbed(), None, &PoseParams::default()).unwrap();
        let (dt, dr) = pose_error(&est.t_cw, &truth());
        std::eprintln!("noisy depth {depth_fraction}: {dt:e} m {dr:e} deg rms {}", {
            est.rms_reprojection_px
        });
        assert!(dt < 5e-3 && dr < 0.1, "{dt} m, {dr} deg");
        assert!(est.num_inliers >= 190, "{}", est.num_inliers);
        // The RMS is of the 2D error norm: sqrt(2) * 0.5 px.
        assert!((est.rms_reprojection_px - 0.707).abs() < 0.1);
        assert!(est.sigma_translation_m < 0.01 && est.sigma_rotation_rad < 0.01);
    }
}

#[test]
fn ransac_recovers_the_pose_and_flags_outliers() {
    let s = scene(200, 0.5, 0.7, 3, 23);
    let params = PoseParams::default();
    let mut rng = TrackingRng::new(42);
    let est = track_pose(&camera(), &s.corrs, None, &params, &mut rng).unwrap();
    let (dt, dr) = pose_error(&est.t_cw, &truth());
    let acc = flag_accuracy(&est, &s);
    std::eprintln!("ransac 30% outliers: {dt:e} m {dr:e} deg flags {acc} {est:?}");
    assert!(dt < 5e-3 && dr < 0.1, "{dt} m, {dr} deg");
    assert!(acc > 0.95, "{acc}");

    // A far-off prediction (30 cm, 20 deg) is refined, rejected and replaced by RANSAC.
    let bad = se3_exp(&Vector6::new(0.3, 0.0, 0.0, 0.0, 0.35, 0.0)) * truth();
    let est2 = track_pose(&camera(), &s.corrs, Some(&bad), &params, &mut rng).unwrap();
    let (dt, dr) = pose_error(&est2.t_cw, &truth());
    assert!(dt < 5e-3 && dr < 0.1, "{dt} m, {dr} deg");
    assert!(flag_accuracy(&est2, &s) > 0.95);

    // A good prediction with outliers: robust refinement alone flags them.
    let est3 = track_pose(&camera(), &s.corrs, Some(&perturbed()), &params, &mut rng).unwrap();
    let (dt, dr) = pose_error(&est3.t_cw, &truth());
    std::eprintln!("refine 30% outliers: {dt:e} m {dr:e} deg flags {}", flag_accuracy(&est3, &s));
    assert!(dt < 5e-3 && dr < 0.1, "{dt} m, {dr} deg");
    assert!(flag_accuracy(&est3, &s) > 0.95);
}

#[test]
fn ransac_is_deterministic_for_a_seed() {
    let s = scene(150, 0.5, 0.6, 3, 5);
    let run = |seed| {
        ransac_pose(&camera(), &s.corrs, &PoseParams::default(), &mut TrackingRng::new(seed))
            .unwrap()
    };
    assert_eq!(run(9), run(9));
}

#[test]
fn too_few_correspondences_are_errors() {
    let s = scene(20, 0.0, 1.0, 0, 3);
    let p = PoseParams::default();
    let r = refine_pose(&camera(), &s.corrs[..2], &truth(), None, &p);
    assert_eq!(r, Err(PoseError::TooFewCorrespondences { count: 2, required: 3 }));
    // Ten exact points are a fine pose but fewer than min_inliers (15).
    let r = refine_pose(&camera(), &s.corrs[..10], &truth(), None, &p);
    assert_eq!(r, Err(PoseError::TooFewInliers { inliers: 10, required: 15 }));
    let no_depth = scene(20, 0.0, 0.0, 0, 3);
    let r = ransac_pose(&camera(), &no_depth.corrs, &p, &mut TrackingRng::new(1));
    assert_eq!(r, Err(PoseError::TooFewCorrespondences { count: 0, required: 3 }));
    let r = track_pose(&camera(), &[], None, &p, &mut TrackingRng::new(1));
    assert!(matches!(r, Err(PoseError::TooFewCorrespondences { .. })));
}

#[test]
fn degenerate_scenes_are_errors_not_panics() {
    let cam = camera();
    let t_wc = truth().inverse();
    let p = PoseParams::default();
    let line = |k: usize| Point3::new(-0.5, -0.3, 1.5) + Vector3::new(0.04, 0.02, 0.05) * k as f32;
    let identical = |_: usize| cam.back_project(300.0, 200.0, 2.0);
    for make in [&line as &dyn Fn(usize) -> Point3<f32>, &identical] {
        for depth in [false, true] {
            let corrs: heapless::Vec<Correspondence, 64> = (0..30)
                .map(|k| {
                    let p_c = make(k);
                    let uv = cam.project(&p_c).unwrap();
                    Correspondence { p_w: t_wc * p_c, uv, depth_m: depth.then_some(p_c.z) }
                })
                .collect();
            let r = refine_pose(&cam, &corrs, &perturbed(), None, &p);
            assert!(matches!(r, Err(PoseError::Degenerate)), "{r:?}");
            let r = track_pose(&cam, &corrs, Some(&perturbed()), &p, &mut TrackingRng::new(3));
            assert!(r.is_err(), "{r:?}");
        }
    }
}

#[test]
fn bad_input_is_an_error() {
    let s = scene(30, 0.0, 1.0, 0, 4);
    let cam = camera();
    let p = PoseParams::default();
    let mut rng = TrackingRng::new(1);
    let cases: [fn(&mut Correspondence); 5] = [
        |c| c.p_w.x = f32::NAN,
        |c| c.uv.y = f32::INFINITY,
        |c| c.depth_m = Some(f32::NAN),
        |c| c.depth_m = Some(0.0),
        |c| c.p_w.z = f32::NEG_INFINITY,
    ];
    for spoil in cases {
        let mut corrs = s.corrs.clone();
        spoil(&mut corrs[17]);
        let want = Err(PoseError::InvalidCorrespondence { index: 17 });
        assert_eq!(refine_pose(&cam, &corrs, &truth(), None, &p), want);
        assert_eq!(ransac_pose(&cam, &corrs, &p, &mut rng), want);
        assert_eq!(track_pose(&cam, &corrs, Some(&truth()), &p, &mut rng), want);
    }
    let many = [s.corrs[0]; MAX_CORRESPONDENCES + 1];
    let r = refine_pose(&cam, &many, &truth(), None, &p);
    assert_eq!(r, Err(PoseError::TooManyCorrespondences { count: MAX_CORRESPONDENCES + 1 }));
    let bad = PoseParams {
        sensor: crate::config::SensorModel { pixel_sigma_px: f32::NAN, ..p.sensor },
        ..p
    };
    assert_eq!(refine_pose(&cam, &s.corrs, &truth(), None, &bad), Err(PoseError::InvalidParams));
    let bad = PoseParams { ransac_confidence: 1.0, ..p };
    assert_eq!(ransac_pose(&cam, &s.corrs, &bad, &mut rng), Err(PoseError::InvalidParams));
    // A NaN prediction is not input error: it fails to refine and RANSAC takes over.
    let nan_pose = Pose::from_parts(Translation3::new(f32::NAN, 0.0, 0.0), truth().rotation);
    let est = track_pose(&cam, &s.corrs, Some(&nan_pose), &p, &mut rng).unwrap();
    assert!(pose_error(&est.t_cw, &truth()).0 < 1e-3);
}

#[test]
fn errors_display() {
    let mut text = heapless::String::<96>::new();
    let e = PoseError::TooFewInliers { inliers: 4, required: 15 };
    core::fmt::write(&mut text, format_args!("{e}")).unwrap();
    assert_eq!(text.as_str(), "4 inliers, need 15");
}

#[test]
fn ransac_succeeds_over_many_seeds_and_scenes() {
    let params = PoseParams::default();
    let (mut worst_t, mut worst_r, mut worst_flags) = (0.0f32, 0.0f32, 1.0f32);
    for seed in 1..=25 {
        let s = scene(80, 0.5, 0.6, 3, 1000 + seed);
        let est = ransac_pose(&camera(), &s.corrs, &params, &mut TrackingRng::new(seed)).unwrap();
        let (dt, dr) = pose_error(&est.t_cw, &truth());
        worst_t = worst_t.max(dt);
        worst_r = worst_r.max(dr);
        worst_flags = worst_flags.min(flag_accuracy(&est, &s));
    }
    std::eprintln!(
        "25 scenes of 80, 30% outliers: worst {worst_t:e} m {worst_r:e} deg {worst_flags}"
    );
    assert!(worst_t < 1e-2 && worst_r < 0.2 && worst_flags > 0.95);
    std::eprintln!(
        "sizes: PoseEstimate {} B, InlierMask {} B, Correspondence {} B, MotionModel {} B",
        core::mem::size_of::<PoseEstimate>(),
        core::mem::size_of::<InlierMask>(),
        core::mem::size_of::<Correspondence>(),
        core::mem::size_of::<MotionModel>()
    );
}

/// The tests' generator is the RANSAC generator's algorithm: the same `next_u32` stream for a seed
/// (the product's generator stays apart from test code).
#[test]
fn the_test_generator_draws_the_ransac_stream() {
    for seed in [0, 1, 42, u64::MAX] {
        let (mut test, mut product) = (TestRng::new(seed), TrackingRng::new(seed));
        for _ in 0..100 {
            assert_eq!(test.next_u32(), product.next_u32(), "seed {seed}");
        }
    }
}
