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
    let dir = out.path().to_str().unwrap();
    let run = sim(&["demo", "--frames", "5", "--skip-frames", "5", "--out", dir]);
    assert_eq!(run.status.code(), Some(1));
    assert!(stderr(&run).contains("--skip-frames 5 leaves no frame"), "{}", stderr(&run));
}

#[test]
fn demo_errors_name_the_option_typed() {
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().to_str().unwrap();
    let cases: [(&[&str], &str); 7] = [
        (&["--holes", "5"], "--holes 5: must be finite, 0 to 0.9"),
        (&["--depth-noise", "0.5"], "--depth-noise 0.5: must be finite, 0 to 0.1"),
        (&["--blur", "0"], "--blur 0: must be 1 to 64"),
        (&["--shake", "9"], "--shake 9: must be finite, 0 to 5"),
        (&["--size", "9000x480"], "--size 9000x480: must be 16 to 8192 pixels"),
        (&["--frames", "0"], "--frames 0: must be 1 to 1000000"),
        (&["--holes=-1", "--write-dataset", dir], "--holes -1: must be finite, 0 to 0.9"),
    ];
    for (args, message) in cases {
        let run = sim(&[&["demo", "--out", dir][..], args].concat());
        assert_eq!(run.status.code(), Some(1), "{args:?}");
        let msg = stderr(&run);
        assert!(msg.contains(message), "{args:?}: {msg}");
        assert!(!msg.contains("synthetic option"), "no library field name: {msg}");
    }
}

#[test]
fn a_demo_started_later_tracks_from_its_first_frame() {
    // Frames 20-29 of the 30 rendered: ten poses, the first at frame 20's time (30 frames a
    // second), against the whole ground truth.
    let (_, report, trajectory) = demo_outputs(&["--frames", "30", "--skip-frames", "20"]);
    assert_eq!(trajectory.lines().count(), 10, "{trajectory}");
    let first: f64 = trajectory.split_whitespace().next().unwrap().parse().unwrap();
    assert!((first - 20.0 / 30.0).abs() < 1e-6, "{first}");
    assert!(report["ate_rmse_m"].as_f64().is_some(), "{report}");
}

/// `demo ARGS` into a new folder, which must succeed: the run, its report.json and its
/// CameraTrajectory.txt.
fn demo_outputs(args: &[&str]) -> (Output, serde_json::Value, String) {
    let out = tempfile::tempdir().unwrap();
    let mut all = vec!["demo"];
    all.extend_from_slice(args);
    all.extend(["--out", out.path().to_str().unwrap()]);
    let run = sim(&all);
    assert!(run.status.success(), "{}", stderr(&run));
    let read = |name: &str| std::fs::read(out.path().join(name)).unwrap();
    let report = serde_json::from_slice(&read("report.json")).unwrap();
    let trajectory = String::from_utf8(read("CameraTrajectory.txt")).unwrap();
    (run, report, trajectory)
}

#[test]
fn a_run_too_short_to_evaluate_keeps_its_outputs() {
    // Two poses cannot be aligned with the ground truth (three are needed): the run still
    // succeeds and writes everything, and the report says why it has no ATE.
    let (run, report, trajectory) = demo_outputs(&["--frames", "2"]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains("ATE RMSE n/a (only 2 matched poses"), "{stdout}");
    assert_eq!(trajectory.lines().count(), 2);
    assert!(report["ate_rmse_m"].is_null());
    let why = report["evaluation_error"].as_str().unwrap();
    assert!(why.contains("at least 3"), "{why}");
}

