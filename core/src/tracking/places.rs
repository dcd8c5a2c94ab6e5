//! The front end's port to the place memory (`crate::loops` implements it): a keyframe about to
//! leave the active map is handed over to be remembered, and a lost frame asks where it is.
//!
//! The port lives here, below `loops`, so that the front end calls it without importing the layer
//! above it (the same inversion as the hardware ports of `crate::frame`).

use nalgebra::Point3;

use crate::features::Descriptor;
use crate::geometry::Pose;
use crate::map::{KeyFrameId, Map, PlaceKey};

/// A feature of a lost frame with valid depth, offered to relocalization.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QueryPoint {
    /// Pixel at the tracking level.
    pub uv: (f32, f32),
    /// Position in the frame's camera, metres.
    pub p_c: Point3<f32>,
    /// Its descriptor.
    pub descriptor: Descriptor,
}

/// What a lost frame offers to relocalization.
#[derive(Debug, Clone, Copy)]
pub struct PlaceQuery<'a> {
    /// The frame's place key.
    pub key: PlaceKey,
    /// Its features with valid depth.
    pub points: &'a [QueryPoint],
    /// The tracking level's size, pixels.
    pub size: (usize, usize),
}

/// A loop closed at a new keyframe: a remembered place outside the active map verified it
/// elsewhere than the map had it, by more than the map's drift can be ignored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopClosure {
    /// Creation number of the remembered keyframe.
    pub record_seq: u32,
    /// Its timestamp, seconds.
    pub record_timestamp_s: f64,
    /// Creation number of the new keyframe.
    pub keyframe_seq: u32,
    /// The rigid motion from the map's world frame to the remembered one (`T_new_old`): applied
    /// to the active map, it puts the new keyframe where the place verified it.
    pub correction: Pose,
}

/// The place memory as the front end sees it.
pub trait Places {
    /// Whether it answers queries at all (a lost frame skips its query work when not).
    fn relocalizes(&self) -> bool;

    /// Whether it holds places already (a map loaded before the run): the front end then starts
    /// by relocalizing in them, not by making a new world frame.
    fn holds_places(&self) -> bool;

    /// The creation number after every held place's (0 when none): a run that starts in a
    /// loaded map numbers its keyframes from here, so that its keyframes and the loaded map's
    /// never share one.
    fn first_free_seq(&self) -> u32;

    /// Keyframe `kf` of `map` is about to leave the map: remember it. The store's write may
    /// wait for [`Self::flush`] (or the memory's next read of its store).
    fn remember<const K: usize, const L: usize>(&mut self, map: &Map<K, L>, kf: KeyFrameId);

    /// Writes what [`Self::remember`] left to write: called after the back end's step, so that
    /// a flash erase and program do not stall the frame's tracking. Nothing to do by default.
    fn flush(&mut self) {}

    /// The pose `t_wc` of the camera that saw `query`, when a remembered place or a keyframe of
    /// the active `map` is verified in it; `None` otherwise.
    fn relocalize<const K: usize, const L: usize>(
        &mut self,
        query: &PlaceQuery<'_>,
        map: &Map<K, L>,
    ) -> Option<Pose>;

    /// Keyframe `kf`, just made in `map` from the frame seen as `query`: the loop it closes, if
    /// any, with a remembered place or a keyframe of `map` made before `track_start` (the
    /// creation number tracking last re-initialized at: the map before it is not connected to
    /// `kf`). The caller then moves the map from `track_start` on by the correction.
    fn close_loop<const K: usize, const L: usize>(
        &mut self,
        query: &PlaceQuery<'_>,
        map: &Map<K, L>,
        kf: KeyFrameId,
        track_start: u32,
    ) -> Option<LoopClosure>;

    /// After [`Self::close_loop`] with the same `query`, while localizing in a loaded map:
    /// `f(i, p_w)` for each point `query.points[i]` that the loaded map's place the query
    /// verified matches (an inlier of the verification), `p_w` that place's point in the map's
    /// world frame (metres). Nothing when no such place verified, or when not localizing.
    fn map_points(&mut self, query: &PlaceQuery<'_>, f: impl FnMut(usize, Point3<f32>));
}

/// No place memory: keyframes leaving the map are forgotten and nothing relocalizes.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoPlaces;

impl Places for NoPlaces {
    fn relocalizes(&self) -> bool {
        false
    }

    fn holds_places(&self) -> bool {
        false
    }

    fn first_free_seq(&self) -> u32 {
        0
    }

    fn remember<const K: usize, const L: usize>(&mut self, _: &Map<K, L>, _: KeyFrameId) {}

    fn relocalize<const K: usize, const L: usize>(
        &mut self,
        _: &PlaceQuery<'_>,
        _: &Map<K, L>,
    ) -> Option<Pose> {
        None
    }

    fn close_loop<const K: usize, const L: usize>(
        &mut self,
        _: &PlaceQuery<'_>,
        _: &Map<K, L>,
        _: KeyFrameId,
        _: u32,
    ) -> Option<LoopClosure> {
        None
    }

    fn map_points(&mut self, _: &PlaceQuery<'_>, _: impl FnMut(usize, Point3<f32>)) {}
}
