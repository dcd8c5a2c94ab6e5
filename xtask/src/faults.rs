//! `cargo xtask faults`: the board's pipeline on real frames (7-Scenes at QVGA) with each fault
//! injected at two rates, measured against the clean run (issue 50's fault-injection bar).
//!
//! ```text
//! cargo xtask faults [--frames A-B,C-D,...] [--rates P,Q] [--seed S] [--strict] [--json FILE]
//!                    [--out DIR]
//! ```
//!
//! The frames played are 7-Scenes' 1000, then frames 100-399 again (the camera carried back to a
//! place it has seen; `--frames` as `replay --frames`). Every run is
//! `ferroslam_firmware::pipeline::run_frame` (the board's code) over the frames, with
//! the board's place memory (a `FlashStore` on a 512 KiB flash region) and its serial link; the
//! poses are those the host decodes from the link's bytes. Faults hit frames in the span
//! [`SPAN`] (input frames 100 to 699) at each rate (percent of frames, default 1 and 10); the
//! frames after it are clean, so a run shows whether tracking resumes. The faults:
//! - each [`FrameFault`] on the frame source (`ferroslam_sim::faults::FaultySource`; a frame of
//!   another scene is one of the demo's rooms);
//! - each [`LinkFault`] on the receiver's side of the link (`ferroslam_firmware::faulty_link`),
//!   over the clean run's bytes;
//! - bit flips on reads of the place store's flash (`ferroslam_core::persist::FlipFlash`), at
//!   that share of reads over the whole run.
//!
//! Each run must: not panic; give the fault's documented state (see `docs/reliability.md` and
//! [`check_state`]); after the span, track every frame the clean run tracks (lost frames in the
//! tail no more than the clean run's); and keep ATE (all poses received, SE(3)-aligned as evo)
//! within [`ATE_TOLERANCE_M`] of the clean run's. The command prints one row per run and fails
//! when a run misses a bar; the ATE bar only with `--strict`, as it is not met in every run (a
//! few frames taken out or perturbed move a SLAM run's ATE by about as much: see
//! `docs/reliability.md`).

use std::ops::Range;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use embedded_io::Read;
use ferroslam_core::config::capacity::BOARD_STORE_FLASH_BYTES;
use ferroslam_core::frame::{FrameSource, RgbdFrame};
use ferroslam_core::geometry::PinholeCamera;
use ferroslam_core::image::ImageError;
use ferroslam_core::loops::PlaceMemory;
use ferroslam_core::persist::{FlashStore, FlipFlash, SliceFlash};
use ferroslam_core::system::SLAM_FRONTEND;
use ferroslam_core::wire::{FaultCode, Message, PoseFlags, PoseMessage, TickUnit, TrackingState};
use ferroslam_firmware::commands::NoCommands;
use ferroslam_firmware::faulty_link::{FaultyLink, LinkFault, LinkPlan};
use ferroslam_firmware::pipeline::{FrameOutcome, Link, Pipeline, TickClock, run_frame};
use ferroslam_sim::dataset::{CalibrationSource, Dataset, DatasetOptions};
use ferroslam_sim::eval::evaluate;
use ferroslam_sim::faults::{FaultPlan, FaultySource, FrameFault};
use ferroslam_sim::frame::{OwnedFrame, halve_frame};
use ferroslam_sim::serial::{WireWriter, decode_capture};
use ferroslam_sim::trajectory::{StampedPose, Trajectory};
use serde_json::json;

use crate::paths::{SEVEN_SCENES, SEVEN_SCENES_CALIBRATION, root};

/// Input frames faults may hit; the frames after it are clean.
pub const SPAN: Range<usize> = 100..700;

/// How far a faulted run's ATE may be from the clean run's, metres (issue 50's bar).
pub const ATE_TOLERANCE_M: f64 = 0.01;

/// The frames played by default: 7-Scenes, then carried back to frame 100 (a revisit, so the
/// place memory is read: a relocalization).
const ORDER: &str = "0-999,100-399";

/// The generator seed of every fault plan, unless `--seed` says another.
const SEED: u64 = 50;

/// What `faults` runs on: the frames at QVGA, the camera, the ground truth.
pub struct Recording {
    pub frames: Vec<OwnedFrame>,
    pub cam: PinholeCamera,
    pub truth: Trajectory,
}

