//! SLAM mode of `replay` and `demo`: the core's [`Slam`] facade with a fixed back-end quota per
//! frame, the back end on its own thread beside the front end ([`Schedule`]; deterministic unless
//! realtime), and the trajectory composed the way ORB-SLAM writes
//! `CameraTrajectory.txt`: each frame's pose relative to its reference keyframe at the time it was
//! tracked, composed with that keyframe's final pose.

use std::collections::HashMap;

use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{Context, Result, anyhow, bail};
use clap::ValueEnum;
use nalgebra::Point3;

use ferroslam_core::ar::PlaneParams;
use ferroslam_core::backend::{BackendError, BackendParams, BackendStatus};
use ferroslam_core::config::capacity::BOARD_STORE_KEYFRAMES;
use ferroslam_core::frame::{FrameSource, RgbdFrame};
use ferroslam_core::geometry::{PinholeCamera, Pose};
use ferroslam_core::loops::PlaceMemory;
use ferroslam_core::map::{KeyFrameId, Map, RamStore};
use ferroslam_core::system::{
    Adjuster, DEFAULT_DRAIN_STEPS, MapAccess, ProfileTypes, Slam, Tracker,
};
use ferroslam_core::tracking::{
    FrameResult, FrontendParams, FrontendState, LoopClosure, NoPlaces, PlaceQuery, Places,
};

use super::MapFiles;
use super::ar::{ArFrame, ArPlan, ArRecorder, OnlineAnchors};
use super::data_path::{Progress, drive};
use super::map_points::MapPoints;
use super::planes::KeyframePlanes;
use super::result::{
    BackendReport, LoadedMap, PlacesReport, TrackedFrame, TrackingRun, frame_figures,
};
use crate::trajectory::{StampedPose, Trajectory};

/// A map of more than this many keyframes is a large one, where issue 4 (after the paper) wants
/// the local window to average 50-65 keyframes.
pub const LARGE_MAP_KEYFRAMES: usize = 120;

/// Work units per slice of the back-end thread in [`Schedule::Realtime`].
const REALTIME_SLICE: u32 = 500;

/// How the back end runs beside the front end.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ValueEnum)]
pub enum Schedule {
    /// The back end on its own thread, advancing its solve by the quota while the front end
    /// tracks the next frame. The result is the same bits as [`Schedule::Sequential`] (and as the
    /// firmware): a solve step reads no map, so it can overlap the next frame's tracking; when the
    /// step finishes a solve, whose result the next frame must see, the front end's state is
    /// restored from a copy taken before the frame and the frame is tracked again after the
    /// write-back. A step that builds a problem (it reads the map) runs alone.
    #[default]
    #[value(help = "The back end on its own thread, with the fixed quota per frame: the same \
                    bits as `sequential` (deterministic)")]
    Threaded,
    /// One thread: front end, then the back-end step, frame after frame (as on the firmware).
    #[value(help = "Front end, then the back-end step, on one thread (as on the firmware)")]
    Sequential,
    /// The back end on its own thread, solving in slices of 500 units for as long as the front end
    /// tracks a frame (at least one slice); a finished solve is written to the map after the
    /// frame. The quota is not used, and the result depends on thread timing: not deterministic.
    #[value(help = "The back end on its own thread, solving for as long as the front end \
                    tracks each frame; the quota is not used. Not deterministic")]
    Realtime,
}

impl Schedule {
    /// The schedule's name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Threaded => "threaded",
            Self::Sequential => "sequential",
            Self::Realtime => "realtime",
        }
    }
}

/// The capacities of the SLAM system's map and back end.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ValueEnum)]
pub enum MapScale {
    /// The reference board's (`BoardMap`, `BoardBackend`): what the firmware runs, bit for bit.
    #[default]
    #[value(help = "The reference board's: 32 keyframes, 1,024 landmarks, a bundle adjuster of \
                    32 keyframes (what the firmware runs, bit for bit)")]
    Board,
    /// Host-scale (`HostMap`, `HostBackend`): room for the paper's local window of 50-65
    /// keyframes in a map of over 120; not what the board runs.
    #[value(help = "Host-scale: 256 keyframes, 16,384 landmarks, a bundle adjuster of 96 \
                    keyframes, so that the local window can reach 65 (not the board's)")]
    Host,
}

impl MapScale {
    /// The scale's name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Board => "board",
            Self::Host => "host",
        }
    }
}

