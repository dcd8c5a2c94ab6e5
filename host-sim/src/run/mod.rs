//! Runs: the library API behind `replay` and `demo`, which xtask and the tests call too.
//!
//! A run takes a [`FrameSource`] (a dataset reader, the synthetic renderer, either wrapped in a
//! [`ProfileSource`] to reach a processing profile) and a [`PinholeCamera`] at the processing
//! resolution, and runs on every frame one of:
//!
//! - the data path alone ([`data_path::data_path`]): timestamps checked, the core's image
//!   statistics taken ([`DataPathRun`]);
//! - odometry or SLAM ([`track`] with a [`TrackMode`]): the data path, then the core's front end
//!   alone, or the front end, map and back end with a fixed work quota per frame
//!   ([`slam::Schedule`] says how the back end runs beside the front end). The result
//!   ([`TrackingRun`]) holds the trajectories, per-frame figures and the back end's record;
//!   [`crate::report`] writes it out.
//!
//! Layers: `source`, `data_path` and `result` at the bottom; `odometry` and `slam` above them;
//! this module's [`track`] on top, choosing the core's sizes for the profile.

mod ar;
pub mod data_path;
mod map_points;
mod odometry;
mod planes;
pub mod result;
pub mod slam;
pub mod source;

use std::path::PathBuf;

use anyhow::Result;
use ferroslam_core::backend::BackendParams;
use ferroslam_core::config::{HostQvga, HostVga, QVGA, Qvga, Resolution, SensorModel, Vga};
use ferroslam_core::frame::FrameSource;
use ferroslam_core::geometry::PinholeCamera;
use ferroslam_core::system::SLAM_FRONTEND;
use ferroslam_core::tracking::{FrontendParams, QvgaFrontend, VgaFrontend};

/// `make()`'s value on the heap. The core's structures are hundreds of KB to megabytes, and Rust
/// builds a value on the stack before boxing it: built in this frame of its own, the value takes
/// stack only while it is made, not in every frame the optimizer inlines its caller into (with
/// all profiles inlined into one frame, a replay overflowed a 2 MB thread's stack).
#[inline(never)]
pub(crate) fn boxed<T>(make: impl FnOnce() -> T) -> Box<T> {
    Box::new(make())
}

pub use ar::{
    ArEvent, ArPlan, ArRun, CUBE_SIDE_M, OBJECT_COLOURS, OnlineAnchor, OnlineAnchorsReport,
    PlacedAnchor,
};
pub use data_path::{DataPathRun, FrameStats, Progress, data_path, drive, median};
pub use map_points::MapCloud;
pub use result::{
    BackendReport, LoadedMap, PlacesReport, PlaneReport, PlanesReport, TrackedFrame, TrackingRun,
};
pub use slam::{MapScale, Schedule};
pub use source::{ProfileSource, ProfileSourceError};

/// What to run on each frame after the data path.
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
        /// Whether keyframes leaving the map are remembered in a long-term store (the board's
        /// capacity, in RAM on the host) and lost frames relocalize in it.
        places: bool,
    },
}

impl TrackMode {
    /// SLAM with the board's defaults: the firmware's quota, threaded schedule, board map and
    /// window levels, with the place memory (what `replay --mode slam` runs unless told
    /// otherwise).
    pub const SLAM: Self = Self::Slam {
        quota: ferroslam_core::config::DEFAULT_BACKEND_QUOTA,
        schedule: Schedule::Threaded,
        map: MapScale::Board,
        window_levels: BackendParams::DEFAULT.window_levels,
        places: true,
    };

    /// The mode's name in reports and on the command line: `odometry` or `slam`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Odometry => "odometry",
            Self::Slam { .. } => "slam",
        }
    }
}

