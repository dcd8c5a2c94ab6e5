//! The `ferroslam-sim` binary as a user runs it: exit status and messages on good and bad input.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ferroslam-sim")).args(args).output().expect("the binary runs")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn seven_scenes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/datasets/7scenes-redkitchen-1000")
}

#[test]
fn replay_of_real_frames_writes_a_report() {
    let out = tempfile::tempdir().unwrap();
    let dataset = seven_scenes();
    let run = sim(&[
        "replay",
        dataset.to_str().unwrap(),
        "--out",
        out.path().to_str().unwrap(),
        "--max-frames",
        "5",
        "--mode",
        "data-path",
    ]);
    assert!(run.status.success(), "replay failed: {}", stderr(&run));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.path().join("report.json")).unwrap()).unwrap();
    assert_eq!(report["frames"], 5);
    assert_eq!(report["profile"], "qvga");
    assert_eq!(report["width"], 320);
    assert_eq!(report["tracked_frames"], 0, "no tracker exists yet; the report must not claim one");
    assert!(report["ate_rmse_m"].is_null());
    assert!(out.path().join("trajectory.svg").exists(), "the ground-truth plot is written");
}

#[test]
fn bad_dataset_exits_non_zero_naming_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("calibration.toml"),
        "fx = 525.0\nfy = 525.0\ncx = 319.5\ncy = 239.5\nwidth = 640\nheight = 480\ndepth_scale = 5000.0\n",
    )
    .unwrap();
    std::fs::write(dir.path().join("rgb.txt"), "# comment\n0.0 rgb/0.png\nnot-a-line\n").unwrap();
    std::fs::write(dir.path().join("depth.txt"), "0.0 depth/0.png\n").unwrap();
    let out = tempfile::tempdir().unwrap();
    let run = sim(&["replay", dir.path().to_str().unwrap(), "--out", out.path().to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(1));
    let msg = stderr(&run);
    assert!(msg.contains("rgb.txt:3"), "message names file and line: {msg}");
    assert!(!msg.contains("panicked"), "{msg}");
}

#[test]
fn missing_dataset_and_bad_calibration_exit_non_zero() {
    let out = tempfile::tempdir().unwrap();
    let run = sim(&["replay", "/nonexistent/dataset", "--out", out.path().to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(1));
    assert!(stderr(&run).contains("/nonexistent/dataset"), "{}", stderr(&run));

    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("calibration.toml"),
        "fx = -1.0\nfy = 525.0\ncx = 319.5\ncy = 239.5\nwidth = 640\nheight = 480\ndepth_scale = 5000.0\n",
    )
    .unwrap();
    let run = sim(&["replay", dir.path().to_str().unwrap(), "--out", out.path().to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(1));
    let msg = stderr(&run);
    assert!(msg.contains("calibration.toml") && msg.contains("fx"), "{msg}");
}

#[test]
fn eval_prints_json_and_rejects_a_bad_line() {
    let dir = tempfile::tempdir().unwrap();
    let gt = seven_scenes().join("groundtruth.txt");
    // The ground truth against itself: every error is zero, every pose matched.
    let run = sim(&["eval", gt.to_str().unwrap(), gt.to_str().unwrap(), "--json"]);
    assert!(run.status.success(), "{}", stderr(&run));
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(report["matched_poses"], 1000);
    assert!(report["ate"]["rmse"].as_f64().unwrap() < 1e-9);

    let bad = dir.path().join("est.txt");
    std::fs::write(&bad, "0.0 0 0 0 0 0 0 1\n0.1 0 0 nan 0 0 0 1\n").unwrap();
    let run = sim(&["eval", gt.to_str().unwrap(), bad.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(1));
    assert!(stderr(&run).contains("est.txt:2"), "{}", stderr(&run));
}

#[test]
fn demo_rejects_bad_options_and_usage_errors_exit_2() {
    let out = tempfile::tempdir().unwrap();
    let run = sim(&["demo", "--frames", "0", "--out", out.path().to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(1));
    assert!(stderr(&run).contains("frames"), "{}", stderr(&run));
    assert_eq!(sim(&["no-such-command"]).status.code(), Some(2));
}

#[test]
fn short_demo_runs_end_to_end() {
    let out = tempfile::tempdir().unwrap();
    // The data-path mode (odometry, the default, is tested in tests/odometry.rs).
    let out_dir = out.path().to_str().unwrap();
    let run = sim(&["demo", "--frames", "12", "--mode", "data-path", "--out", out_dir]);
    assert!(run.status.success(), "{}", stderr(&run));
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains("no tracker yet"), "the demo says what it did: {stdout}");
    for file in
        ["groundtruth.txt", "baseline_trajectory.txt", "report.json", "trajectory.svg", "ate.svg"]
    {
        assert!(out.path().join(file).exists(), "{file} written");
    }
    let gt = std::fs::read_to_string(out.path().join("groundtruth.txt")).unwrap();
    assert_eq!(gt.lines().count(), 12);
}
