//! The host end of the firmware's serial link: decoding a UART capture into
//! [`wire`] messages ([`decode_capture`]), and host writers that implement
//! the core's [`TelemetrySink`] port as the firmware's serial link does ([`TumPoseWriter`],
//! [`WireWriter`]).

use std::io;

use ferroslam_core::frame::TelemetrySink;
use ferroslam_core::wire::{
    self, DecoderStats, FrameError, MAX_FRAME_ON_WIRE, Message, PoseMessage, StreamDecoder,
    TrackingState,
};

use crate::trajectory::{StampedPose, format_tum_line};

/// Everything a capture held.
#[derive(Debug, Clone, Default)]
pub struct Capture {
    /// The messages decoded, in order.
    pub messages: Vec<Message>,
    /// Frames dropped: the byte offset just past each (its delimiter, or the end of the capture)
    /// and why.
    pub dropped: Vec<(u64, FrameError)>,
    /// The decoder's counts (frames decoded, dropped, of an unknown version; bytes skipped).
    pub stats: DecoderStats,
}

impl Capture {
    /// The pose messages, in order.
    pub fn poses(&self) -> impl Iterator<Item = &PoseMessage> {
        self.messages.iter().filter_map(|m| match m {
            Message::Pose(p) => Some(p),
            _ => None,
        })
    }
}

/// Decodes a whole capture: every frame, resynchronizing after corrupt or truncated bytes; a
/// capture that ends inside a frame counts that frame as dropped.
pub fn decode_capture(bytes: &[u8]) -> Capture {
    let mut decoder: StreamDecoder = StreamDecoder::new();
    let mut capture = Capture::default();
    for (offset, &b) in bytes.iter().enumerate() {
        match decoder.push(b) {
            Some(Ok(m)) => capture.messages.push(m),
            Some(Err(e)) => capture.dropped.push((offset as u64 + 1, e)),
            None => {}
        }
    }
    if let Some(e) = decoder.finish() {
        capture.dropped.push((bytes.len() as u64, e));
    }
    capture.stats = decoder.stats();
    capture
}

/// A pose message as a trajectory sample (camera to world; f32 values widened exactly).
pub fn stamped_pose(p: &PoseMessage) -> StampedPose {
    StampedPose { timestamp_s: p.timestamp_s, t_wc: p.t_wc().cast::<f64>() }
}

/// A [`TelemetrySink`] writing each pose as a TUM trajectory line (`timestamp tx ty tz qx qy qz
/// qw`); other messages are not trajectory data and are skipped, and so are the poses of frames
/// before the first keyframe (state `Initializing`: no world frame yet, the pose is a
/// placeholder), as in `ferroslam-sim`'s CameraTrajectory.txt.
#[derive(Debug)]
pub struct TumPoseWriter<W> {
    out: W,
}

impl<W: io::Write> TumPoseWriter<W> {
    /// A writer of TUM lines to `out`.
    pub fn new(out: W) -> Self {
        Self { out }
    }

    /// The output, to reclaim it.
    pub fn into_inner(self) -> W {
        self.out
    }
}

impl<W: io::Write> TelemetrySink for TumPoseWriter<W> {
    type Error = io::Error;

    fn send(&mut self, message: &Message) -> Result<(), io::Error> {
        if let Message::Pose(p) = message
            && p.state != TrackingState::Initializing
        {
            writeln!(self.out, "{}", format_tum_line(&stamped_pose(p)))?;
        }
        Ok(())
    }
}

/// A [`TelemetrySink`] writing wire frames to any `std::io::Write` (a file, a serial port):
/// byte for byte what the firmware's serial link sends.
#[derive(Debug)]
pub struct WireWriter<W> {
    out: W,
}

impl<W: io::Write> WireWriter<W> {
    /// A writer of wire frames to `out`.
    pub fn new(out: W) -> Self {
        Self { out }
    }

    /// The output, to reclaim it.
    pub fn into_inner(self) -> W {
        self.out
    }

    /// The output, to read or empty it between messages.
    pub fn get_mut(&mut self) -> &mut W {
        &mut self.out
    }
}

impl<W: io::Write> TelemetrySink for WireWriter<W> {
    type Error = io::Error;

    fn send(&mut self, message: &Message) -> Result<(), io::Error> {
        let mut frame = [0u8; MAX_FRAME_ON_WIRE];
        let n = wire::encode(message, &mut frame).map_err(io::Error::other)?;
        self.out.write_all(&frame[..n])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferroslam_core::wire::{FaultCode, FaultMessage, PoseFlags};

    fn pose(i: u32) -> PoseMessage {
        PoseMessage {
            frame_index: i,
            timestamp_s: 10.0 + f64::from(i),
            translation_m: [0.5, -1.25, 2.0],
            rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
            state: TrackingState::Tracking,
            flags: PoseFlags(PoseFlags::TRACKED),
            inliers: 50,
            matches: 60,
        }
    }

    #[test]
    fn writers_round_trip_through_the_decoder() {
        let fault = FaultMessage { frame_index: 1, code: FaultCode::FrameSource, detail: 2 };
        let messages = [Message::Pose(pose(0)), Message::Fault(fault), Message::Pose(pose(2))];
        let mut wire = WireWriter::new(Vec::new());
        let mut tum = TumPoseWriter::new(Vec::new());
        for m in &messages {
            wire.send(m).unwrap();
            tum.send(m).unwrap();
        }
        let mut bytes = wire.into_inner();
        // A corrupted byte in the middle frame and a truncated tail.
        let second = bytes.iter().position(|&b| b == 0).unwrap() + 2;
        bytes[second] ^= 0x40;
        bytes.extend_from_slice(&[7, 7, 7]);
        let capture = decode_capture(&bytes);
        assert_eq!(capture.messages, [messages[0], messages[2]]);
        assert_eq!((capture.stats.frames_dropped, capture.dropped.len()), (2, 2));
        assert_eq!(capture.dropped[1], (bytes.len() as u64, FrameError::Truncated { len: 3 }));
        assert_eq!(capture.poses().count(), 2);
        let text = String::from_utf8(tum.into_inner()).unwrap();
        assert_eq!(
            text,
            "10.000000 0.5000000 -1.2500000 2.0000000 0.0000000 0.0000000 0.0000000 1.0000000\n\
             12.000000 0.5000000 -1.2500000 2.0000000 0.0000000 0.0000000 0.0000000 1.0000000\n"
        );
    }

    #[test]
    fn poses_before_the_first_keyframe_are_not_trajectory_lines() {
        let waiting = PoseMessage { state: TrackingState::Initializing, ..pose(0) };
        let mut tum = TumPoseWriter::new(Vec::new());
        for m in [Message::Pose(waiting), Message::Pose(pose(1))] {
            tum.send(&m).unwrap();
        }
        let text = String::from_utf8(tum.into_inner()).unwrap();
        assert!(text.starts_with("11.000000 ") && text.lines().count() == 1, "{text}");
    }
}