/// One frame's pose relative to its reference keyframe (`None`: the frame had none; the pose is
/// then absolute).
struct Relative {
    timestamp_s: f64,
    keyframe: Option<KeyFrameId>,
    pose: Pose,
}

/// The back-end step owed for the previous frame, then the front end on `frame`, under
/// `schedule`; keyframe poses are recorded after the step.
struct Stepper<'a, P: ProfileTypes> {
    slam: &'a mut Slam<P>,
    /// The place memory, when the run has one.
    places: &'a mut RunPlaces,
    cam: &'a PinholeCamera,
    quota: u32,
    schedule: Schedule,
    record: &'a mut Record,
    /// Whether a frame was tracked whose back-end step has not run yet.
    owed: bool,
}

impl<P: ProfileTypes> Stepper<'_, P> {
    /// The back-end step alone.
    fn step(&mut self) -> Result<BackendStatus> {
        let status = self.slam.step_backend(self.cam, self.quota).map_err(backend_error)?;
        // The place memory's pending store write, after the step as on the board.
        self.places.flush();
        self.record.update(self.slam);
        Ok(status)
    }

    /// The step owed for the previous frame (none before the first), then the front end on
    /// `frame`; the step is then owed for this frame. The step runs beside the front end when the
    /// schedule and the core allow it ([`Slam::overlap`]).
    fn step_then_track(&mut self, frame: &RgbdFrame<'_>) -> Result<FrameResult> {
        if std::mem::replace(&mut self.owed, true) {
            // A solve step leaves the map as the previous frame left it: recorded now.
            self.record.update(self.slam);
            let tracked = match self.schedule {
                Schedule::Threaded => self.track_beside_solve(frame)?,
                Schedule::Realtime => self.track_beside_realtime_solve(frame)?,
                Schedule::Sequential => None,
            };
            if let Some(result) = tracked {
                self.record.steps_beside_tracking += 1;
                return Ok(result);
            }
            self.step()?;
        }
        Ok(self.slam.process_with(frame, self.cam, self.places)?)
    }

    /// [`Schedule::Threaded`]: the front end on `frame` with the owed solve step on another
    /// thread, when that step cannot finish its solve (the same bits as running them in turn);
    /// `None` when it could, or no solve is under way.
    fn track_beside_solve(&mut self, frame: &RgbdFrame<'_>) -> Result<Option<FrameResult>> {
        let (cam, quota) = (self.cam, self.quota);
        let Some((mut track, mut solve)) = self.slam.overlap(quota) else {
            return Ok(None);
        };
        let places = &mut *self.places;
        let (solved, tracked) = std::thread::scope(|scope| {
            let solver = scope.spawn(move || solve.advance(quota));
            let tracked = track.process_with(frame, cam, places);
            (solver.join(), tracked)
        });
        if solve_finished(solved)? {
            bail!("a back-end step that could not finish its solve finished it");
        }
        Ok(Some(tracked?))
    }

    /// [`Schedule::Realtime`]: the front end on `frame` with the solve under way advancing in
    /// slices on another thread for as long as the front end tracks (at least one slice); a solve
    /// it finishes is written to the map by the next frame's step. `None` when no solve is under
    /// way.
    fn track_beside_realtime_solve(
        &mut self,
        frame: &RgbdFrame<'_>,
    ) -> Result<Option<FrameResult>> {
        let cam = self.cam;
        let Some((mut track, mut solve)) = self.slam.overlap_any() else {
            return Ok(None);
        };
        let places = &mut *self.places;
        let tracking = AtomicBool::new(true);
        let (solved, tracked) = std::thread::scope(|scope| {
            let solver = scope.spawn(|| {
                loop {
                    match solve.advance(REALTIME_SLICE) {
                        Ok(false) if tracking.load(Ordering::Acquire) => {}
                        done => return done,
                    }
                }
            });
            let tracked = track.process_with(frame, cam, places);
            tracking.store(false, Ordering::Release);
            (solver.join(), tracked)
        });
        solve_finished(solved)?;
        Ok(Some(tracked?))
    }
}

