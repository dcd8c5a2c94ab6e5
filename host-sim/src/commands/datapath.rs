//! The data path every frame takes before tracking: a [`FrameSource`] (dataset reader, synthetic
//! renderer, or one wrapped in [`ProfileSource`]), then the core's per-frame image statistics.
//!
//! [`run`] computes the image variation `W(I)` of the paper's Eq. 3 and the depth coverage;
//! [`run_odometry`] also runs the core's odometry front end on every frame.

use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use ferroslam_core::backend::BackendParams;
use ferroslam_core::config::{Profile, Tunables};
use ferroslam_core::frame::{FrameSource, RgbdFrame};
use ferroslam_core::geometry::PinholeCamera;
use ferroslam_core::image::{ImageError, total_variation};
use ferroslam_core::map::BoardMap;
use ferroslam_core::system::SLAM_FRONTEND;
use ferroslam_core::tracking::{FrameResult, Frontend, FrontendParams, FrontendState, GuideStage};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

pub use super::slam::{MapScale, Schedule};
use crate::eval::stats::median_of_sorted;
use crate::frame::{OwnedFrame, halve_frame};
use crate::trajectory::{StampedPose, Trajectory};

/// A source that halves every frame of `inner` `levels` times with the core's downsampling, as the
/// firmware does with sensor frames: the port wrapper that puts a VGA source at the QVGA profile.
#[derive(Debug)]
pub struct ProfileSource<S> {
    inner: S,
    levels: u8,
    depth_level: u8,
    current: Option<OwnedFrame>,
}

impl<S> ProfileSource<S> {
    /// Wraps `inner`, halving its frames `levels` times and their depth `depth_level` more
    /// times (see [`OwnedFrame::coarsen_depth`]; both 0 = pass frames through unchanged).
    pub fn new(inner: S, levels: u8, depth_level: u8) -> Self {
        Self { inner, levels, depth_level, current: None }
    }

    /// The wrapped source.
    pub fn inner(&self) -> &S {
        &self.inner
    }
}

/// The command-line parser of a `--depth-level`: 0 to the core's
/// [`MAX_DEPTH_LEVEL`](ferroslam_core::image::MAX_DEPTH_LEVEL).
pub fn depth_level_parser() -> clap::builder::RangedI64ValueParser<u8> {
    clap::value_parser!(u8).range(0..=i64::from(ferroslam_core::image::MAX_DEPTH_LEVEL))
}

/// Why a [`ProfileSource`] could not give a frame.
#[derive(Debug, thiserror::Error)]
pub enum ProfileSourceError<E: std::error::Error + 'static> {
    /// The wrapped source failed.
    #[error(transparent)]
    Source(E),
    /// The frame could not be downsampled.
    #[error("downsampling the frame failed: {0}")]
    Image(#[from] ImageError),
}

impl<S> FrameSource for ProfileSource<S>
where
    S: FrameSource,
    S::Error: std::error::Error + 'static,
{
    type Error = ProfileSourceError<S::Error>;

    fn next_frame(&mut self) -> Result<Option<RgbdFrame<'_>>, Self::Error> {
        let frame = self.inner.next_frame().map_err(ProfileSourceError::Source)?;
        let Some(frame) = frame else { return Ok(None) };
        if self.levels == 0 && self.depth_level == 0 {
            return Ok(Some(frame));
        }
        let halved = self.current.insert(halve_frame(&frame, self.levels)?);
        halved.coarsen_depth(self.depth_level)?;
        Ok(Some(halved.view()?))
    }
}

/// What the data path saw in one frame.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct FrameStats {
    /// Capture time, seconds.
    pub timestamp_s: f64,
    /// `W(I)`: the image's total variation (paper Eq. 3), gray levels summed over all pixels.
    pub total_variation: u64,
    /// Fraction of pixels with a depth reading.
    pub valid_depth_fraction: f32,
    /// Host wall-clock time the core spent on the frame, microseconds (informational only: the
    /// cost contract is counted in instructions by the benchmarks).
    pub process_us: f64,
}

