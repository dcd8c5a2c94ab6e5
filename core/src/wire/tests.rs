//! Tests of the wire format: round trips, and recovery with exact counts after every kind of
//! corruption.
//!
//! Test code only: this file is compiled under #[cfg(test)] (see the `mod` line that includes it).

extern crate std;

use std::vec::Vec;

use super::*;
use crate::geometry::Pose;
use crate::tracking::{FrameResult, FrontendState, FrontendWork, GuideStage};
use nalgebra::{Translation3, UnitQuaternion, Vector3};

fn pose_message(i: u32) -> PoseMessage {
    let t_wc = Pose::from_parts(
        Translation3::new(0.1 * i as f32, -2.5, 1.0 / 3.0),
        UnitQuaternion::from_scaled_axis(Vector3::new(0.1, -0.2, 0.3 * i as f32)),
    );
    let mut map: crate::map::Map<1, 1> = crate::map::Map::new();
    let kf = map.add_keyframe(Pose::identity(), 0.0).ok();
    let r = FrameResult {
        t_wc,
        state: FrontendState::Tracking,
        tracked: true,
        reinitialized: false,
        relocalized: false,
        keyframe: kf.filter(|_| i.is_multiple_of(2)),
        reference_keyframe: kf,
        inliers: 120 + i as usize,
        matches: 70_000,
        guide_matches: 24,
        guide_stage: if i.is_multiple_of(3) {
            GuideStage::AffineBank
        } else {
            GuideStage::MotionModel
        },
        tracked_landmarks: 100,
        keyframe_landmarks: (0, 0, 0),
        work: FrontendWork::default(),
        loop_closure: None,
    };
    PoseMessage::from_frame_result(i, 1_305_031_102.175_304 + f64::from(i) / 30.0, &r)
}

fn all_kinds() -> [Message; 4] {
    [
        Message::Pose(pose_message(7)),
        Message::Status(StatusMessage {
            frames: 60,
            tracked_frames: 59,
            lost_frames: 1,
            reinitializations: 1,
            relocalizations: 3,
            keyframes: 4,
            recoveries: 2,
            faults: 0,
            state_bytes: 190_000,
            stack_peak_bytes: 12_345,
        }),
        Message::Cost(CostMessage {
            frame_index: 3,
            unit: TickUnit::Instructions { per_tick: 40 },
            acquire_ticks: 100_000,
            frontend_ticks: u32::MAX,
            backend_ticks: 7,
            report_ticks: 0,
        }),
        Message::Fault(FaultMessage { frame_index: 9, code: FaultCode::FrameSource, detail: 3 }),
    ]
}

fn frame_bytes(m: &Message) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_ON_WIRE];
    let n = encode(m, &mut buf).unwrap();
    buf[..n].to_vec()
}

/// Everything `bytes` gives, and the decoder's counts after `finish`.
fn decode_all(bytes: &[u8]) -> (Vec<Message>, Vec<FrameError>, DecoderStats) {
    let mut d: StreamDecoder = StreamDecoder::new();
    let (mut ok, mut bad) = (Vec::new(), Vec::new());
    for &b in bytes {
        match d.push(b) {
            Some(Ok(m)) => ok.push(m),
            Some(Err(e)) => bad.push(e),
            None => {}
        }
    }
    bad.extend(d.finish());
    let s = d.stats();
    assert_eq!(s.bytes_received, bytes.len() as u64);
    assert_eq!(s.bytes_delivered + s.bytes_skipped, s.bytes_received, "every byte accounted for");
    (ok, bad, s)
}

#[test]
fn every_message_round_trips_bit_for_bit() {
    for m in all_kinds() {
        let bytes = frame_bytes(&m);
        assert_eq!(bytes.last(), Some(&0), "a frame ends with the delimiter");
        assert!(!bytes[..bytes.len() - 1].contains(&0), "no zero inside a frame");
        assert!(bytes.len() <= MAX_FRAME_ON_WIRE);
        let (ok, bad, s) = decode_all(&bytes);
        assert_eq!(ok, [m]);
        assert!(bad.is_empty());
        assert_eq!((s.frames_decoded, s.bytes_skipped), (1, 0));
    }
    let Message::Pose(p) = all_kinds()[0] else { unreachable!() };
    let back = p.t_wc();
    assert_eq!(back.translation.vector.x.to_bits(), p.translation_m[0].to_bits());
    assert_eq!(back.rotation.coords.w.to_bits(), p.rotation_xyzw[3].to_bits());
}

