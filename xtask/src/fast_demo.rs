//! The second recording the budgets are held on: the demo with shake and fast rotation
//! (`ferroslam-sim demo --shake 1 --fast-rotation`), written as a TUM folder and replayed by the
//! firmware. It is rendered, so every machine has it, and its fast turns (about 110 degrees per
//! second) make the front end's costly steps run far more often than on 7-Scenes.

use std::path::Path;

use anyhow::Result;
use ferroslam_sim::demo::{DemoOptions, write_dataset};

use crate::replay::{self, ReplayOptions};

/// The name its figures take in `memory-budget.md` (`fast_demo.insn_per_frame_max`, ...).
pub const NAME: &str = "fast_demo";

/// The sequence: the default demo's 300 frames at 640 x 480 with shake 1 and fast rotation.
fn options() -> DemoOptions {
    let mut o = DemoOptions::default();
    o.synth.shake = 1.0;
    o.synth.fast_rotation = true;
    o.progress_bar = false;
    o
}

/// The folder in `firmware-replay`'s output the sequence is written into.
const FOLDER: &str = "demo-shake-fast-rotation";

/// Writes the sequence into `out/demo-shake-fast-rotation` (as `demo --write-dataset` does) and
/// runs `firmware-replay` on all of it into `out`, bit-identical check included.
///
/// # Errors
/// A file that cannot be written, a build, QEMU or replay failure.
pub fn write_and_replay(root: &Path, out: &Path) -> Result<()> {
    let dataset = out.join(FOLDER);
    let made_by = "cargo xtask (budgets' second recording: demo --shake 1 --fast-rotation)";
    let frames = write_dataset(&dataset, &options(), made_by)?;
    let replay = ReplayOptions {
        dataset,
        calibration: None,
        max_frames: frames,
        frames: None,
        out: out.to_path_buf(),
        qemu_args: Vec::new(),
        maps: Default::default(),
        anchors: None,
    };
    replay::run(root, &replay)
}