/// Loads `maps.load` into the run's place memory (frozen when `maps.localize`), and the planes and
/// anchors it holds into `slam`; returns what it held (`None`: no map loaded).
fn load_map<P: ProfileTypes>(
    memory: &mut RunPlaces,
    slam: &mut Slam<P>,
    maps: &MapFiles,
) -> Result<Option<LoadedMap>> {
    let RunPlaces::On(m) = memory else {
        if maps.load.is_some() || maps.save.is_some() || maps.localize {
            bail!("map files need the place memory: drop --no-places");
        }
        return Ok(None);
    };
    let mut loaded = None;
    if let Some(path) = &maps.load {
        let bytes =
            std::fs::read(path).with_context(|| format!("reading map {}", path.display()))?;
        let world =
            m.load(&bytes).map_err(|e| anyhow!("map {}: {e}; nothing loaded", path.display()))?;
        let (planes, anchors) = match &world {
            Some(w) => (w.planes().len(), w.anchors().len()),
            None => (0, 0),
        };
        if let Some(w) = &world {
            slam.restore_world(w);
        }
        eprintln!(
            "map: {} keyframes, {planes} planes and {anchors} anchors loaded from {}",
            m.len(),
            path.display()
        );
        loaded = Some(LoadedMap { keyframes: m.len(), planes, anchors });
    } else if maps.localize {
        bail!("--localize needs a map to localize in (--load-map FILE)");
    }
    m.freeze(maps.localize);
    Ok(loaded)
}

/// Saves the run's place memory to `maps.save`, with the active map's keyframes remembered
/// first (oldest first) unless localizing (the saved map is then the loaded one), and `slam`'s
/// planes and anchors after them.
fn save_map<P: ProfileTypes>(
    memory: &mut RunPlaces,
    slam: &Slam<P>,
    maps: &MapFiles,
) -> Result<()> {
    let (RunPlaces::On(m), Some(path)) = (memory, &maps.save) else { return Ok(()) };
    slam.map().remember_all_in(m.as_mut());
    let world = slam.world();
    let mut file = Vec::new();
    m.save(Some(&world), |b: &[u8]| -> Result<(), std::convert::Infallible> {
        file.extend_from_slice(b);
        Ok(())
    })
    .map_err(|e| anyhow!("saving the map: {e:?}"))?;
    std::fs::write(path, &file).with_context(|| format!("writing map {}", path.display()))?;
    eprintln!(
        "map: {} keyframes, {} planes and {} anchors saved to {} ({} bytes)",
        m.len(),
        world.planes.planes().len(),
        world.anchors.len(),
        path.display(),
        file.len()
    );
    Ok(())
}

/// What the place memory did over a run; the relocalized frames and those that closed a loop by
/// their index in the order played.
fn places_report(
    memory: &HostPlaces,
    loaded: Option<LoadedMap>,
    per_frame: &[TrackedFrame],
) -> PlacesReport {
    let frames = |which: fn(&TrackedFrame) -> bool| -> Vec<usize> {
        per_frame.iter().enumerate().filter(|(_, f)| which(f)).map(|(i, _)| i).collect()
    };
    PlacesReport {
        store_capacity: memory.places_capacity(),
        loaded,
        stored: memory.len(),
        stats: memory.stats(),
        relocalized_frames: frames(|f| f.relocalized),
        loops: memory.loop_stats(),
        loop_frames: frames(|f| f.loop_closed),
    }
}

fn backend_error(e: BackendError) -> anyhow::Error {
    anyhow!("back end: {e}")
}

/// Whether the back-end thread finished its solve.
fn solve_finished(joined: std::thread::Result<Result<bool, BackendError>>) -> Result<bool> {
    joined.map_err(|_| anyhow!("back-end thread panicked"))?.map_err(backend_error)
}

