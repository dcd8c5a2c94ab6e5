//! MCAP input (issue 51, item 1): a TUM folder converted to MCAP replays to the same bits; topics
//! are chosen by encoding or by name; a file that cannot be used is refused with a message that
//! says why (no panic).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use ferroslam_sim::dataset::mcap::messages::{
    CAMERA_INFO, CameraInfoMsg, IMAGE, ImageMsg, Stamp, schema_text,
};
use ferroslam_sim::dataset::mcap::{McapTopics, convert_to_mcap};
use ferroslam_sim::dataset::{CalibrationSource, Dataset, DatasetOptions};
use ferroslam_sim::demo::{DemoOptions, write_dataset};
use ferroslam_sim::replay::{ReplayOptions, replay};
use ferroslam_sim::run::TrackMode;
use ferroslam_sim::synth::SynthOptions;

use common::sim;

/// A 30-frame demo sequence written as a TUM folder into `dir`.
fn demo_folder(dir: &Path) {
    let options = DemoOptions {
        synth: SynthOptions { frames: 30, ..SynthOptions::default() },
        progress_bar: false,
        ..DemoOptions::new(Some(TrackMode::SLAM))
    };
    write_dataset(dir, &options, "tests/mcap.rs").unwrap();
}

/// Rewrites the demo folder's depth (5000 units per metre) in millimetres.
fn to_millimetres(folder: &Path) {
    for entry in std::fs::read_dir(folder.join("depth")).unwrap() {
        let path = entry.unwrap().path();
        let mut depth = image::open(&path).unwrap().into_luma16();
        depth.pixels_mut().for_each(|p| p.0[0] = (p.0[0] + 2) / 5);
        depth.save(&path).unwrap();
    }
    let path = folder.join("calibration.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let line = text.lines().find(|l| l.starts_with("depth_scale")).unwrap().to_owned();
    std::fs::write(&path, text.replace(&line, "depth_scale = 1000.0")).unwrap();
}

/// Replays `path` (folder or MCAP file) in SLAM mode into `out`; returns the trajectories' bytes.
fn trajectories(path: &Path, out: &Path) -> (Vec<u8>, Vec<u8>) {
    let options = ReplayOptions { progress_bar: false, ..ReplayOptions::default() };
    let outputs = replay(path, out, options).unwrap();
    let why = &outputs.report.evaluation_error;
    assert!(outputs.evaluation.is_some(), "{}: evaluated: {why:?}", path.display());
    let read = |name| std::fs::read(out.join(name)).unwrap();
    (read("CameraTrajectory.txt"), read("KeyFrameTrajectory.txt"))
}

#[test]
fn a_converted_folder_replays_to_the_same_bits() {
    let tmp = tempfile::tempdir().unwrap();
    let folder = tmp.path().join("demo");
    demo_folder(&folder);
    // The demo's depth scale (5000) is written as 32FC1 metres; brought to millimetres, as 16UC1.
    for encoding in ["32FC1", "16UC1"] {
        if encoding == "16UC1" {
            to_millimetres(&folder);
        }
        let file = tmp.path().join(format!("demo-{encoding}.mcap"));
        let written = convert_to_mcap(&folder, &file, &CalibrationSource::File).unwrap();
        assert_eq!((written.rgb_images, written.depth_images), (30, 30));
        assert_eq!((written.groundtruth_poses, written.depth_encoding), (30, encoding));
        let from_folder = trajectories(&folder, &tmp.path().join(format!("f-{encoding}")));
        let from_file = trajectories(&file, &tmp.path().join(format!("m-{encoding}")));
        assert!(from_folder.0.len() > 100, "a trajectory was written");
        assert!(from_folder == from_file, "{encoding}: the MCAP replay differs from the folder's");
    }
}

/// Writes an MCAP file of `frames` colour (`colour` encoding, 16x12) and depth (`depth`
/// encoding, `depth_size`) images on `/cam/color/image_raw` and `/cam/depth/image_raw`, with a
/// CameraInfo beside the colour topic when `info`; chunked and indexed when `chunked`.
fn write_file(path: &Path, colour: &str, depth: (&str, u32, u32), info: bool, chunked: bool) {
    let options = mcap::WriteOptions::new().use_chunks(chunked);
    let mut w = options.create(BufWriter::new(File::create(path).unwrap())).unwrap();
    let mut channel = |topic: &str, schema: &str| {
        let id = w.add_schema(schema, "ros2msg", schema_text(schema).as_bytes()).unwrap();
        w.add_channel(id, topic, "cdr", &BTreeMap::new()).unwrap()
    };
    let channels = [
        channel("/cam/color/image_raw", IMAGE),
        channel("/cam/depth/image_raw", IMAGE),
        channel("/cam/color/camera_info", CAMERA_INFO),
    ];
    let pixel_bytes = |e: &str| match e {
        "rgb8" | "bgr8" | "bayer_rggb8" => 3,
        "32FC1" => 4,
        "16UC1" => 2,
        _ => 1,
    };
    for i in 0..5u32 {
        let stamp = Stamp { sec: 100, nanosec: i * 33_333_000 };
        let depth_stamp = Stamp { nanosec: stamp.nanosec + 4_000_000, ..stamp };
        let colour_data = vec![(40 * i) as u8; 16 * 12 * pixel_bytes(colour)];
        let (encoding, width, height) = depth;
        let depth_data: Vec<u8> = match encoding {
            "32FC1" => (0..width * height).flat_map(|_| 1.25f32.to_le_bytes()).collect(),
            _ => (0..width * height).flat_map(|_| 1250u16.to_le_bytes()).collect(),
        };
        let images = [
            (0, stamp, colour, 16, 12, colour_data),
            (1, depth_stamp, encoding, width, height, depth_data),
        ];
        for (k, stamp, encoding, width, height, data) in images {
            let step = width * pixel_bytes(encoding) as u32;
            let msg =
                ImageMsg { stamp, height, width, encoding, is_bigendian: false, step, data: &data };
            write_message(&mut w, channels[k], stamp, &msg.encode("cam"));
        }
        if info {
            let k = [20.0, 0.0, 7.5, 0.0, 20.0, 5.5, 0.0, 0.0, 1.0];
            let d = vec![0.0; 5];
            let (distortion_model, width, height) = ("plumb_bob".to_owned(), 16, 12);
            let msg = CameraInfoMsg { stamp, height, width, distortion_model, d, k };
            write_message(&mut w, channels[2], stamp, &msg.encode("cam"));
        }
    }
    w.finish().unwrap();
}

fn write_message<W: std::io::Write + std::io::Seek>(
    w: &mut mcap::Writer<W>,
    channel_id: u16,
    stamp: Stamp,
    data: &[u8],
) {
    let (log_time, sequence) = (stamp.as_nanos(), 0);
    let header =
        mcap::records::MessageHeader { channel_id, sequence, log_time, publish_time: log_time };
    w.write_to_known_channel(&header, data).unwrap();
}

fn open(path: &Path, topics: McapTopics) -> Result<Dataset, String> {
    let opts = DatasetOptions { topics, ..DatasetOptions::default() };
    Dataset::open(path, &opts).map_err(|e| e.to_string())
}

#[test]
fn a_ros_recording_reads_with_camera_info_indexed_or_not() {
    let tmp = tempfile::tempdir().unwrap();
    let mut frames = Vec::new();
    for chunked in [true, false] {
        let path = tmp.path().join(format!("ros-{chunked}.mcap"));
        write_file(&path, "bgr8", ("32FC1", 16, 12), true, chunked);
        let ds = open(&path, McapTopics::default()).unwrap();
        assert_eq!(ds.len(), 5);
        // The chunked file is read back through its indexes, the other kept in memory.
        assert!(format!("{ds:?}").contains(&format!("indexed: {chunked}")), "{ds:?}");
        assert!(ds.groundtruth().is_none(), "no ground truth: replayed without evaluation");
        assert!(
            ds.calibration_origin().to_string().contains("CameraInfo on /cam/color/camera_info")
        );
        // Depth in metres comes in the CameraInfo default of millimetres.
        assert_eq!(ds.sensor_calibration().depth_scale, 1000.0);
        frames.push((0..5).map(|i| ds.load_frame(i).unwrap()).collect::<Vec<_>>());
    }
    assert_eq!(frames[0], frames[1], "a file without indexes reads the same frames");
    let frame = &frames[0][1];
    assert_eq!((frame.width, frame.height, frame.depth_scale), (8, 6, 1000.0));
    assert!(frame.depth.iter().all(|&d| d == 1250), "1.25 m at 1000 units per metre");
}

#[test]
fn topics_are_chosen_by_name_and_a_wrong_one_lists_those_there() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("ros.mcap");
    write_file(&path, "rgb8", ("16UC1", 16, 12), true, true);
    let named = |rgb: &str| McapTopics { rgb: Some(rgb.to_owned()), depth: None };
    assert_eq!(open(&path, named("/cam/color/image_raw")).unwrap().len(), 5);
    let err = open(&path, named("/cam/colour")).unwrap_err();
    assert!(err.contains("--rgb-topic /cam/colour: no such topic"), "{err}");
    assert!(
        err.contains("/cam/color/image_raw (sensor_msgs/msg/Image rgb8, 5 messages)")
            && err.contains("/cam/color/camera_info (sensor_msgs/msg/CameraInfo, 5 messages)"),
        "{err}"
    );
    let err = open(&path, named("/cam/color/camera_info")).unwrap_err();
    assert!(
        err.contains("a sensor_msgs/msg/CameraInfo topic (cdr), not sensor_msgs/msg/Image"),
        "{err}"
    );
    let err = open(&path, named("/cam/depth/image_raw")).unwrap_err();
    assert!(
        err.contains("encoding \"16UC1\" is not supported; colour: rgb8, bgr8, mono8"),
        "{err}"
    );
    // The command line: the option, and the error on a folder.
    let out = tmp.path().join("out");
    let (file, out) = (path.to_str().unwrap(), out.to_str().unwrap());
    let run = sim(&["replay", file, "--out", out, "--rgb-topic", "/nope", "--mode", "data-path"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("no such topic; the file's topics: /cam/color/camera_info"),
        "{stderr}"
    );
    let topic = "/cam/color/image_raw";
    let run = sim(&["replay", file, "--out", out, "--rgb-topic", topic, "--mode", "data-path"]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let err = open(tmp.path(), named(topic)).unwrap_err();
    assert!(err.contains("--rgb-topic and --depth-topic apply to MCAP files"), "{err}");
}

#[test]
fn unusable_files_are_refused_saying_why() {
    let tmp = tempfile::tempdir().unwrap();
    let path = |name: &str| tmp.path().join(name);
    // No CameraInfo, no calibration carried or given.
    write_file(&path("a.mcap"), "mono8", ("16UC1", 16, 12), false, true);
    let err = open(&path("a.mcap"), McapTopics::default()).unwrap_err();
    assert!(
        err.contains("has no sensor_msgs/msg/CameraInfo topic and carries no calibration"),
        "{err}"
    );
    // An unknown colour encoding: no colour topic found, and named, its encoding refused.
    write_file(&path("b.mcap"), "bayer_rggb8", ("16UC1", 16, 12), true, true);
    let err = open(&path("b.mcap"), McapTopics::default()).unwrap_err();
    assert!(
        err.contains("no colour image topic (rgb8, bgr8, mono8); name one with --rgb-topic"),
        "{err}"
    );
    let named = McapTopics { rgb: Some("/cam/color/image_raw".into()), depth: None };
    let err = open(&path("b.mcap"), named).unwrap_err();
    assert!(err.contains("message 1: encoding \"bayer_rggb8\" is not supported"), "{err}");
    assert!(err.contains("depth: 16UC1 (millimetres), 32FC1 (metres)"), "{err}");
    // Depth of another size than the calibration's.
    write_file(&path("c.mcap"), "rgb8", ("16UC1", 8, 6), true, true);
    let err = open(&path("c.mcap"), McapTopics::default()).unwrap_err();
    assert!(
        err.contains("/cam/depth/image_raw message 1 is 8x6, but the calibration says 16x12"),
        "{err}"
    );
    // Cut short, and not MCAP at all: errors, not panics.
    let bytes = std::fs::read(path("a.mcap")).unwrap();
    for len in [bytes.len() / 2, 40, 3] {
        std::fs::write(path("cut.mcap"), &bytes[..len]).unwrap();
        let err = open(&path("cut.mcap"), McapTopics::default()).unwrap_err();
        assert!(err.contains("is not a readable MCAP file"), "{len}: {err}");
    }
    let err = open(&path("missing.mcap"), McapTopics::default()).unwrap_err();
    assert!(err.starts_with("cannot read ") && err.contains("missing.mcap"), "{err}");
    std::fs::write(path("text.mcap"), "not an mcap file").unwrap();
    let err = open(&path("text.mcap"), McapTopics::default()).unwrap_err();
    assert!(err.contains("does not start with the MCAP magic"), "{err}");
}
