//! The `ferroslam-sim` binary replaying recorded frames: its report, its options, and its exit
//! status and messages on bad or incomplete datasets.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::Path;

use common::{seven_scenes, sim, stderr};

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
fn a_coarser_depth_is_an_option_within_the_core_levels() {
    let out = tempfile::tempdir().unwrap();
    let dataset = seven_scenes();
    let (data, dir) = (dataset.to_str().unwrap(), out.path().to_str().unwrap());
    let frames = ["--max-frames", "3", "--mode", "odometry"];
    let run = sim(&[&["replay", data, "--out", dir, "--depth-level", "1"][..], &frames].concat());
    assert!(run.status.success(), "replay failed: {}", stderr(&run));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.path().join("report.json")).unwrap()).unwrap();
    assert_eq!((report["frames"].as_u64(), report["width"].as_u64()), (Some(3), Some(320)));
    let note = report["note"].as_str().unwrap_or_default();
    assert!(note.contains("1 halving(s) coarser"), "the report says so: {note}");
    let run = sim(&[&["replay", data, "--out", dir, "--depth-level", "3"][..], &frames].concat());
    assert_eq!(run.status.code(), Some(2));
    assert!(stderr(&run).contains("--depth-level"), "{}", stderr(&run));
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
    let msg = stderr(&run);
    // Said as a missing folder, not as the first file that cannot be read in it.
    assert!(msg.contains("dataset folder /nonexistent/dataset does not exist"), "{msg}");
    assert!(!msg.contains("calibration.toml"), "{msg}");
    // A folder that is there but holds no dataset, and a file.
    let empty = tempfile::tempdir().unwrap();
    let empty_dir = empty.path().to_str().unwrap();
    let run = sim(&["replay", empty_dir, "--out", out.path().to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(1));
    let msg = stderr(&run);
    assert!(msg.contains(&format!("{empty_dir} has no rgb.txt: not a TUM RGB-D folder")), "{msg}");
    let file = empty.path().join("rgb.txt");
    std::fs::write(&file, "").unwrap();
    let run = sim(&["replay", empty_dir, "--out", out.path().to_str().unwrap()]);
    assert!(stderr(&run).contains("has no depth.txt"), "{}", stderr(&run));
    let run = sim(&["replay", file.to_str().unwrap(), "--out", out.path().to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(1));
    assert!(stderr(&run).contains("rgb.txt is not a folder"), "{}", stderr(&run));

    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("rgb.txt"), "").unwrap();
    std::fs::write(dir.path().join("depth.txt"), "").unwrap();
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

/// A 10-frame recording written by `demo --write-dataset` into `dir`, in which colour image 3
/// is missing and depth image 6 is moved 25 ms off its colour image (past the 0.02 s limit):
/// two of the ten frames cannot be played.
fn recording_with_two_bad_frames(dir: &Path) {
    let run = sim(&["demo", "--frames", "10", "--write-dataset", dir.to_str().unwrap()]);
    assert!(run.status.success(), "{}", stderr(&run));
    std::fs::remove_file(dir.join("rgb/000003.png")).unwrap();
    let depth = std::fs::read_to_string(dir.join("depth.txt")).unwrap();
    assert!(depth.contains("\n0.2 depth/000006.png\n"), "{depth}");
    let depth = depth.replace("\n0.2 depth/000006.png\n", "\n0.225 depth/000006.png\n");
    std::fs::write(dir.join("depth.txt"), depth).unwrap();
}

#[test]
fn skipped_frames_are_said_and_strict_refuses_them() {
    let data = tempfile::tempdir().unwrap();
    recording_with_two_bad_frames(data.path());
    let out = tempfile::tempdir().unwrap();
    let (data_dir, out_dir) = (data.path().to_str().unwrap(), out.path().to_str().unwrap());
    let run = sim(&["replay", data_dir, "--out", out_dir, "--mode", "data-path"]);
    assert!(run.status.success(), "{}", stderr(&run));
    let msg = stderr(&run);
    let rgb = format!("{data_dir}/rgb.txt");
    assert!(
        msg.contains(&format!("warning: 2 of the 10 frames listed in {rgb} skipped:")),
        "{msg}"
    );
    assert!(msg.contains(&format!("{rgb}:6: {data_dir}/rgb/000003.png does not exist")), "{msg}");
    let far =
        format!("{rgb}:9: {data_dir}/rgb/000006.png (t = 0.2 s): no depth image within 0.02 s");
    assert!(msg.contains(&far), "{msg}");
    assert!(msg.contains("note: 2 depth images listed in"), "{msg}");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains("frames listed in rgb.txt but skipped: 2;"), "{stdout}");
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.path().join("report.json")).unwrap()).unwrap();
    assert_eq!((report["frames"].as_u64(), report["skipped_frames"].as_u64()), (Some(8), Some(2)));
    let reasons: Vec<&str> = report["skipped_images"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| s["list"].as_str().unwrap().ends_with("rgb.txt"))
        .map(|s| s["reason"].as_str().unwrap())
        .collect();
    assert_eq!(reasons, ["file missing", "no depth image within 0.02 s"]);

    let strict = tempfile::tempdir().unwrap();
    let run = sim(&["replay", data_dir, "--out", strict.path().to_str().unwrap(), "--strict"]);
    assert_eq!(run.status.code(), Some(1));
    let msg = stderr(&run);
    assert!(msg.contains(&format!("error: --strict: 2 of the 10 frames listed in {rgb}")), "{msg}");
    assert!(msg.contains(&far) && msg.contains("nothing was run"), "{msg}");
    assert!(!strict.path().join("report.json").exists(), "nothing written");
    // A whole recording passes --strict.
    let whole = tempfile::tempdir().unwrap();
    let whole_dir = whole.path().join("data");
    let run = sim(&["demo", "--frames", "3", "--write-dataset", whole_dir.to_str().unwrap()]);
    assert!(run.status.success(), "{}", stderr(&run));
    let whole_data = whole_dir.to_str().unwrap();
    let run = sim(&["replay", whole_data, "--out", out_dir, "--mode", "data-path", "--strict"]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(!stderr(&run).contains("skipped"), "{}", stderr(&run));
}

