//! `ferroslam-sim replay DATASET --out DIR`: a TUM-layout recording through the core.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use std::time::Instant;

use ferroslam_core::config::{Profile, QVGA, Tunables, VGA};
use ferroslam_core::geometry::PinholeCamera;
use nalgebra::Point3;

use super::datapath::{self, depth_level_parser};
use super::report::{Report, write_odometry};
use crate::dataset::{CalibrationOrigin, CalibrationSource, Dataset, DatasetOptions};
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
    DataPath,
    /// The data path, then the core's frame-to-map front end alone (depth fused into the
    /// landmarks; no bundle adjustment).
    Odometry,
    /// Front end, map and back end (local and segmented global bundle adjustment), the back end
    /// getting a fixed work quota after every frame (deterministic).
    Slam,
}

impl ModeArg {
    /// The tracker mode, run in SLAM mode as `slam` says.
    pub fn track_mode(self, slam: &SlamArgs) -> Option<datapath::TrackMode> {
        match self {
            Self::DataPath => None,
            Self::Odometry => Some(datapath::TrackMode::Odometry),
            Self::Slam => Some(datapath::TrackMode::Slam {
                quota: slam.backend_quota,
                schedule: slam.schedule,
                map: slam.map,
                window_levels: slam.window_levels,
            }),
        }
    }

    /// The mode's name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::DataPath => "data-path",
            Self::Odometry => "odometry",
            Self::Slam => "slam",
        }
    }
}

/// The back-end options of SLAM mode, shared by `replay` and `demo`.
#[derive(Debug, Args)]
pub struct SlamArgs {
    /// Back-end work units after each frame (SLAM mode); the same quota gives the same bits.
    #[arg(long, default_value_t = ferroslam_core::system::DEFAULT_BACKEND_QUOTA)]
    pub backend_quota: u32,
    /// How the back end runs beside the front end (SLAM mode).
    #[arg(long, value_enum, default_value = "threaded")]
    pub schedule: datapath::Schedule,
    /// The capacities of the map and the back end (SLAM mode).
    #[arg(long, value_enum, default_value = "board")]
    pub map: datapath::MapScale,
    /// Covisibility levels a local bundle adjustment's window grows by (SLAM mode, 1-255): 1
    /// takes the keyframes sharing landmarks with the new one, 2 also those sharing with them,
    /// and so on; the window also stops at 65 keyframes or when no keyframe joins. The paper's
    /// window of 50-65 keyframes in a map of over 120 takes `--map host --window-levels 255`.
    #[arg(long, default_value_t = ferroslam_core::backend::BackendParams::DEFAULT.window_levels,
          value_parser = clap::value_parser!(u8).range(1..))]
    pub window_levels: u8,
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
    /// `DepthView` level). Default: the profile's (`Profile::depth_level`), what the firmware
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
        let run = datapath::run_seeded(
            &mut reader,
            frames,
            &cam,
            profile,
            track_mode,
            args.seed,
            &Tunables::default(),
        )?;
        let wall_s = started.elapsed().as_secs_f64();
        let note = with_depth_level(
            run_note(args.mode, profile.name, (run.data.width, run.data.height)),
            depth_level,
        );
        let note = format!("{note}; {calibration_note}");
        let out = write_odometry(&args.out, &run, gt.as_ref(), profile.name, skipped, note)?;
        println!("replay {}: {}", args.dataset.display(), summary(&out.report, wall_s));
        return Ok(());
    }
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

/// The report's note on what a tracking run did.
pub fn run_note(mode: ModeArg, profile: &str, (width, height): (usize, usize)) -> String {
    match mode {
        ModeArg::Slam => format!(
            "slam: frame-to-map front end, map and back end (local and segmented global bundle \
             adjustment, fixed work quota per frame) at {profile} ({width}x{height}); \
             CameraTrajectory.txt composes each frame's pose relative to its reference keyframe \
             with that keyframe's final pose; no loop closure"
        ),
        _ => format!(
            "odometry: frame-to-map front end at {profile} ({width}x{height}), depth fused into \
             the landmarks; no bundle adjustment, no loop closure"
        ),
    }
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

/// `note`, plus what `--depth-level` changed when it is not 0.
pub fn with_depth_level(note: String, depth_level: u8) -> String {
    if depth_level == 0 {
        return note;
    }
    let s = 1u32 << depth_level;
    format!("{note}; depth kept {depth_level} halving(s) coarser than the gray image ({s}x{s} px)")
}

/// The one-line summary of an odometry run.
pub fn summary(report: &Report, wall_s: f64) -> String {
    let ate = match (report.ate_rmse_m, &report.evaluation_error) {
        (Some(a), _) => format!("{a:.4} m"),
        (None, Some(why)) => format!("n/a ({why})"),
        (None, None) => "n/a (no ground truth)".to_owned(),
    };
    format!(
        "{} ({}): {} frames, {} tracked, {} lost, {} keyframes; ATE RMSE {ate}; RPE {}; \
         {:.1} s wall ({:.1} ms median per frame in the core); core state {} bytes",
        report.mode,
        report.profile,
        report.frames,
        report.tracked_frames,
        report.lost_frames,
        report.keyframes,
        report.rpe_trans_m_per_s.map_or("n/a".to_owned(), |r| format!("{r:.4} m/s")),
        wall_s,
        report.host_cost.process_median / 1000.0,
        report.state_bytes,
    )
}