/// The data path's result over a whole source.
#[derive(Debug, Clone, Serialize)]
pub struct DataPathRun {
    /// Frames processed.
    pub frames: usize,
    /// Processing size of the frames, pixels.
    pub width: usize,
    /// Processing height of the frames, pixels.
    pub height: usize,
    /// Per-frame statistics, in capture order.
    pub per_frame: Vec<FrameStats>,
    /// Total time spent waiting for the source (decoding, rendering), seconds.
    pub source_wait_s: f64,
    /// Total time spent in the core, seconds.
    pub process_s: f64,
}

/// Runs every frame of `source` through the core's data path, with a progress bar of `expected`
/// frames on a terminal.
///
/// # Errors
/// The source's error, with the index of the frame it came from; timestamps that do not increase.
pub fn run<S>(source: &mut S, expected: usize) -> Result<DataPathRun>
where
    S: FrameSource,
    S::Error: std::error::Error + Send + Sync + 'static,
{
    run_with(source, expected, |_| Ok(()))
}

/// [`run`], also calling `on_frame` on every frame after the statistics (its time counts as
/// processing time).
///
/// # Errors
/// As [`run`], and `on_frame`'s error with the index of the frame.
pub fn run_with<S, F>(source: &mut S, expected: usize, mut on_frame: F) -> Result<DataPathRun>
where
    S: FrameSource,
    S::Error: std::error::Error + Send + Sync + 'static,
    F: FnMut(&RgbdFrame<'_>) -> Result<()>,
{
    let bar = ProgressBar::new(expected as u64);
    if let Ok(style) =
        ProgressStyle::with_template("{bar:40} {pos}/{len} frames {per_sec} eta {eta}")
    {
        bar.set_style(style);
    }
    let mut run = DataPathRun {
        frames: 0,
        width: 0,
        height: 0,
        per_frame: Vec::with_capacity(expected),
        source_wait_s: 0.0,
        process_s: 0.0,
    };
    let mut wait = Duration::ZERO;
    let mut last_t = f64::NEG_INFINITY;
    loop {
        let asked = Instant::now();
        let frame = source.next_frame().with_context(|| format!("frame {}", run.frames))?;
        wait += asked.elapsed();
        let Some(frame) = frame else { break };
        if frame.timestamp_s <= last_t {
            anyhow::bail!(
                "frame {}: timestamp {} s does not follow {} s",
                run.frames,
                frame.timestamp_s,
                last_t
            );
        }
        last_t = frame.timestamp_s;
        let started = Instant::now();
        let stats = frame_stats(&frame);
        on_frame(&frame).with_context(|| format!("frame {}", run.frames))?;
        let process = started.elapsed();
        run.process_s += process.as_secs_f64();
        (run.width, run.height) = frame.gray.size();
        run.per_frame.push(FrameStats { process_us: process.as_secs_f64() * 1e6, ..stats });
        run.frames += 1;
        bar.inc(1);
    }
    bar.finish_and_clear();
    run.source_wait_s = wait.as_secs_f64();
    Ok(run)
}

/// What the odometry front end made of one frame.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct OdometryFrame {
    /// Capture time, seconds.
    pub timestamp_s: f64,
    /// `"initializing"`, `"tracking"` or `"lost"` after the frame.
    pub state: &'static str,
    /// Whether the pose was estimated from the frame (else it is the motion-model prediction).
    pub tracked: bool,
    /// Whether the frame became a keyframe.
    pub keyframe: bool,
    /// Pose inliers.
    pub inliers: usize,
    /// Landmarks matched into the frame.
    pub matches: usize,
    /// Guide landmarks matched from the motion-model prediction.
    pub guide_matches: usize,
    /// Which attempt gave the final stage's start pose: `"motion-model"`, `"small-image"`,
    /// `"wide-search"`, `"affine-bank"` or `"none"`.
    pub guide_stage: &'static str,
    /// Whether a recovery path (small image, wide search, bank) gave it.
    pub recovery: bool,
    /// Whether tracking restarted at this frame after a loss.
    pub reinitialized: bool,
    /// Final stages run (the rerun of the winning one included).
    pub final_stages: u8,
    /// Guide runs.
    pub guide_runs: u8,
    /// Whether the rotation was estimated from the small images.
    pub rotation_estimated: bool,
    /// Whether features were detected (a keyframe made or attempted).
    pub detected: bool,
}