/// Frames lent out of a slice, in order.
struct Frames<'a> {
    frames: &'a [OwnedFrame],
    next: usize,
}

impl FrameSource for Frames<'_> {
    type Error = ImageError;

    fn next_frame(&mut self) -> Result<Option<RgbdFrame<'_>>, ImageError> {
        let Some(f) = self.frames.get(self.next) else { return Ok(None) };
        self.next += 1;
        f.view().map(Some)
    }
}

/// `S`, keeping the timestamp of every frame it gives.
struct Stamped<S> {
    inner: S,
    stamps: Vec<f64>,
}

impl<S: FrameSource> FrameSource for Stamped<S> {
    type Error = S::Error;

    fn next_frame(&mut self) -> Result<Option<RgbdFrame<'_>>, S::Error> {
        let frame = self.inner.next_frame()?;
        if let Some(f) = &frame {
            self.stamps.push(f.timestamp_s);
        }
        Ok(frame)
    }
}

/// Frames of `stamps` that do not follow the last frame accepted: what the core rejects.
fn out_of_order(stamps: &[f64]) -> usize {
    let mut last = f64::NEG_INFINITY;
    stamps
        .iter()
        .filter(|&&t| {
            let late = t <= last;
            last = last.max(t);
            late
        })
        .count()
}

/// The pipeline's clock here: one tick a reading (the cost figures are not what is measured).
struct Ticks(u32);

impl TickClock for Ticks {
    const UNIT: TickUnit = TickUnit::CoreCycle;

    fn now(&mut self) -> u32 {
        self.0 = self.0.wrapping_add(1);
        self.0
    }
}

/// One run of the board's pipeline: the link's bytes, the frames delivered, and what the place
/// memory counted.
struct BoardRun {
    bytes: Vec<u8>,
    /// Timestamps of the frames the pipeline was given, in order.
    stamps: Vec<f64>,
    store_errors: u32,
    /// Reads of the place store's flash, and those that flipped a bit.
    store_reads: u64,
    store_flips: u64,
    injected: usize,
}

/// The board's pipeline on the host: the pipeline, its place memory on a flash region (the
/// board's `FlashStore`, its reads flipped as [`FlipFlash`] says), and its serial link into
/// memory.
pub struct Board<'r> {
    pub pipeline: Box<Pipeline>,
    pub places: Box<PlaceMemory<FlashStore<FlipFlash<SliceFlash<'r>>>>>,
    pub sink: WireWriter<Vec<u8>>,
    clock: Ticks,
}

impl<'r> Board<'r> {
    /// A board at the start, its store on `region` (erased: 0xFF), one bit flipped in
    /// `flips.0` of a thousand reads with the seed `flips.1`.
    ///
    /// # Errors
    /// The store cannot be mounted.
    pub fn new(region: &'r mut [u8], flips: (u16, u64)) -> Result<Self> {
        let flash = FlipFlash::new(SliceFlash::new(region), flips.0, flips.1);
        let store = FlashStore::mount(flash).map_err(|e| anyhow!("mounting the store: {e:?}"))?;
        Ok(Self {
            pipeline: Box::new(Pipeline::new()),
            places: Box::new(PlaceMemory::new(store, SLAM_FRONTEND.rng_seed)),
            sink: WireWriter::new(Vec::new()),
            clock: Ticks(0),
        })
    }

    /// One frame of `source` through `run_frame`; `false` when the source has no more.
    ///
    /// # Errors
    /// The link failed (never for a link into memory).
    pub fn step<S: FrameSource>(&mut self, source: &mut S, cam: &PinholeCamera) -> Result<bool> {
        let outcome = run_frame(
            source,
            self.pipeline.as_mut(),
            self.places.as_mut(),
            cam,
            Link { tx: &mut self.sink, rx: &mut NoCommands },
            &mut self.clock,
            |_| 0,
        )
        .map_err(|e| anyhow!("the link: {e:?}"))?;
        Ok(outcome != FrameOutcome::End)
    }
}

