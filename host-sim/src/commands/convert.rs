//! `ferroslam-sim convert DATASET --mcap OUT`: a TUM-layout folder written as an MCAP recording
//! ([`crate::dataset::mcap::convert`]) whose replay gives the same bits as the folder's.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use clap::Args;

use crate::dataset::CalibrationSource;
use crate::dataset::mcap::convert_to_mcap;

/// Arguments of `convert`.
#[derive(Debug, Args)]
pub struct ConvertArgs {
    /// A TUM RGB-D folder: rgb.txt, depth.txt, optional groundtruth.txt, calibration.toml.
    pub dataset: PathBuf,
    /// The MCAP file to write (replaced if it exists).
    #[arg(long, value_name = "OUT")]
    pub mcap: PathBuf,
    /// Carry this calibration file instead of the folder's calibration.toml.
    #[arg(long, value_name = "FILE", conflicts_with = "preset")]
    pub calibration: Option<PathBuf>,
    /// Carry a TUM sensor's calibration (tum1, tum2, tum3) instead of the folder's.
    #[arg(long)]
    pub preset: Option<String>,
}

/// Runs `convert`: writes the file and says what it holds.
///
/// # Errors
/// A folder that cannot be read (as `replay` says it), a time no header stamp holds, a file
/// that cannot be written.
pub fn run(args: &ConvertArgs) -> Result<()> {
    let source = match (&args.preset, &args.calibration) {
        (Some(name), _) => CalibrationSource::Preset(name.clone()),
        (None, Some(path)) => CalibrationSource::Path(path.clone()),
        (None, None) => CalibrationSource::File,
    };
    let started = Instant::now();
    let written = convert_to_mcap(&args.dataset, &args.mcap, &source)?;
    let bytes = std::fs::metadata(&args.mcap).map_or(0, |m| m.len());
    println!(
        "convert {}: wrote {} ({:.1} MB, {:.1} s): {} colour and {} depth images ({} depth), {} \
         ground-truth poses; calibration {} carried",
        args.dataset.display(),
        args.mcap.display(),
        bytes as f64 / 1e6,
        started.elapsed().as_secs_f64(),
        written.rgb_images,
        written.depth_images,
        written.depth_encoding,
        written.groundtruth_poses,
        written.calibration,
    );
    if written.missing_images > 0 {
        eprintln!(
            "warning: {} images listed but not on disk were left out (a replay of the folder \
             skips them too)",
            written.missing_images
        );
    }
    Ok(())
}
