//! `cargo xtask soak`: the board's pipeline run for a long time over recordings played in laps
//! (issue 50's soak).
//!
//! ```text
//! cargo xtask soak [--frames N] [--recording demo|7scenes|both] [--json FILE]
//! ```
//!
//! Each recording (the built-in demo's 300 frames, 7-Scenes' 1000, at QVGA) is played again and
//! again, its timestamps continuing at 30 Hz, for N frames (default 5,000; 100,000 by hand),
//! through `ferroslam_firmware::pipeline::run_frame` (the board's code) with the board's place
//! memory on a 512 KiB flash region and its serial link, the poses decoded as the host does.
//! Each lap carries the camera from the end of the recording back to its start: a place the map
//! has seen.
//!
//! Checks, with one row per lap printed: no panic (a panic ends the command); the state's bytes
//! constant (the pipeline and place memory are fixed-size types, and the map's keyframes and
//! landmarks stay within their capacities); no frame lost after the first lap except at a lap's
//! start, and a lap lost there relocalized or loop-closed; the place memory's records never fewer
//! and never over its capacity (full, it thins: its steady state); no store error; every pose
//! decoded from the link. Measured, not a bar: each lap's position error after the first lap's
//! SE(3) alignment to the ground truth, which shows the drift the laps leave (loops to places of
//! the same track move the map only for 20 cm or more: `loops::HELD_MIN_CORRECTION_M`). Cost per
//! frame is not measured here (the host does not count instructions): the instruction budgets are
//! `cargo xtask budgets`' (QEMU), on 7-Scenes and the fast demo.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use ferroslam_core::config::capacity::{BOARD_STORE_FLASH_BYTES, MAX_KEYFRAMES, MAX_LANDMARKS};
use ferroslam_core::frame::{FrameSource, RgbdFrame};
use ferroslam_core::geometry::{PinholeCamera, align_rigid};
use ferroslam_core::image::ImageError;
use ferroslam_core::loops::{INDEXED_RECORDS, PlaceMemory};
use ferroslam_core::persist::{FlashStore, SliceFlash};
use ferroslam_core::wire::{Message, PoseFlags, TrackingState};
use ferroslam_firmware::pipeline::Pipeline;
use ferroslam_sim::frame::{OwnedFrame, halve_frame};
use ferroslam_sim::serial::decode_capture;
use ferroslam_sim::trajectory::Trajectory;
use nalgebra::{Isometry3, Point3};
use serde_json::json;

use crate::faults::{Board, seven_scenes};

/// Frames of the soak by default (CI's run).
const DEFAULT_FRAMES: usize = 5_000;

/// A recording played in laps, timestamps continuing 1/30 s apart.
struct Laps<'a> {
    frames: &'a [OwnedFrame],
    /// Frames to give in all.
    total: usize,
    next: usize,
}

impl Laps<'_> {
    /// Seconds one lap takes, its last frame to the next lap's first included.
    fn lap_s(&self) -> f64 {
        let first = self.frames.first().map_or(0.0, |f| f.timestamp_s);
        let last = self.frames.last().map_or(0.0, |f| f.timestamp_s);
        last - first + 1.0 / 30.0
    }
}

impl FrameSource for Laps<'_> {
    type Error = ImageError;

    fn next_frame(&mut self) -> Result<Option<RgbdFrame<'_>>, ImageError> {
        if self.next >= self.total || self.frames.is_empty() {
            return Ok(None);
        }
        let (lap, i) = (self.next / self.frames.len(), self.next % self.frames.len());
        self.next += 1;
        let offset = lap as f64 * self.lap_s();
        let Some(f) = self.frames.get(i) else { return Ok(None) };
        let mut view = f.view()?;
        view.timestamp_s += offset;
        Ok(Some(view))
    }
}

/// One lap's figures.
#[derive(Debug, Clone, Default)]
struct Lap {
    frames: usize,
    poses: usize,
    lost: usize,
    /// Lost frames before the lap's first tracked frame (the camera carried back).
    lost_at_start: usize,
    relocalized: usize,
    loops: usize,
    map_keyframes: usize,
    map_landmarks: usize,
    store_held: usize,
    remembered: u32,
    thinned: u32,
    store_errors: u32,
    /// Position error of the lap's poses after the first lap's SE(3) alignment to the ground
    /// truth (drift the laps did not take out), RMSE and largest over frames reported tracked,
    /// metres.
    rmse_m: f64,
    worst_tracked_m: f64,
    seconds: f64,
}

