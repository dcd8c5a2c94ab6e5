//! The anchors a run holds ([`Anchors`]): placed, scaled and removed by [`AnchorCommand`]s (from
//! the serial link on the board, a script on the host), each remembering the keyframe its
//! placing frame was tracked against, so that a loop correction, which moves the active map and
//! its keyframes rigidly, moves the anchors placed in that map with it.

use heapless::Vec;
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use super::anchor::{Anchor, AnchorError};
use super::planes::Plane;
use crate::config::capacity::MAX_ANCHORS;
use crate::geometry::{PinholeCamera, Pose};
use crate::image::DepthView;
use crate::map::{Fnv1a, KeyFrameId};

/// What a user asks of the anchors. On the serial link it travels as it is (postcard, in a
/// `wire::CommandMessage`): a change here is a new wire schema.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AnchorCommand {
    /// Place `object` at `scale` where the ray of `pixel` (the frame's pixel coordinates at the
    /// processing resolution, centres at integers) meets the plane under it; an object already
    /// placed moves there.
    Place {
        /// The caller's object id.
        object: u16,
        /// The pixel, `[u, v]`.
        pixel: [f32; 2],
        /// Its scale (1: the object's own size).
        scale: f32,
    },
    /// Give a placed object a new scale.
    Scale {
        /// The object.
        object: u16,
        /// Its new scale, finite and positive.
        scale: f32,
    },
    /// Remove a placed object.
    Remove {
        /// The object.
        object: u16,
    },
}

impl AnchorCommand {
    /// The object the command is about.
    pub const fn object(&self) -> u16 {
        match *self {
            Self::Place { object, .. } | Self::Scale { object, .. } | Self::Remove { object } => {
                object
            }
        }
    }
}

/// The frame a [`AnchorCommand::Place`] is applied in.
#[derive(Debug, Clone, Copy)]
pub struct PlacingFrame<'a> {
    /// Its depth image (the processing resolution).
    pub depth: &'a DepthView<'a>,
    /// Its camera.
    pub cam: &'a PinholeCamera,
    /// Its camera-to-world pose.
    pub t_wc: &'a Pose,
    /// Its planes in its camera's frame (`PlaneDetector::detect`).
    pub planes: &'a [Plane],
    /// The keyframe it was tracked against (`None`: no loop correction moves the anchor).
    pub reference: Option<KeyFrameId>,
}

/// An anchor and the keyframe its placing frame was tracked against.
#[derive(Debug, Clone, Copy)]
struct Attached {
    anchor: Anchor,
    keyframe: Option<KeyFrameId>,
}

/// The placed anchors, at most [`MAX_ANCHORS`] (about 0.5 KiB), one per object id.
///
/// An anchor stays where it was placed in the world frame, except when a loop closes
/// ([`Self::correct`]): the correction moves the active map rigidly, and with it the anchors whose
/// keyframe the map still holds; those of retired keyframes belong to the remembered places,
/// which the correction moves the map onto. Bundle adjustment's refinements of the keyframe are
/// not followed: they moved anchors away from where they belong (docs/decisions.md, "Anchors
/// follow loop corrections, not bundle adjustment").
#[derive(Debug, Clone, Default)]
pub struct Anchors {
    items: Vec<Attached, MAX_ANCHORS>,
    /// Calls that may have changed the anchors (wrapping): what tells a saved map they changed.
    changes: u32,
}

impl Anchors {
    /// No anchors.
    pub const fn new() -> Self {
        Self { items: Vec::new(), changes: 0 }
    }

    /// Calls so far that may have changed the anchors (wrapping; it counts at least every
    /// change, so an equal count means the same anchors): a save skips anchors it already holds.
    pub fn changes(&self) -> u32 {
        self.changes
    }

    /// The anchors `saved` by an earlier run ([`super::SavedWorld`]), in their order: of the
    /// remembered world, attached to no keyframe of this run's map, so no loop moves them.
    pub fn restored(saved: &[Anchor]) -> Self {
        let mut anchors = Self::new();
        for &anchor in saved.iter().take(MAX_ANCHORS) {
            let _ = anchors.items.push(Attached { anchor, keyframe: None });
        }
        anchors
    }