/// How a SLAM run is set up: the back end's quota per frame and schedule, the capacities of the
/// map and back end, and the parameters of both halves.
#[derive(Debug, Clone)]
pub struct Setup {
    /// Back-end work units after each frame.
    pub quota: u32,
    /// How the back end runs beside the front end.
    pub schedule: Schedule,
    /// The capacities of the map and the back end.
    pub scale: MapScale,
    /// The front end's parameters.
    pub frontend: FrontendParams,
    /// The back end's parameters.
    pub backend: BackendParams,
    /// Whether the run remembers keyframes leaving the map and relocalizes in them.
    pub places: bool,
    /// Which virtual objects the run places and draws (`None`: no AR).
    pub ar: Option<ArPlan>,
}

/// The host's place memory: the board's store capacity, in RAM.
pub type HostPlaces = PlaceMemory<RamStore<BOARD_STORE_KEYFRAMES>>;

/// A run's place memory: the host's (boxed: half a megabyte), or none (`--no-places`).
#[derive(Debug)]
enum RunPlaces {
    On(Box<HostPlaces>),
    Off(NoPlaces),
}

impl Places for RunPlaces {
    fn relocalizes(&self) -> bool {
        match self {
            Self::On(m) => m.relocalizes(),
            Self::Off(n) => n.relocalizes(),
        }
    }

    fn holds_places(&self) -> bool {
        match self {
            Self::On(m) => m.holds_places(),
            Self::Off(n) => n.holds_places(),
        }
    }

    fn first_free_seq(&self) -> u32 {
        match self {
            Self::On(m) => m.first_free_seq(),
            Self::Off(n) => n.first_free_seq(),
        }
    }

    fn remember<const K: usize, const L: usize>(&mut self, map: &Map<K, L>, kf: KeyFrameId) {
        match self {
            Self::On(m) => m.remember(map, kf),
            Self::Off(n) => n.remember(map, kf),
        }
    }

    fn flush(&mut self) {
        match self {
            Self::On(m) => m.flush(),
            Self::Off(n) => n.flush(),
        }
    }

    fn relocalize<const K: usize, const L: usize>(
        &mut self,
        query: &PlaceQuery<'_>,
        map: &Map<K, L>,
    ) -> Option<Pose> {
        match self {
            Self::On(m) => m.relocalize(query, map),
            Self::Off(n) => n.relocalize(query, map),
        }
    }

    fn close_loop<const K: usize, const L: usize>(
        &mut self,
        query: &PlaceQuery<'_>,
        map: &Map<K, L>,
        kf: KeyFrameId,
        track_start: u32,
    ) -> Option<LoopClosure> {
        match self {
            Self::On(m) => m.close_loop(query, map, kf, track_start),
            Self::Off(n) => n.close_loop(query, map, kf, track_start),
        }
    }

    fn map_points(&mut self, query: &PlaceQuery<'_>, f: impl FnMut(usize, Point3<f32>)) {
        match self {
            Self::On(m) => m.map_points(query, f),
            Self::Off(n) => n.map_points(query, f),
        }
    }
}

