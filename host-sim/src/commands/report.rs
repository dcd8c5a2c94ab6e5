//! `report.json`: what a run did, in the fields `shared/design.md` promises.

use std::path::Path;

use anyhow::{Context, Result};
use serde::Serialize;

use super::datapath::{DataPathRun, FrameStats, median};

/// Wall-clock cost figures of the host run. Informational: the per-frame cost contract is counted
/// in instructions by the benchmarks, never in seconds.
#[derive(Debug, Clone, Serialize)]
pub struct HostCost {
    /// Unit of the figures below.
    pub unit: &'static str,
    /// Median time the core spent on a frame.
    pub process_median: f64,
    /// Longest time the core spent on a frame.
    pub process_max: f64,
    /// Mean time the pipeline waited for the frame source (decoding or rendering) per frame.
    pub source_wait_mean: f64,
}

/// The report of a `replay` or `demo` run.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// What ran: `"data-path"` until tracking exists.
    pub mode: &'static str,
    /// Plain words on what this run did and did not do.
    pub note: String,
    /// The processing profile (`"qvga"`, `"vga"`).
    pub profile: &'static str,
    /// Processing width, pixels.
    pub width: usize,
    /// Processing height, pixels.
    pub height: usize,
    /// Frames processed.
    pub frames: usize,
    /// Frames with a tracked pose (0: no tracker yet).
    pub tracked_frames: usize,
    /// Keyframes in the map (0: no map yet).
    pub keyframes: usize,
    /// ATE RMSE of CameraTrajectory.txt against ground truth, metres; null without one of them.
    pub ate_rmse_m: Option<f64>,
    /// RPE translation per second of CameraTrajectory.txt, metres per second; null without it.
    pub rpe_trans_m_per_s: Option<f64>,
    /// Bytes of SLAM state the core holds (0: no tracker or map yet).
    pub state_bytes: usize,
    /// SHA-256 of CameraTrajectory.txt; null when none was written.
    pub output_sha256: Option<String>,
    /// Frames the dataset lists but that could not be used (missing files, no association).
    pub skipped_frames: usize,
    /// Median `W(I)` (paper Eq. 3) over the frames, gray levels.
    pub total_variation_median: f64,
    /// Mean fraction of pixels with depth.
    pub valid_depth_fraction_mean: f64,
    /// Host wall-clock cost (informational).
    pub host_cost: HostCost,
    /// Per-frame figures.
    pub per_frame: Vec<FrameStats>,
}

impl Report {
    /// A data-path report of `run`; `note` says what the run did.
    pub fn data_path(
        run: &DataPathRun,
        profile: &'static str,
        skipped: usize,
        note: String,
    ) -> Self {
        let n = run.frames.max(1) as f64;
        Self {
            mode: "data-path",
            note,
            profile,
            width: run.width,
            height: run.height,
            frames: run.frames,
            tracked_frames: 0,
            keyframes: 0,
            ate_rmse_m: None,
            rpe_trans_m_per_s: None,
            state_bytes: 0,
            output_sha256: None,
            skipped_frames: skipped,
            total_variation_median: median(run.per_frame.iter().map(|f| f.total_variation as f64)),
            valid_depth_fraction_mean: run
                .per_frame
                .iter()
                .map(|f| f64::from(f.valid_depth_fraction))
                .sum::<f64>()
                / n,
            host_cost: HostCost {
                unit: "microseconds, host wall clock",
                process_median: median(run.per_frame.iter().map(|f| f.process_us)),
                process_max: run.per_frame.iter().map(|f| f.process_us).fold(0.0, f64::max),
                source_wait_mean: run.source_wait_s * 1e6 / n,
            },
            per_frame: run.per_frame.clone(),
        }
    }

    /// Writes the report as pretty JSON to `dir/report.json`.
    ///
    /// # Errors
    /// When the file cannot be written.
    pub fn write(&self, dir: &Path) -> Result<()> {
        let path = dir.join("report.json");
        let text = serde_json::to_string_pretty(self)?;
        std::fs::write(&path, text + "\n").with_context(|| format!("writing {}", path.display()))
    }
}