/// A recording to soak: its frames at QVGA, the camera, and each frame's ground truth
/// (camera to world).
struct Soaked {
    name: &'static str,
    frames: Vec<OwnedFrame>,
    cam: PinholeCamera,
    truth: Vec<Isometry3<f64>>,
}

/// `poses` (camera to world, one per frame of a lap) against `truth` under `align`
/// (`T_gt_est`): RMSE, and the largest error among frames `tracked` says were tracked.
fn lap_errors(
    poses: &[(Isometry3<f64>, bool)],
    truth: &[Isometry3<f64>],
    align: &Isometry3<f64>,
) -> (f64, f64) {
    let errors: Vec<(f64, bool)> = poses
        .iter()
        .zip(truth)
        .map(|((p, tracked), g)| {
            (((align * p).translation.vector - g.translation.vector).norm(), *tracked)
        })
        .collect();
    let n = errors.len().max(1) as f64;
    let rmse = (errors.iter().map(|(e, _)| e * e).sum::<f64>() / n).sqrt();
    let worst = errors.iter().filter(|(_, t)| *t).map(|(e, _)| *e).fold(0.0, f64::max);
    (rmse, worst)
}

/// `T_gt_est` aligning the first lap's `poses` to `truth`: the camera centres aligned by SE(3)
/// without scale, as `evaluate` (evo) aligns them.
fn first_lap_alignment(
    poses: &[(Isometry3<f64>, bool)],
    truth: &[Isometry3<f64>],
) -> Result<Isometry3<f64>> {
    let centre = |t: &Isometry3<f64>| Point3::from(t.translation.vector);
    let est: Vec<Point3<f64>> = poses.iter().map(|(p, _)| centre(p)).collect();
    let gt: Vec<Point3<f64>> = truth.iter().map(centre).collect();
    align_rigid(&est, &gt).map_err(|e| anyhow!("aligning the first lap: {e:?}"))
}

/// Soaks one recording (see the module documentation); returns the laps.
fn soak(rec: &Soaked, total: usize) -> Result<Vec<Lap>> {
    let (name, frames, cam) = (rec.name, &rec.frames[..], &rec.cam);
    let mut region = vec![0xFF; BOARD_STORE_FLASH_BYTES];
    let mut board = Board::new(&mut region, (0, 0))?;
    let mut source = Laps { frames, total, next: 0 };
    let mut laps = Vec::new();
    let mut lap = Lap::default();
    let mut started = Instant::now();
    let mut align: Option<Isometry3<f64>> = None;
    let mut poses: Vec<(Isometry3<f64>, bool)> = Vec::new();
    loop {
        let end = !board.step(&mut source, cam)?;
        if !end {
            lap.frames += 1;
        }
        if (end || lap.frames == frames.len()) && lap.frames > 0 {
            let capture = decode_capture(board.sink.get_mut());
            if capture.stats.frames_dropped > 0 {
                bail!("{name}: the link dropped {} frames", capture.stats.frames_dropped);
            }
            poses.clear();
            for m in &capture.messages {
                let Message::Pose(p) = m else { continue };
                poses.push((p.t_wc().cast::<f64>(), p.state == TrackingState::Tracking));
                if p.state == TrackingState::Lost {
                    lap.lost += 1;
                    if lap.lost == poses.len() {
                        lap.lost_at_start += 1;
                    }
                }
                lap.relocalized += usize::from(p.flags.contains(PoseFlags::RELOCALIZED));
                lap.loops += usize::from(p.flags.contains(PoseFlags::LOOP_CLOSED));
            }
            board.sink.get_mut().clear();
            lap.poses = poses.len();
            let truth = &rec.truth[..poses.len().min(rec.truth.len())];
            let align = match align {
                Some(a) => a,
                None => *align.insert(first_lap_alignment(&poses, truth)?),
            };
            (lap.rmse_m, lap.worst_tracked_m) = lap_errors(&poses, truth, &align);
            let (map, places) = (board.pipeline.slam().map(), &board.places);
            let stats = places.stats();
            lap.map_keyframes = map.num_keyframes();
            lap.map_landmarks = map.num_landmarks();
            lap.store_held = places.len();
            lap.remembered = stats.remembered;
            lap.thinned = stats.thinned;
            lap.store_errors = stats.store_errors;
            lap.seconds = started.elapsed().as_secs_f64();
            print_lap(name, laps.len(), &lap);
            laps.push(std::mem::take(&mut lap));
            started = Instant::now();
        }
        if end {
            break;
        }
    }
    Ok(laps)
}

