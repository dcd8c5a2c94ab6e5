//! `ferroslam-sim decode-serial FILE`: a capture of the firmware's UART decoded into poses, with
//! what was lost to corruption.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use ferroslam_core::frame::TelemetrySink;
use ferroslam_core::wire::{
    AnchorMessage, FaultCode, FaultMessage, Message, PoseFlags, StatusMessage, TrackingState,
};

use crate::serial::{TumPoseWriter, decode_capture};

/// Arguments of `decode-serial`.
#[derive(Debug, Args)]
pub struct DecodeSerialArgs {
    /// The capture: raw bytes of the UART (QEMU `-serial file:...`, a logic analyser export).
    pub file: PathBuf,
    /// Print the poses as TUM trajectory lines (`timestamp tx ty tz qx qy qz qw`) instead of a
    /// table.
    #[arg(long)]
    pub tum: bool,
}

/// Runs `decode-serial`: poses to stdout (a table, or TUM lines with `--tum`), the other messages
/// and the counts of what was lost to stderr.
///
/// # Errors
/// An unreadable file; an empty file; a file in which no frame decodes.
pub fn run(args: &DecodeSerialArgs) -> Result<()> {
    let bytes = std::fs::read(&args.file)
        .with_context(|| format!("cannot read the capture {}", args.file.display()))?;
    if bytes.is_empty() {
        bail!(
            "{}: the capture is empty (0 bytes): nothing was received, so there is nothing to \
             decode (was the UART captured, e.g. QEMU's -serial file:FILE, and did the firmware \
             run?)",
            args.file.display()
        );
    }
    let capture = decode_capture(&bytes);
    let s = capture.stats;
    if s.frames_decoded == 0 {
        bail!(
            "{}: {} bytes, no frame of the ferroslam wire format (schema version {}) in them: {} \
             frames dropped, {} of another schema version",
            args.file.display(),
            bytes.len(),
            ferroslam_core::wire::SCHEMA_VERSION,
            s.frames_dropped,
            s.frames_unknown_version,
        );
    }
    let stdout = std::io::stdout().lock();
    if args.tum {
        let mut writer = TumPoseWriter::new(stdout);
        for m in &capture.messages {
            writer.send(m).context("writing to stdout")?;
        }
    } else {
        print_table(stdout, &capture.messages).context("writing to stdout")?;
    }
    // Each object's last anchor message: where it stood when the capture ended.
    let mut anchors: Vec<&AnchorMessage> = Vec::new();
    for m in &capture.messages {
        match m {
            Message::Status(st) => eprintln!("status: {}", status_words(st)),
            Message::Fault(f) => eprintln!("fault: {}", fault_words(f)),
            Message::Command(c) => {
                eprintln!("command for frame {}: {:?}", c.frame_index, c.command)
            }
            Message::Anchor(a) => match anchors.iter_mut().find(|b| b.object == a.object) {
                Some(last) => *last = a,
                None => anchors.push(a),
            },
            Message::Pose(_) | Message::Cost(_) => {}
        }
    }
    for a in anchors {
        eprintln!("{}", anchor_words(a));
    }
    for (offset, e) in &capture.dropped {
        eprintln!("dropped frame ending at byte {offset}: {e}");
    }
    eprintln!(
        "{}: {} bytes, {} frames decoded ({} poses), {} frames dropped, {} of an unknown schema \
         version, {} bytes skipped",
        args.file.display(),
        s.bytes_received,
        s.frames_decoded,
        capture.poses().count(),
        s.frames_dropped,
        s.frames_unknown_version,
        s.bytes_skipped,
    );
    Ok(())
}

/// A status message in words: `500 frames, 499 tracked, 0 lost, ..., peak stack 37,716 B`.
fn status_words(s: &StatusMessage) -> String {
    let stack = match s.stack_peak_bytes {
        0 => "peak stack not measured".to_owned(),
        bytes => format!("peak stack {} B", crate::report::thousands(u64::from(bytes))),
    };
    format!(
        "{} frames, {} tracked, {} lost, {} re-initialised, {} relocalised, {} keyframes, {} \
         recoveries, {} faults, state {} B, {stack}",
        s.frames,
        s.tracked_frames,
        s.lost_frames,
        s.reinitializations,
        s.relocalizations,
        s.keyframes,
        s.recoveries,
        s.faults,
        crate::report::thousands(u64::from(s.state_bytes)),
    )
}