/// How a tracking run is set up, apart from its source and camera.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOptions {
    /// The processing resolution: with the SLAM mode's map scale, it names the core's profile
    /// (QVGA: 320 x 240; VGA: 640 x 480).
    pub profile: Resolution,
    /// Odometry or SLAM, and SLAM's back-end settings.
    pub mode: TrackMode,
    /// The front end's RANSAC seed (`None`: the core's default, `FrontendParams::rng_seed`).
    /// Runs with other seeds show how much of an accuracy figure is chance.
    pub seed: Option<u64>,
    /// The sensor's measurement model as the core is told it (depth range, noise), given to the
    /// front end and the back end.
    pub sensor: SensorModel,
    /// Whether to draw a progress bar on stderr (only ever drawn on a terminal; see
    /// [`Progress`]).
    pub progress_bar: bool,
    /// Map files the place memory starts from and is saved to (SLAM mode).
    pub maps: MapFiles,
    /// Which virtual objects to place and record where each frame draws them (SLAM mode;
    /// `--ar`, `--anchors`; `None`: no AR).
    pub ar: Option<ArPlan>,
}

/// The map files of a SLAM run with a place memory ([`ferroslam_core::persist`]).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct MapFiles {
    /// A map to start in: the run begins once a frame relocalizes in it, in its world frame.
    pub load: Option<PathBuf>,
    /// Where to save the map at the end: the remembered keyframes and those of the active map.
    pub save: Option<PathBuf>,
    /// Localization only: nothing is added to the loaded map's store, and the run is held on it
    /// by its points.
    pub localize: bool,
}

impl RunOptions {
    /// `mode` at `profile` with the core's default seed and tunables, and a progress bar.
    pub fn new(profile: Resolution, mode: TrackMode) -> Self {
        Self {
            profile,
            mode,
            seed: None,
            sensor: SensorModel::DEFAULT,
            progress_bar: true,
            maps: MapFiles::default(),
            ar: None,
        }
    }
}

impl Default for RunOptions {
    /// SLAM on the reference board's profile, as the firmware runs it.
    fn default() -> Self {
        Self::new(QVGA, TrackMode::SLAM)
    }
}

/// Runs every frame of `source` (about `expected` of them, for the progress bar) through the
/// core as `options` say, with the camera `cam` at the processing resolution. The front end
/// takes the mode's defaults (odometry: `FrontendParams::DEFAULT`; SLAM:
/// `system::SLAM_FRONTEND` and `BackendParams::DEFAULT`) with the options' seed and sensor.
///
/// # Errors
/// As [`drive`]; a frame the front end rejects (size or timestamp); a back-end error.
pub fn track<S>(
    source: &mut S,
    expected: usize,
    cam: &PinholeCamera,
    options: &RunOptions,
) -> Result<TrackingRun>
where
    S: FrameSource,
    S::Error: std::error::Error + Send + Sync + 'static,
{
    let seeded = |mut p: FrontendParams| {
        if let Some(seed) = options.seed {
            p.rng_seed = seed;
        }
        p.with_sensor(options.sensor)
    };
    let (odometry, slam) = (seeded(FrontendParams::DEFAULT), seeded(SLAM_FRONTEND));
    let mut backend = BackendParams::DEFAULT.with_sensor(options.sensor);
    if let TrackMode::Slam { window_levels, .. } = options.mode {
        backend.window_levels = window_levels;
    }
    // The smallest profile whose front end holds the processing frame.
    let vga = cam.width() > QVGA.max_width() || cam.height() > QVGA.max_height();
    let progress = Progress { expected_frames: expected, bar: options.progress_bar };
    match (options.mode, vga) {
        (TrackMode::Odometry, true) => {
            let frontend = || boxed(|| VgaFrontend::with_params(odometry));
            odometry::run(source, progress, cam, frontend)
        }
        (TrackMode::Odometry, false) => {
            let frontend = || boxed(|| QvgaFrontend::with_params(odometry));
            odometry::run(source, progress, cam, frontend)
        }
        (TrackMode::Slam { quota, schedule, map, places, .. }, vga) => {
            let setup = slam::Setup {
                quota,
                schedule,
                scale: map,
                frontend: slam,
                backend,
                places,
                ar: options.ar.clone(),
            };
            let m = &options.maps;
            match (map, vga) {
                (MapScale::Board, false) => slam::run::<Qvga, S>(source, progress, cam, &setup, m),
                (MapScale::Board, true) => slam::run::<Vga, S>(source, progress, cam, &setup, m),
                (MapScale::Host, false) => {
                    slam::run::<HostQvga, S>(source, progress, cam, &setup, m)
                }
                (MapScale::Host, true) => slam::run::<HostVga, S>(source, progress, cam, &setup, m),
            }
        }
    }
}