/// What the back end did over a run (SLAM mode).
#[derive(Debug, Clone, Serialize)]
pub struct BackendReport {
    /// The capacities of the map and the back end: `board` (the firmware's) or `host`.
    pub map_scale: &'static str,
    /// Work units the back end may spend per frame (deterministic replay).
    pub work_quota_per_frame: u32,
    /// How the back end ran beside the front end: `threaded`, `sequential` or `realtime`.
    pub schedule: &'static str,
    /// Whether the run is deterministic (the same input gives the same bits): all but realtime.
    pub deterministic: bool,
    /// Covisibility levels a local window grows by (`--window-levels`; the board's 2 unless
    /// told).
    pub window_levels: u8,
    /// Local bundle adjustments finished.
    pub local_runs: u32,
    /// Segmented global bundle adjustments finished.
    pub global_runs: u32,
    /// Local windows by size: `[free keyframes, count]` pairs.
    pub window_sizes: Vec<[u32; 2]>,
    /// Mean local window size, keyframes.
    pub window_mean: f64,
    /// Local windows built while the map held more than 120 keyframes
    /// ([`super::slam::LARGE_MAP_KEYFRAMES`]; issue 4 wants their mean at 50-65).
    pub windows_in_large_map: usize,
    /// Mean size of those windows, keyframes (`None`: there were none).
    pub window_mean_in_large_map: Option<f64>,
    /// Keyframes in the map at the end.
    pub map_keyframes: usize,
    /// The most keyframes the map held, seen after each back-end step.
    pub map_keyframes_max: usize,
    /// Landmarks in the map at the end.
    pub map_landmarks: usize,
    /// Reference landmarks in the map at the end (fixed in bundle adjustment).
    pub reference_landmarks: usize,
    /// Over all local adjustments: the fraction of point variables that reference landmarks
    /// removed (fixed points over all points).
    pub reference_fraction_of_points: f64,
    /// Work units spent, problem building included.
    pub work_units: u64,
}

/// What to run on each frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackMode {
    /// The front end alone (depth fused into landmarks, no bundle adjustment).
    Odometry,
    /// Front end, map and back end, with `quota` back-end work units after every frame.
    Slam {
        /// Back-end work units per frame.
        quota: u32,
        /// How the back end runs beside the front end.
        schedule: Schedule,
        /// The capacities of the map and the back end.
        map: MapScale,
        /// Covisibility levels a local BA's window grows by (`BackendParams::window_levels`;
        /// the default, 2, is the board's).
        window_levels: u8,
    },
}

/// The tracker's result over a whole source.
#[derive(Debug, Clone)]
pub struct OdometryRun {
    /// The data path's figures (processing time includes the front end and the back end).
    pub data: DataPathRun,
    /// The trajectory written to CameraTrajectory.txt: in odometry mode each frame's pose as
    /// tracked; in SLAM mode each frame's pose relative to its reference keyframe, composed with
    /// that keyframe's final (bundle-adjusted) pose. Frames before the first keyframe (state
    /// `initializing`: no world frame yet) have no pose and are left out, as ORB-SLAM leaves them
    /// out; they are in `per_frame`.
    pub camera: Trajectory,
    /// Each frame's pose as the front end output it at that frame (what the firmware sends),
    /// from the first keyframe on.
    pub online: Trajectory,
    /// Camera-to-world pose of every keyframe (SLAM: final; odometry: when it was made).
    pub keyframes: Trajectory,
    /// Per-frame front-end figures.
    pub per_frame: Vec<OdometryFrame>,
    /// Frames with an estimated pose.
    pub tracked_frames: usize,
    /// Frames in the lost state.
    pub lost_frames: usize,
    /// Bytes of the core's state.
    pub state_bytes: usize,
    /// The back end's figures (SLAM mode).
    pub backend: Option<BackendReport>,
}

