//! What a run wrote: `report.json` (the fields `shared/design.md` promises), the trajectories,
//! the plots, and the one-line summary and notes the console and the report give.

use std::path::Path;

use anyhow::{Context, Result};
use ferroslam_core::loops::LoopStats;
use serde::Serialize;
use sha2::Digest;

use crate::dataset::{SkippedFrame, Stream};
use crate::eval::{self, EvalReport};
use crate::plot;
use crate::run::{
    BackendReport, DataPathRun, FrameStats, PlacesReport, PlanesReport, TrackMode, TrackedFrame,
    TrackingRun, median,
};
use crate::trajectory::Trajectory;

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
    /// What ran: `"data-path"`, `"odometry"` or `"slam"`.
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
    /// Frames with a pose estimated from the images (0 in data-path mode).
    pub tracked_frames: usize,
    /// Frames the front end was lost in: their pose is the motion-model prediction.
    pub lost_frames: usize,
    /// Frames where tracking restarted from a keyframe at the predicted pose after a loss: a pose
    /// the images did not confirm.
    pub reinitialized_frames: usize,
    /// Frames where tracking restarted in a remembered place that geometric verification
    /// accepted: a pose the images confirmed against the map.
    pub relocalized_frames: usize,
    /// Frames before the first keyframe: no pose, no world frame yet. With the four above they
    /// add up to `frames` (tracking modes).
    pub initializing_frames: usize,
    /// Relocalizations: how many and at which frames (0-based, in the order played); null
    /// without a place memory (odometry, `--no-places`).
    pub relocalizations: Option<Relocalizations>,
    /// Loops: keyframes that looked for one (`queries`), loops verified (`detected`), those that
    /// moved the map (`accepted`), those that agreed with it within a verification's accuracy
    /// (`consistent`), those that disagreed with a map tracked without a restart since and were
    /// not applied alone (`held`), the accepted ones that were the last of such held loops in a
    /// row that agreed (`confirmed`), queries refused as ambiguous (`rejected`), and the frames
    /// (0-based, in the order played) of the accepted ones; null without a place memory.
    pub loops: Option<Loops>,
    /// The place memory's figures (SLAM mode with places).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub places: Option<PlacesReport>,
    /// Keyframes made (0 in data-path mode).
    pub keyframes: usize,
    /// ATE RMSE of CameraTrajectory.txt against ground truth, metres; null without one of them
    /// or when they cannot be compared (`evaluation_error` says why).
    pub ate_rmse_m: Option<f64>,
    /// Why the trajectory was not evaluated although there is ground truth (e.g. fewer than three
    /// poses matched it in time, or the poses lie on a line and do not fix the alignment); absent
    /// when it was evaluated or there is no ground truth. The run's outputs are written anyway.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub evaluation_error: Option<String>,
    /// RPE translation per second of CameraTrajectory.txt, metres per second; null without it.
    pub rpe_trans_m_per_s: Option<f64>,
    /// Bytes of SLAM state the core holds (`size_of` the front end; 0 in data-path mode).
    pub state_bytes: usize,
    /// SHA-256 of CameraTrajectory.txt; null when none was written.
    pub output_sha256: Option<String>,
    /// Frames `rgb.txt` lists that were not played: their colour image is missing, or no depth
    /// image lies within the association limit. With `frames` they make up the frames listed,
    /// unless some were left out on purpose (`--skip-frames`, `--max-frames`, `--frames`), which
    /// are not counted. Depth images without a frame are not frames: they are only in
    /// `skipped_images`.
    pub skipped_frames: usize,
    /// Every listed image not used, colour (the skipped frames) and depth, by list and line.
    pub skipped_images: Vec<SkippedImage>,
    /// Median `W(I)` (paper Eq. 3) over the frames, gray levels.
    pub total_variation_median: f64,
    /// Mean fraction of pixels with depth.
    pub valid_depth_fraction_mean: f64,
    /// Host wall-clock cost (informational).
    pub host_cost: HostCost,
    /// Per-frame figures.
    pub per_frame: Vec<FrameStats>,
    /// ATE RMSE of the poses as output frame by frame (before later bundle adjustment moved
    /// their keyframes), metres; null without ground truth or in data-path mode.
    pub ate_online_rmse_m: Option<f64>,
    /// The back end's figures (SLAM mode).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub backend: Option<BackendReport>,
    /// The world's planes from the keyframes' depth, in the trajectory's world frame (SLAM
    /// mode).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub planes: Option<PlanesReport>,
    /// The planes against the room's (the demo: its renderer knows the room).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub plane_accuracy: Option<crate::plane_truth::PlaneAccuracy>,
    /// The objects placed (`--ar`) and, on the demo, their pixel error against where the room
    /// says they are.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ar: Option<crate::plane_truth::ArAccuracy>,
    /// Per-frame front-end figures (odometry and SLAM modes).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub odometry: Vec<TrackedFrame>,
}

