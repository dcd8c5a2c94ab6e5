//! The core structures whose size `memory-budget.md` states: one list, read by the
//! `memory_budget` test (the file's table must say exactly this) and by `cargo xtask budgets
//! --write` (which writes the table from it).
//!
//! Sizes are `size_of` on the host that runs this (64-bit in CI): views and frames hold a slice
//! pointer and `usize` fields, so they are smaller on the 32-bit Cortex-M; buffers are the same.

use std::mem::size_of;

use ferroslam_core::backend::{BoardBackend, BoardBundleAdjuster, HostBackend};
use ferroslam_core::config::capacity::{
    MAX_FEATURES_PER_FRAME, MAX_KEYFRAMES, MAX_LANDMARKS, MAX_OBSERVATIONS_PER_KEYFRAME,
    MAX_TRACKED_LANDMARKS,
};
use ferroslam_core::config::{
    BOARD_MAP, HOST_MAP, QvgaDepthBuffer, QvgaGrayBuffer, SensorModel, VgaDepthBuffer,
    VgaGrayBuffer,
};
use ferroslam_core::features::{Feature, FeatureVec, QvgaHessianDetector, VgaHessianDetector};
use ferroslam_core::frame::RgbdFrame;
use ferroslam_core::geometry::{PinholeCamera, Pose};
use ferroslam_core::image::{DepthView, GrayView};
use ferroslam_core::loops::{INDEXED_RECORDS, PlaceMemory};
use ferroslam_core::map::{
    BoardMap, HostMap, KeyFrame, Landmark, NoStore, Observation, PLACE_KEY_CELLS,
};
use ferroslam_core::persist::{FlashStore, MAX_RECORD_UNITS, SliceFlash, TABLE_SLOTS};
use ferroslam_core::pose::small_image_rotation::SmallImage;
use ferroslam_core::pose::{InlierMask, MotionModel, PoseEstimate};
use ferroslam_core::system::{HostQvga, QvgaSlam, Slam, VgaSlam};
use ferroslam_core::tracking::{BoardLocalMap, QvgaFrontend, TrackedLandmark, VgaFrontend};

/// One row of the table: a core type, what drives its size, and its `size_of`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Structure {
    /// The type's path under `ferroslam_core`, e.g. `map::BoardMap`.
    pub name: &'static str,
    /// The capacity (or content) that drives its size, for a reader (named capacities are
    /// printed from their constants, so the text follows them).
    pub capacity: String,
    /// `size_of` on this host, bytes.
    pub bytes: usize,
}

fn row<T>(name: &'static str, capacity: impl Into<String>) -> Structure {
    Structure { name, capacity: capacity.into(), bytes: size_of::<T>() }
}

