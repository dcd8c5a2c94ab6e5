//! `ferroslam-sim decode-serial`: decoding a capture of the serial wire format, and its
//! messages on empty, unreadable or foreign input.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::{sim, stderr};

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