/// A listed image a replay did not use (report.json `skipped_images`).
#[derive(Debug, Clone, Serialize)]
pub struct SkippedImage {
    /// The list naming it: `.../rgb.txt` (a frame) or `.../depth.txt`.
    pub list: String,
    /// 1-based line in that list.
    pub line: usize,
    /// Its timestamp, seconds.
    pub timestamp_s: f64,
    /// The image file.
    pub path: String,
    /// Why it was not used: `file missing`, or `no depth image within 0.02 s` (or `colour`),
    /// with the missing partner when there is one.
    pub reason: String,
}

impl From<&SkippedFrame> for SkippedImage {
    fn from(s: &SkippedFrame) -> Self {
        Self {
            list: s.list.display().to_string(),
            line: s.line,
            timestamp_s: s.timestamp_s,
            path: s.path.display().to_string(),
            reason: s.why(),
        }
    }
}

/// Loops of a run (report.json `loops`).
#[derive(Debug, Clone, Serialize)]
pub struct Loops {
    /// Loop detection's counters.
    #[serde(flatten)]
    pub stats: LoopStats,
    /// The frames on which a loop closed, 0-based, in the order played.
    pub frames: Vec<usize>,
}

/// Relocalizations of a run (report.json `relocalizations`).
#[derive(Debug, Clone, Serialize)]
pub struct Relocalizations {
    /// Frames that relocalized.
    pub count: usize,
    /// Their indices, 0-based, in the order played.
    pub frames: Vec<usize>,
}