#[test]
fn frames_before_the_first_keyframe_have_no_pose() {
    // With 90% of the depth removed (18.6% of the pixels keep a reading) the front end finds too
    // few features with depth for a first keyframe in these three frames.
    let (_, report, trajectory) = demo_outputs(&["--frames", "3", "--holes", "0.9"]);
    let frames = report["odometry"].as_array().unwrap();
    let states: Vec<&str> = frames.iter().map(|f| f["state"].as_str().unwrap()).collect();
    assert_eq!(states, ["initializing"; 3], "the premise: no first keyframe");
    // No made-up pose (the identity) is written for them, and the report says why there is no ATE.
    assert_eq!(trajectory.lines().count(), 0, "{trajectory}");
    let why = report["evaluation_error"].as_str().unwrap();
    assert!(why.contains("never made its first keyframe"), "{why}");
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

#[test]
fn a_short_demo_with_ar_places_two_objects_and_checks_its_planes() {
    let out = tempfile::tempdir().unwrap();
    let out_dir = out.path().to_str().unwrap();
    let run = sim(&["demo", "--frames", "15", "--ar", "--out", out_dir]);
    assert!(run.status.success(), "{}", stderr(&run));
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains("AR: 2 objects from frame 0"), "the summary says it: {stdout}");
    let text = std::fs::read_to_string(out.path().join("report.json")).unwrap();
    let report: serde_json::Value = serde_json::from_str(&text).unwrap();
    let ar = &report["ar"];
    assert_eq!(ar["objects"], 2);
    assert_eq!(ar["anchors"].as_array().map(Vec::len), Some(2));
    // Fifteen frames of a smooth path: the objects stay within a pixel of the room's points.
    assert!(ar["error_px"]["count"].as_u64().unwrap() >= 15, "{ar}");
    assert!(ar["error_px"]["max"].as_f64().unwrap() < 1.0, "{ar}");
    let planes = &report["plane_accuracy"];
    assert!(planes["found"].as_u64().unwrap() >= 1, "{planes}");
    assert_eq!(planes["missed"], 0, "{planes}");
    assert!(report["planes"]["planes"].as_array().is_some_and(|p| !p.is_empty()));
    // The files a person opens: the drawings, an overlay frame and the preview.
    let ar_dir = out.path().join("ar");
    let pixels = std::fs::read_to_string(ar_dir.join("pixels.csv")).unwrap();
    assert_eq!(pixels.lines().next(), Some("frame,timestamp_s,object,u,v"));
    assert!(pixels.lines().count() > 15, "{pixels}");
    let overlay = image::open(ar_dir.join("frame_0000.png")).unwrap().to_rgb8();
    assert_eq!(overlay.dimensions(), (320, 240));
    assert!(overlay.pixels().any(|p| p.0 == [230, 40, 40]), "the red object is drawn");
    assert!(std::fs::metadata(ar_dir.join("preview.gif")).unwrap().len() > 0);
    // The run's page: self-contained (nothing fetched), its 3D view's data inline.
    let page = std::fs::read_to_string(out.path().join("report.html")).unwrap();
    for fetch in ["src=\"http", "href=\"http", "<link", "@import", "<iframe"] {
        assert!(!page.contains(fetch), "report.html fetches nothing: {fetch}");
    }
    let start = page.find("<script type=\"application/json\" id=\"scene\">").unwrap();
    let data = &page[start..];
    let data = &data[data.find('>').unwrap() + 1..data.find("</script>").unwrap()];
    let scene: serde_json::Value = serde_json::from_str(data).unwrap();
    assert_eq!(scene["trajectory"].as_array().map(Vec::len), Some(15));
    assert_eq!(scene["ground_truth"].as_array().map(Vec::len), Some(15));
    assert_eq!(scene["anchors"].as_array().map(Vec::len), Some(2));
    assert!(scene["points"].as_array().is_some_and(|p| p.len() > 50), "map points drawn");
    assert!(page.contains("<svg"), "the trajectory plot is inline");
}

