//! Replays of a recorded TUM-layout folder: the library behind `ferroslam-sim replay`, which xtask
//! calls in process too (CI's accuracy bars, `heldout`, `spread`), so that both run the same code.
//!
//! [`Replay::open`] opens the folder as [`ReplayOptions::dataset`] says (calibration, profile,
//! frames kept); [`Replay::run`] runs its frames through the data path and, unless the options ask
//! for the data path alone, the odometry or SLAM tracker ([`run::track`]), writes the output
//! folder ([`crate::report`]) and returns what it wrote, the typed [`Report`] among it.
//! [`replay`] does both. Nothing here prints: the caller decides what the console shows.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use ferroslam_core::config::SensorModel;
use ferroslam_core::geometry::PinholeCamera;
use nalgebra::Point3;

use crate::dataset::{Dataset, DatasetOptions, SkipReason, Stream};
use crate::eval;
use crate::mcap_out::write_run_mcap;
use crate::plane_truth::{ArAccuracy, ar_accuracy_with_gt};
use crate::plot;
use crate::report::{Report, RunOutputs, run_note, with_depth_level, write_odometry};
use crate::run::{self, MapFiles, Progress, RunOptions, TrackMode};
use crate::trajectory::Trajectory;

/// Frames the dataset reader decodes ahead of the core.
const READ_AHEAD_FRAMES: usize = 8;

/// Skipped frames named one by one on the console or in the `--strict` error; report.json lists
/// every one.
pub const SKIPPED_FRAMES_SHOWN: usize = 5;

/// How a replay runs, apart from its folder and output folder.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayOptions {
    /// How the folder is opened: where the calibration comes from, the processing profile, the
    /// frames skipped and kept, the depth level.
    pub dataset: DatasetOptions,
    /// What runs on each frame after the data path: odometry or SLAM; `None`: the data path
    /// alone (no trajectory, no ATE).
    pub mode: Option<TrackMode>,
    /// The front end's RANSAC seed (`None`: the core's default; see [`RunOptions::seed`]).
    pub seed: Option<u64>,
    /// Whether to draw a progress bar on stderr (only ever drawn on a terminal). Replays run side
    /// by side in one process turn it off.
    pub progress_bar: bool,
    /// Map files the SLAM run starts from and saves to.
    pub maps: MapFiles,
    /// Refuse to run when a frame listed in `rgb.txt` would be skipped (its colour image
    /// missing, or no depth image within the association limit): [`Replay::open`] fails saying
    /// which (`replay --strict`). Depth images without a frame do not count. Default `false`:
    /// skipped frames are left out, said by [`skipped_frames_text`] and counted in the report.
    pub strict: bool,
    /// Which virtual objects to place; with ground truth, their pixel error is measured (SLAM
    /// mode; `--ar`, `--anchors`; `None`: no AR).
    pub ar: Option<crate::run::ArPlan>,
    /// Also write the run's results to this MCAP file of Foxglove messages
    /// ([`crate::mcap_out`]; odometry and SLAM modes; `--mcap`).
    pub mcap: Option<PathBuf>,
}

impl ReplayOptions {
    /// `mode` with the dataset's defaults (its own calibration, QVGA, every frame), the core's
    /// seed and a progress bar.
    pub fn new(mode: Option<TrackMode>) -> Self {
        Self {
            dataset: DatasetOptions::default(),
            mode,
            seed: None,
            progress_bar: true,
            maps: MapFiles::default(),
            strict: false,
            ar: None,
            mcap: None,
        }
    }
}

impl Default for ReplayOptions {
    /// SLAM with the board's defaults: what `ferroslam-sim replay DATASET` runs.
    fn default() -> Self {
        Self::new(Some(TrackMode::SLAM))
    }
}

/// A recorded folder opened for a replay: its frames listed and associated, its calibration
/// read; nothing decoded yet.
#[derive(Debug)]
pub struct Replay {
    dataset: Dataset,
    options: ReplayOptions,
    calibration_note: String,
}

