//! `ferroslam-sim replay DATASET --out DIR`: a TUM-layout recording through the core.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use ferroslam_core::config::{Profile, QVGA, VGA};
use nalgebra::Point3;

use super::datapath;
use super::report::Report;
use crate::dataset::{CalibrationSource, Dataset, DatasetOptions};
use crate::plot;

/// The processing resolution.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ProfileArg {
    /// 320x240: the sensor's 640x480 frames halved once (the reference board).
    Qvga,
    /// 640x480: full resolution.
    Vga,
}

impl ProfileArg {
    /// The core's profile.
    pub fn profile(self) -> Profile {
        match self {
            Self::Qvga => QVGA,
            Self::Vga => VGA,
        }
    }
}

/// What `replay` runs on each frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ModeArg {
    /// The data path only: decoding, the profile's downsampling and the core's image statistics.
    /// Tracking (`odometry`) and mapping (`slam`) are the next issues' work.
    DataPath,
}

/// Arguments of `replay`.
#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// A TUM RGB-D folder: rgb.txt, depth.txt, optional groundtruth.txt, calibration.toml.
    pub dataset: PathBuf,
    /// Output folder (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Processing resolution.
    #[arg(long, value_enum, default_value = "qvga")]
    pub profile: ProfileArg,
    /// TUM intrinsics (tum1, tum2, tum3) instead of the folder's calibration.toml.
    #[arg(long)]
    pub preset: Option<String>,
    /// Process at most this many frames (the earliest).
    #[arg(long)]
    pub max_frames: Option<usize>,
    /// What runs on each frame.
    #[arg(long, value_enum, default_value = "data-path")]
    pub mode: ModeArg,
}

/// Runs `replay`.
///
/// # Errors
/// Any dataset error (it names the file and line), or a file that cannot be written.
pub fn run(args: &ReplayArgs) -> Result<()> {
    let profile = args.profile.profile();
    let opts = DatasetOptions {
        calibration: args.preset.clone().map_or(CalibrationSource::File, CalibrationSource::Preset),
        profile,
        max_frames: args.max_frames,
        ..DatasetOptions::default()
    };
    let dataset = Dataset::open(&args.dataset, &opts)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let (frames, skipped) = (dataset.len(), dataset.skipped().len());
    let gt: Option<Vec<Point3<f64>>> = dataset
        .groundtruth_trajectory()
        .map(|t| t.poses.iter().map(|p| Point3::from(p.t_wc.translation.vector)).collect());
    let mut reader = dataset.into_reader(8);
    let run = datapath::run(&mut reader, frames)?;
    let note = format!(
        "data path only: {} frames decoded, brought to {} ({}x{}) and measured by the core (W(I), \
         depth coverage); no tracking yet, so no CameraTrajectory.txt and no ATE",
        run.frames, profile.name, run.width, run.height
    );
    let report = Report::data_path(&run, profile.name, skipped, note.clone());
    report.write(&args.out)?;
    if let Some(gt) = gt.filter(|g| !g.is_empty()) {
        let path = args.out.join("trajectory.svg");
        plot::plot_trajectory_top_view(&path, &gt, &[], "ground truth (no estimate yet)")?;
    }
    println!("replay {}: {note}", args.dataset.display());
    println!(
        "  W(I) median {:.0}, depth coverage {:.1}%, {} listed frames skipped; wrote {}",
        report.total_variation_median,
        100.0 * report.valid_depth_fraction_mean,
        skipped,
        args.out.join("report.json").display()
    );
    Ok(())
}
