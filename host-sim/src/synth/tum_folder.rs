//! The synthetic sequence written as a TUM RGB-D folder (`demo --write-dataset DIR`), so that
//! everything that reads a recording (`replay`, the firmware replay, the budgets, `--frames`)
//! runs on it too: `rgb/` (8-bit gray PNG), `depth/` (16-bit PNG, `depth_scale` units per metre),
//! `rgb.txt`, `depth.txt`, `groundtruth.txt` and `calibration.toml`.
//!
//! Timestamps are written in Rust's shortest round-trip form, so that a reader parses back the
//! very `f64` the renderer used; the intrinsics likewise.

use std::fmt::Write as _;
use std::path::Path;

use super::{SynthError, SynthFrame, SyntheticSequence};

/// Writes every frame of `sequence` into the folder `dir` (created if missing; files of the same
/// names are replaced), with a `README.md` saying what made it (`made_by`) and the depth noise the
/// core should be told (`calibration.toml`'s `depth_noise_coeff_per_m`, in 1/m); returns the
/// frames written.
///
/// # Errors
/// [`SynthError::Io`] when a file cannot be written, [`SynthError::Png`] when an image cannot be
/// encoded, and the renderer's errors.
pub fn write_tum_folder(
    sequence: &SyntheticSequence,
    dir: &Path,
    made_by: &str,
    depth_noise_coeff_per_m: f32,
) -> Result<usize, SynthError> {
    for sub in ["rgb", "depth"] {
        let path = dir.join(sub);
        std::fs::create_dir_all(&path).map_err(|source| SynthError::Io { path, source })?;
    }
    let header = |what: &str| {
        format!("# ferroslam synthetic sequence ({made_by}); timestamps = index / 30 s\n# {what}\n")
    };
    let (mut rgb, mut depth) = (header("timestamp filename"), header("timestamp filename"));
    let mut frame = SynthFrame::empty(super::DEPTH_SCALE as f32);
    for i in 0..sequence.len() {
        sequence.render_into(i, &mut frame)?;
        let stem = format!("{i:06}");
        let (gray_png, depth_png) = super::write_pngs(&frame, dir, &stem)?;
        let gray_name = format!("rgb/{stem}.png");
        let depth_name = format!("depth/{stem}.png");
        rename(&gray_png, &dir.join(&gray_name))?;
        rename(&depth_png, &dir.join(&depth_name))?;
        let t = frame.timestamp_s;
        // Infallible: writing to a String.
        let _ = writeln!(rgb, "{t} {gray_name}");
        let _ = writeln!(depth, "{t} {depth_name}");
    }
    write(&dir.join("rgb.txt"), &rgb)?;
    write(&dir.join("depth.txt"), &depth)?;
    let gt_path = dir.join("groundtruth.txt");
    let mut gt = header("timestamp tx ty tz qx qy qz qw (camera to world)");
    gt.push_str(&sequence.ground_truth_all().to_tum_string());
    write(&gt_path, &gt)?;
    let k = sequence.intrinsics();
    let calibration = format!(
        "# ferroslam synthetic sequence ({made_by}): exact pinhole intrinsics, no distortion\n\
         fx = {:?}\nfy = {:?}\ncx = {:?}\ncy = {:?}\nwidth = {}\nheight = {}\n\
         # raw depth value / depth_scale = metres; 0 = no reading\ndepth_scale = {:?}\n\
         # the depth noise the core is told, as the demo tells it (inverse depth, 1/m)\n\
         depth_noise_coeff_per_m = {:?}\n",
        k.fx, k.fy, k.cx, k.cy, k.width, k.height, k.depth_scale, depth_noise_coeff_per_m
    );
    write(&dir.join("calibration.toml"), &calibration)?;
    let readme = format!(
        "# Synthetic RGB-D sequence\n\nWritten by `{made_by}`: {} frames rendered at {}x{} with \
         exact ground truth, in TUM RGB-D layout.\n",
        sequence.len(),
        k.width,
        k.height
    );
    write(&dir.join("README.md"), &readme)?;
    Ok(sequence.len())
}

fn write(path: &Path, text: &str) -> Result<(), SynthError> {
    std::fs::write(path, text).map_err(|source| SynthError::Io { path: path.to_owned(), source })
}

fn rename(from: &Path, to: &Path) -> Result<(), SynthError> {
    std::fs::rename(from, to).map_err(|source| SynthError::Io { path: to.to_owned(), source })
}
