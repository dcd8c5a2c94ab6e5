//! `ferroslam-sim decode-serial FILE`: a capture of the firmware's UART decoded into poses, with
//! what was lost to corruption.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use ferroslam_core::frame::TelemetrySink;
use ferroslam_core::wire::{Message, PoseFlags, TrackingState};

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
/// An unreadable file; a file in which no frame decodes although it is not empty.
pub fn run(args: &DecodeSerialArgs) -> Result<()> {
    let bytes = std::fs::read(&args.file)
        .with_context(|| format!("cannot read the capture {}", args.file.display()))?;
    let capture = decode_capture(&bytes);
    let s = capture.stats;
    if !bytes.is_empty() && s.frames_decoded == 0 {
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
    for m in &capture.messages {
        match m {
            Message::Status(st) => eprintln!("status: {st:?}"),
            Message::Fault(f) => eprintln!("fault: {f:?}"),
            Message::Pose(_) | Message::Cost(_) => {}
        }
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

/// One row per pose: index, time, state, flags, inliers, position, and the frame's instructions
/// when a cost message follows it.
fn print_table(mut out: impl std::io::Write, messages: &[Message]) -> std::io::Result<()> {
    writeln!(
        out,
        "{:>6} {:>18} {:<12} {:<5} {:>7} {:>10} {:>10} {:>10} {:>14}",
        "frame", "timestamp_s", "state", "flags", "inliers", "tx_m", "ty_m", "tz_m", "instructions"
    )?;
    for (i, m) in messages.iter().enumerate() {
        let Message::Pose(p) = m else { continue };
        let cost = messages.get(i + 1).and_then(|n| match n {
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
