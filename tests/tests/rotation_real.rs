//! The small-image rotation (`pose::small_image_rotation`) against 7-Scenes' ground truth: the front end's
//! iteration settings ([`RotationParams::DEFAULT`]) are as close to the truth as Gauss-Newton
//! converged on both levels ([`RotationParams::CONVERGED`]), because the estimate's error comes
//! from its pure-rotation model (the camera also translates), not from the last iterations.
//! Run with `--nocapture` to see the figures.

// The helpers below are test code too (clippy only exempts `#[test]` functions themselves).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use ferroslam_core::geometry::PinholeCamera;
use ferroslam_core::pose::small_image_rotation::{
    RotationParams, SmallImage, estimate_rotation_with,
};
use ferroslam_sim::dataset::{CalibrationSource, Dataset, DatasetOptions};
use ferroslam_tests::{shared_dataset, workspace_root};
use nalgebra::UnitQuaternion;

/// Errors of one setting over the pairs, degrees, sorted; and the pairs with no estimate.
struct Errors {
    sorted_deg: Vec<f32>,
    failures: usize,
}

impl Errors {
    fn quantile(&self, q: f32) -> f32 {
        let last = self.sorted_deg.len() - 1;
        self.sorted_deg[(last as f32 * q).round() as usize]
    }
}

/// The small images of every 7-Scenes frame at QVGA (depth registered as CI replays it), the
/// camera, and each frame's ground-truth rotation (camera to world).
fn frames() -> (Vec<SmallImage>, PinholeCamera, Vec<UnitQuaternion<f32>>) {
    let opts = DatasetOptions {
        calibration: CalibrationSource::Path(
            workspace_root().join("calibration/7scenes-kinect-v1.toml"),
        ),
        ..DatasetOptions::default()
    };
    let ds = Dataset::open(&shared_dataset("7scenes-redkitchen-1000"), &opts).unwrap();
    let c = ds.calibration();
    let cam =
        PinholeCamera::new(c.fx, c.fy, c.cx, c.cy, c.width as usize, c.height as usize).unwrap();
    let truth: Vec<UnitQuaternion<f32>> =
        ds.groundtruth().unwrap().iter().map(|p| nalgebra::convert(p.t_wc.rotation)).collect();
    assert_eq!(truth.len(), ds.len());
    let smalls = (0..ds.len())
        .map(|i| {
            let frame = ds.load_frame(i).unwrap();
            let mut small = SmallImage::new();
            assert!(small.build(&frame.view().unwrap().gray));
            small
        })
        .collect();
    (smalls, cam, truth)
}

/// The rotation error of `params` over the pairs `gap` frames apart, each started from the
/// rotation of the `gap` frames before (constant angular velocity, as the front end predicts).
fn errors(
    (smalls, cam, truth): &(Vec<SmallImage>, PinholeCamera, Vec<UnitQuaternion<f32>>),
    gap: usize,
    params: &RotationParams,
) -> Errors {
    let mut sorted_deg = Vec::new();
    let mut failures = 0;
    for i in 2 * gap..smalls.len() {
        // r_cp: previous camera to current camera.
        let r_cp = truth[i].inverse() * truth[i - gap];
        let initial = truth[i - gap].inverse() * truth[i - 2 * gap];
        match estimate_rotation_with(&smalls[i - gap], &smalls[i], cam, &initial, params) {
            Some(r) => sorted_deg.push((r * r_cp.inverse()).angle().to_degrees()),
            None => failures += 1,
        }
    }
    sorted_deg.sort_by(f32::total_cmp);
    Errors { sorted_deg, failures }
}

#[test]
fn the_front_ends_iterations_are_as_close_to_the_truth_as_converged_ones() {
    let data = frames();
    for (gap, max_median_deg) in [(1, 0.30), (3, 0.70)] {
        let default = errors(&data, gap, &RotationParams::DEFAULT);
        let converged = errors(&data, gap, &RotationParams::CONVERGED);
        for (name, e) in [("default", &default), ("converged", &converged)] {
            eprintln!(
                "{gap} frame(s) apart, {name}: {} estimates, {} failures, error median {:.3}, \
                 p90 {:.3}, max {:.3} degrees",
                e.sorted_deg.len(),
                e.failures,
                e.quantile(0.5),
                e.quantile(0.9),
                e.quantile(1.0)
            );
        }
        assert!(default.failures <= converged.failures);
        // Measured: one frame apart, medians 0.230 (default) and 0.231 (converged), p90 0.440
        // and 0.443; three apart 0.584 and 0.584, p90 0.989 and 0.977 degrees. A QVGA pixel is
        // 0.22 degrees here. The coarse level alone (no fine step) is 0.01 degrees worse in the
        // median, and fails.
        assert!(default.quantile(0.5) < max_median_deg, "gap {gap}");
        assert!(default.quantile(0.5) <= converged.quantile(0.5) + 0.005, "gap {gap}");
        assert!(default.quantile(0.9) <= converged.quantile(0.9) + 0.015, "gap {gap}");
    }
}