#[test]
fn an_anchor_script_places_scales_and_removes_objects_and_says_what_it_refused() {
    let out = tempfile::tempdir().unwrap();
    let script = out.path().join("anchors.toml");
    // Object 5 on the floor at frame 2 (sensor pixels), twice as big at frame 6, removed at 10;
    // a scale of object 7, never placed, is refused.
    let text = "[[step]]\nframe = 2\naction = \"place\"\nobject = 5\npixel = [248.0, 426.0]\n\n\
                [[step]]\nframe = 6\naction = \"scale\"\nobject = 5\nscale = 2.0\n\n\
                [[step]]\nframe = 6\naction = \"scale\"\nobject = 7\nscale = 2.0\n\n\
                [[step]]\nframe = 10\naction = \"remove\"\nobject = 5\n";
    std::fs::write(&script, text).unwrap();
    let out_dir = out.path().join("run");
    let (script, out_dir) = (script.to_str().unwrap(), out_dir.to_str().unwrap());
    let run = sim(&["demo", "--frames", "14", "--anchors", script, "--out", out_dir]);
    assert!(run.status.success(), "{}", stderr(&run));
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains("AR: 1 objects from frame 2"), "{stdout}");
    assert!(stdout.contains("1 of 4 script steps refused"), "{stdout}");
    let text = std::fs::read_to_string(Path::new(out_dir).join("report.json")).unwrap();
    let report: serde_json::Value = serde_json::from_str(&text).unwrap();
    let ar = &report["ar"];
    let events = ar["events"].as_array().unwrap();
    let refused: Vec<_> = events.iter().map(|e| e["refused"].as_str()).collect();
    assert_eq!(refused, [None, None, Some("UnknownObject"), None], "{ar}");
    // Placed at the processing pixel the sensor pixel is; drawn frames 2 to 9 only, within a
    // pixel of where it belongs.
    assert_eq!(ar["anchors"][0]["pixel"], serde_json::json!([123.75, 212.75]));
    assert_eq!(ar["error_px"]["count"], 8, "{ar}");
    assert!(ar["error_px"]["max"].as_f64().unwrap() < 1.0, "{ar}");
    let pixels = std::fs::read_to_string(Path::new(out_dir).join("ar/pixels.csv")).unwrap();
    let frames: Vec<&str> = pixels.lines().skip(1).map(|l| l.split(',').next().unwrap()).collect();
    assert_eq!(frames, ["2", "3", "4", "5", "6", "7", "8", "9"]);
    // A bad script is refused before anything runs, naming the file and the step's line.
    std::fs::write(script, "[[step]]\nframe = 1\naction = \"place\"\nobject = 0\n").unwrap();
    let run = sim(&["demo", "--frames", "3", "--anchors", script, "--out", out_dir]);
    assert!(!run.status.success());
    assert!(
        stderr(&run).contains("anchors.toml, step at line 1: a place needs"),
        "{}",
        stderr(&run)
    );
}

#[test]
fn decode_serial_prints_poses_and_counts_losses() {
    use ferroslam_core::frame::TelemetrySink;
    use ferroslam_core::wire::{Message, PoseFlags, PoseMessage, StatusMessage, TrackingState};
    use ferroslam_sim::serial::WireWriter;

    let pose = |i: u32| PoseMessage {
        frame_index: i,
        timestamp_s: 100.0 + f64::from(i) / 4.0,
        translation_m: [0.25 * i as f32, 0.0, -1.0],
        rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
        state: TrackingState::Tracking,
        flags: PoseFlags(PoseFlags::TRACKED),
        inliers: 90,
        matches: 100,
    };
    let mut writer = WireWriter::new(Vec::new());
    for i in 0..3 {
        writer.send(&Message::Pose(pose(i))).unwrap();
    }
    writer.send(&Message::Status(StatusMessage { frames: 3, ..StatusMessage::default() })).unwrap();
    let mut bytes = writer.into_inner();
    // Corrupt the second frame (one byte after the first delimiter) and append garbage.
    let second = bytes.iter().position(|&b| b == 0).unwrap() + 3;
    bytes[second] ^= 0x01;
    bytes.extend_from_slice(&[0x42, 0x42]);
    let dir = tempfile::tempdir().unwrap();
    let capture = dir.path().join("uart.bin");
    std::fs::write(&capture, &bytes).unwrap();

    let run = sim(&["decode-serial", capture.to_str().unwrap(), "--tum"]);
    assert!(run.status.success(), "{}", stderr(&run));
    let stdout = String::from_utf8_lossy(&run.stdout);
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(
        lines,
        [
            "100.000000 0.0000000 0.0000000 -1.0000000 0.0000000 0.0000000 0.0000000 1.0000000",
            "100.500000 0.5000000 0.0000000 -1.0000000 0.0000000 0.0000000 0.0000000 1.0000000",
        ]
    );
    let msg = stderr(&run);
    assert!(msg.contains("3 frames decoded (2 poses), 2 frames dropped"), "{msg}");
    // The status in words, not in Rust's debug format.
    assert!(msg.contains("status: 3 frames, 0 tracked, 0 lost, "), "{msg}");
    assert!(msg.contains(", peak stack not measured\n"), "{msg}");
    assert!(!msg.contains("StatusMessage"), "{msg}");

    // The table form names every pose.
    let run = sim(&["decode-serial", capture.to_str().unwrap()]);
    assert!(run.status.success(), "{}", stderr(&run));
    let table = String::from_utf8_lossy(&run.stdout);
    assert_eq!(table.lines().count(), 3, "header and two poses: {table}");
    assert!(table.lines().nth(2).unwrap().contains("tracking"), "{table}");
}