/// Runs every frame of `source` through the core, sized for `profile` (QVGA: 320 x 240; VGA:
/// 640 x 480), with the camera `cam` at the processing resolution and the front end's default
/// parameters.
///
/// # Errors
/// As [`run_with`]; a frame the front end rejects (size or timestamp); a back-end error.
pub fn run_odometry<S>(
    source: &mut S,
    expected: usize,
    cam: &PinholeCamera,
    profile: Profile,
    mode: TrackMode,
) -> Result<OdometryRun>
where
    S: FrameSource,
    S::Error: std::error::Error + Send + Sync + 'static,
{
    run_seeded(source, expected, cam, profile, mode, None, &Tunables::default())
}

/// [`run_odometry`] with the front end's RANSAC seeded by `rng_seed` (`None`: the core's default
/// seed, `FrontendParams::rng_seed`) and the sensor described by `tunables` (depth range and depth
/// noise, given to the front end and the back end); everything else as the mode's defaults
/// (odometry: `FrontendParams::DEFAULT`; SLAM: `system::SLAM_FRONTEND` and
/// `BackendParams::DEFAULT`). Runs with other seeds show how much of an accuracy figure is chance.
///
/// # Errors
/// As [`run_odometry`].
pub fn run_seeded<S>(
    source: &mut S,
    expected: usize,
    cam: &PinholeCamera,
    profile: Profile,
    mode: TrackMode,
    rng_seed: Option<u64>,
    tunables: &Tunables,
) -> Result<OdometryRun>
where
    S: FrameSource,
    S::Error: std::error::Error + Send + Sync + 'static,
{
    let seeded = |mut p: FrontendParams| {
        if let Some(seed) = rng_seed {
            p.rng_seed = seed;
        }
        p.with_tunables(tunables)
    };
    let (odometry, slam) = (seeded(FrontendParams::DEFAULT), seeded(SLAM_FRONTEND));
    let mut backend = BackendParams::DEFAULT.with_tunables(tunables);
    if let TrackMode::Slam { window_levels, .. } = mode {
        backend.window_levels = window_levels;
    }
    match (mode, profile.downsample_levels == 0) {
        (TrackMode::Odometry, true) => {
            odometry_with::<640, 480, S>(source, expected, cam, odometry)
        }
        (TrackMode::Odometry, false) => {
            odometry_with::<320, 240, S>(source, expected, cam, odometry)
        }
        (TrackMode::Slam { quota, schedule, map, .. }, true) => super::slam::run::<640, 480, S>(
            source, expected, cam, quota, schedule, map, slam, backend,
        ),
        (TrackMode::Slam { quota, schedule, map, .. }, false) => super::slam::run::<320, 240, S>(
            source, expected, cam, quota, schedule, map, slam, backend,
        ),
    }
}

/// The per-frame figures of a front-end result.
pub(crate) fn frame_figures(timestamp_s: f64, r: &FrameResult) -> OdometryFrame {
    let state = match r.state {
        FrontendState::Initializing => "initializing",
        FrontendState::Tracking => "tracking",
        FrontendState::Lost => "lost",
    };
    OdometryFrame {
        timestamp_s,
        state,
        tracked: r.tracked,
        keyframe: r.keyframe.is_some(),
        inliers: r.inliers,
        matches: r.matches,
        guide_matches: r.guide_matches,
        guide_stage: match r.guide_stage {
            GuideStage::MotionModel => "motion-model",
            GuideStage::SmallImageRotation => "small-image",
            GuideStage::WideSearch => "wide-search",
            GuideStage::AffineBank => "affine-bank",
            _ => "none",
        },
        recovery: r.guide_stage.is_recovery(),
        reinitialized: r.reinitialized,
        final_stages: r.work.final_stages,
        guide_runs: r.work.guide_runs,
        rotation_estimated: r.work.rotation_estimated,
        detected: r.work.detected,
    }
}

