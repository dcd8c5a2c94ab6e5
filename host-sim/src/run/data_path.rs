//! The data path every frame takes before tracking: frames pulled from a [`FrameSource`], their
//! timestamps checked, the core's per-frame image statistics (the image variation `W(I)` of the
//! paper's Eq. 3 and the depth coverage) taken, and the frame handed to whatever runs on it.

use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use ferroslam_core::frame::{FrameSource, RgbdFrame};
use ferroslam_core::image::total_variation;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use crate::eval::stats::median_of_sorted;

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

/// How a run shows its progress: a bar on stderr when it is a terminal, or nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress {
    /// Frames the source is expected to give: the bar's length (a guess does no harm).
    pub expected_frames: usize,
    /// Whether to draw the bar (never drawn when stderr is not a terminal). Runs side by side
    /// in one process turn it off: their bars would overwrite each other.
    pub bar: bool,
}

/// Runs every frame of `source` through the core's data path, showing `progress`.
///
/// # Errors
/// The source's error, with the index of the frame it came from; timestamps that do not increase.
pub fn data_path<S>(source: &mut S, progress: Progress) -> Result<DataPathRun>
where
    S: FrameSource,
    S::Error: std::error::Error + Send + Sync + 'static,
{
    drive(source, progress, |_| Ok(()))
}

/// [`data_path`], also calling `on_frame` on every frame after the statistics (its time counts as
/// processing time).
///
/// # Errors
/// As [`data_path`], and `on_frame`'s error with the index of the frame.
pub fn drive<S, F>(source: &mut S, progress: Progress, mut on_frame: F) -> Result<DataPathRun>
where
    S: FrameSource,
    S::Error: std::error::Error + Send + Sync + 'static,
    F: FnMut(&RgbdFrame<'_>) -> Result<()>,
{
    let expected = progress.expected_frames;
    let bar = if progress.bar { ProgressBar::new(expected as u64) } else { ProgressBar::hidden() };
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