#[test]
fn decode_serial_of_an_empty_capture_fails() {
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("uart.bin");
    std::fs::write(&empty, b"").unwrap();
    for file in ["/dev/null", empty.to_str().unwrap()] {
        let run = sim(&["decode-serial", file]);
        assert_eq!(run.status.code(), Some(1), "{file}");
        let msg = stderr(&run);
        assert!(msg.contains(&format!("{file}: the capture is empty (0 bytes)")), "{msg}");
        assert!(run.stdout.is_empty(), "no table of nothing");
    }
    // Delimiters alone hold no frame either.
    std::fs::write(&empty, [0u8; 4]).unwrap();
    let run = sim(&["decode-serial", empty.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(1));
    assert!(stderr(&run).contains("no frame of the ferroslam wire format"), "{}", stderr(&run));
}

#[test]
fn decode_serial_rejects_unreadable_and_foreign_input() {
    let run = sim(&["decode-serial", "/nonexistent/uart.bin"]);
    assert_eq!(run.status.code(), Some(1));
    assert!(
        stderr(&run).contains("cannot read the capture /nonexistent/uart.bin"),
        "{}",
        stderr(&run)
    );

    let dir = tempfile::tempdir().unwrap();
    let text = dir.path().join("log.txt");
    std::fs::write(&text, "this is a text log, not a capture\n\0more text\0").unwrap();
    let run = sim(&["decode-serial", text.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(1));
    let msg = stderr(&run);
    assert!(
        msg.contains("no frame of the ferroslam wire format") && msg.contains("2 frames dropped"),
        "{msg}"
    );
    assert!(!msg.contains("panicked"), "{msg}");
}

#[test]
fn the_host_scale_map_matches_the_board_map_while_both_have_room() {
    // Sixty frames make fewer keyframes than the board's map holds (32), so nothing is retired
    // and the two capacities must give the same trajectory bits; only the sizes differ.
    let (_, board, board_trajectory) = demo_outputs(&["--frames", "60"]);
    let (_, host, host_trajectory) = demo_outputs(&["--frames", "60", "--map", "host"]);
    assert_eq!(board["backend"]["map_scale"], "board");
    assert_eq!(host["backend"]["map_scale"], "host");
    let keyframes = host["backend"]["map_keyframes_max"].as_u64().unwrap();
    assert!((1..32).contains(&keyframes), "{keyframes} keyframes: the board's map has room");
    assert_eq!(board_trajectory, host_trajectory);
    assert!(host["state_bytes"].as_u64().unwrap() > board["state_bytes"].as_u64().unwrap());
}

#[test]
fn window_levels_reach_the_back_end_and_zero_is_refused() {
    let (_, default, _) = demo_outputs(&["--frames", "30"]);
    assert_eq!(default["backend"]["window_levels"], 2, "the board's default");
    let (_, wide, _) = demo_outputs(&["--frames", "30", "--map", "host", "--window-levels", "255"]);
    assert_eq!(wide["backend"]["window_levels"], 255);
    assert_eq!(wide["backend"]["map_scale"], "host");
    let run = sim(&["demo", "--frames", "5", "--window-levels", "0"]);
    assert_eq!(run.status.code(), Some(2));
    assert!(stderr(&run).contains("--window-levels"), "{}", stderr(&run));
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

/// A map file of `keyframes` records at x = 0, 1, ... m, each with 10 points 2 m ahead.
fn map_file_of(keyframes: u32) -> Vec<u8> {
    use ferroslam_core::features::Descriptor;
    use ferroslam_core::geometry::Pose;
    use ferroslam_core::map::{PlaceKey, PlacePoint, PlaceRecord};
    use nalgebra::{Point3, Translation3, UnitQuaternion};

    let records: Vec<PlaceRecord> = (0..keyframes)
        .map(|seq| {
            let mut r = PlaceRecord {
                seq,
                timestamp_s: f64::from(seq) / 2.0,
                t_wc: Pose::from_parts(
                    Translation3::new(seq as f32, 0.0, 0.0),
                    UnitQuaternion::identity(),
                ),
                key: PlaceKey::default(),
                points: Default::default(),
            };
            for i in 0..10 {
                let p = PlacePoint { p_c: Point3::new(0.0, 0.0, 2.0), descriptor: Descriptor(i) };
                r.points.push(p).unwrap();
            }
            r
        })
        .collect();
    ferroslam_sim::map_file::encode_map_file(&records)
}

/// The vertex lines of a PLY `text` after checking its header: how many the header declares and
/// the lines themselves.
fn ply_vertices(text: &str) -> (usize, Vec<&str>) {
    let (header, body) = text.split_once("end_header\n").expect("a PLY header");
    assert!(header.starts_with("ply\nformat ascii 1.0\n"), "{header}");
    let declared = header
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .expect("a vertex element")
        .parse()
        .unwrap();
    (declared, body.lines().collect())
}

#[test]
fn map_info_and_export_read_a_map_file() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("three.fsmp");
    std::fs::write(&map, map_file_of(3)).unwrap();
    let run = sim(&["map", "info", map.to_str().unwrap()]);
    assert!(run.status.success(), "{}", stderr(&run));
    let info = String::from_utf8_lossy(&run.stdout);
    for figure in [
        "keyframes: 3",
        "verification points: 30 (per keyframe: min 10, median 10, max 10)",
        "file: 3092 bytes",
        "(FNV-1a of the records and world: matches)",
        "segments: not stored in this format",
        "timestamps: 0.000000 s to 1.000000 s",
        "x 0.000 to 2.000",
    ] {
        assert!(info.contains(figure), "{figure:?} in {info}");
    }

    let ply = dir.path().join("three.ply");
    let run = sim(&["map", "export", map.to_str().unwrap(), "--ply", ply.to_str().unwrap()]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(String::from_utf8_lossy(&run.stdout).contains("wrote 33 vertices"));
    let text = std::fs::read_to_string(&ply).unwrap();
    let (declared, vertices) = ply_vertices(&text);
    assert_eq!((declared, vertices.len()), (33, 33));
    assert_eq!(vertices[10], "1.0000 0.0000 2.0000 170 170 170", "t_wc * p_c");
    assert_eq!(vertices[31], "1.0000 0.0000 0.0000 255 40 40", "a camera");
}

#[test]
fn map_of_a_damaged_or_missing_file_fails_saying_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let good = map_file_of(2);
    let ply = dir.path().join("out.ply");
    let mut flipped = good.clone();
    flipped[20 + 1024 + 40] ^= 0x01;
    let cases: [(&str, &[u8], &str); 4] = [
        (
            "truncated.fsmp",
            &good[..good.len() - 100],
            "truncated: 1968 bytes where the header says 2068",
        ),
        ("flipped.fsmp", &flipped, "the file changed since it was written"),
        ("text.fsmp", b"not a map at all\n", "not a ferroslam map file"),
        ("empty.fsmp", b"", "truncated: 0 bytes where the header says 20"),
    ];
    for (name, bytes, why) in cases {
        let file = dir.path().join(name);
        std::fs::write(&file, bytes).unwrap();
        let path = file.to_str().unwrap();
        for args in
            [vec!["map", "info", path], vec!["map", "export", path, "--ply", ply.to_str().unwrap()]]
        {
            let run = sim(&args);
            assert_eq!(run.status.code(), Some(1), "{args:?}");
            let msg = stderr(&run);
            assert!(msg.contains(&format!("map {path}: ")) && msg.contains(why), "{msg}");
            assert!(!msg.contains("panicked"), "{msg}");
            assert!(run.stdout.is_empty(), "nothing printed of a refused map");
        }
    }
    assert!(!ply.exists(), "no PLY written of a refused map");
    let run = sim(&["map", "info", "/nonexistent/map.fsmp"]);
    assert_eq!(run.status.code(), Some(1));
    assert!(stderr(&run).contains("cannot read the map /nonexistent/map.fsmp"), "{}", stderr(&run));
    assert_eq!(sim(&["map", "export", "x.fsmp"]).status.code(), Some(2), "--ply is required");
}

#[test]
fn a_map_saved_by_a_replay_reads_back_with_its_keyframes() {
    let dir = tempfile::tempdir().unwrap();
    let (data, out) = (dir.path().join("data"), dir.path().join("out"));
    let map = dir.path().join("run.fsmp");
    let run = sim(&["demo", "--frames", "40", "--write-dataset", data.to_str().unwrap()]);
    assert!(run.status.success(), "{}", stderr(&run));
    let args = ["replay", data.to_str().unwrap(), "--out", out.to_str().unwrap()];
    let run = sim(&[&args[..], &["--save-map", map.to_str().unwrap()]].concat());
    assert!(run.status.success(), "{}", stderr(&run));
    // The replay says "map: N keyframes, P planes and A anchors saved to FILE (B bytes)".
    let msg = stderr(&run);
    let (keyframes, planes) = msg
        .lines()
        .filter(|l| l.contains(" anchors saved to "))
        .find_map(|l| {
            let (n, rest) = l.strip_prefix("map: ")?.split_once(" keyframes, ")?;
            Some((n.parse::<usize>().ok()?, rest.split_once(" planes")?.0.parse::<usize>().ok()?))
        })
        .unwrap_or_else(|| panic!("the replay names the keyframes and planes saved: {msg}"));
    assert!(keyframes > 1 && planes > 0, "{msg}");

    let run = sim(&["map", "info", map.to_str().unwrap()]);
    assert!(run.status.success(), "{}", stderr(&run));
    let info = String::from_utf8_lossy(&run.stdout);
    assert!(info.contains(&format!("keyframes: {keyframes}\n")), "{info}");
    assert!(info.contains(&format!("planes: {planes}, anchors: 0\n")), "{info}");
    assert!(info.contains("(FNV-1a of the records and world: matches)"), "{info}");
    let file_bytes = std::fs::metadata(&map).unwrap().len();
    assert!(info.contains(&format!("file: {file_bytes} bytes")), "{info}");

    let ply = dir.path().join("run.ply");
    let run = sim(&["map", "export", map.to_str().unwrap(), "--ply", ply.to_str().unwrap()]);
    assert!(run.status.success(), "{}", stderr(&run));
    let text = std::fs::read_to_string(&ply).unwrap();
    let (declared, vertices) = ply_vertices(&text);
    assert_eq!(declared, vertices.len());
    let cameras = vertices.iter().filter(|v| v.ends_with(" 255 40 40")).count();
    assert_eq!(cameras, keyframes, "one camera vertex per keyframe");
    let centroids = vertices.iter().filter(|v| v.ends_with(" 40 110 255")).count();
    assert_eq!(centroids, planes, "one vertex per saved plane");
    assert!(declared > keyframes + planes, "and the verification points");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains(&format!("wrote {declared} vertices")), "{stdout}");

    // Played again in the saved map: it starts with the keyframes and the planes, and says so.
    let again = dir.path().join("again");
    let args = ["replay", data.to_str().unwrap(), "--out", again.to_str().unwrap()];
    let run = sim(&[&args[..], &["--load-map", map.to_str().unwrap(), "--localize"]].concat());
    assert!(run.status.success(), "{}", stderr(&run));
    let loaded = format!("map: {keyframes} keyframes, {planes} planes and 0 anchors loaded from ");
    assert!(stderr(&run).contains(&loaded), "{}", stderr(&run));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(again.join("report.json")).unwrap()).unwrap();
    let expected = serde_json::json!({"keyframes": keyframes, "planes": planes, "anchors": 0});
    assert_eq!(report["places"]["loaded"], expected);
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