impl Replay {
    /// Opens the TUM-layout folder `dir` as `options.dataset` says.
    ///
    /// # Errors
    /// Any dataset error ([`crate::dataset::DatasetError`]: it names the file and line); with
    /// [`ReplayOptions::strict`], a frame that would be skipped (the error names the first few).
    pub fn open(dir: &Path, options: ReplayOptions) -> Result<Self> {
        let dataset = Dataset::open(dir, &options.dataset)?;
        if let Some(text) = skipped_frames_text(&dataset, SKIPPED_FRAMES_SHOWN)
            && options.strict
        {
            bail!(
                "--strict: {text}\nnothing was run (without --strict they are left out, with a \
                 warning)"
            );
        }
        let calibration_note = calibration_note(&dataset);
        Ok(Self { dataset, options, calibration_note })
    }

    /// The opened folder: its frames, calibration, where the calibration came from
    /// ([`Dataset::calibration_origin`]), the listed frames skipped.
    pub fn dataset(&self) -> &Dataset {
        &self.dataset
    }

    /// Where the calibration came from, and whether a lens distortion is removed from the frames
    /// (`calibration: ORIGIN[, lens distortion removed from the frames]`), as the report's note
    /// says it.
    pub fn calibration_note(&self) -> &str {
        &self.calibration_note
    }

    /// Runs every frame and writes into `out` (created if missing): `report.json` always; in
    /// odometry and SLAM modes `CameraTrajectory.txt` and `KeyFrameTrajectory.txt`, and with
    /// ground truth `trajectory.svg` and `ate.svg` (see [`write_odometry`]); in data-path mode,
    /// with ground truth, its plot `trajectory.svg`. [`ReplayOptions::mcap`] names an MCAP file
    /// to write the tracking run's results to as well.
    ///
    /// # Errors
    /// A frame that cannot be read or decoded (naming it), a frame the core rejects, a back-end
    /// error, a file that cannot be written, an MCAP file asked of the data path.
    pub fn run(self, out: &Path) -> Result<RunOutputs> {
        if self.options.mode.is_none()
            && let Some(path) = &self.options.mcap
        {
            bail!("--mcap {}: the data path alone has no poses to write", path.display());
        }
        std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
        match self.options.mode {
            Some(mode) => self.track(mode, out),
            None => self.data_path(out),
        }
    }

    /// [`Replay::run`] in odometry or SLAM mode.
    fn track(self, mode: TrackMode, out: &Path) -> Result<RunOutputs> {
        let Self { dataset, options, calibration_note } = self;
        let (profile, depth_level) = (dataset.profile(), dataset.depth_level());
        let (frames, skipped) = (dataset.len(), dataset.skipped().to_vec());
        let gt = dataset.groundtruth_trajectory().cloned();
        let c = *dataset.calibration();
        let cam = PinholeCamera::new(c.fx, c.fy, c.cx, c.cy, c.width as usize, c.height as usize)
            .map_err(|e| anyhow::anyhow!("calibration: {e}"))?;
        let mut reader = dataset.into_reader(READ_AHEAD_FRAMES);
        let started = Instant::now();
        let default = RunOptions::new(profile, mode);
        let sensor = match c.depth_noise_coeff_per_m {
            Some(depth_noise_coeff_per_m) => {
                SensorModel { depth_noise_coeff_per_m, ..default.sensor }
            }
            None => default.sensor,
        };
        let run_options = RunOptions {
            seed: options.seed,
            progress_bar: options.progress_bar,
            sensor,
            maps: options.maps.clone(),
            ar: options.ar.clone(),
            ..default
        };
        let run = run::track(&mut reader, frames, &cam, &run_options)?;
        let wall_s = started.elapsed().as_secs_f64();
        let note = with_depth_level(
            run_note(&mode, profile.name, (run.data.width, run.data.height)),
            depth_level,
        );
        let note = format!("{note}; {calibration_note}");
        let written = write_odometry(out, &run, gt.as_ref(), profile.name, &skipped, note)?;
        let mut report = written.report;
        if let Some(ar) = &run.ar {
            let stamps: Vec<f64> = run.per_frame.iter().map(|f| f.timestamp_s).collect();
            let measure = |ar: &run::ArRun| match &gt {
                Some(gt) => ar_accuracy_with_gt(ar, &cam, gt, &stamps, eval::DEFAULT_MAX_DT_S),
                None => ArAccuracy::unmeasured(ar),
            };
            report.ar = Some(measure(ar).with_online(measure));
            report.write_with_page(out, &written.scene)?;
        }
        if let Some(path) = &options.mcap {
            write_run_mcap(path, &run, written.evaluation.as_ref())?;
        }
        Ok(RunOutputs { report, evaluation: written.evaluation, wall_s })
    }