    /// Applies `command`; `frame` is needed by [`AnchorCommand::Place`] only (`None`: the frame
    /// was not tracked, so a place fails with [`AnchorError::NotTracked`]). Returns the anchor
    /// as it is after the command (the removed one for a remove).
    ///
    /// # Errors
    /// [`AnchorError`]: nothing changed.
    pub fn apply(
        &mut self,
        command: &AnchorCommand,
        frame: Option<&PlacingFrame<'_>>,
    ) -> Result<Anchor, AnchorError> {
        match *command {
            AnchorCommand::Place { object, pixel, scale } => {
                self.place(object, scale, pixel.into(), frame.ok_or(AnchorError::NotTracked)?)
            }
            AnchorCommand::Scale { object, scale } => self.scale(object, scale),
            AnchorCommand::Remove { object } => self.remove(object),
        }
    }

    /// Places `object` (see [`Anchor::place`]); an object already placed moves there.
    ///
    /// # Errors
    /// [`AnchorError`]: nothing changed; [`AnchorError::Full`] when [`MAX_ANCHORS`] other
    /// objects are placed.
    pub fn place(
        &mut self,
        object: u16,
        scale: f32,
        (u, v): (f32, f32),
        frame: &PlacingFrame<'_>,
    ) -> Result<Anchor, AnchorError> {
        self.changes = self.changes.wrapping_add(1);
        let anchor =
            Anchor::place(object, scale, (u, v), frame.depth, frame.cam, frame.t_wc, frame.planes)?;
        let attached = Attached { anchor, keyframe: frame.reference };
        match self.items.iter_mut().find(|a| a.anchor.object == object) {
            Some(slot) => *slot = attached,
            None => self.items.push(attached).map_err(|_| AnchorError::Full)?,
        }
        Ok(anchor)
    }

    /// Gives placed `object` a new `scale`.
    ///
    /// # Errors
    /// [`AnchorError::InvalidScale`], [`AnchorError::UnknownObject`]: nothing changed.
    pub fn scale(&mut self, object: u16, scale: f32) -> Result<Anchor, AnchorError> {
        self.changes = self.changes.wrapping_add(1);
        if !Anchor::is_valid_scale(scale) {
            return Err(AnchorError::InvalidScale);
        }
        let slot = self.items.iter_mut().find(|a| a.anchor.object == object);
        let slot = slot.ok_or(AnchorError::UnknownObject)?;
        slot.anchor.scale = scale;
        Ok(slot.anchor)
    }

    /// Removes placed `object` and returns it.
    ///
    /// # Errors
    /// [`AnchorError::UnknownObject`]: nothing was placed with that id.
    pub fn remove(&mut self, object: u16) -> Result<Anchor, AnchorError> {
        self.changes = self.changes.wrapping_add(1);
        let k = self.items.iter().position(|a| a.anchor.object == object);
        let k = k.ok_or(AnchorError::UnknownObject)?;
        // Order kept: anchors are listed in the order they were first placed.
        let removed = self.items.remove(k);
        Ok(removed.anchor)
    }

    /// A loop closed and moved the active map by `correction` (a world-to-world motion, the
    /// `LoopClosure::correction` of the frame's result): moves every anchor whose keyframe
    /// `in_map` says the active map holds. Cost: one pose transform per anchor.
    pub fn correct(&mut self, correction: &Pose, in_map: impl Fn(KeyFrameId) -> bool) {
        self.changes = self.changes.wrapping_add(1);
        for a in &mut self.items {
            if a.keyframe.is_some_and(&in_map) {
                a.anchor.p_w = (correction * Point3::from(a.anchor.p_w)).coords.into();
                a.anchor.up_w = (correction.rotation * Vector3::from(a.anchor.up_w)).into();
            }
        }
    }

    /// The anchor of `object`, if placed.
    pub fn get(&self, object: u16) -> Option<&Anchor> {
        self.iter().find(|a| a.object == object)
    }

    /// The anchors, in the order their objects were first placed.
    pub fn iter(&self) -> impl Iterator<Item = &Anchor> {
        self.items.iter().map(|a| &a.anchor)
    }

    /// FNV-1a over every anchor's fields (their bits, in order): what a board and a host replay
    /// of the same frames and commands compare.
    pub fn fingerprint(&self) -> u32 {
        let mut hash = Fnv1a::default();
        for a in self.iter() {
            hash.add(&a.object.to_le_bytes());
            let floats = [a.p_w, a.up_w, [a.scale, 0.0, 0.0]];
            floats.iter().flatten().for_each(|f| hash.add(&f.to_bits().to_le_bytes()));
        }
        hash.value()
    }

    /// Anchors placed.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// No anchor is placed.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }
}
