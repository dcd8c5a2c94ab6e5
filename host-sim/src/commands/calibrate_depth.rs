//! `ferroslam-sim calibrate-depth DATASET --out FILE`: the depth-to-colour registration of a
//! sensor whose depth is not registered to colour, estimated from the images
//! ([`crate::dataset::calibrate_depth`]), written as a calibration file with a `[depth]` table
//! (what `replay --calibration` reads), or checked against one with `--check FILE`.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{ArgGroup, Args};

use crate::dataset::Calibration;
use crate::dataset::calibrate_depth::{FrameSelection, estimate};

/// Arguments of `calibrate-depth`.
#[derive(Debug, Args)]
#[command(group(ArgGroup::new("output").args(["out", "check"]).required(true).multiple(true)))]
pub struct CalibrateDepthArgs {
    /// A TUM-layout folder whose calibration.toml holds the depth camera's own intrinsics and no
    /// `[depth]` table (e.g. Microsoft 7-Scenes).
    pub dataset: PathBuf,
    /// Write the estimated calibration here: the colour camera's intrinsics and a `[depth]` table
    /// with the depth camera's intrinsics and offset.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Compare the estimate with this calibration file's colour fx, cx, cy (within 0.5 px) and
    /// depth offset tx, ty (within 1.5 mm); fail when a value is further off.
    #[arg(long, value_name = "FILE")]
    pub check: Option<PathBuf>,
    /// The first frame used.
    #[arg(long, value_name = "N", default_value_t = FrameSelection::default().start)]
    pub start: usize,
    /// Use every Nth frame from --start.
    #[arg(
        long,
        value_name = "N",
        default_value_t = FrameSelection::default().step,
        value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..)
    )]
    pub step: usize,
}

/// Runs `calibrate-depth`: the summary to stdout; with `--out`, the file written; with `--check`,
/// the comparison value by value to stderr and a failure when a value is off. The `--check` file
/// is read before the estimate, so a bad one fails at once; the `--out` file's folder is created.
///
/// # Errors
/// As [`estimate`]; the file or its folder cannot be written; with `--check`, the file cannot be read, is not a
/// calibration or has no depth camera, or a value is off by more than its tolerance.
pub fn run(args: &CalibrateDepthArgs) -> Result<()> {
    let stated = args.check.as_ref().map(Calibration::load).transpose()?;
    let selection = FrameSelection { start: args.start, step: args.step };
    let e = estimate(&args.dataset, selection)?;
    println!("{e}");
    if let Some(out) = &args.out {
        if let Some(dir) = out.parent() {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        std::fs::write(out, e.to_toml()).with_context(|| format!("writing {}", out.display()))?;
        println!("wrote {}", out.display());
    }
    if let (Some(file), Some(stated)) = (&args.check, &stated) {
        let check = e.compare(stated, file)?;
        eprint!("{check}");
        check.ensure()?;
        eprintln!("{}: every value within tolerance of the estimate", file.display());
    }
    Ok(())
}
