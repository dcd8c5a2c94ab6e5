#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::vec::Vec;

use embedded_io::{Read, Write};
use ferroslam_core::frame::TelemetrySink;
use ferroslam_core::wire::{Message, PoseFlags, PoseMessage, StreamDecoder, TrackingState, encode};

use super::*;
use crate::serial::SerialLink;

/// A byte sink that keeps everything.
#[derive(Default)]
struct Bytes(Vec<u8>);

impl embedded_io::ErrorType for Bytes {
    type Error = embedded_io::ErrorKind;
}

impl embedded_io::Write for Bytes {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        self.0.extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

/// `n` distinct pose messages.
fn sent(n: u32) -> Vec<Message> {
    (0..n)
        .map(|i| {
            Message::Pose(PoseMessage {
                frame_index: i,
                timestamp_s: f64::from(i) / 30.0,
                translation_m: [0.01 * i as f32, -1.0, 2.5],
                rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
                state: TrackingState::Tracking,
                flags: PoseFlags(0),
                inliers: (i % 300) as u16,
                matches: 7,
            })
        })
        .collect()
}

/// Decodes `bytes`: the messages and the frames dropped.
fn decode(bytes: &[u8]) -> (Vec<Message>, u64) {
    let mut d: StreamDecoder = StreamDecoder::new();
    let got: Vec<Message> =
        bytes.iter().filter_map(|&b| d.push(b)).filter_map(Result::ok).collect();
    let _ = d.finish();
    (got, d.stats().frames_dropped)
}

/// Whether `got` is `sent` with some messages left out, in order, none changed.
fn is_subsequence(got: &[Message], sent: &[Message]) -> bool {
    let mut it = sent.iter();
    got.iter().all(|g| it.any(|s| s == g))
}

const FAULTS: [LinkFault; 3] = [LinkFault::DropByte, LinkFault::FlipBit, LinkFault::Truncate];

#[test]
fn no_fault_passes_the_bytes_through() {
    for fault in FAULTS {
        let mut link = SerialLink::new(FaultyLink::new(
            Bytes::default(),
            LinkPlan { fault, per_mille: 0, seed: 1 },
        ));
        let mut clean = Vec::new();
        for m in sent(50) {
            link.send(&m).unwrap();
            let mut f = [0u8; MAX_FRAME_ON_WIRE];
            let n = encode(&m, &mut f).unwrap();
            clean.extend_from_slice(&f[..n]);
        }
        let faulty = link.into_inner();
        assert_eq!((faulty.frames(), faulty.hit()), (50, 0));
        assert_eq!(faulty.into_inner().0, clean);
    }
}

#[test]
fn the_sender_side_loses_hit_frames_only_and_never_delivers_a_wrong_value() {
    let messages = sent(2000);
    for fault in FAULTS {
        for per_mille in [10, 100, 1000] {
            let plan = LinkPlan { fault, per_mille, seed: 9 };
            let mut link = SerialLink::new(FaultyLink::new(Bytes::default(), plan));
            for m in &messages {
                link.send(m).unwrap();
            }
            let faulty = link.into_inner();
            let hit = faulty.hit() as usize;
            let (got, dropped) = decode(&faulty.into_inner().0);
            assert!(is_subsequence(&got, &messages), "{fault:?} {per_mille}: a changed message");
            // Each hit frame is lost, and at most one neighbour with it (a merge or a split).
            let lost = messages.len() - got.len();
            assert!(lost >= hit.min(1) && lost <= 2 * hit, "{fault:?} {per_mille}: {lost}, {hit}");
            assert!(dropped as usize >= hit / 2, "{fault:?}: lost frames are counted");
            let expect = messages.len() * usize::from(per_mille) / 1000;
            assert!(hit.abs_diff(expect) <= expect / 4 + 10, "{fault:?}: {hit} hit of ~{expect}");
        }
    }
}

#[test]
fn the_receiver_side_does_the_same_on_read() {
    let messages = sent(1000);
    let mut clean = SerialLink::new(Bytes::default());
    for m in &messages {
        clean.send(m).unwrap();
    }
    let bytes = clean.into_inner().0;
    for fault in FAULTS {
        let mut link = FaultyLink::new(&bytes[..], LinkPlan { fault, per_mille: 100, seed: 3 });
        let mut read = Vec::new();
        let mut chunk = [0u8; 37];
        loop {
            let n = link.read(&mut chunk).unwrap();
            if n == 0 {
                break;
            }
            read.extend_from_slice(&chunk[..n]);
        }
        assert_eq!(link.frames(), 1000);
        let hit = link.hit() as usize;
        assert!((60..140).contains(&hit), "{fault:?}: {hit}");
        let (got, _) = decode(&read);
        assert!(is_subsequence(&got, &messages), "{fault:?}");
        assert!(messages.len() - got.len() <= 2 * hit && got.len() < messages.len());
    }
}

#[test]
fn a_flush_mid_frame_passes_the_unfinished_bytes_on() {
    let plan = LinkPlan { fault: LinkFault::FlipBit, per_mille: 1000, seed: 1 };
    let mut link = FaultyLink::new(Bytes::default(), plan);
    link.write_all(&[5, 6, 7]).unwrap();
    link.flush().unwrap();
    assert_eq!(link.hit(), 0);
    assert_eq!(link.into_inner().0, [5, 6, 7]);
}
