//! The `ferroslam-sim demo` command (synthetic frames with known poses): its options, its
//! outputs, AR objects and anchor scripts, and its exit status and messages on bad input.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::Path;
use std::process::Output;

use common::{sim, stderr};

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