fn odometry_with<const W: usize, const H: usize, S>(
    source: &mut S,
    expected: usize,
    cam: &PinholeCamera,
    params: FrontendParams,
) -> Result<OdometryRun>
where
    S: FrameSource,
    S::Error: std::error::Error + Send + Sync + 'static,
{
    // Hundreds of KB each: boxed, never kept on the stack.
    let mut frontend: Box<Frontend<W, H>> = Box::new(Frontend::with_params(params));
    let mut map: Box<BoardMap> = Box::default();
    let (mut camera, mut keyframes, mut per_frame) = (Vec::new(), Vec::new(), Vec::new());
    let data = run_with(source, expected, |frame| {
        let r = frontend.process(frame, cam, &mut map)?;
        per_frame.push(frame_figures(frame.timestamp_s, &r));
        if r.state == FrontendState::Initializing {
            // No pose before the first keyframe, which defines the world frame.
            return Ok(());
        }
        let pose = StampedPose { timestamp_s: frame.timestamp_s, t_wc: r.t_wc.cast::<f64>() };
        camera.push(pose);
        if r.keyframe.is_some() {
            keyframes.push(pose);
        }
        Ok(())
    })?;
    let stats = frontend.stats();
    let camera = Trajectory::new(camera);
    Ok(OdometryRun {
        data,
        online: camera.clone(),
        camera,
        keyframes: Trajectory::new(keyframes),
        per_frame,
        tracked_frames: stats.tracked_frames as usize,
        lost_frames: stats.lost_frames as usize,
        state_bytes: std::mem::size_of::<Frontend<W, H>>() + std::mem::size_of::<BoardMap>(),
        backend: None,
    })
}

/// The core's statistics of one frame.
fn frame_stats(frame: &RgbdFrame<'_>) -> FrameStats {
    let raw = frame.depth.raw();
    let valid: usize = raw.rows().map(|r| r.iter().filter(|&&d| d != 0).count()).sum();
    let pixels = raw.width() * raw.height();
    FrameStats {
        timestamp_s: frame.timestamp_s,
        total_variation: total_variation(&frame.gray),
        valid_depth_fraction: valid as f32 / pixels.max(1) as f32,
        process_us: 0.0,
    }
}

/// The median of `values` (the mean of the middle two for an even count); 0 when empty.
pub fn median(values: impl IntoIterator<Item = f64>) -> f64 {
    let mut v: Vec<f64> = values.into_iter().collect();
    v.sort_by(f64::total_cmp);
    median_of_sorted(&v).unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(width: usize, height: usize, depth_level: u8) -> OwnedFrame {
        let (dw, dh) = (width >> depth_level, height >> depth_level);
        OwnedFrame {
            timestamp_s: 0.0,
            width,
            height,
            gray: vec![0; width * height],
            depth: vec![0; dw * dh],
            depth_level,
            depth_scale: 5000.0,
        }
    }

    fn camera(width: usize, height: usize) -> PinholeCamera {
        let (w, h) = (width as f32, height as f32);
        PinholeCamera::new(w, w, (w - 1.0) / 2.0, (h - 1.0) / 2.0, width, height).unwrap()
    }

    #[test]
    fn frames_that_do_not_fit_the_front_end_name_every_size() {
        // What a replay reports when the front end refuses a frame: the core's error.
        let fits = |f: &OwnedFrame, c: &PinholeCamera| {
            let mut frontend: Box<Frontend<320, 240>> = Box::default();
            let mut map: Box<BoardMap> = Box::default();
            frontend.process(&f.view().unwrap(), c, &mut map).map(|_| ()).map_err(|e| e.to_string())
        };
        assert!(fits(&frame(320, 240, 1), &camera(320, 240)).is_ok());
        assert!(fits(&frame(160, 120, 0), &camera(160, 120)).is_ok(), "smaller frames fit");
        let e = fits(&frame(640, 480, 1), &camera(640, 480)).unwrap_err().to_string();
        assert_eq!(
            e,
            "gray image 640x480, depth covering 640x480, camera 640x480: the three must have one \
             size, at most the 320x240 that the front end holds"
        );
        // An odd height at depth level 1: the depth covers one row fewer.
        let e = fits(&frame(4, 3, 1), &camera(4, 3)).unwrap_err().to_string();
        assert!(e.starts_with("gray image 4x3, depth covering 4x2, camera 4x3"), "{e}");
        let e = fits(&frame(320, 240, 1), &camera(160, 120)).unwrap_err().to_string();
        assert!(e.contains("camera 160x120"), "{e}");
    }
}
