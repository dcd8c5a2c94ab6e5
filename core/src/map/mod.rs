//! The map: fixed-capacity arenas of keyframes and landmarks addressed by typed ids, with the
//! keyframes' observations of landmarks.
//!
//! - A [`KeyFrame`] holds its camera-to-world pose, its timestamp, a creation number and the
//!   [`Observation`]s it made (landmark, pixel, measured depth), compactly encoded.
//! - The long-term tier ([`PlaceRecord`] behind a [`KeyframeStore`], in `place.rs`): what is
//!   remembered of a keyframe once it leaves the active map.
//! - A [`Landmark`] holds its world position, the keyframe that created it, how many keyframes
//!   observe it, the counters the back end keeps (times optimized, the reference flag), and a
//!   compact descriptor of its appearance (for map reuse).
//! - Ids ([`KeyFrameId`], [`LandmarkId`]) come from the arenas and are generation-checked: an id
//!   of a removed object is never valid again, even after its slot is reused.
//!
//! The map holds no images and no templates: the tracker keeps templates for the landmarks it
//! tracks (see [`crate::tracking`]) and the back end reads poses, positions and observations.
//!
//! # When an arena is full
//!
//! Inserting into a full arena returns an error; nothing grows and nothing panics. The front end
//! makes room first with [`Map::retire_oldest_keyframe`]: the keyframe with the lowest creation
//! number is removed with its observations, and every landmark no longer observed by any
//! keyframe is removed too unless the caller still tracks it. An unbounded run therefore keeps the
//! most recent keyframes, and the map never grows past its capacities.
//!
//! # Units and frames
//!
//! Poses are `t_wc` (camera to world), positions `p_w` in world metres, pixels at the processing
//! resolution with integer coordinates at pixel centres.

mod arena;
mod observation;
mod place;

#[cfg(test)]
mod tests;

use core::fmt;

use heapless::Vec;
use nalgebra::Point3;

pub use arena::{Arena, Handle};
pub use observation::Observation;
pub use place::{
    Fnv1a, KEY_BITS_WORDS, KeyBits, KeyframeStore, NoStore, PLACE_KEY_CELLS, PlaceKey, PlacePoint,
    PlaceRecord, RamStore, RecordBytes, RecordError, SlotOutOfRange,
};
pub(crate) use place::{Get, Put, is_sealed, seal};

use crate::config::{BOARD_MAP, HOST_MAP, capacity};
use crate::features::Descriptor;
use crate::geometry::Pose;

/// Observations one keyframe holds at most.
pub const MAX_OBSERVATIONS_PER_KEYFRAME: usize = capacity::MAX_OBSERVATIONS_PER_KEYFRAME;

/// A keyframe's id: valid until the keyframe is removed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct KeyFrameId(pub Handle);

/// A landmark's id: valid until the landmark is removed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LandmarkId(pub Handle);

/// A keyframe of the map.
#[derive(Debug, Clone)]
pub struct KeyFrame {
    /// Camera-to-world pose (the back end refines it).
    pub t_wc: Pose,
    /// Capture time, seconds.
    pub timestamp_s: f64,
    /// Creation number: 0 for the first keyframe of the map, then increasing by one.
    pub seq: u32,
    /// The landmarks this keyframe observed, in the order they were added.
    pub observations: Vec<Observation, MAX_OBSERVATIONS_PER_KEYFRAME>,
    /// Its frame's place key (for the long-term store; zeros until the front end sets it).
    pub place_key: PlaceKey,
}

/// A landmark of the map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Landmark {
    /// Position in the world frame, metres.
    pub p_w: Point3<f32>,
    /// The keyframe that created it (it may have been removed since).
    pub host: KeyFrameId,
    /// Keyframes holding an observation of it.
    pub num_observations: u16,
    /// Times bundle adjustment optimized its position.
    pub times_optimized: u8,
    /// A reference landmark: frozen in later bundle adjustments, it anchors poses.
    pub reference: bool,
    /// Its appearance where it was created, for recognizing it again once the tracker no longer
    /// follows it (map reuse); `None` when none could be computed.
    pub descriptor: Option<Descriptor>,
}

/// Why a map operation failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum MapError {
    /// The keyframe arena is full.
    KeyFramesFull,
    /// The landmark arena is full.
    LandmarksFull,
    /// The keyframe holds its maximum of observations.
    ObservationsFull,
    /// The id names an object that was removed (or never existed).
    UnknownId,
}

impl fmt::Display for MapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::KeyFramesFull => write!(f, "the keyframe arena is full"),
            Self::LandmarksFull => write!(f, "the landmark arena is full"),
            Self::ObservationsFull => write!(f, "the keyframe's observation list is full"),
            Self::UnknownId => write!(f, "no such keyframe or landmark"),
        }
    }
}