/// Runs the board's pipeline over `source`, its place store's reads flipped in `flips.0` of a
/// thousand (seed `flips.1`).
fn run_board<S>(source: S, cam: &PinholeCamera, flips: (u16, u64)) -> Result<(BoardRun, S)>
where
    S: FrameSource,
{
    let mut source = Stamped { inner: source, stamps: Vec::new() };
    let mut region = vec![0xFF; BOARD_STORE_FLASH_BYTES];
    let mut board = Board::new(&mut region, flips)?;
    while board.step(&mut source, cam)? {}
    let flash = board.places.store().flash();
    let run = BoardRun {
        store_errors: board.places.stats().store_errors,
        store_reads: flash.reads(),
        store_flips: flash.flipped(),
        bytes: board.sink.into_inner(),
        stamps: source.stamps,
        injected: 0,
    };
    Ok((run, source.inner))
}

/// A case: what is injected, and at which rate (percent).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Fault {
    Clean,
    Frame(FrameFault),
    Link(LinkFault),
    StoreReadFlip,
}

impl Fault {
    fn name(self) -> String {
        match self {
            Self::Clean => "none".into(),
            Self::Frame(f) => format!("frame: {}", f.name()),
            Self::Link(f) => format!("link: {}", link_name(f)),
            Self::StoreReadFlip => "store: bit flip on read".into(),
        }
    }
}

fn link_name(f: LinkFault) -> &'static str {
    match f {
        LinkFault::DropByte => "byte dropped",
        LinkFault::FlipBit => "bit flipped",
        LinkFault::Truncate => "frame cut short",
    }
}

/// What the host received from one run, and how it compares.
#[derive(Debug, Clone)]
struct Received {
    poses: Vec<PoseMessage>,
    rejected_timestamp: usize,
    rejected_other: usize,
    frames_dropped_by_decoder: u64,
}

fn receive(bytes: &[u8]) -> Received {
    let capture = decode_capture(bytes);
    let mut r = Received {
        poses: Vec::new(),
        rejected_timestamp: 0,
        rejected_other: 0,
        frames_dropped_by_decoder: capture.stats.frames_dropped,
    };
    for m in capture.messages {
        match m {
            Message::Pose(p) => r.poses.push(p),
            Message::Fault(f) if f.code == FaultCode::FrameRejected && f.detail == 2 => {
                r.rejected_timestamp += 1;
            }
            Message::Fault(_) => r.rejected_other += 1,
            _ => {}
        }
    }
    r
}

/// One row of the table.
#[derive(Debug, Clone)]
struct Row {
    fault: String,
    rate_percent: u32,
    injected: usize,
    delivered: usize,
    poses: usize,
    rejected: usize,
    lost: usize,
    lost_in_tail: usize,
    relocalized: usize,
    loops: usize,
    store_errors: u32,
    store_reads: u64,
    ate_m: f64,
    problems: Vec<String>,
    /// The ATE bar's miss, when missed (enforced with `--strict`).
    ate_miss: Option<String>,
}

/// `poses` as a trajectory in time order (a pose sent twice for one time kept once).
fn trajectory(poses: &[PoseMessage]) -> Trajectory {
    let mut est: Vec<StampedPose> = poses
        .iter()
        .map(|p| StampedPose { timestamp_s: p.timestamp_s, t_wc: p.t_wc().cast::<f64>() })
        .collect();
    est.sort_by(|a, b| a.timestamp_s.total_cmp(&b.timestamp_s));
    est.dedup_by(|a, b| a.timestamp_s == b.timestamp_s);
    Trajectory::new(est)
}

/// ATE of `poses` against `truth` (evo's: SE(3) alignment, 0.02 s).
fn ate(poses: &[PoseMessage], truth: &Trajectory) -> Result<f64> {
    Ok(evaluate(truth, &trajectory(poses), 0.02).context("ATE")?.ate.rmse)
}

