//! The depth-to-colour calibration estimate (`ferroslam-sim calibrate-depth`) on real data:
//! `../shared/datasets/7scenes-redkitchen-1000`, whose depth (Kinect v1) is not registered to
//! colour. The estimate from the images must agree with `calibration/7scenes-kinect-v1.toml`, the
//! registration every 7-Scenes replay uses, within the check's tolerances (as `cargo xtask ci`
//! checks too). The data is only read. About 20 s in a debug build.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use ferroslam_sim::dataset::Calibration;
use ferroslam_sim::dataset::calibrate_depth::{
    CHECK_METRES, CHECK_PIXELS, FrameSelection, estimate,
};
use ferroslam_tests::{shared_dataset, workspace_root};

#[test]
fn the_seven_scenes_estimate_agrees_with_the_registered_calibration() {
    let dir = shared_dataset("7scenes-redkitchen-1000");
    assert!(dir.join("rgb.txt").is_file(), "real dataset not found at {}", dir.display());
    let e = estimate(&dir, FrameSelection::default()).unwrap();
    assert_eq!(e.frames, 40, "frames 0, 25, ..., 975");
    // The edge correlation rises from about 0.09 to about 0.41 (the file's header).
    assert!(e.nominal_correlation < 0.15 && e.correlation > 0.35, "{e}");

    let file = workspace_root().join("calibration").join("7scenes-kinect-v1.toml");
    let check = e.compare_file(&file).unwrap();
    assert_eq!(check.values.len(), 5);
    assert!(check.values.iter().all(|v| [CHECK_PIXELS, CHECK_METRES].contains(&v.tolerance)));
    check.ensure().unwrap_or_else(|err| panic!("{err}\n{check}"));

    // The file it writes is a calibration the loader reads, and it passes its own check.
    let out = tempfile::tempdir().unwrap();
    let written = out.path().join("cal.toml");
    std::fs::write(&written, e.to_toml()).unwrap();
    let c = Calibration::load(&written).unwrap();
    assert_eq!((c.width, c.height, c.depth_scale), (640, 480, 1000.0));
    assert_eq!(c.depth.map(|d| (d.fx, d.cx, d.t_m[2])), Some((585.0, 320.0, 0.0)));
    e.compare_file(&written).unwrap().ensure().unwrap();
}
