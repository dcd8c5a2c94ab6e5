//! `--mode slam` (the default) and `--mode odometry` end to end: the synthetic demo (known poses)
//! and a few real 7-Scenes frames.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ferroslam-sim")).args(args).output().expect("the binary runs")
}

fn report(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap()
}

fn seven_scenes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/datasets/7scenes-redkitchen-1000")
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
    assert!(r["ate_rmse_m"].as_f64().unwrap() < 0.05);
    assert_eq!(r["output_sha256"].as_str().unwrap().len(), 64);
    let traj = std::fs::read_to_string(out.path().join("CameraTrajectory.txt")).unwrap();
    assert_eq!(traj.lines().count(), 10);
}