/// Runs `source` through a boxed `Slam<P>` set up by `setup` (`setup.scale` must name `P`'s
/// map: it is what the report says), its place memory loaded from and saved to `maps`.
///
/// # Errors
/// As [`drive`]; a back-end error; a map file that cannot be read, loaded or written, or map
/// files without a place memory.
pub fn run<P: ProfileTypes, S>(
    source: &mut S,
    progress: Progress,
    cam: &PinholeCamera,
    setup: &Setup,
    maps: &MapFiles,
) -> Result<TrackingRun>
where
    S: FrameSource,
    S::Error: std::error::Error + Send + Sync + 'static,
{
    let Setup { quota, schedule, scale, frontend, backend, places, ar } = setup.clone();
    // A megabyte or more.
    let mut slam: Box<Slam<P>> = super::boxed(|| Slam::with_params(frontend, backend));
    // Half a megabyte; its RANSAC seeded as the front end's.
    let mut memory = if places {
        RunPlaces::On(super::boxed(|| PlaceMemory::new(RamStore::new(), frontend.rng_seed)))
    } else {
        RunPlaces::Off(NoPlaces)
    };
    let loaded = load_map(&mut memory, &mut slam, maps)?;
    let (mut online, mut per_frame, mut relative) = (Vec::new(), Vec::new(), Vec::new());
    let mut record = Record::default();
    let plane_params = PlaneParams { sensor: *frontend.sensor(), ..PlaneParams::DEFAULT };
    let mut planes = KeyframePlanes::new(plane_params);
    let mut online_anchors = ar.as_ref().and_then(OnlineAnchors::new);
    let mut anchors = ar.map(|plan| ArRecorder::new(plane_params, plan));
    let (mut points, mut last_keyframe) = (MapPoints::default(), None);
    let mut stepper = Stepper {
        slam: &mut slam,
        places: &mut memory,
        cam,
        quota,
        schedule,
        record: &mut record,
        owed: false,
    };
    let data = drive(source, progress, |frame| {
        let r = stepper.step_then_track(frame)?;
        per_frame.push(frame_figures(frame.timestamp_s, &r));
        if let Some(online) = &mut online_anchors {
            online.frame(per_frame.len() - 1, stepper.slam, (frame, cam, &r));
        }
        if let Some(kf) = r.keyframe {
            planes.observe(kf, frame, cam).map_err(|e| anyhow!("plane detection: {e:?}"))?;
            points.observe(stepper.slam.map().landmarks());
            last_keyframe = Some(kf);
        }
        if r.state == FrontendState::Initializing {
            // No pose before the first keyframe, which defines the world frame.
            return Ok(());
        }
        online.push(StampedPose { timestamp_s: frame.timestamp_s, t_wc: r.t_wc.cast::<f64>() });
        let map = stepper.slam.map();
        let reference = r.reference_keyframe.and_then(|k| map.keyframe(k).map(|kf| (k, kf.t_wc)));
        if let Some(anchors) = &mut anchors {
            let f = ArFrame {
                index: per_frame.len() - 1,
                t_wc: r.t_wc,
                tracked: r.tracked,
                reference: r.reference_keyframe,
                loop_correction: r.loop_closure.map(|l| l.correction),
            };
            anchors.frame(&f, frame, cam, |k| map.keyframe(k).is_some());
        }
        relative.push(match reference {
            Some((k, t_wk)) => Relative {
                timestamp_s: frame.timestamp_s,
                keyframe: Some(k),
                pose: t_wk.inverse() * r.t_wc,
            },
            None => Relative { timestamp_s: frame.timestamp_s, keyframe: None, pose: r.t_wc },
        });
        Ok(())
    })?;
    if stepper.owed {
        stepper.step()?;
    }
    slam.drain_backend(cam, quota, DEFAULT_DRAIN_STEPS).map_err(backend_error)?;
    record.update(&slam);
    points.observe(slam.map().landmarks());
    let map_points = points.finish(last_keyframe, slam.map().landmarks());
    let keyframe_pose = &record.keyframe_pose;
    let camera = relative
        .iter()
        .map(|r| {
            let t_wc = match r.keyframe.and_then(|k| keyframe_pose.get(&k)) {
                Some((_, t_wk)) => t_wk * r.pose,
                None => r.pose,
            };
            StampedPose { timestamp_s: r.timestamp_s, t_wc: t_wc.cast::<f64>() }
        })
        .collect();
    let mut keyframes: Vec<StampedPose> = keyframe_pose
        .values()
        .map(|&(timestamp_s, t_wc)| StampedPose { timestamp_s, t_wc: t_wc.cast::<f64>() })
        .collect();
    keyframes.sort_by(|a, b| a.timestamp_s.total_cmp(&b.timestamp_s));
    let stats = slam.frontend().stats();
    let places = match &memory {
        RunPlaces::On(m) => Some(places_report(m, loaded, &per_frame)),
        RunPlaces::Off(_) => None,
    };
    save_map(&mut memory, &slam, maps)?;
    Ok(TrackingRun {
        data,
        camera: Trajectory::new(camera),
        online: Trajectory::new(online),
        keyframes: Trajectory::new(keyframes),
        per_frame,
        tracked_frames: stats.tracked_frames as usize,
        lost_frames: stats.lost_frames as usize,
        reinitialized_frames: stats.reinitializations as usize,
        relocalized_frames: stats.relocalizations as usize,
        places,
        initializing_frames: stats.initializing_frames as usize,
        state_bytes: std::mem::size_of::<Slam<P>>(),
        backend: Some(backend_report(&slam, &record, quota, schedule, scale)),
        planes: Some(planes.report(&record.keyframe_pose, slam.planes())),
        ar: anchors.and_then(ArRecorder::finish).map(|mut run| {
            run.online = online_anchors.map(|o| o.finish(&slam));
            run
        }),
        map_points: Some(map_points),
    })
}

