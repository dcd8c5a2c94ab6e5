#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! Deterministic replay: the same real frames through the SLAM pipeline (front end, map, back end
//! with a fixed work quota per frame) twice give the same bytes, and a different quota gives a
//! different (but still valid) run, so the test is not vacuous.

use ferroslam_core::config::QVGA;
use ferroslam_core::geometry::PinholeCamera;
use ferroslam_core::system::DEFAULT_BACKEND_QUOTA;
use ferroslam_sim::commands::datapath::{OdometryRun, TrackMode, run_odometry};
use ferroslam_sim::dataset::{Dataset, DatasetOptions};

const FRAMES: usize = 120;

fn replay(quota: u32) -> OdometryRun {
    let dir = ferroslam_tests::workspace_root().join("../shared/datasets/7scenes-redkitchen-1000");
    let opts = DatasetOptions { max_frames: Some(FRAMES), ..DatasetOptions::default() };
    let dataset = Dataset::open(&dir, &opts).unwrap();
    let c = dataset.calibration();
    let cam =
        PinholeCamera::new(c.fx, c.fy, c.cx, c.cy, c.width as usize, c.height as usize).unwrap();
    let mut reader = dataset.into_reader(4);
    run_odometry(&mut reader, FRAMES, &cam, QVGA, TrackMode::Slam { quota }).unwrap()
}

#[test]
fn two_slam_replays_give_identical_bytes() {
    let (a, b) = (replay(DEFAULT_BACKEND_QUOTA), replay(DEFAULT_BACKEND_QUOTA));
    let backend = a.backend.clone().unwrap();
    assert!(backend.local_runs >= 1, "the back end ran: {backend:?}");
    assert_eq!(a.camera.to_tum_string(), b.camera.to_tum_string());
    assert_eq!(a.online.to_tum_string(), b.online.to_tum_string());
    assert_eq!(a.keyframes.to_tum_string(), b.keyframes.to_tum_string());
    // The back end's schedule is part of the result: another quota changes the bits.
    let c = replay(DEFAULT_BACKEND_QUOTA / 4);
    assert_ne!(a.camera.to_tum_string(), c.camera.to_tum_string());
    assert_eq!(c.camera.len(), FRAMES);
}
