//! `ferroslam-sim replay DATASET --out DIR`: a TUM-layout recording through the core.

use std::path::PathBuf;

use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use ferroslam_core::geometry::PinholeCamera;
use nalgebra::Point3;

use super::args::{ModeArg, ProfileArg, SlamArgs, depth_level_parser};
use crate::dataset::{CalibrationOrigin, CalibrationSource, Dataset, DatasetOptions};
use crate::plot;
use crate::report::{Report, run_note, summary, with_depth_level, write_odometry};
use crate::run::{self, RunOptions};

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
    #[arg(long, conflicts_with = "calibration")]
    pub preset: Option<String>,
    /// A calibration file to use instead of the folder's calibration.toml (same format; its
    /// optional `[depth]` table registers depth to colour). For 7-Scenes, whose own file holds
    /// the nominal depth intrinsics only: `calibration/7scenes-kinect-v1.toml`.
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// Skip this many frames at the start (before `--max-frames`).
    #[arg(long, default_value_t = 0)]
    pub skip_frames: usize,
    /// Process at most this many frames (the earliest, after `--skip-frames`).
    #[arg(long)]
    pub max_frames: Option<usize>,
    /// What runs on each frame.
    #[arg(long, value_enum, default_value = "slam")]
    pub mode: ModeArg,
    /// How SLAM mode runs its back end.
    #[command(flatten)]
    pub slam: SlamArgs,
    /// Seed of the front end's RANSAC (default: the core's). Runs with other seeds show how
    /// much of an accuracy figure is chance (`cargo xtask spread`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Keep the depth coarser than the gray image by this many halvings (0-2; the core's
    /// `DepthView` level). Default: the resolution's (`Resolution::depth_level`), what the firmware
    /// keeps: 1 at QVGA (a 160x120 depth), 0 at VGA.
    #[arg(long, value_parser = depth_level_parser())]
    pub depth_level: Option<u8>,
}

/// Runs `replay`.
///
/// # Errors
/// Any dataset error (it names the file and line), or a file that cannot be written.
pub fn run(args: &ReplayArgs) -> Result<()> {
    let profile = args.profile.profile();
    let opts = DatasetOptions {
        calibration: match (&args.preset, &args.calibration) {
            (Some(name), _) => CalibrationSource::Preset(name.clone()),
            (None, Some(path)) => CalibrationSource::Path(path.clone()),
            (None, None) => CalibrationSource::File,
        },
        profile,
        skip_frames: args.skip_frames,
        max_frames: args.max_frames,
        depth_level: args.depth_level,
        ..DatasetOptions::default()
    };
    let dataset = Dataset::open(&args.dataset, &opts)?;
    let depth_level = dataset.depth_level();
    let calibration_note = calibration_note(&dataset);
    if let CalibrationOrigin::FolderName(_) = dataset.calibration_origin() {
        eprintln!("note: {calibration_note}");
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let (frames, skipped) = (dataset.len(), dataset.skipped().len());
    let gt = dataset.groundtruth_trajectory().cloned();
    if let Some(track_mode) = args.mode.track_mode(&args.slam) {
        let c = dataset.calibration();
        let cam = PinholeCamera::new(c.fx, c.fy, c.cx, c.cy, c.width as usize, c.height as usize)
            .map_err(|e| anyhow::anyhow!("calibration: {e}"))?;
        let mut reader = dataset.into_reader(8);
        let started = Instant::now();
        let options = RunOptions { seed: args.seed, ..RunOptions::new(profile, track_mode) };
        let run = run::track(&mut reader, frames, &cam, &options)?;
        let wall_s = started.elapsed().as_secs_f64();
        let note = with_depth_level(
            run_note(&track_mode, profile.name, (run.data.width, run.data.height)),
            depth_level,
        );
        let note = format!("{note}; {calibration_note}");
        let out = write_odometry(&args.out, &run, gt.as_ref(), profile.name, skipped, note)?;
        println!("replay {}: {}", args.dataset.display(), summary(&out.report, wall_s));
        return Ok(());
    }
    let mut reader = dataset.into_reader(8);
    let run = run::data_path(&mut reader, frames)?;
    let note = format!(
        "data path only: {} frames decoded, brought to {} ({}x{}) and measured by the core (W(I), \
         depth coverage); no tracking yet, so no CameraTrajectory.txt and no ATE",
        run.frames, profile.name, run.width, run.height
    );
    let report = Report::data_path(&run, profile.name, skipped, note.clone());
    report.write(&args.out)?;
    if let Some(gt) = gt.filter(|g| !g.is_empty()) {
        let gt: Vec<Point3<f64>> =
            gt.poses.iter().map(|p| Point3::from(p.t_wc.translation.vector)).collect();
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

/// Where the dataset's calibration came from, and whether a lens distortion is removed from its
/// frames, for the report's note.
fn calibration_note(dataset: &Dataset) -> String {
    let origin = dataset.calibration_origin();
    if dataset.sensor_calibration().distortion.is_none() {
        format!("calibration: {origin}")
    } else {
        format!("calibration: {origin}, lens distortion removed from the frames")
    }
}