fn print_lap(name: &str, n: usize, l: &Lap) {
    eprintln!(
        "| {name} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.4} | {:.4} | \
         {:.1} |",
        n + 1,
        l.frames,
        l.poses,
        l.lost,
        l.lost_at_start,
        l.relocalized,
        l.loops,
        l.map_keyframes,
        l.map_landmarks,
        l.store_held,
        l.remembered,
        l.thinned,
        l.rmse_m,
        l.worst_tracked_m,
        l.seconds
    );
}

/// The soak's bars on `laps` of one recording (see the module documentation).
fn check(name: &str, laps: &[Lap]) -> Vec<String> {
    let mut problems = Vec::new();
    for (n, l) in laps.iter().enumerate().skip(1) {
        let lap = n + 1;
        if l.lost_at_start > 0 && l.relocalized + l.loops == 0 {
            problems.push(format!(
                "{name} lap {lap}: lost at the return, then neither relocalized nor loop-closed"
            ));
        }
        if l.lost > l.lost_at_start {
            problems.push(format!(
                "{name} lap {lap}: {} frames lost after the camera was placed again",
                l.lost - l.lost_at_start
            ));
        }
    }
    for (n, l) in laps.iter().enumerate() {
        if l.poses != l.frames {
            problems.push(format!(
                "{name} lap {}: {} poses of {} frames",
                n + 1,
                l.poses,
                l.frames
            ));
        }
        if l.map_keyframes > MAX_KEYFRAMES || l.map_landmarks > MAX_LANDMARKS {
            problems.push(format!("{name} lap {}: the map is over its capacity", n + 1));
        }
        if l.store_errors > 0 {
            problems.push(format!("{name} lap {}: {} store errors", n + 1, l.store_errors));
        }
    }
    let capacity = INDEXED_RECORDS;
    for w in laps.windows(2) {
        if w[1].store_held < w[0].store_held || w[1].store_held > capacity {
            problems.push(format!(
                "{name}: the place memory's records went from {} to {} (capacity {capacity})",
                w[0].store_held, w[1].store_held
            ));
        }
    }
    problems
}

/// Options of `cargo xtask soak`.
struct Options {
    frames: usize,
    demo: bool,
    seven_scenes: bool,
    json: Option<PathBuf>,
}

fn parse(args: &[String]) -> Result<Options> {
    let mut o = Options { frames: DEFAULT_FRAMES, demo: true, seven_scenes: true, json: None };
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = || it.next().with_context(|| format!("{a} needs a value"));
        match a.as_str() {
            "--frames" => o.frames = value()?.parse().context("--frames: a count of frames")?,
            "--recording" => match value()?.as_str() {
                "demo" => o.seven_scenes = false,
                "7scenes" => o.demo = false,
                "both" => {}
                other => bail!("--recording {other}: demo, 7scenes or both"),
            },
            "--json" => o.json = Some(PathBuf::from(value()?)),
            other => bail!(
                "soak: unknown option {other} (--frames N, --recording demo|7scenes|both, \
                 --json FILE)"
            ),
        }
    }
    if o.frames == 0 {
        bail!("--frames must be at least 1");
    }
    Ok(o)
}

/// The demo's 300 frames at QVGA, its camera and ground truth.
fn demo() -> Result<Soaked> {
    let (mut source, cam, truth) = ferroslam_tests::demo_frames::demo_frames((0..300).collect());
    let mut frames = Vec::new();
    while let Some(f) = source.next_frame()? {
        frames.push(halve_frame(&f, 0)?);
    }
    let truth = truth.iter().map(|t| t.cast::<f64>()).collect();
    Ok(Soaked { name: "demo", frames, cam, truth })
}

