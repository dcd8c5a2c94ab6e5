//! What a run gives back: the trajectories, per-frame figures and the back end's record.

use ferroslam_core::loops::{LoopStats, PlaceStats};
use ferroslam_core::tracking::{FrameResult, FrontendState, GuideStage};
use serde::Serialize;

use super::data_path::DataPathRun;
pub use super::planes::{OnlinePlanesReport, PlaneReport, PlanesReport};
use crate::trajectory::Trajectory;

/// What the odometry front end made of one frame.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct TrackedFrame {
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
    /// Whether tracking restarted at this frame in a verified remembered place.
    pub relocalized: bool,
    /// Whether a loop closed on this frame (the map and its pose moved by the correction).
    pub loop_closed: bool,
    /// Final stages run (the rerun of the winning one included).
    pub final_stages: u8,
    /// Guide runs.
    pub guide_runs: u8,
    /// Whether the rotation was estimated from the small images.
    pub rotation_estimated: bool,
    /// Whether features were detected (a keyframe made or attempted).
    pub detected: bool,
}

/// What the place memory did over a run (SLAM mode with places; `loops::PlaceStats`).
#[derive(Debug, Clone, Serialize)]
pub struct PlacesReport {
    /// Records the long-term store holds at most (the board's store less the slots kept for the
    /// world's planes and anchors, `PlaceMemory::places_capacity`).
    pub store_capacity: usize,
    /// The map the run started in (`--load-map`), `None` for a run that started empty.
    pub loaded: Option<LoadedMap>,
    /// Records it held at the end.
    pub stored: usize,
    /// The place memory's counters (`remembered`, `thinned`, `too_few_points`, `store_errors`,
    /// `queries`, `verified`, `relocalized`, `ambiguous`: see `loops::PlaceStats`).
    #[serde(flatten)]
    pub stats: PlaceStats,
    /// The frames (0-based, in the order played) that relocalized.
    pub relocalized_frames: Vec<usize>,
    /// Loop detection's counters (see `loops::LoopStats`).
    pub loops: LoopStats,
    /// The frames (0-based, in the order played) on which a loop closed.
    pub loop_frames: Vec<usize>,
}

/// A saved map a run started in: what it held.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct LoadedMap {
    /// Remembered keyframes (place records).
    pub keyframes: usize,
    /// Planes, restored as the world's.
    pub planes: usize,
    /// Anchors (placed objects), restored.
    pub anchors: usize,
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
    /// Back-end steps taken (building a problem, solving, writing a result back).
    pub steps: u64,
    /// Of those, the solve steps that ran beside the front end's tracking of the next frame
    /// (threaded and realtime schedules; `Slam::overlap`).
    pub steps_beside_tracking: u64,
}

/// The tracker's result over a whole source.
#[derive(Debug, Clone)]
pub struct TrackingRun {
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
    pub per_frame: Vec<TrackedFrame>,
    /// Frames with a pose estimated from their images.
    pub tracked_frames: usize,
    /// Frames not tracked: their pose is the motion model's prediction.
    pub lost_frames: usize,
    /// Frames where tracking restarted from a keyframe at the predicted pose after a loss.
    pub reinitialized_frames: usize,
    /// Frames where tracking restarted in a verified remembered place.
    pub relocalized_frames: usize,
    /// Frames before the first keyframe (no pose). The five counts add up to the frames.
    pub initializing_frames: usize,
    /// The place memory's figures (SLAM mode with places).
    pub places: Option<PlacesReport>,
    /// Bytes of the core's state.
    pub state_bytes: usize,
    /// The back end's figures (SLAM mode).
    pub backend: Option<BackendReport>,
    /// The world's planes, from the keyframes' depth (SLAM mode).
    pub planes: Option<PlanesReport>,
    /// The objects placed and where each frame drew them (SLAM mode with `ar`).
    pub ar: Option<super::ar::ArRun>,
    /// The map's points over the run (SLAM mode).
    pub map_points: Option<super::map_points::MapCloud>,
}

/// The per-frame figures of a front-end result.
pub(super) fn frame_figures(timestamp_s: f64, r: &FrameResult) -> TrackedFrame {
    let state = match r.state {
        FrontendState::Initializing => "initializing",
        FrontendState::Tracking => "tracking",
        FrontendState::Lost => "lost",
    };
    TrackedFrame {
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
        relocalized: r.relocalized,
        loop_closed: r.loop_closure.is_some(),
        final_stages: r.work.final_stages,
        guide_runs: r.work.guide_runs,
        rotation_estimated: r.work.rotation_estimated,
        detected: r.work.detected,
    }
}