#[test]
fn pose_message_carries_the_frame_result() {
    let p = pose_message(6);
    assert_eq!(p.state, TrackingState::Tracking);
    assert!(p.flags.contains(PoseFlags::TRACKED | PoseFlags::KEYFRAME | PoseFlags::RECOVERY));
    assert_eq!((p.inliers, p.matches), (126, u16::MAX), "counts saturate");
    assert!(!pose_message(1).flags.contains(PoseFlags::KEYFRAME));
}

#[test]
fn the_payload_layout_is_version_body_crc() {
    let m = Message::Fault(FaultMessage { frame_index: 1, code: FaultCode::Telemetry, detail: 2 });
    let mut frame = frame_bytes(&m);
    frame.pop();
    let n = cobs::decode_in_place(&mut frame).unwrap();
    let payload = &frame[..n];
    // the version, variant Fault = 3, frame_index 1, code Telemetry = 2, detail 2, then the CRC.
    assert_eq!(&payload[..5], &[SCHEMA_VERSION, 3, 1, 2, 2]);
    assert_eq!(payload[5..].to_vec(), crc32(&payload[..5]).to_le_bytes().to_vec());
    // The published check value of CRC-32/ISO-HDLC.
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
}

#[test]
fn a_small_output_buffer_is_an_error() {
    let m = all_kinds()[0];
    let need = frame_bytes(&m).len();
    let mut buf = [0u8; 8];
    assert_eq!(encode(&m, &mut buf), Err(EncodeError::BufferTooSmall { got: 8 }));
    let mut exact = std::vec![0u8; need];
    assert_eq!(encode(&m, &mut exact), Ok(need));
    let mut one_short = std::vec![0u8; need - 1];
    assert!(encode(&m, &mut one_short).is_err());
}

/// Four good frames (one of each kind).
fn stream() -> (Vec<Vec<u8>>, [Message; 4]) {
    let msgs = all_kinds();
    (msgs.iter().map(frame_bytes).collect(), msgs)
}

#[test]
fn a_flipped_bit_costs_only_its_frame() {
    let (frames, msgs) = stream();
    for bit in 0..8 {
        for at in 0..frames[1].len() - 1 {
            let mut f1 = frames[1].clone();
            f1[at] ^= 1 << bit;
            let bytes =
                [frames[0].clone(), f1.clone(), frames[2].clone(), frames[3].clone()].concat();
            let (ok, bad, s) = decode_all(&bytes);
            if f1[at] == 0 {
                // The flip made a delimiter: frame 1 splits in two pieces, both dropped (one
                // piece is empty when the flip hit its first byte).
                assert_eq!(ok, [msgs[0], msgs[2], msgs[3]], "bit {bit} at {at}");
                let pieces = if at == 0 { 1 } else { 2 };
                assert_eq!(s.frames_dropped, pieces, "bit {bit} at {at}");
            } else {
                assert_eq!(ok, [msgs[0], msgs[2], msgs[3]], "bit {bit} at {at}");
                assert_eq!(bad.len(), 1);
                assert_eq!(s.frames_dropped, 1);
            }
            assert_eq!(s.frames_decoded, 3);
            assert_eq!(s.bytes_skipped, f1.len() as u64, "bit {bit} at {at}");
        }
    }
}

#[test]
fn truncation_recovers_at_the_next_good_frame() {
    let (frames, msgs) = stream();
    let f1 = &frames[1];
    // Cut the tail of frame 1, delimiter included: frame 1 and frame 2 run together and are
    // dropped as one; frame 3 is decoded.
    let cut = &f1[..f1.len() / 2];
    let bytes = [frames[0].clone(), cut.to_vec(), frames[2].clone(), frames[3].clone()].concat();
    let (ok, _, s) = decode_all(&bytes);
    assert_eq!(ok, [msgs[0], msgs[3]]);
    assert_eq!((s.frames_decoded, s.frames_dropped), (2, 1));
    assert_eq!(s.bytes_skipped, (cut.len() + frames[2].len()) as u64);
    // Cut inside frame 1 but keep its delimiter: only frame 1 is lost.
    let cut = [&f1[..f1.len() / 2], &[0u8][..]].concat();
    let bytes = [frames[0].clone(), cut.clone(), frames[2].clone()].concat();
    let (ok, _, s) = decode_all(&bytes);
    assert_eq!(ok, [msgs[0], msgs[2]]);
    assert_eq!((s.frames_dropped, s.bytes_skipped), (1, cut.len() as u64));
    // A stream that ends inside a frame: the tail is counted when the stream ends.
    let bytes = [frames[0].clone(), f1[..5].to_vec()].concat();
    let (ok, bad, s) = decode_all(&bytes);
    assert_eq!(ok, [msgs[0]]);
    assert_eq!(bad, [FrameError::Truncated { len: 5 }]);
    assert_eq!((s.frames_dropped, s.bytes_skipped), (1, 5));
}

