//! The library's runs (`ferroslam_sim::replay`, `ferroslam_sim::demo`), which xtask calls in
//! process, against the `ferroslam-sim` binary: the same run writes the same bytes, and the typed
//! report is the one written.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::Path;
use std::process::Command;

use ferroslam_sim::dataset::{CalibrationSource, DatasetOptions};
use ferroslam_sim::demo::{DemoOptions, demo};
use ferroslam_sim::replay::{ReplayOptions, replay};
use ferroslam_sim::report::RunOutputs;
use ferroslam_sim::run::TrackMode;
use ferroslam_sim::synth::SynthOptions;
use serde_json::Value;

use common::seven_scenes;

fn sim(args: &[&str]) {
    let run = Command::new(env!("CARGO_BIN_EXE_ferroslam-sim")).args(args).output().unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
}

fn manifest_dir() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// `dir/report.json` without its wall-clock figures (`host_cost`, `per_frame[].process_us`),
/// the only ones two runs of the same frames may differ in.
fn report_without_wall_clock(report: Value) -> Value {
    let mut report = report;
    let object = report.as_object_mut().unwrap();
    object.remove("host_cost").expect("the report has host_cost");
    for frame in object["per_frame"].as_array_mut().unwrap() {
        frame.as_object_mut().unwrap().remove("process_us").expect("each frame has process_us");
    }
    report
}

fn read_report(dir: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap()
}

/// The library's outputs in `lib` against the binary's in `cli`: the same trajectories, the same
/// report apart from the wall clock, and the typed report is the one written.
fn assert_same_outputs(outputs: &RunOutputs, lib: &Path, cli: &Path) {
    for file in ["CameraTrajectory.txt", "KeyFrameTrajectory.txt", "groundtruth.txt"] {
        if cli.join(file).exists() || lib.join(file).exists() {
            let read = |dir: &Path| std::fs::read(dir.join(file)).unwrap();
            assert!(read(lib) == read(cli), "{file} differs");
        }
    }
    let written = read_report(lib);
    // Through text both ways: a value parsed back from JSON need not be the f64 serialized (f32
    // fields, and serde_json parses floats exactly only with its float_roundtrip feature).
    let typed: Value =
        serde_json::from_str(&serde_json::to_string(&outputs.report).unwrap()).unwrap();
    assert_eq!(typed, written, "the typed report");
    let (lib_report, cli_report) = (report_without_wall_clock(written), read_report(cli));
    assert_eq!(lib_report, report_without_wall_clock(cli_report));
}

#[test]
fn the_library_replay_writes_what_the_command_line_writes() {
    let dataset = seven_scenes();
    let calibration = manifest_dir().join("../calibration/7scenes-kinect-v1.toml");
    for mode in [TrackMode::SLAM, TrackMode::Odometry] {
        let (cli, lib) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
        sim(&[
            "replay",
            dataset.to_str().unwrap(),
            "--out",
            cli.path().to_str().unwrap(),
            "--calibration",
            calibration.to_str().unwrap(),
            "--max-frames",
            "30",
            "--mode",
            mode.name(),
        ]);
        let options = ReplayOptions {
            dataset: DatasetOptions {
                calibration: CalibrationSource::Path(calibration.clone()),
                max_frames: Some(30),
                ..DatasetOptions::default()
            },
            progress_bar: false,
            ..ReplayOptions::new(Some(mode))
        };
        let outputs = replay(&dataset, lib.path(), options).unwrap();
        assert_eq!((outputs.report.frames, outputs.report.mode), (30, mode.name()));
        assert!(outputs.report.ate_rmse_m.is_some() && outputs.evaluation.is_some());
        assert_same_outputs(&outputs, lib.path(), cli.path());
    }
}

#[test]
fn the_library_demo_writes_what_the_command_line_writes() {
    let (cli, lib) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let out = cli.path().to_str().unwrap();
    sim(&["demo", "--out", out, "--frames", "16", "--skip-frames", "3", "--mode", "odometry"]);
    let options = DemoOptions {
        synth: SynthOptions { frames: 16, ..SynthOptions::default() },
        skip_frames: 3,
        progress_bar: false,
        ..DemoOptions::new(Some(TrackMode::Odometry))
    };
    let outputs = demo(lib.path(), &options).unwrap();
    assert_eq!(outputs.report.frames, 13);
    assert_same_outputs(&outputs, lib.path(), cli.path());
}