/// Every core structure the budget file states, in the file's order.
pub fn core_structures() -> Vec<Structure> {
    vec![
        row::<QvgaGrayBuffer>("config::QvgaGrayBuffer", "320 x 240 gray, u8"),
        row::<QvgaDepthBuffer>(
            "config::QvgaDepthBuffer",
            "160 x 120 depth, u16 (one reading per 2 x 2 gray pixels: level 1)",
        ),
        row::<VgaGrayBuffer>("config::VgaGrayBuffer", "640 x 480 gray, u8"),
        row::<VgaDepthBuffer>("config::VgaDepthBuffer", "640 x 480 depth, u16"),
        row::<SensorModel>("config::SensorModel", "pixel and depth noise, Huber, depth range"),
        row::<GrayView<'static>>("image::GrayView", "borrowed: slice + size + stride"),
        row::<DepthView<'static>>("image::DepthView", "borrowed view + depth scale"),
        row::<RgbdFrame<'static>>("frame::RgbdFrame", "timestamp + gray and depth views"),
        row::<PinholeCamera>("geometry::PinholeCamera", "fx, fy, cx, cy, size"),
        row::<Pose>("geometry::Pose", "`Isometry3<f32>`"),
        row::<QvgaHessianDetector>(
            "features::QvgaHessianDetector",
            "320 px rows: rolling u16 integral ring (32 rows), middle-layer response rows and \
             their suppression marks, bucketing grid",
        ),
        row::<VgaHessianDetector>("features::VgaHessianDetector", "the same at 640 px rows"),
        row::<FeatureVec>(
            "features::FeatureVec",
            format!(
                "`MAX_FEATURES_PER_FRAME` = {MAX_FEATURES_PER_FRAME} features of {} bytes",
                size_of::<Feature>()
            ),
        ),
        row::<InlierMask>(
            "pose::InlierMask",
            format!("{MAX_FEATURES_PER_FRAME} correspondences, one bit each"),
        ),
        row::<PoseEstimate>("pose::PoseEstimate", "pose, inlier mask, figures"),
        row::<MotionModel>("pose::MotionModel", "last two stamped poses"),
        row::<QvgaFrontend>(
            "tracking::QvgaFrontend",
            format!(
                "detector + local map ({MAX_TRACKED_LANDMARKS} templates) + scratch + small \
                 images, 320x240"
            ),
        ),
        row::<VgaFrontend>("tracking::VgaFrontend", "the same with the detector at 640 px rows"),
        row::<TrackedLandmark>(
            "tracking::TrackedLandmark",
            "a 16 x 16 template, its anchoring pose, pixel and depth, counters",
        ),
        row::<BoardLocalMap>(
            "tracking::BoardLocalMap",
            format!("`MAX_TRACKED_LANDMARKS` = {MAX_TRACKED_LANDMARKS} tracked landmarks"),
        ),
        row::<SmallImage>(
            "pose::small_image_rotation::SmallImage",
            "80 x 60 + 40 x 30 blurred thumbnails (rotation recovery); two per front end",
        ),
        row::<Observation>("map::Observation", "landmark id, pixel (1/32 px), depth (1/4 mm)"),
        row::<Landmark>("map::Landmark", "position, host keyframe, counters"),
        row::<KeyFrame>(
            "map::KeyFrame",
            format!(
                "pose, time, `MAX_OBSERVATIONS_PER_KEYFRAME` = {MAX_OBSERVATIONS_PER_KEYFRAME} \
                 observations, a {PLACE_KEY_CELLS}-byte place key"
            ),
        ),
        row::<PlaceMemory<NoStore>>(
            "loops::PlaceMemory",
            format!(
                "the place memory beside its store: the RAM index of {INDEXED_RECORDS} records' \
                 key bits (24 B each), one record's buffer (1 KiB), counters, RANSAC state; the \
                 store itself is a port (flash on a board, RAM on the host)"
            ),
        ),
        row::<FlashStore<SliceFlash<'static>>>(
            "persist::FlashStore",
            format!(
                "the board's durable store in RAM: its table of {TABLE_SLOTS} slots' units (2 B \
                 each) and three bitmaps of {MAX_RECORD_UNITS} units (the third for flash with \
                 large sectors); the records are in flash"
            ),
        ),
        row::<BoardMap>(
            "map::BoardMap",
            format!(
                "`MAX_KEYFRAMES` = {MAX_KEYFRAMES} keyframes, `MAX_LANDMARKS` = {MAX_LANDMARKS} \
                 landmarks"
            ),
        ),
        row::<BoardBundleAdjuster>(
            "backend::BoardBundleAdjuster",
            format!(
                "the BA workspace of `BOARD_MAP`: {} rigs, {} cameras, {} points, {} \
                 observations (local and global BA share it)",
                BOARD_MAP.ba_rigs,
                BOARD_MAP.keyframes,
                BOARD_MAP.ba_points,
                BOARD_MAP.ba_observations
            ),
        ),
        row::<BoardBackend>(
            "backend::BoardBackend",
            "the BA workspace + the window and segment bookkeeping",
        ),
        row::<ferroslam_core::ar::PlaneDetector>(
            "ar::PlaneDetector",
            format!(
                "on the board's stack while it runs (`system::OnlinePlanes`, once per keyframe): \
                 {} x {} cells (moments and normal each, two bits), the seeds' order and the \
                 growing's queue",
                ferroslam_core::ar::PLANE_GRID.0,
                ferroslam_core::ar::PLANE_GRID.1
            ),
        ),
        row::<ferroslam_core::system::OnlinePlanes>(
            "system::OnlinePlanes",
            "the world's planes SLAM finds as it runs: a plane map of `MAX_MAP_PLANES` planes",
        ),
        row::<ferroslam_core::ar::Anchors>(
            "ar::Anchors",
            format!(
                "the virtual objects placed (`Slam::command`): `MAX_ANCHORS` = {} anchors and \
                 their keyframes",
                ferroslam_core::config::capacity::MAX_ANCHORS
            ),
        ),
        row::<QvgaSlam>(
            "system::QvgaSlam",
            "QVGA front end + map + back end + its planes and anchors",
        ),
        row::<VgaSlam>("system::VgaSlam", "VGA front end + map + back end"),
        row::<HostMap>(
            "map::HostMap",
            format!(
                "host only: `HOST_MAP`: {} keyframes, {} landmarks",
                HOST_MAP.keyframes, HOST_MAP.landmarks
            ),
        ),
        row::<HostBackend>(
            "backend::HostBackend",
            format!(
                "host only: a BA workspace of {} rigs, {} cameras, {} points, {} \
                 observations, and the bookkeeping",
                HOST_MAP.ba_rigs, HOST_MAP.keyframes, HOST_MAP.ba_points, HOST_MAP.ba_observations
            ),
        ),
        row::<Slam<HostQvga>>(
            "system::Slam<HostQvga>",
            "host only: QVGA front end + `HostMap` + `HostBackend`",
        ),
    ]
}

/// The size of the structure named `name` in [`core_structures`].
pub fn bytes_of(name: &str) -> Option<usize> {
    core_structures().into_iter().find(|s| s.name == name).map(|s| s.bytes)
}
