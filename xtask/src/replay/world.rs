//! What `firmware-replay` compares besides the poses: the planes and anchors the firmware kept
//! against the host replay's, and the anchor commands it is sent.

use std::fs;
use std::path::Path;

use anyhow::{Context, Result, anyhow, bail};
use ferroslam_core::frame::TelemetrySink;
use ferroslam_core::wire::{CommandMessage, FaultCode, Message};
use ferroslam_sim::anchor_script::AnchorScript;
use ferroslam_sim::run::TrackingRun;
use ferroslam_sim::serial::{Capture, WireWriter};

/// The planes the firmware found as it ran (its log's `planes: N kept of D detections, X dropped,
/// fingerprint F` line) against the host replay's (`planes.online` of its run): `Ok(summary)`
/// when the same, `Err` naming both.
pub(super) fn compare_planes(log: &[String], host: &TrackingRun) -> Result<String> {
    let (line, numbers) = logged_numbers(log, "planes: ")?;
    let online = host.planes.as_ref().map(|p| &p.online).context("the host run has no planes")?;
    let expected = [
        online.planes as u64,
        u64::from(online.detections),
        u64::from(online.dropped),
        u64::from(online.fingerprint),
    ];
    if numbers != expected {
        bail!(
            "the firmware's planes differ from the host's: firmware `{line}`, host {} kept of {} \
             detections, {} dropped, fingerprint {}",
            expected[0],
            expected[1],
            expected[2],
            expected[3]
        );
    }
    Ok(format!(
        "planes found as it ran the same as the host's: {} kept of {} detections, fingerprint \
         {:#010x}",
        online.planes, online.detections, online.fingerprint
    ))
}

/// The commands file of a replay with `--anchors`: the bytes the board's serial link receives.
pub const COMMANDS: &str = "commands.bin";

/// Writes `script`'s steps as the host sends them to the board: one wire frame of a
/// [`CommandMessage`] per step, in order.
pub(super) fn write_commands(script: &AnchorScript, path: &Path) -> Result<()> {
    let mut wire = WireWriter::new(Vec::new());
    for step in &script.steps {
        let frame_index = u32::try_from(step.frame).context("a script frame past u32")?;
        wire.send(&Message::Command(CommandMessage { frame_index, command: step.command }))
            .context("encoding a command")?;
    }
    fs::write(path, wire.into_inner()).with_context(|| format!("writing {}", path.display()))
}

/// The anchors the firmware placed against the host replay's (`ar.online` of its run): the
/// anchor messages of the last frame, bit for bit, the commands refused (its `Command` faults:
/// frame and error code), and its log's `anchors: N placed, fingerprint F` line. `Ok(summary)`
/// when all agree.
pub(super) fn compare_anchors(
    log: &[String],
    capture: &Capture,
    host: &TrackingRun,
) -> Result<String> {
    let online = host
        .ar
        .as_ref()
        .and_then(|a| a.online.as_ref())
        .context("the host run applied no anchor commands")?;
    let last = capture.poses().last().map_or(0, |p| p.frame_index);
    let board: Vec<[u32; 8]> = capture
        .messages
        .iter()
        .filter_map(|m| match m {
            Message::Anchor(a) if a.frame_index == last => {
                Some(anchor_bits(a.object, a.position_m, a.up, a.scale))
            }
            _ => None,
        })
        .collect();
    let expected: Vec<[u32; 8]> =
        online.anchors.iter().map(|a| anchor_bits(a.object, a.position_m, a.up, a.scale)).collect();
    if board != expected {
        bail!(
            "the firmware's anchors after frame {last} differ from the host's: firmware \
             {board:?}, host {expected:?} (object, then position, up and scale as f32 bits)"
        );
    }
    let refused: Vec<(usize, u32)> = capture
        .messages
        .iter()
        .filter_map(|m| match m {
            Message::Fault(f) if f.code == FaultCode::Command => {
                Some((f.frame_index as usize, f.detail))
            }
            _ => None,
        })
        .collect();
    let host_refused: Vec<(usize, u32)> =
        online.refused.iter().map(|r| (r.frame, r.code)).collect();
    if refused != host_refused {
        bail!(
            "the firmware refused other commands than the host: firmware {refused:?}, host \
             {host_refused:?} (frame, error code)"
        );
    }
    let (line, numbers) = logged_numbers(log, "anchors: ")?;
    let logged = [online.anchors.len() as u64, u64::from(online.fingerprint)];
    if numbers != logged {
        bail!("the firmware logged `anchors: {line}`, the host has {logged:?}");
    }
    Ok(format!(
        "anchors the same as the host's: {} commands applied, {} refused (the same frames and \
         errors), {} anchors at the end, bit for bit, fingerprint {:#010x}",
        online.applied,
        online.refused.len(),
        online.anchors.len(),
        online.fingerprint
    ))
}

/// The firmware log's first line holding `prefix`: what follows it, and the numbers in that.
fn logged_numbers<'a>(log: &'a [String], prefix: &str) -> Result<(&'a str, Vec<u64>)> {
    let line = log
        .iter()
        .find_map(|l| l.split(prefix).nth(1))
        .ok_or_else(|| anyhow!("the firmware logged no `{}` line", prefix.trim_end()))?;
    let numbers =
        line.split(|c: char| !c.is_ascii_digit()).filter_map(|w| w.parse().ok()).collect();
    Ok((line, numbers))
}

/// An anchor's object id and float fields as bits.
fn anchor_bits(object: u16, position: [f32; 3], up: [f32; 3], scale: f32) -> [u32; 8] {
    let [x, y, z] = position.map(f32::to_bits);
    let [a, b, c] = up.map(f32::to_bits);
    [u32::from(object), x, y, z, a, b, c, scale.to_bits()]
}