/// The row of a run, its checks against the clean run's row and poses.
#[allow(clippy::too_many_arguments)]
fn row(
    fault: Fault,
    rate_percent: u32,
    run: &BoardRun,
    received: &Received,
    tail_start_s: f64,
    truth: &Trajectory,
    clean: Option<(&Row, &[PoseMessage])>,
) -> Result<Row> {
    let poses = &received.poses;
    let is_lost = |p: &&PoseMessage| p.state == TrackingState::Lost;
    let mut r = Row {
        fault: fault.name(),
        rate_percent,
        injected: run.injected,
        delivered: run.stamps.len(),
        poses: poses.len(),
        rejected: received.rejected_timestamp + received.rejected_other,
        lost: poses.iter().filter(is_lost).count(),
        lost_in_tail: poses
            .iter()
            .filter(|p| p.timestamp_s >= tail_start_s)
            .filter(is_lost)
            .count(),
        relocalized: poses.iter().filter(|p| p.flags.contains(PoseFlags::RELOCALIZED)).count(),
        loops: poses.iter().filter(|p| p.flags.contains(PoseFlags::LOOP_CLOSED)).count(),
        store_errors: run.store_errors,
        store_reads: run.store_reads,
        ate_m: ate(poses, truth)?,
        problems: Vec::new(),
        ate_miss: None,
    };
    if let Some((clean, clean_poses)) = clean {
        r.problems = check_state(fault, &r, received, &run.stamps, clean_poses);
        if r.lost_in_tail > clean.lost_in_tail {
            r.problems.push(format!(
                "tracking did not resume: {} lost after the faults (clean run {})",
                r.lost_in_tail, clean.lost_in_tail
            ));
        }
        if (r.ate_m - clean.ate_m).abs() > ATE_TOLERANCE_M {
            r.ate_miss = Some(format!(
                "ATE {:.4} m is over {ATE_TOLERANCE_M} m from the clean run's {:.4} m",
                r.ate_m, clean.ate_m
            ));
        }
    }
    Ok(r)
}

/// The documented state of each fault (`docs/reliability.md`): what the run must show.
fn check_state(
    fault: Fault,
    r: &Row,
    rx: &Received,
    stamps: &[f64],
    clean: &[PoseMessage],
) -> Vec<String> {
    let mut problems = Vec::new();
    let mut need = |ok: bool, what: String| {
        if !ok {
            problems.push(what);
        }
    };
    match fault {
        Fault::Clean => {}
        Fault::Frame(_) | Fault::StoreReadFlip => {
            let late = out_of_order(stamps);
            need(
                rx.rejected_timestamp == late && rx.rejected_other == 0,
                format!(
                    "each frame that does not follow the last accepted is rejected (timestamp), \
                     no other: {} and {} rejected, {late} out of order",
                    rx.rejected_timestamp, rx.rejected_other
                ),
            );
            need(
                r.poses + r.rejected == r.delivered,
                format!("every frame accepted gets a pose: {} of {}", r.poses, r.delivered),
            );
        }
        Fault::Link(_) => {
            let mut it = clean.iter();
            need(
                rx.poses.iter().all(|p| it.any(|c| c == p)),
                "a pose decoded that the board did not send".into(),
            );
            need(
                rx.frames_dropped_by_decoder > 0 || r.injected == 0,
                "the frames lost are counted by the decoder".into(),
            );
        }
    }
    if matches!(fault, Fault::Frame(FrameFault::Drop)) {
        need(r.delivered + r.injected == clean.len(), "a dropped frame is simply absent".into());
    }
    problems
}

/// Options of `cargo xtask faults`.
struct Options {
    frames: String,
    rates: Vec<u32>,
    json: Option<PathBuf>,
    /// Where each run's received poses go as a TUM trajectory.
    out: Option<PathBuf>,
    seed: u64,
    /// Fail on the ATE bar too.
    strict: bool,
}

fn parse(args: &[String]) -> Result<Options> {
    let mut o = Options {
        frames: ORDER.to_owned(),
        rates: vec![1, 10],
        json: None,
        out: None,
        seed: SEED,
        strict: false,
    };
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = || it.next().with_context(|| format!("{a} needs a value"));
        match a.as_str() {
            "--frames" => value()?.clone_into(&mut o.frames),
            "--rates" => {
                o.rates = value()?
                    .split(',')
                    .map(|r| r.trim().parse::<u32>().context("--rates: percents, e.g. 1,10"))
                    .collect::<Result<_>>()?;
            }
            "--json" => o.json = Some(PathBuf::from(value()?)),
            "--out" => o.out = Some(PathBuf::from(value()?)),
            "--seed" => o.seed = value()?.parse().context("--seed")?,
            "--strict" => o.strict = true,
            other => {
                bail!(
                    "faults: unknown option {other} (--frames A-B,..., --rates P,Q, --seed S, --strict, --json FILE, --out DIR)"
                )
            }
        }
    }
    if o.rates.iter().any(|&r| r > 100) {
        bail!("--rates are percents, at most 100");
    }
    Ok(o)
}