impl core::error::Error for MapError {}

/// The map at the reference board's capacities ([`BOARD_MAP`]).
pub type BoardMap = Map<{ BOARD_MAP.keyframes }, { BOARD_MAP.landmarks }>;

/// The host-scale map ([`HOST_MAP`]): room for the paper's local window in a map of over 120
/// keyframes; about 1 MB, for the host simulator, not the board.
pub type HostMap = Map<{ HOST_MAP.keyframes }, { HOST_MAP.landmarks }>;

/// A map of at most `K` keyframes and `L` landmarks (both at most 65,536).
#[derive(Debug, Clone)]
pub struct Map<const K: usize, const L: usize> {
    keyframes: Arena<KeyFrame, K>,
    landmarks: Arena<Landmark, L>,
    next_seq: u32,
}

impl<const K: usize, const L: usize> Default for Map<K, L> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const K: usize, const L: usize> Map<K, L> {
    /// An empty map (`const`: it can initialize a `static`).
    pub const fn new() -> Self {
        Self { keyframes: Arena::new(), landmarks: Arena::new(), next_seq: 0 }
    }

    /// Empties the map (ids of the old objects stay invalid).
    pub fn clear(&mut self) {
        for i in 0..K {
            if let Some(h) = self.keyframes.handle_at(i) {
                let _ = self.keyframes.remove(h);
            }
        }
        for i in 0..L {
            if let Some(h) = self.landmarks.handle_at(i) {
                let _ = self.landmarks.remove(h);
            }
        }
    }

    /// Keyframes held.
    pub fn num_keyframes(&self) -> usize {
        self.keyframes.len()
    }

    /// Landmarks held.
    pub fn num_landmarks(&self) -> usize {
        self.landmarks.len()
    }

    /// Whether the keyframe arena is full.
    pub fn keyframes_full(&self) -> bool {
        self.keyframes.is_full()
    }

    /// Whether the landmark arena is full.
    pub fn landmarks_full(&self) -> bool {
        self.landmarks.is_full()
    }

    /// Numbers the keyframes added from now on from `seq` at least (a run that extends a loaded
    /// map continues its numbering).
    pub fn number_from(&mut self, seq: u32) {
        self.next_seq = self.next_seq.max(seq);
    }

    /// Adds a keyframe with no observations; its `seq` is the next creation number.
    ///
    /// # Errors
    /// [`MapError::KeyFramesFull`].
    pub fn add_keyframe(&mut self, t_wc: Pose, timestamp_s: f64) -> Result<KeyFrameId, MapError> {
        let kf = KeyFrame {
            t_wc,
            timestamp_s,
            seq: self.next_seq,
            observations: Vec::new(),
            place_key: PlaceKey([0; PLACE_KEY_CELLS]),
        };
        let id = self.keyframes.insert(kf).map_err(|_| MapError::KeyFramesFull)?;
        self.next_seq = self.next_seq.wrapping_add(1);
        Ok(KeyFrameId(id))
    }

    /// Adds a landmark at `p_w` created by `host` (no observation yet).
    ///
    /// # Errors
    /// [`MapError::LandmarksFull`].
    pub fn add_landmark(
        &mut self,
        p_w: Point3<f32>,
        host: KeyFrameId,
    ) -> Result<LandmarkId, MapError> {
        let lm = Landmark {
            p_w,
            host,
            num_observations: 0,
            times_optimized: 0,
            reference: false,
            descriptor: None,
        };
        self.landmarks.insert(lm).map(LandmarkId).map_err(|_| MapError::LandmarksFull)
    }

    /// Records that keyframe `kf` observed `obs.landmark`.
    ///
    /// # Errors
    /// [`MapError::UnknownId`] for a removed keyframe or landmark; [`MapError::ObservationsFull`].
    pub fn add_observation(&mut self, kf: KeyFrameId, obs: Observation) -> Result<(), MapError> {
        if self.landmarks.get(obs.landmark.0).is_none() {
            return Err(MapError::UnknownId);
        }
        let frame = self.keyframes.get_mut(kf.0).ok_or(MapError::UnknownId)?;
        frame.observations.push(obs).map_err(|_| MapError::ObservationsFull)?;
        if let Some(lm) = self.landmarks.get_mut(obs.landmark.0) {
            lm.num_observations = lm.num_observations.saturating_add(1);
        }
        Ok(())
    }

    /// The keyframe `id`, unless removed.
    pub fn keyframe(&self, id: KeyFrameId) -> Option<&KeyFrame> {
        self.keyframes.get(id.0)
    }

    /// The keyframe `id` mutably, unless removed. Edit observations through the map's methods
    /// only (they keep the landmarks' observation counts).
    pub fn keyframe_mut(&mut self, id: KeyFrameId) -> Option<&mut KeyFrame> {
        self.keyframes.get_mut(id.0)
    }