/// The per-frame outcomes of a report's `odometry` array, counted as the report counts them:
/// `[tracked, relocalised, re-initialised, lost, before the first keyframe]`.
fn outcomes(report: &serde_json::Value) -> [u64; 5] {
    let mut n = [0; 5];
    for f in report["odometry"].as_array().unwrap() {
        let flag = |name: &str| f[name].as_bool().unwrap();
        let i = match () {
            () if flag("tracked") => 0,
            () if flag("relocalized") => 1,
            () if flag("reinitialized") => 2,
            () if f["state"] == "initializing" => 4,
            () => 3,
        };
        n[i] += 1;
    }
    n
}

#[test]
fn every_frame_is_counted_once_and_skipped_frames_apart() {
    let counts = |report: &serde_json::Value| -> [u64; 5] {
        [
            "tracked_frames",
            "relocalized_frames",
            "reinitialized_frames",
            "lost_frames",
            "initializing_frames",
        ]
        .map(|key| report[key].as_u64().unwrap())
    };
    // A replay with two frames skipped: the eight played add up, and the two skipped are said
    // apart, so that played and skipped make the ten listed.
    let data = tempfile::tempdir().unwrap();
    recording_with_two_bad_frames(data.path());
    let out = tempfile::tempdir().unwrap();
    let (data_dir, out_dir) = (data.path().to_str().unwrap(), out.path().to_str().unwrap());
    let run = sim(&["replay", data_dir, "--out", out_dir, "--mode", "odometry"]);
    assert!(run.status.success(), "{}", stderr(&run));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.path().join("report.json")).unwrap()).unwrap();
    let frames = report["frames"].as_u64().unwrap();
    let skipped = report["skipped_frames"].as_u64().unwrap();
    assert_eq!(counts(&report).iter().sum::<u64>(), frames, "{:?}", counts(&report));
    assert_eq!(counts(&report), outcomes(&report));
    assert_eq!((frames, skipped), (8, 2), "played and skipped make the ten listed");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains("8 frames: 8 tracked, 0 relocalised"), "{stdout}");
    assert!(stdout.contains("; 2 more listed in rgb.txt skipped, not played;"), "{stdout}");

    // 7-Scenes carried from frame 15 to frame 600 and back to frame 0: tracking is lost,
    // restarts at a prediction, and relocalizes in the place it left. Every outcome is counted
    // once, in the summary as in the report.
    let dataset = seven_scenes();
    let frames = ["--frames", "0-15,600-615,0-10"];
    let run =
        sim(&[&["replay", dataset.to_str().unwrap(), "--out", out_dir][..], &frames].concat());
    assert!(run.status.success(), "{}", stderr(&run));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.path().join("report.json")).unwrap()).unwrap();
    let [tracked, relocalised, reinitialised, lost, initializing] = counts(&report);
    assert_eq!(counts(&report), outcomes(&report));
    assert_eq!(tracked + relocalised + reinitialised + lost + initializing, 43);
    assert!(relocalised > 0 && reinitialised > 0 && lost > 0, "the premise: {:?}", counts(&report));
    assert_eq!(report["relocalizations"]["count"].as_u64(), Some(relocalised));
    let stdout = String::from_utf8_lossy(&run.stdout);
    let said = format!(
        "43 frames: {tracked} tracked, {relocalised} relocalised, {reinitialised} re-initialised, \
         {lost} lost, {initializing} before the first keyframe; {} keyframes;",
        report["keyframes"]
    );
    assert!(stdout.contains(&said), "{said} in {stdout}");
    assert_eq!(report["skipped_frames"], 0);
}
