//! The host simulator as CI runs it: `ferroslam-sim replay`'s library
//! ([`ferroslam_sim::replay`]) called in process, its typed report held to an accuracy bar.
//! Shared by `ci` and `heldout`.

use std::path::Path;

use anyhow::{Context, Result, bail};
use ferroslam_core::config::QVGA;
use ferroslam_sim::dataset::{CalibrationOrigin, CalibrationSource, DatasetOptions};
use ferroslam_sim::replay::{Replay, ReplayOptions};
use ferroslam_sim::report::RunOutputs;
use ferroslam_sim::report::summary;
use ferroslam_sim::run::{ArPlan, TrackMode};

/// Replays `dataset` (with `calibration`, else its own) at QVGA from its first frame in `mode`
/// into `out`, as `ferroslam-sim replay` does; fails when a frame was not tracked or the ATE RMSE
/// is over `bar_m` (when given). Returns the frames processed and the ATE RMSE in metres; `label`
/// names the data in messages.
pub fn replay_with_bar(
    label: &str,
    dataset: &Path,
    calibration: Option<&Path>,
    mode: TrackMode,
    bar_m: Option<f64>,
    out: &Path,
) -> Result<(usize, f64)> {
    let outputs = replay_qvga(dataset, calibration, mode, None, out)?;
    let report = &outputs.report;
    let mode = mode.name();
    let (frames, tracked) = (report.frames, report.tracked_frames);
    let ate = report.ate_rmse_m.with_context(|| {
        let why = report.evaluation_error.as_deref().unwrap_or("no ground truth");
        format!("{label} {mode}: the replay has no ATE RMSE ({why})")
    })?;
    let bar = bar_m.map_or_else(|| "no bar".to_string(), |b| format!("bar {b:.3} m"));
    eprintln!("{label} {mode}: {frames} frames, {tracked} tracked, ATE RMSE {ate:.4} m ({bar})");
    if frames == 0 || tracked != frames {
        bail!("{label} {mode}: {frames} frames processed and {tracked} tracked; all must be");
    }
    if let Some(bar_m) = bar_m.filter(|b| ate > *b) {
        bail!("{label} {mode}: ATE RMSE {ate:.4} m is over the bar of {bar_m:.3} m");
    }
    Ok((frames, ate))
}

/// Replays `dataset` (with `calibration`, else its own) at QVGA in `mode` into `out`, its frames
/// in the order `frames` gives (`A-B,C-D,...`) or the recording's, as `ferroslam-sim replay`
/// does, and prints its summary.
fn replay_qvga(
    dataset: &Path,
    calibration: Option<&Path>,
    mode: TrackMode,
    frames: Option<&str>,
    out: &Path,
) -> Result<RunOutputs> {
    let calibration =
        calibration.map_or(CalibrationSource::File, |c| CalibrationSource::Path(c.to_path_buf()));
    let options = ReplayOptions {
        dataset: DatasetOptions {
            calibration,
            profile: QVGA,
            frames: frames.map(str::parse).transpose()?,
            ..DatasetOptions::default()
        },
        // SLAM replays place the two AR objects too (issue 49): it changes no pose.
        ar: matches!(mode, TrackMode::Slam { .. }).then_some(ArPlan::Paper),
        ..ReplayOptions::new(Some(mode))
    };
    let replay = Replay::open(dataset, options)?;
    if let CalibrationOrigin::FolderName(_) = replay.dataset().calibration_origin() {
        eprintln!("note: {}", replay.calibration_note());
    }
    let outputs = replay.run(out)?;
    let order = frames.map_or_else(String::new, |f| format!(" --frames {f}"));
    eprintln!("replay {}{order}: {}", dataset.display(), summary(&outputs.report, outputs.wall_s));
    Ok(outputs)
}

/// What a jump-back replay must show (issue 47): the camera carried back to a place it has
/// seen is relocalized soon after the jump, the run's ATE stays within a bar, and no frame
/// whose pose is far off is reported as tracking.
#[derive(Debug, Clone, Copy)]
pub struct JumpBack<'a> {
    /// The frame ranges played, e.g. `0-700,100-999`.
    pub frames: &'a str,
    /// The first frame (0-based, in the order played) after the jump.
    pub jump_at: usize,
    /// The relocalization must come at most this many frames after `jump_at`.
    pub within_frames: usize,
    /// ATE RMSE bar of the SLAM trajectory, metres.
    pub bar_m: f64,
    /// A frame whose aligned error is over this (metres) must not be reported tracking.
    pub wrong_m: f64,
}

/// Replays `dataset` with `calibration` at QVGA in SLAM mode (the board's defaults, place memory
/// on) over `jump.frames` into `out`, and checks [`JumpBack`]'s bars. Returns the ATE RMSE and
/// the first relocalized frame.
///
/// # Errors
/// A bar not met, or the replay's own errors.
pub fn replay_jump_back(
    dataset: &Path,
    calibration: &Path,
    jump: &JumpBack<'_>,
    out: &Path,
) -> Result<(f64, usize)> {
    let outputs = replay_qvga(dataset, Some(calibration), TrackMode::SLAM, Some(jump.frames), out)?;
    let report = &outputs.report;
    let label = format!("jump-back {}", jump.frames);
    let first = report
        .relocalizations
        .as_ref()
        .and_then(|r| r.frames.iter().copied().find(|&f| f >= jump.jump_at))
        .with_context(|| {
            format!("{label}: no relocalization after the jump at frame {}", jump.jump_at)
        })?;
    if first > jump.jump_at + jump.within_frames {
        bail!(
            "{label}: relocalized at frame {first}, over {} frames after the jump at {}",
            jump.within_frames,
            jump.jump_at
        );
    }
    let evaluation =
        outputs.evaluation.as_ref().with_context(|| format!("{label}: no evaluation"))?;
    let ate = evaluation.ate.rmse;
    let tracking: std::collections::HashSet<u64> = report
        .odometry
        .iter()
        .filter(|f| f.state == "tracking")
        .map(|f| f.timestamp_s.to_bits())
        .collect();
    let wrong: Vec<f64> = evaluation
        .matches
        .iter()
        .filter(|m| m.ate_m > jump.wrong_m && tracking.contains(&m.est.timestamp_s.to_bits()))
        .map(|m| m.est.timestamp_s)
        .collect();
    eprintln!(
        "{label}: relocalized at frame {first} (jump at {}), ATE RMSE {ate:.4} m (bar {:.3} m), {} frames over {:.2} m reported tracking",
        jump.jump_at,
        jump.bar_m,
        wrong.len(),
        jump.wrong_m
    );
    if ate > jump.bar_m {
        bail!("{label}: ATE RMSE {ate:.4} m is over the bar of {:.3} m", jump.bar_m);
    }
    if let Some(t) = wrong.first() {
        bail!(
            "{label}: {} frames reported tracking with an error over {:.2} m, the first at t = {t} s",
            wrong.len(),
            jump.wrong_m
        );
    }
    Ok((ate, first))
}