/// 7-Scenes' frames in the order `order` gives (as `replay --frames`), at QVGA as the board takes
/// them.
pub fn seven_scenes(order: &str) -> Result<Recording> {
    let dir = root().join(SEVEN_SCENES);
    let opts = DatasetOptions {
        calibration: CalibrationSource::Path(root().join(SEVEN_SCENES_CALIBRATION)),
        frames: Some(order.parse().with_context(|| format!("--frames {order}"))?),
        ..DatasetOptions::default()
    };
    let dataset = Dataset::open(&dir, &opts).with_context(|| format!("{}", dir.display()))?;
    let c = dataset.calibration();
    let cam = PinholeCamera::new(c.fx, c.fy, c.cx, c.cy, c.width as usize, c.height as usize)
        .map_err(|e| anyhow!("the camera: {e:?}"))?;
    let truth = dataset.groundtruth_trajectory().cloned().context("7-Scenes' ground truth")?;
    let mut reader = dataset.into_reader(4);
    let mut frames = Vec::new();
    while let Some(f) = reader.next_owned()? {
        frames.push(f);
    }
    Ok(Recording { frames, cam, truth })
}

/// Frames of another scene at the board's size: the demo's room, every 25th frame.
fn foreign_frames() -> Result<Vec<OwnedFrame>> {
    let (mut source, _, _) =
        ferroslam_tests::demo_frames::demo_frames((0..300).step_by(25).collect());
    let mut out = Vec::new();
    while let Some(f) = source.next_frame()? {
        out.push(halve_frame(&f, 0)?);
    }
    Ok(out)
}

/// Runs `cargo xtask faults` (see the module documentation).
///
/// # Errors
/// Bad options, a recording that cannot be read, or a run that misses a bar.
pub fn run(args: &[String]) -> Result<()> {
    let o = parse(args)?;
    let started = Instant::now();
    let rec = seven_scenes(&o.frames)?;
    if rec.frames.len() <= SPAN.end {
        bail!("--frames must give over {} frames (the faults' span ends there)", SPAN.end);
    }
    let foreign = foreign_frames()?;
    let tail_start_s = rec.frames.get(SPAN.end).map_or(f64::INFINITY, |f| f.timestamp_s);
    eprintln!(
        "faults: 7-Scenes frames {} at QVGA, faults in frames {}-{} played ({:.1} s to load)",
        o.frames,
        SPAN.start,
        SPAN.end - 1,
        started.elapsed().as_secs_f64()
    );
    let (clean_run, _) = run_board(Frames { frames: &rec.frames, next: 0 }, &rec.cam, (0, 0))?;
    let clean_rx = receive(&clean_run.bytes);
    if let Some(dir) = &o.out {
        std::fs::create_dir_all(dir)?;
        rec.truth.write_tum(&dir.join("groundtruth.txt"))?;
        trajectory(&clean_rx.poses).write_tum(&dir.join("none-0.txt"))?;
    }
    let clean = row(Fault::Clean, 0, &clean_run, &clean_rx, tail_start_s, &rec.truth, None)?;
    let mut rows = vec![clean.clone()];
    print_header();
    print_row(&clean);
    let mut cases: Vec<(Fault, u32)> = Vec::new();
    for &rate in &o.rates {
        cases.extend(FrameFault::ALL.iter().map(|&f| (Fault::Frame(f), rate)));
        cases.extend(
            [LinkFault::DropByte, LinkFault::FlipBit, LinkFault::Truncate]
                .iter()
                .map(|&f| (Fault::Link(f), rate)),
        );
        cases.push((Fault::StoreReadFlip, rate));
    }
    for (fault, rate) in cases {
        let run = match fault {
            Fault::Frame(f) => {
                let plan =
                    FaultPlan { fault: f, rate: f64::from(rate) / 100.0, span: SPAN, seed: o.seed };
                let source = FaultySource::new(
                    Frames { frames: &rec.frames, next: 0 },
                    plan,
                    foreign.clone(),
                );
                let (mut run, source) = run_board(source, &rec.cam, (0, 0))?;
                run.injected = source.injected().len();
                run
            }
            Fault::Link(f) => {
                let plan = LinkPlan { fault: f, per_mille: (rate * 10) as u16, seed: o.seed };
                let mut link = FaultyLink::new(&clean_run.bytes[..], plan);
                let mut bytes = Vec::new();
                let mut chunk = [0u8; 256];
                loop {
                    let n = link.read(&mut chunk).map_err(|e| anyhow!("{e:?}"))?;
                    if n == 0 {
                        break;
                    }
                    bytes.extend_from_slice(&chunk[..n]);
                }
                BoardRun {
                    bytes,
                    stamps: clean_run.stamps.clone(),
                    injected: link.hit() as usize,
                    ..clean_run
                }
            }
            Fault::StoreReadFlip => {
                let source = Frames { frames: &rec.frames, next: 0 };
                let (mut run, _) = run_board(source, &rec.cam, ((rate * 10) as u16, o.seed))?;
                run.injected = run.store_flips as usize;
                run
            }
            Fault::Clean => continue,
        };
        let rx = receive(&run.bytes);
        if let Some(dir) = &o.out {
            let name = format!("{}-{rate}.txt", fault.name().replace([':', ' '], "-"));
            trajectory(&rx.poses).write_tum(&dir.join(name))?;
        }
        let r =
            row(fault, rate, &run, &rx, tail_start_s, &rec.truth, Some((&clean, &clean_rx.poses)))?;
        print_row(&r);
        rows.push(r);
    }
    if let Some(path) = &o.json {
        write_json(path, &rows)?;
    }
    let ate_missed = rows.iter().filter(|r| r.ate_miss.is_some()).count();
    eprintln!(
        "faults: {} runs in {:.0} s; the ATE bar (within {ATE_TOLERANCE_M} m of the clean run) \
         met by {} of {}{}",
        rows.len(),
        started.elapsed().as_secs_f64(),
        rows.len() - 1 - ate_missed,
        rows.len() - 1,
        if o.strict { "" } else { " (not enforced without --strict)" }
    );
    let failed: Vec<&Row> = rows
        .iter()
        .filter(|r| !r.problems.is_empty() || (o.strict && r.ate_miss.is_some()))
        .collect();
    if !failed.is_empty() {
        for r in &failed {
            let all: Vec<&String> = r.problems.iter().chain(&r.ate_miss).collect();
            eprintln!("{} at {}%: {all:?}", r.fault, r.rate_percent);
        }
        bail!("{} of {} fault runs missed a bar", failed.len(), rows.len() - 1);
    }
    Ok(())
}