    /// [`Replay::run`] in data-path mode.
    fn data_path(self, out: &Path) -> Result<RunOutputs> {
        let Self { dataset, options, .. } = self;
        let profile = dataset.profile();
        let (frames, skipped) = (dataset.len(), dataset.skipped().to_vec());
        let gt = dataset.groundtruth_trajectory().cloned();
        let mut reader = dataset.into_reader(READ_AHEAD_FRAMES);
        let started = Instant::now();
        let progress = Progress { expected_frames: frames, bar: options.progress_bar };
        let run = run::data_path(&mut reader, progress)?;
        let wall_s = started.elapsed().as_secs_f64();
        let note = format!(
            "data path only: {} frames decoded, brought to {} ({}x{}) and measured by the core \
             (W(I), depth coverage); no tracking yet, so no CameraTrajectory.txt and no ATE",
            run.frames, profile.name, run.width, run.height
        );
        let report = Report::data_path(&run, profile.name, &skipped, note);
        report.write_with_page(out, &crate::page::Scene::default())?;
        if let Some(gt) = gt.filter(|g| !g.is_empty()) {
            plot_ground_truth(&gt, &out.join("trajectory.svg"))?;
        }
        Ok(RunOutputs { report, evaluation: None, wall_s })
    }
}

/// Opens the TUM-layout folder `dir` and replays it into `out` as `options` say: [`Replay::open`]
/// then [`Replay::run`].
///
/// # Errors
/// As [`Replay::open`] and [`Replay::run`].
pub fn replay(dir: &Path, out: &Path, options: ReplayOptions) -> Result<RunOutputs> {
    Replay::open(dir, options)?.run(out)
}

/// The frames `dataset` skips (colour images of `rgb.txt` missing or without a depth image
/// within the limit), for the console: their count, then at most `shown` of them named with the
/// reason, one per line; `None` when no frame is skipped.
pub fn skipped_frames_text(dataset: &Dataset, shown: usize) -> Option<String> {
    let frames: Vec<_> = dataset.skipped_frames().collect();
    let first = frames.first()?;
    let mut text = format!(
        "{} of the {} frames listed in {} skipped:",
        frames.len(),
        dataset.listed_frames(),
        first.list.display()
    );
    for s in frames.iter().take(shown) {
        text.push_str(&format!("\n  {s}"));
    }
    if frames.len() > shown {
        text.push_str(&format!("\n  ... and {} more", frames.len() - shown));
    }
    Some(text)
}

/// The depth images `dataset` does not use (missing, or without a colour image within the
/// limit), counted in one line for the console; `None` when it uses every one. They are no
/// frames: TUM's two streams run on clocks of their own, and a few are normal.
pub fn unused_depth_text(dataset: &Dataset) -> Option<String> {
    let depth: Vec<_> = dataset.skipped().iter().filter(|s| s.stream == Stream::Depth).collect();
    let first = depth.first()?;
    let missing = depth.iter().filter(|s| s.reason == SkipReason::Missing).count();
    let unpaired = depth.len() - missing;
    let mut why = Vec::new();
    if missing > 0 {
        why.push(format!("{missing} missing"));
    }
    if unpaired > 0 {
        why.push(format!("{unpaired} with no colour image within {} s", first.max_dt_s));
    }
    let images = if depth.len() == 1 { "image" } else { "images" };
    Some(format!(
        "{} depth {images} listed in {} not used: {}",
        depth.len(),
        first.list.display(),
        why.join(", ")
    ))
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

/// The top view of the ground truth alone, for a run without an estimate.
fn plot_ground_truth(gt: &Trajectory, path: &Path) -> Result<()> {
    let gt: Vec<Point3<f64>> =
        gt.poses.iter().map(|p| Point3::from(p.t_wc.translation.vector)).collect();
    plot::plot_trajectory_top_view(path, &gt, &[], &[], "ground truth (no estimate yet)")?;
    Ok(())
}
