#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! Deterministic replay: the same real frames through the SLAM pipeline (front end, map, back end
//! with a fixed work quota per frame) twice give the same bytes, with the back end on its own
//! thread or on the front end's; and a different quota gives a different (but still valid) run,
//! so the test is not vacuous.

use ferroslam_core::backend::BackendParams;
use ferroslam_core::config::QVGA;
use ferroslam_core::geometry::PinholeCamera;
use ferroslam_core::system::DEFAULT_BACKEND_QUOTA;
use ferroslam_sim::dataset::{Dataset, DatasetOptions};
use ferroslam_sim::run::{self, MapScale, RunOptions, Schedule, TrackMode, TrackingRun};

const FRAMES: usize = 120;

fn replay(quota: u32, schedule: Schedule) -> TrackingRun {
    let dir = ferroslam_tests::workspace_root().join("../shared/datasets/7scenes-redkitchen-1000");
    let opts = DatasetOptions { max_frames: Some(FRAMES), ..DatasetOptions::default() };
    let dataset = Dataset::open(&dir, &opts).unwrap();
    let c = dataset.calibration();
    let cam =
        PinholeCamera::new(c.fx, c.fy, c.cx, c.cy, c.width as usize, c.height as usize).unwrap();
    let mut reader = dataset.into_reader(4);
    let mode = TrackMode::Slam {
        quota,
        schedule,
        map: MapScale::Board,
        window_levels: BackendParams::DEFAULT.window_levels,
        places: true,
    };
    run::track(&mut reader, FRAMES, &cam, &RunOptions::new(QVGA, mode)).unwrap()
}

fn assert_same_bytes(a: &TrackingRun, b: &TrackingRun) {
    assert_eq!(a.camera.to_tum_string(), b.camera.to_tum_string());
    assert_eq!(a.online.to_tum_string(), b.online.to_tum_string());
    assert_eq!(a.keyframes.to_tum_string(), b.keyframes.to_tum_string());
}

#[test]
fn two_slam_replays_give_identical_bytes() {
    let a = replay(DEFAULT_BACKEND_QUOTA, Schedule::Threaded);
    let b = replay(DEFAULT_BACKEND_QUOTA, Schedule::Threaded);
    let backend = a.backend.clone().unwrap();
    assert!(backend.local_runs >= 1, "the back end ran: {backend:?}");
    assert!(backend.deterministic);
    assert_same_bytes(&a, &b);
    // The back end on the front end's thread, as on the firmware: the same bits. Several solves
    // finished in the 120 frames, so the threaded run restored and re-tracked frames.
    let sequential = replay(DEFAULT_BACKEND_QUOTA, Schedule::Sequential);
    assert_eq!(sequential.backend.as_ref().map(|b| b.schedule), Some("sequential"));
    assert_same_bytes(&a, &sequential);
    // The back end's schedule is part of the result: another quota changes the bits.
    let c = replay(DEFAULT_BACKEND_QUOTA / 4, Schedule::Threaded);
    assert_ne!(a.camera.to_tum_string(), c.camera.to_tum_string());
    assert_eq!(c.camera.len(), FRAMES);
}

#[test]
fn realtime_replay_tracks_every_frame_and_says_it_is_not_deterministic() {
    let run = replay(DEFAULT_BACKEND_QUOTA, Schedule::Realtime);
    let backend = run.backend.clone().unwrap();
    assert_eq!(backend.schedule, "realtime");
    assert!(!backend.deterministic);
    assert!(backend.local_runs >= 1, "the back end ran: {backend:?}");
    assert_eq!(run.camera.len(), FRAMES);
    assert_eq!(run.tracked_frames, FRAMES);
}