fn print_header() {
    eprintln!(
        "| fault | rate | injected | frames in | poses | rejected | lost | lost after | reloc. | \
         loops | store reads | store errors | ATE m | bars |"
    );
    eprintln!(
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
}

fn print_row(r: &Row) {
    eprintln!(
        "| {} | {}% | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.4} | {} |",
        r.fault,
        r.rate_percent,
        r.injected,
        r.delivered,
        r.poses,
        r.rejected,
        r.lost,
        r.lost_in_tail,
        r.relocalized,
        r.loops,
        r.store_reads,
        r.store_errors,
        r.ate_m,
        if r.problems.is_empty() && r.ate_miss.is_none() {
            "met".to_owned()
        } else {
            r.problems.iter().chain(&r.ate_miss).cloned().collect::<Vec<_>>().join("; ")
        }
    );
}

fn write_json(path: &std::path::Path, rows: &[Row]) -> Result<()> {
    let rows: Vec<_> = rows
        .iter()
        .map(|r| {
            json!({
                "fault": r.fault,
                "rate_percent": r.rate_percent,
                "injected": r.injected,
                "frames_delivered": r.delivered,
                "poses": r.poses,
                "rejected": r.rejected,
                "lost": r.lost,
                "lost_after_faults": r.lost_in_tail,
                "relocalized": r.relocalized,
                "loops": r.loops,
                "store_reads": r.store_reads,
                "store_errors": r.store_errors,
                "ate_rmse_m": r.ate_m,
                "problems": r.problems,
                "ate_bar_missed": r.ate_miss,
            })
        })
        .collect();
    let report = json!({ "span": [SPAN.start, SPAN.end], "runs": rows });
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(path, serde_json::to_string_pretty(&report)?)
        .with_context(|| format!("writing {}", path.display()))
}