/// An anchor message in words: `object 0 at (0.112, -0.530, 1.204) m, up (0.01, -0.99, 0.05),
/// scale 1 (frame 999)`.
fn anchor_words(a: &AnchorMessage) -> String {
    let [x, y, z] = a.position_m;
    let [ux, uy, uz] = a.up;
    format!(
        "anchor: object {} at ({x:.3}, {y:.3}, {z:.3}) m, up ({ux:.2}, {uy:.2}, {uz:.2}), scale {} \
         (frame {})",
        a.object, a.scale, a.frame_index
    )
}

/// A fault message in words: `frame 12: the frame source failed (detail 2)`.
fn fault_words(f: &FaultMessage) -> String {
    let what = match f.code {
        FaultCode::FrameSource => "the frame source failed".to_owned(),
        FaultCode::FrameRejected => "the pipeline rejected the frame".to_owned(),
        FaultCode::Telemetry => "a telemetry message could not be encoded".to_owned(),
        FaultCode::Configuration => "the board's configuration is unusable".to_owned(),
        FaultCode::StackOverflow => "the stack reached its limit".to_owned(),
        FaultCode::Command => "an anchor command was not applied".to_owned(),
        other => format!("fault {other:?}"),
    };
    format!("frame {}: {what} (detail {})", f.frame_index, f.detail)
}

/// One row per pose: index, time, state, flags, inliers, position, and the frame's instructions
/// when a cost message follows it (after the frame's anchor messages).
fn print_table(mut out: impl std::io::Write, messages: &[Message]) -> std::io::Result<()> {
    writeln!(
        out,
        "{:>6} {:>18} {:<12} {:<5} {:>7} {:>10} {:>10} {:>10} {:>14}",
        "frame", "timestamp_s", "state", "flags", "inliers", "tx_m", "ty_m", "tz_m", "instructions"
    )?;
    for (i, m) in messages.iter().enumerate() {
        let Message::Pose(p) = m else { continue };
        // The frame's anchors come between its pose and its cost.
        let after = messages.get(i + 1..).unwrap_or_default();
        let next = after.iter().find(|n| !matches!(n, Message::Anchor(_)));
        let cost = next.and_then(|n| match n {
            Message::Cost(c) if c.frame_index == p.frame_index => c.total_instructions(),
            _ => None,
        });
        let state = match p.state {
            TrackingState::Initializing => "initializing",
            TrackingState::Tracking => "tracking",
            TrackingState::Lost => "lost",
        };
        let flags: String = [
            (PoseFlags::TRACKED, 'T'),
            (PoseFlags::KEYFRAME, 'K'),
            (PoseFlags::RECOVERY, 'R'),
            (PoseFlags::REINITIALIZED, 'I'),
            (PoseFlags::RELOCALIZED, 'L'),
            (PoseFlags::LOOP_CLOSED, 'C'),
        ]
        .iter()
        .map(|&(bit, c)| if p.flags.contains(bit) { c } else { '-' })
        .collect();
        let [x, y, z] = p.translation_m;
        let cost = cost.map_or_else(|| "-".to_owned(), |c| c.to_string());
        writeln!(
            out,
            "{:>6} {:>18.6} {:<12} {:<5} {:>7} {:>10.4} {:>10.4} {:>10.4} {:>14}",
            p.frame_index, p.timestamp_s, state, flags, p.inliers, x, y, z, cost
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_and_faults_read_as_words() {
        let status = StatusMessage {
            frames: 500,
            tracked_frames: 499,
            lost_frames: 1,
            keyframes: 31,
            state_bytes: 356_536,
            stack_peak_bytes: 37_716,
            ..StatusMessage::default()
        };
        assert_eq!(
            status_words(&status),
            "500 frames, 499 tracked, 1 lost, 0 re-initialised, 0 relocalised, 31 keyframes, 0 \
             recoveries, 0 faults, state 356,536 B, peak stack 37,716 B"
        );
        let unmeasured = StatusMessage { stack_peak_bytes: 0, ..status };
        assert!(status_words(&unmeasured).ends_with("peak stack not measured"));
        let fault = FaultMessage { frame_index: 12, code: FaultCode::FrameSource, detail: 2 };
        assert_eq!(fault_words(&fault), "frame 12: the frame source failed (detail 2)");
        for (n, text) in [(0, "0"), (999, "999"), (1000, "1,000"), (u32::MAX, "4,294,967,295")] {
            assert_eq!(crate::report::thousands(u64::from(n)), text);
        }
    }
}