/// The pose of `truth` nearest `timestamp_s`, within 0.02 s.
fn nearest(truth: &Trajectory, timestamp_s: f64) -> Option<Isometry3<f64>> {
    truth
        .poses
        .iter()
        .min_by(|a, b| {
            (a.timestamp_s - timestamp_s).abs().total_cmp(&(b.timestamp_s - timestamp_s).abs())
        })
        .filter(|p| (p.timestamp_s - timestamp_s).abs() < 0.02)
        .map(|p| p.t_wc)
}

/// Runs `cargo xtask soak` (see the module documentation).
///
/// # Errors
/// Bad options, a recording that cannot be read, or a bar missed.
pub fn run(args: &[String]) -> Result<()> {
    let o = parse(args)?;
    let started = Instant::now();
    let mut recordings = Vec::new();
    if o.demo {
        recordings.push(demo()?);
    }
    if o.seven_scenes {
        let rec = seven_scenes("0-999")?;
        let truth = rec
            .frames
            .iter()
            .map(|f| nearest(&rec.truth, f.timestamp_s))
            .collect::<Option<Vec<_>>>()
            .context("7-Scenes: a frame without ground truth within 0.02 s")?;
        recordings.push(Soaked { name: "7-Scenes", frames: rec.frames, cam: rec.cam, truth });
    }
    eprintln!(
        "soak: {} frames of each recording, in laps ({:.1} s to load); state {} B (pipeline {} \
         B, place memory {} B)",
        o.frames,
        started.elapsed().as_secs_f64(),
        std::mem::size_of::<Pipeline>() + std::mem::size_of::<BoardPlaces>(),
        std::mem::size_of::<Pipeline>(),
        std::mem::size_of::<BoardPlaces>(),
    );
    eprintln!(
        "| recording | lap | frames | poses | lost | lost at start | relocalized | loops | map \
         keyframes | map landmarks | records held | remembered | thinned | error RMSE m | worst tracked m | s |"
    );
    eprintln!(
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- \
         | --- |"
    );
    let mut problems = Vec::new();
    let mut report = Vec::new();
    for rec in &recordings {
        let (name, laps) = (rec.name, soak(rec, o.frames)?);
        problems.extend(check(name, &laps));
        if let (Some(first), Some(last)) = (laps.first(), laps.last()) {
            let most = laps.iter().map(|l| l.worst_tracked_m).fold(0.0, f64::max);
            eprintln!(
                "soak: {name}: {} laps; error RMSE (first lap's alignment) {:.4} m in the first \
                 lap, {:.4} m in the last; largest error of a frame reported tracked {most:.4} m; \
                 {} records held, {} thinned",
                laps.len(),
                first.rmse_m,
                last.rmse_m,
                last.store_held,
                last.thinned
            );
        }
        report.push(json!({
            "recording": name,
            "frames": o.frames,
            "laps": laps.iter().map(|l| json!({
                "frames": l.frames, "poses": l.poses, "lost": l.lost,
                "lost_at_start": l.lost_at_start, "relocalized": l.relocalized, "loops": l.loops,
                "map_keyframes": l.map_keyframes, "map_landmarks": l.map_landmarks,
                "records_held": l.store_held, "remembered": l.remembered, "thinned": l.thinned,
                "error_rmse_m": l.rmse_m, "worst_tracked_error_m": l.worst_tracked_m,
            })).collect::<Vec<_>>(),
        }));
    }
    if let Some(path) = &o.json {
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        std::fs::write(path, serde_json::to_string_pretty(&report)?)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    eprintln!("soak: done in {:.0} s", started.elapsed().as_secs_f64());
    if !problems.is_empty() {
        for p in &problems {
            eprintln!("soak: {p}");
        }
        bail!("the soak missed {} bars", problems.len());
    }
    Ok(())
}

/// The board's place memory type.
type BoardPlaces = PlaceMemory<FlashStore<SliceFlash<'static>>>;
