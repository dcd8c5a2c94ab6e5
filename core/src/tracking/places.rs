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

/// The place memory as the front end sees it.
pub trait Places {
    /// Whether it answers queries at all (a lost frame skips its query work when not).
    fn relocalizes(&self) -> bool;

    /// Keyframe `kf` of `map` is about to leave the map: remember it.
    fn remember<const K: usize, const L: usize>(&mut self, map: &Map<K, L>, kf: KeyFrameId);

    /// The pose `t_wc` of the camera that saw `query`, when a remembered place or a keyframe of
    /// the active `map` is verified in it; `None` otherwise.
    fn relocalize<const K: usize, const L: usize>(
        &mut self,
        query: &PlaceQuery<'_>,
        map: &Map<K, L>,
    ) -> Option<Pose>;
}

/// No place memory: keyframes leaving the map are forgotten and nothing relocalizes.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoPlaces;

impl Places for NoPlaces {
    fn relocalizes(&self) -> bool {
        false
    }

    fn remember<const K: usize, const L: usize>(&mut self, _: &Map<K, L>, _: KeyFrameId) {}

    fn relocalize<const K: usize, const L: usize>(
        &mut self,
        _: &PlaceQuery<'_>,
        _: &Map<K, L>,
    ) -> Option<Pose> {
        None
    }
}
