//! The `ferroslam-sim eval` and `calibrate-depth` commands: output, help, and exit status and
//! messages on bad input.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::{seven_scenes, sim, stderr};

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
fn calibrate_depth_has_help_naming_its_options() {
    let run = sim(&["calibrate-depth", "--help"]);
    assert!(run.status.success(), "{}", stderr(&run));
    let help = String::from_utf8_lossy(&run.stdout);
    for option in ["<DATASET>", "--out <FILE>", "--check <FILE>", "--start <N>", "--step <N>"] {
        assert!(help.contains(option), "--help names {option}: {help}");
    }
}

#[test]
fn calibrate_depth_of_a_missing_dataset_fails_clearly() {
    let out = tempfile::tempdir().unwrap();
    let file = out.path().join("cal.toml");
    let missing = out.path().join("no-such-dataset");
    let run = sim(&["calibrate-depth", missing.to_str().unwrap(), "--out", file.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(1));
    let msg = stderr(&run);
    assert!(msg.contains("no-such-dataset is not a dataset folder"), "{msg}");
    assert!(!msg.contains("panicked"), "{msg}");
    assert!(!file.exists(), "nothing is written");
    // A folder without calibration.toml says what the estimate needs.
    let run =
        sim(&["calibrate-depth", out.path().to_str().unwrap(), "--out", file.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(1));
    assert!(stderr(&run).contains("has no calibration.toml"), "{}", stderr(&run));
    // Neither --out nor --check, or a step of 0: usage errors.
    let run = sim(&["calibrate-depth", missing.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
    let run = sim(&["calibrate-depth", "x", "--out", "y", "--step", "0"]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
}
