//! `--mode slam` (the default) and `--mode odometry` end to end: the synthetic demo (known poses)
//! and a few real 7-Scenes frames.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::Path;

use common::{seven_scenes, sim};

fn report(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap()
}

#[test]
fn demo_odometry_tracks_the_synthetic_sequence_deterministically() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    for dir in [&a, &b] {
        let run = sim(&["demo", "--frames", "20", "--out", dir.path().to_str().unwrap()]);
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        assert!(String::from_utf8_lossy(&run.stdout).contains("slam"));
    }
    let r = report(a.path());
    assert_eq!(r["mode"], "slam");
    assert!(r["backend"]["local_runs"].as_u64().unwrap() >= 1, "{}", r["backend"]);
    assert!(r["ate_online_rmse_m"].as_f64().unwrap() < 0.01);
    assert_eq!(r["frames"], 20);
    assert_eq!(r["tracked_frames"], 20);
    assert_eq!(r["lost_frames"], 0);
    assert_eq!(
        (r["reinitialized_frames"].as_u64(), r["initializing_frames"].as_u64()),
        (Some(0), Some(0))
    );
    assert!(r["keyframes"].as_u64().unwrap() >= 1);
    let ate = r["ate_rmse_m"].as_f64().unwrap();
    assert!(ate < 0.01, "ATE {ate} m on 20 synthetic frames");
    assert!(r["state_bytes"].as_u64().unwrap() > 100_000);
    let traj = std::fs::read_to_string(a.path().join("CameraTrajectory.txt")).unwrap();
    assert_eq!(traj.lines().count(), 20);
    for f in ["KeyFrameTrajectory.txt", "trajectory.svg", "ate.svg"] {
        assert!(a.path().join(f).exists(), "{f} written");
    }
    assert_eq!(r["output_sha256"], report(b.path())["output_sha256"], "same frames, same bits");
}

#[test]
fn replay_odometry_on_real_frames_writes_a_trajectory() {
    let out = tempfile::tempdir().unwrap();
    let dataset = seven_scenes();
    let o = out.path().to_str().unwrap();
    let args = ["replay", dataset.to_str().unwrap(), "--out", o, "--max-frames", "10"];
    let run = sim(&[&args[..], &["--mode", "odometry"]].concat());
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let r = report(out.path());
    assert_eq!(r["frames"], 10);
    assert_eq!(r["mode"], "odometry");
    let tracked = r["tracked_frames"].as_u64().unwrap();
    assert!(tracked >= 8, "{tracked} of 10 tracked");
    // Every frame is one of tracked, re-initialised, relocalised, lost, before the first keyframe.
    let tally: u64 = [
        "tracked_frames",
        "reinitialized_frames",
        "relocalized_frames",
        "lost_frames",
        "initializing_frames",
    ]
    .iter()
    .map(|k| r[*k].as_u64().unwrap())
    .sum();
    assert_eq!(tally, 10);
    assert!(r["ate_rmse_m"].as_f64().unwrap() < 0.05);
    assert_eq!(r["output_sha256"].as_str().unwrap().len(), 64);
    let traj = std::fs::read_to_string(out.path().join("CameraTrajectory.txt")).unwrap();
    assert_eq!(traj.lines().count(), 10);
}

/// `--frames` plays a recording in another order: out and back over the first 12 frames of
/// 7-Scenes, timestamps increasing, the ground truth following its frames (so the way back is
/// evaluated against the poses of the way out), and a range past the end refused by name.
#[test]
fn replay_plays_frame_ranges_out_and_back() {
    let out = tempfile::tempdir().unwrap();
    let dataset = seven_scenes();
    let o = out.path().to_str().unwrap();
    let args = ["replay", dataset.to_str().unwrap(), "--out", o, "--mode", "odometry"];
    let run = sim(&[&args[..], &["--frames", "0-11,10-0"]].concat());
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let r = report(out.path());
    assert_eq!(r["frames"], 23);
    let traj = std::fs::read_to_string(out.path().join("CameraTrajectory.txt")).unwrap();
    let t: Vec<f64> = traj.lines().map(|l| l.split(' ').next().unwrap().parse().unwrap()).collect();
    assert_eq!(t.len(), 23);
    assert!(t.windows(2).all(|w| w[1] > w[0]), "timestamps increase: {t:?}");
    // Played back over the same places: the evaluation matched every frame to ground truth.
    assert!(r["ate_rmse_m"].as_f64().unwrap() < 0.05, "{}", r["ate_rmse_m"]);
    let bad = sim(&[&args[..], &["--frames", "0-5000"]].concat());
    assert!(!bad.status.success());
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert!(
        stderr.contains("frame range 0-5000 is outside the recording's 1000 frames"),
        "{stderr}"
    );
    let bad = sim(&[&args[..], &["--frames", "7..9"]].concat());
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("not a list of frame ranges"));
}

/// `demo --write-dataset` writes the rendered sequence as a TUM folder that replays to the very
/// bits of the demo itself (same frames, timestamps, intrinsics and depth noise).
#[test]
fn the_demo_written_as_a_dataset_replays_to_the_demo_s_bits() {
    let (data, demo_out, replay_out) =
        (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let d = data.path().to_str().unwrap();
    let run = sim(&["demo", "--frames", "30", "--shake", "1", "--write-dataset", d]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    for f in ["rgb.txt", "depth.txt", "groundtruth.txt", "calibration.toml", "rgb/000029.png"] {
        assert!(data.path().join(f).exists(), "{f} written");
    }
    let o = demo_out.path().to_str().unwrap();
    let run = sim(&["demo", "--frames", "30", "--shake", "1", "--out", o]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let o = replay_out.path().to_str().unwrap();
    let run = sim(&["replay", d, "--out", o]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let (demo, replay) = (report(demo_out.path()), report(replay_out.path()));
    assert_eq!(replay["frames"], 30);
    assert_eq!(replay["output_sha256"], demo["output_sha256"]);
    // groundtruth.txt holds 7 decimals (0.1 um): the ATE agrees to about that.
    let ate = |r: &serde_json::Value| r["ate_rmse_m"].as_f64().unwrap();
    assert!((ate(&replay) - ate(&demo)).abs() < 1e-6, "{} {}", ate(&replay), ate(&demo));
}

/// Any even resolution works: a RealSense-class 848x480 sensor processed at 424x240, and
/// 512x384 processed at full size (tracked on its halved level); every frame tracked, sub-
/// centimetre on the synthetic sequence.
#[test]
fn the_demo_tracks_at_other_resolutions() {
    for (size, profile, processed) in [("848x480", "qvga", 424), ("512x384", "vga", 512)] {
        let out = tempfile::tempdir().unwrap();
        let o = out.path().to_str().unwrap();
        let run =
            sim(&["demo", "--frames", "24", "--size", size, "--profile", profile, "--out", o]);
        assert!(run.status.success(), "{size}: {}", String::from_utf8_lossy(&run.stderr));
        let r = report(out.path());
        assert_eq!(
            (r["width"].as_u64(), r["tracked_frames"].as_u64()),
            (Some(processed), Some(24))
        );
        assert!(r["ate_rmse_m"].as_f64().unwrap() < 0.01, "{size}: {}", r["ate_rmse_m"]);
    }
    let bad = sim(&["demo", "--size", "641x480"]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("even numbers"));
}
