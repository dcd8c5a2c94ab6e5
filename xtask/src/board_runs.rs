//! The firmware runs on 7-Scenes that CI checks and `budgets` measures besides the run once
//! through: the camera carried back to a place the board's map has retired (a relocalization
//! from the flash store), and a power cycle (a run that saves its map, then a second boot that
//! localizes in it). What a boot from a saved map cost ([`BootCost`]) is read from such a run's
//! folder.

use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow};
use ferroslam_core::wire::PoseFlags;

use crate::cost::FirmwareRun;
use crate::paths::{SEVEN_SCENES, SEVEN_SCENES_CALIBRATION, root};
use crate::replay::{BoardMaps, ReplayOptions};

/// Frames of 7-Scenes a board run replays at most: all of them.
pub const MAX_FRAMES: usize = 1000;

/// The frames of 7-Scenes the jump-back plays: the camera carried back 420 frames to a place the
/// board's map has retired (the host relocalizes at frame 521).
pub const JUMP_BACK: &str = "0-520,100-130";

/// The frames of 7-Scenes the board maps and saves, then localizes in after a second boot.
pub const SAVE_FRAMES: &str = "0-499";
/// The frames the second boot localizes on.
pub const LOCALIZE_FRAMES: &str = "500-999";

/// The firmware replay of 7-Scenes (at most [`MAX_FRAMES`], in the order `frames` gives, or the
/// recording's) into `out`, compared with the host's, with `maps` saved or booted from.
///
/// # Errors
/// As [`crate::replay::run`]: a build, QEMU or file failure, or poses that differ.
pub fn seven_scenes(frames: Option<&str>, out: PathBuf, maps: BoardMaps) -> Result<()> {
    seven_scenes_with(frames, out, maps, None)
}

/// [`seven_scenes`] with the anchor script `anchors` sent to the board (`firmware-replay
/// --anchors`).
///
/// # Errors
/// As [`seven_scenes`], or anchors that differ.
pub fn seven_scenes_with(
    frames: Option<&str>,
    out: PathBuf,
    maps: BoardMaps,
    anchors: Option<PathBuf>,
) -> Result<()> {
    let opts = ReplayOptions {
        dataset: root().join(SEVEN_SCENES),
        calibration: Some(root().join(SEVEN_SCENES_CALIBRATION)),
        max_frames: MAX_FRAMES,
        frames: frames.map(str::parse).transpose()?,
        out,
        qemu_args: Vec::new(),
        maps,
        anchors,
    };
    crate::replay::run(&root(), &opts)
}

/// [`JUMP_BACK`] on the board into `out`; the frame files, half a gigabyte not needed again,
/// are removed.
///
/// # Errors
/// As [`seven_scenes`].
pub fn jump_back(out: &Path) -> Result<()> {
    seven_scenes(Some(JUMP_BACK), out.to_path_buf(), BoardMaps::default())?;
    let _ = fs::remove_file(out.join("frames.fsrs"));
    Ok(())
}

/// The anchor script the board receives on 7-Scenes (`firmware-replay --anchors`): in the
/// budgets' run, CI's firmware run and the power cycle's first run.
pub const BOARD_ANCHORS: &str = "docs/anchor-scripts/7scenes-board.toml";

/// The anchor script of the power cycle's second boot: it changes objects the first run placed,
/// so it applies only where the boot took the saved anchors.
pub const BOOT_ANCHORS: &str = "docs/anchor-scripts/7scenes-boot.toml";

/// The power cycle: [`SAVE_FRAMES`] on the board into `first`, receiving the budgets' anchor
/// commands and saving its map (its planes and anchors with it), then a second boot with that
/// flash image localizing on [`LOCALIZE_FRAMES`] into `second`, receiving [`BOOT_ANCHORS`].
///
/// # Errors
/// As [`seven_scenes`], for either run.
pub fn power_cycle(first: &Path, second: &Path) -> Result<()> {
    let save = BoardMaps { save: true, ..Default::default() };
    let anchors = Some(root().join(BOARD_ANCHORS));
    seven_scenes_with(Some(SAVE_FRAMES), first.to_path_buf(), save, anchors)?;
    let boot = BoardMaps { boot_from: Some(first.to_path_buf()), localize: true, save: false };
    let anchors = Some(root().join(BOOT_ANCHORS));
    seven_scenes_with(Some(LOCALIZE_FRAMES), second.to_path_buf(), boot, anchors)
}

/// The keyframes held and the instructions of the mount in the firmware's log: its line
/// `place store: N keyframes held (...), mounted and indexed in M instructions`.
fn mount_figures(log: &str) -> Result<(u64, u64)> {
    let line = log
        .lines()
        .find(|l| l.contains("place store: "))
        .ok_or_else(|| anyhow!("no `place store:` line"))?;
    let number_after =
        |marker: &str| line.split(marker).nth(1)?.split_whitespace().next()?.parse::<u64>().ok();
    match (number_after("place store: "), number_after("mounted and indexed in ")) {
        (Some(held), Some(mount)) => Ok((held, mount)),
        _ => Err(anyhow!("no mount figures in `{line}`")),
    }
}

/// What a boot from a saved map cost on the board, from a firmware run's folder: the store's
/// mount and index (the firmware's log), and the frames up to the first relocalized pose (its
/// UART capture). Instructions on QEMU's Cortex-M4F, as `cost.json`'s.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BootCost {
    /// Keyframes the store held at the boot.
    pub held: u64,
    /// Instructions to mount the store and index its records, before the first frame.
    pub mount: u64,
    /// The index in the run of the first relocalized frame, if one was.
    pub first_relocalized: Option<usize>,
}

impl BootCost {
    /// The boot of the run in `dir`, or `None` when its store held no map (a first boot).
    ///
    /// # Errors
    /// A missing `firmware.log` or `uart.bin`, or a log without the mount figure.
    pub fn read(dir: &Path) -> Result<Option<Self>> {
        let log_path = dir.join("firmware.log");
        let log = fs::read_to_string(&log_path)
            .with_context(|| format!("reading {}", log_path.display()))?;
        let (held, mount) =
            mount_figures(&log).with_context(|| format!("reading {}", log_path.display()))?;
        if held == 0 {
            return Ok(None);
        }
        let uart = dir.join("uart.bin");
        let bytes = fs::read(&uart).with_context(|| format!("reading {}", uart.display()))?;
        let capture = ferroslam_sim::serial::decode_capture(&bytes);
        let first_relocalized =
            capture.poses().position(|p| p.flags.contains(PoseFlags::RELOCALIZED));
        Ok(Some(Self { held, mount, first_relocalized }))
    }

    /// Instructions from power-on to the first relocalized pose: the mount, then the pipeline
    /// of every frame up to that one (frame acquisition left out, as in the per-frame figures).
    pub fn insn_to_first_pose(&self, run: &FirmwareRun) -> Option<u64> {
        let first = self.first_relocalized?;
        let frames = run.frames.get(..=first)?;
        Some(self.mount + frames.iter().map(|f| f.pipeline()).sum::<u64>())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    #[test]
    fn the_mount_line_gives_held_keyframes_and_instructions() {
        let log = "INFO  ferroslam qemu-mps2: statics 115200 B\nINFO  place store: 39 keyframes \
                   held (table generation 1), mounted and indexed in 592560 instructions\n";
        assert_eq!(mount_figures(log).unwrap(), (39, 592_560));
        assert!(mount_figures("INFO  frames: 0-499\n").is_err());
        assert!(mount_figures("INFO  place store: many keyframes held, mounted").is_err());
    }
}