impl Report {
    /// A data-path report of `run`; `skipped` are the listed images not used (none for the
    /// demo); `note` says what the run did.
    pub fn data_path(
        run: &DataPathRun,
        profile: &'static str,
        skipped: &[SkippedFrame],
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
            lost_frames: 0,
            reinitialized_frames: 0,
            relocalized_frames: 0,
            initializing_frames: 0,
            relocalizations: None,
            loops: None,
            places: None,
            keyframes: 0,
            ate_rmse_m: None,
            evaluation_error: None,
            rpe_trans_m_per_s: None,
            state_bytes: 0,
            output_sha256: None,
            skipped_frames: skipped.iter().filter(|s| s.stream == Stream::Rgb).count(),
            skipped_images: skipped.iter().map(SkippedImage::from).collect(),
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
            ate_online_rmse_m: None,
            backend: None,
            planes: None,
            plane_accuracy: None,
            ar: None,
            odometry: Vec::new(),
        }
    }

    /// An odometry report of `run`, with `evaluation` against ground truth when there is one and
    /// `sha256` of the CameraTrajectory.txt written; `skipped` as for [`Report::data_path`].
    pub fn odometry(
        run: &TrackingRun,
        profile: &'static str,
        skipped: &[SkippedFrame],
        note: String,
        evaluation: Option<&EvalReport>,
        online_ate: Option<f64>,
        sha256: String,
    ) -> Self {
        Self {
            mode: if run.backend.is_some() { "slam" } else { "odometry" },
            tracked_frames: run.tracked_frames,
            lost_frames: run.lost_frames,
            reinitialized_frames: run.reinitialized_frames,
            relocalized_frames: run.relocalized_frames,
            initializing_frames: run.initializing_frames,
            relocalizations: run.places.as_ref().map(|p| Relocalizations {
                count: p.relocalized_frames.len(),
                frames: p.relocalized_frames.clone(),
            }),
            loops: run
                .places
                .as_ref()
                .map(|p| Loops { stats: p.loops, frames: p.loop_frames.clone() }),
            places: run.places.clone(),
            keyframes: run.keyframes.len(),
            ate_rmse_m: evaluation.map(|e| e.ate.rmse),
            evaluation_error: None,
            rpe_trans_m_per_s: evaluation.and_then(|e| e.rpe_per_second.map(|r| r.trans.rmse)),
            state_bytes: run.state_bytes,
            output_sha256: Some(sha256),
            ate_online_rmse_m: online_ate,
            backend: run.backend.clone(),
            planes: run.planes.clone(),
            plane_accuracy: None,
            ar: None,
            odometry: run.per_frame.clone(),
            ..Self::data_path(&run.data, profile, skipped, note)
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

    /// [`Self::write`], and `dir/report.html` with it and `scene` ([`crate::page`]).
    ///
    /// # Errors
    /// A file that cannot be written.
    pub fn write_with_page(&self, dir: &Path, scene: &crate::page::Scene) -> Result<()> {
        self.write(dir)?;
        crate::page::write_page(dir, self, scene)
    }
}

/// What [`write_odometry`] wrote and measured.
#[derive(Debug, Clone)]
pub struct OdometryOutputs {
    /// The report written to `report.json`.
    pub report: Report,
    /// The evaluation against ground truth, when there is one.
    pub evaluation: Option<EvalReport>,
    /// The 3D view's data in report.html.
    pub scene: crate::page::Scene,
}

/// What a replay or a demo wrote, and how long its frames took.
#[derive(Debug, Clone)]
pub struct RunOutputs {
    /// The report written to `report.json`.
    pub report: Report,
    /// The evaluation against ground truth of the trajectory written, when there is one: in
    /// odometry and SLAM modes `CameraTrajectory.txt`'s; in the demo's data-path mode the
    /// simulated dead reckoning's (`baseline_trajectory.txt`); none in a replay's data-path mode.
    pub evaluation: Option<EvalReport>,
    /// Host wall-clock seconds the frames took, from the first frame asked for to the last one
    /// processed (informational, like [`HostCost`]).
    pub wall_s: f64,
}

/// Writes `CameraTrajectory.txt`, `KeyFrameTrajectory.txt`, `report.json`, with ground truth
/// `trajectory.svg` and `ate.svg`, and with AR objects `ar/` ([`crate::ar_files::write_ar`]) into
/// `dir`; `skipped` are the listed images the run did not use.
///
/// # Errors
/// A file that cannot be written. A trajectory that cannot be evaluated (e.g. no estimated pose
/// near a ground-truth one) is not an error: its report has no ATE and says why.
pub fn write_odometry(
    dir: &Path,
    run: &TrackingRun,
    gt: Option<&Trajectory>,
    profile: &'static str,
    skipped: &[SkippedFrame],
    note: String,
) -> Result<OdometryOutputs> {
    // Hash the very text written, rather than reading the file back.
    let camera_text = run.camera.to_tum_string();
    let camera_path = dir.join("CameraTrajectory.txt");
    std::fs::write(&camera_path, &camera_text)
        .with_context(|| format!("writing {}", camera_path.display()))?;
    run.keyframes.write_tum(&dir.join("KeyFrameTrajectory.txt"))?;
    let sha256: String =
        sha2::Sha256::digest(camera_text.as_bytes()).iter().map(|b| format!("{b:02x}")).collect();
    let gt = gt.filter(|g| !g.is_empty());
    let evaluate = |gt, estimate| eval::evaluate(gt, estimate, eval::DEFAULT_MAX_DT_S);
    // A trajectory that cannot be compared with the ground truth (too short, degenerate) is
    // still the run's output: it is written, and the report says why it has no ATE.
    let (evaluation, evaluation_error) = match gt {
        None => (None, None),
        Some(_) if run.camera.is_empty() => {
            let why = "no frame has a pose: the front end never made its first keyframe, for \
                       want of texture or depth";
            (None, Some(why.to_owned()))
        }
        Some(gt) => match evaluate(gt, &run.camera) {
            Ok(e) => (Some(e), None),
            Err(e) => (None, Some(e.to_string())),
        },
    };
    if let Some(e) = &evaluation {
        let at = |which: fn(&TrackedFrame) -> bool| -> Vec<f64> {
            run.per_frame.iter().filter(|f| which(f)).map(|f| f.timestamp_s).collect()
        };
        let events =
            [("relocalized", at(|f| f.relocalized)), ("loop closed", at(|f| f.loop_closed))];
        plot::plot_report(e, &dir.join("trajectory.svg"), &dir.join("ate.svg"), &events)?;
    }
    // An online trajectory that cannot be evaluated (e.g. empty) has no ATE either.
    let online_ate = gt.and_then(|gt| evaluate(gt, &run.online).ok()).map(|e| e.ate.rmse);
    let mut report =
        Report::odometry(run, profile, skipped, note, evaluation.as_ref(), online_ate, sha256);
    report.evaluation_error = evaluation_error;
    let scene = crate::page::Scene::of(run, evaluation.as_ref());
    report.write_with_page(dir, &scene)?;
    crate::ar_files::write_ar(dir, run)?;
    Ok(OdometryOutputs { report, evaluation, scene })
}

/// The report's note on what a tracking run in `mode` did at `profile` (`width` x `height`).
pub fn run_note(mode: &TrackMode, profile: &str, (width, height): (usize, usize)) -> String {
    match mode {
        TrackMode::Slam { .. } => format!(
            "slam: frame-to-map front end, map and back end (local and segmented global bundle \
             adjustment, fixed work quota per frame) at {profile} ({width}x{height}); \
             CameraTrajectory.txt composes each frame's pose relative to its reference keyframe \
             with that keyframe's final pose"
        ),
        TrackMode::Odometry => format!(
            "odometry: frame-to-map front end at {profile} ({width}x{height}), depth fused into \
             the landmarks; no bundle adjustment, no loop closure"
        ),
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

/// The one-line summary of a tracking run that took `wall_s` seconds. Each frame played is
/// counted once (tracked, relocalised, re-initialised, lost or before the first keyframe); the
/// frames listed but skipped, when there are any, are said apart.
pub fn summary(report: &Report, wall_s: f64) -> String {
    let ate = match (report.ate_rmse_m, &report.evaluation_error) {
        (Some(a), _) => format!("{a:.4} m"),
        (None, Some(why)) => format!("n/a ({why})"),
        (None, None) => "n/a (no ground truth)".to_owned(),
    };
    let skipped = match report.skipped_frames {
        0 => String::new(),
        n => format!(" {n} more listed in rgb.txt skipped, not played;"),
    };
    format!(
        "{} ({}): {} frames: {} tracked, {} relocalised, {} re-initialised, {} lost, {} before \
         the first keyframe;{skipped} {} keyframes;{}{}{} ATE RMSE {ate}; RPE {}; {:.1} s wall ({:.1} \
         ms median per frame in the core); core state {} bytes",
        report.mode,
        report.profile,
        report.frames,
        report.tracked_frames,
        report.relocalized_frames,
        report.reinitialized_frames,
        report.lost_frames,
        report.initializing_frames,
        report.keyframes,
        report
            .loops
            .as_ref()
            .map_or(String::new(), |l| format!(" {} loops closed;", l.frames.len())),
        report.planes.as_ref().map_or(String::new(), |p| {
            let accuracy = report.plane_accuracy.as_ref().map_or(String::new(), |a| {
                format!(
                    " ({} of {} room faces over {:.0}% of a frame found, worst {:.2} deg, {:.1} mm)",
                    a.found,
                    a.found + a.missed,
                    100.0 * a.min_fraction,
                    a.normal_error_deg_max.unwrap_or(f64::NAN),
                    1000.0 * a.offset_error_m_max.unwrap_or(f64::NAN)
                )
            });
            format!(" {} planes{accuracy};", p.planes.len())
        }),
        report.ar.as_ref().map_or(String::new(), ar_summary),
        report.rpe_trans_m_per_s.map_or("n/a".to_owned(), |r| format!("{r:.4} m/s")),
        wall_s,
        report.host_cost.process_median / 1000.0,
        report.state_bytes,
    )
}

/// `1234567` as `1,234,567`: counts printed for a reader.
pub fn thousands(value: u64) -> String {
    let digits = value.to_string();
    let mut out = String::with_capacity(digits.len() + digits.len() / 3);
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// The summary's AR part: objects placed, their pixel error, and script steps refused.
fn ar_summary(a: &crate::plane_truth::ArAccuracy) -> String {
    let error = match (&a.error_px, &a.jitter_px) {
        (Some(e), Some(j)) if e.count > 0 => format!(
            "pixel error median {:.2} px, p95 {:.2} px, jitter median {:.2} px",
            e.median, e.p95, j.median
        ),
        (Some(_), _) => "no drawing in view to measure".to_owned(),
        _ => "pixel error not measured (no ground truth)".to_owned(),
    };
    let refused = a.events.iter().filter(|e| e.refused.is_some()).count();
    let script = if a.events.is_empty() {
        String::new()
    } else {
        format!(", {refused} of {} script steps refused (report.json ar.events)", a.events.len())
    };
    let online = a.online.as_ref().map_or(String::new(), |o| {
        let error = match &o.error_px {
            Some(e) if e.count > 0 => {
                format!(", pixel error median {:.2} px, p95 {:.2} px", e.median, e.p95)
            }
            _ => String::new(),
        };
        format!(
            ", as the board: {} steps applied, {} refused, {} anchors{error} (report.json \
             ar.online)",
            o.applied,
            o.refused.len(),
            o.anchors.len()
        )
    });
    if a.objects == 0 {
        return format!(" AR: no object placed{script}{online};");
    }
    format!(" AR: {} objects from frame {}, {error}{script}{online};", a.objects, a.frame)
}