    /// The landmark `id`, unless removed.
    pub fn landmark(&self, id: LandmarkId) -> Option<&Landmark> {
        self.landmarks.get(id.0)
    }

    /// The landmark `id` mutably, unless removed.
    pub fn landmark_mut(&mut self, id: LandmarkId) -> Option<&mut Landmark> {
        self.landmarks.get_mut(id.0)
    }

    /// The landmark in arena slot `index`, mutably, if the slot is taken (for passes over every
    /// landmark by slot).
    pub fn landmark_at_mut(&mut self, index: usize) -> Option<&mut Landmark> {
        let h = self.landmarks.handle_at(index)?;
        self.landmarks.get_mut(h)
    }

    /// Moves the keyframes made from creation number `first_seq` on, and the landmarks they
    /// host, by `c` (`T_new_old`, a loop's correction of the world frame); their relative
    /// geometry is unchanged. Cost: one pass over the keyframes and the landmarks.
    pub fn move_world_from(&mut self, first_seq: u32, c: &Pose) {
        for (_, k) in self.keyframes.iter_mut() {
            if k.seq >= first_seq {
                k.t_wc = c * k.t_wc;
            }
        }
        let keyframes = &self.keyframes;
        for (_, lm) in self.landmarks.iter_mut() {
            if keyframes.get(lm.host.0).is_some_and(|k| k.seq >= first_seq) {
                lm.p_w = c * lm.p_w;
            }
        }
    }

    /// Every keyframe id, in slot order (not creation order: see [`KeyFrame::seq`]).
    pub fn keyframe_ids(&self) -> impl Iterator<Item = KeyFrameId> + '_ {
        self.keyframes.iter().map(|(h, _)| KeyFrameId(h))
    }

    /// Every keyframe with its id, in slot order.
    pub fn keyframes(&self) -> impl Iterator<Item = (KeyFrameId, &KeyFrame)> + '_ {
        self.keyframes.iter().map(|(h, k)| (KeyFrameId(h), k))
    }

    /// Every landmark with its id, in slot order.
    pub fn landmarks(&self) -> impl Iterator<Item = (LandmarkId, &Landmark)> + '_ {
        self.landmarks.iter().map(|(h, l)| (LandmarkId(h), l))
    }

    /// The keyframe with the lowest creation number.
    pub fn oldest_keyframe(&self) -> Option<KeyFrameId> {
        self.keyframes.iter().min_by_key(|(_, k)| k.seq).map(|(h, _)| KeyFrameId(h))
    }

    /// Removes keyframe `id` and its observations; landmarks it observed lose one observation.
    /// Landmarks are not removed here (see [`Self::remove_orphans`]).
    ///
    /// # Errors
    /// [`MapError::UnknownId`].
    pub fn remove_keyframe(&mut self, id: KeyFrameId) -> Result<KeyFrame, MapError> {
        let kf = self.keyframes.remove(id.0).ok_or(MapError::UnknownId)?;
        for obs in &kf.observations {
            if let Some(lm) = self.landmarks.get_mut(obs.landmark.0) {
                lm.num_observations = lm.num_observations.saturating_sub(1);
            }
        }
        Ok(kf)
    }

    /// Removes landmark `id`; observations of it left in keyframes become dangling (their id no
    /// longer resolves) and are skipped by every reader.
    ///
    /// # Errors
    /// [`MapError::UnknownId`].
    pub fn remove_landmark(&mut self, id: LandmarkId) -> Result<Landmark, MapError> {
        self.landmarks.remove(id.0).ok_or(MapError::UnknownId)
    }

    /// Removes every landmark that no keyframe observes and for which `keep` is false; returns
    /// how many were removed.
    pub fn remove_orphans(&mut self, mut keep: impl FnMut(LandmarkId) -> bool) -> usize {
        let mut removed = 0;
        for i in 0..L {
            let Some(h) = self.landmarks.handle_at(i) else { continue };
            let orphan = self.landmarks.get(h).is_some_and(|l| l.num_observations == 0);
            if orphan && !keep(LandmarkId(h)) && self.landmarks.remove(h).is_some() {
                removed += 1;
            }
        }
        removed
    }

    /// The documented full-arena policy: removes the oldest keyframe and then the landmarks no
    /// keyframe observes any more, except those `keep` names (e.g. the ones still tracked).
    /// Returns the removed keyframe's id, or `None` on an empty map.
    pub fn retire_oldest_keyframe(
        &mut self,
        keep: impl FnMut(LandmarkId) -> bool,
    ) -> Option<KeyFrameId> {
        let oldest = self.oldest_keyframe()?;
        let _ = self.remove_keyframe(oldest);
        self.remove_orphans(keep);
        Some(oldest)
    }
}
