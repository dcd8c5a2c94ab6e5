//! The host simulator as CI runs it: `ferroslam-sim replay`'s library
//! ([`ferroslam_sim::replay`]) called in process, its typed report held to an accuracy bar.
//! Shared by `ci` and `heldout`.

use std::path::Path;

use anyhow::{Context, Result, bail};
use ferroslam_core::config::QVGA;
use ferroslam_sim::dataset::{CalibrationOrigin, CalibrationSource, DatasetOptions};
use ferroslam_sim::replay::{Replay, ReplayOptions};
use ferroslam_sim::report::summary;
use ferroslam_sim::run::TrackMode;

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
    let calibration =
        calibration.map_or(CalibrationSource::File, |c| CalibrationSource::Path(c.to_path_buf()));
    let options = ReplayOptions {
        dataset: DatasetOptions { calibration, profile: QVGA, ..DatasetOptions::default() },
        ..ReplayOptions::new(Some(mode))
    };
    let replay = Replay::open(dataset, options)?;
    if let CalibrationOrigin::FolderName(_) = replay.dataset().calibration_origin() {
        eprintln!("note: {}", replay.calibration_note());
    }
    let outputs = replay.run(out)?;
    let report = &outputs.report;
    eprintln!("replay {}: {}", dataset.display(), summary(report, outputs.wall_s));
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