#[test]
fn garbage_and_zero_bytes_between_frames_are_skipped() {
    let (frames, msgs) = stream();
    // Three lone delimiters (empty frames), then garbage ending in a delimiter (one bad frame),
    // then a frame whose start was lost (one bad frame).
    let garbage = [0x55u8, 0xAA, 0x13, 0x37, 0x00];
    let headless = frames[2][3..].to_vec();
    let bytes = [
        std::vec![0u8, 0, 0],
        frames[0].clone(),
        garbage.to_vec(),
        frames[1].clone(),
        headless.clone(),
        frames[3].clone(),
    ]
    .concat();
    let (ok, bad, s) = decode_all(&bytes);
    assert_eq!(ok, [msgs[0], msgs[1], msgs[3]]);
    assert_eq!(bad.len(), 2);
    assert_eq!((s.frames_decoded, s.frames_dropped, s.frames_unknown_version), (3, 2, 0));
    assert_eq!(s.bytes_skipped, (3 + garbage.len() + headless.len()) as u64);
}

#[test]
fn a_run_without_delimiter_longer_than_any_frame_is_dropped() {
    let (frames, msgs) = stream();
    let noise = std::vec![0xA5u8; 3 * MAX_ENCODED_FRAME];
    let bytes = [noise.clone(), std::vec![0], frames[0].clone()].concat();
    let (ok, bad, s) = decode_all(&bytes);
    assert_eq!(ok, [msgs[0]]);
    assert_eq!(bad, [FrameError::TooLong]);
    assert_eq!((s.frames_dropped, s.bytes_skipped), (1, noise.len() as u64 + 1));
}

#[test]
fn an_unknown_version_is_counted_and_skipped() {
    let (frames, msgs) = stream();
    // A well-formed frame of the next schema version: right CRC, other version.
    let next = SCHEMA_VERSION + 1;
    let mut payload = std::vec![next, 0xDE, 0xAD];
    let crc = crc32(&payload);
    payload.extend_from_slice(&crc.to_le_bytes());
    let mut future = std::vec![0u8; MAX_ENCODED_FRAME];
    let n = cobs::try_encode(&payload, &mut future).unwrap();
    future.truncate(n);
    future.push(0);
    let bytes = [frames[0].clone(), future.clone(), frames[1].clone()].concat();
    let (ok, bad, s) = decode_all(&bytes);
    assert_eq!(ok, [msgs[0], msgs[1]]);
    assert_eq!(bad, [FrameError::UnknownVersion { found: next }]);
    assert_eq!((s.frames_unknown_version, s.frames_dropped), (1, 0));
    assert_eq!(s.bytes_skipped, future.len() as u64);
}

#[test]
fn a_valid_crc_over_a_bad_body_is_dropped() {
    // This version, variant 9 (no such message), right CRC.
    let mut payload = std::vec![SCHEMA_VERSION, 9, 1];
    let crc = crc32(&payload);
    payload.extend_from_slice(&crc.to_le_bytes());
    let mut enc = std::vec![0u8; MAX_ENCODED_FRAME];
    let n = cobs::try_encode(&payload, &mut enc).unwrap();
    assert_eq!(decode_frame(&mut enc[..n]), Err(FrameError::Body));
    // Too short to hold a CRC.
    let mut short = [3u8, 1, 1];
    assert_eq!(decode_frame(&mut short), Err(FrameError::TooShort { len: 2 }));
}

#[test]
fn a_cost_adds_its_stages_up() {
    let c = CostMessage {
        frame_index: 0,
        unit: TickUnit::Instructions { per_tick: 40 },
        acquire_ticks: 1,
        frontend_ticks: 10,
        backend_ticks: 100,
        report_ticks: 1000,
    };
    assert_eq!(c.total_instructions(), Some(44_440));
    let cycles = CostMessage { unit: TickUnit::CoreCycle, ..c };
    assert_eq!(cycles.total_instructions(), None);
}