/// What a run keeps of the map and the back end after every back-end step.
#[derive(Default)]
struct Record {
    /// The latest pose of every keyframe seen: keyframes the map retires keep their last one.
    keyframe_pose: HashMap<KeyFrameId, (f64, Pose)>,
    /// The back end's window histogram (`BackendStats::window_sizes`) at the last update.
    windows_seen: Vec<u32>,
    /// `(window keyframes, map keyframes)` of every local window, in the order built: a window
    /// is built by a step that reads the map and does not change it.
    windows: Vec<(usize, usize)>,
    /// The most keyframes the map held at an update.
    map_keyframes_max: usize,
    /// Back-end steps that ran beside the front end's tracking of a frame.
    steps_beside_tracking: u64,
}

impl Record {
    fn update<P: ProfileTypes>(&mut self, slam: &Slam<P>) {
        for (id, k) in slam.map().keyframes() {
            self.keyframe_pose.insert(id, (k.timestamp_s, k.t_wc));
        }
        let sizes = &slam.backend().stats().window_sizes;
        self.windows_seen.resize(sizes.len(), 0);
        let map_keyframes = slam.map().num_keyframes();
        self.map_keyframes_max = self.map_keyframes_max.max(map_keyframes);
        for (n, (&now, seen)) in sizes.iter().zip(&mut self.windows_seen).enumerate() {
            for _ in *seen..now {
                self.windows.push((n, map_keyframes));
            }
            *seen = now;
        }
    }
}

fn backend_report<P: ProfileTypes>(
    slam: &Slam<P>,
    record: &Record,
    quota: u32,
    schedule: Schedule,
    scale: MapScale,
) -> BackendReport {
    let b = slam.backend().stats();
    let window_sizes: Vec<[u32; 2]> = b
        .window_sizes
        .iter()
        .enumerate()
        .filter(|(_, n)| **n > 0)
        .map(|(size, &n)| [u32::try_from(size).unwrap_or(u32::MAX), n])
        .collect();
    let windows: u32 = window_sizes.iter().map(|w| w[1]).sum();
    let weighted: u64 = window_sizes.iter().map(|w| u64::from(w[0]) * u64::from(w[1])).sum();
    let all_points = b.free_points + b.fixed_points;
    let large: Vec<usize> =
        record.windows.iter().filter(|w| w.1 > LARGE_MAP_KEYFRAMES).map(|w| w.0).collect();
    BackendReport {
        map_scale: scale.name(),
        map_keyframes_max: record.map_keyframes_max,
        work_quota_per_frame: quota,
        schedule: schedule.name(),
        deterministic: schedule != Schedule::Realtime,
        window_levels: slam.backend().params().window_levels,
        local_runs: b.local_runs,
        global_runs: b.global_runs,
        window_mean: if windows > 0 { weighted as f64 / f64::from(windows) } else { 0.0 },
        window_sizes,
        windows_in_large_map: large.len(),
        window_mean_in_large_map: (!large.is_empty())
            .then(|| large.iter().sum::<usize>() as f64 / large.len() as f64),
        map_keyframes: slam.map().num_keyframes(),
        map_landmarks: slam.map().num_landmarks(),
        reference_landmarks: slam.map().landmarks().filter(|(_, l)| l.reference).count(),
        reference_fraction_of_points: if all_points > 0 {
            b.fixed_points as f64 / all_points as f64
        } else {
            0.0
        },
        work_units: b.work_units,
        steps: b.steps,
        steps_beside_tracking: record.steps_beside_tracking,
    }
}
