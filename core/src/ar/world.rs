//! The world's planes and anchors as a map saves them ([`World`]) and loads them
//! ([`SavedWorld`]): [`WORLD_UNITS`] units of a place record's size written after the place
//! records, in a map file as on a board's flash, so the objects a user placed are where they
//! were after a power cycle.
//!
//! A unit (little-endian, [`PLACE_RECORD_BYTES`]): `FW`, format version, the unit's index, the
//! planes and anchors it holds (one byte each), 0 (2 bytes); each plane (40 bytes: normal,
//! offset, centroid, RMS as f32, samples u32, cells u16, observations u16), then each anchor (32
//! bytes: object u16, 0 (2), position, up, scale as f32); zeros; the FNV-1a of the bytes before
//! it (4), as a place record's. The first unit takes planes while they fit; the second the rest
//! and the anchors.
//!
//! What a plane or an anchor is saved without: the track a plane was seen in and the keyframe
//! an anchor was placed against. A loaded world is the remembered one (as the place records
//! are): a loop moves the planes and anchors of the run that loaded it onto it, never it.

use heapless::Vec;

use super::anchor::Anchor;
use super::anchors::Anchors;
use super::plane_map::{MAX_MAP_PLANES, MapPlane, PlaneMap};
use super::planes::{Plane, dot};
use crate::config::capacity::{MAX_ANCHORS, PLACE_RECORD_BYTES};
use crate::map::{Get, Put, RecordBytes, is_sealed, seal};

/// Units a saved world takes after the place records.
pub const WORLD_UNITS: usize = 2;

const MAGIC: [u8; 2] = *b"FW";
const VERSION: u8 = 1;
const HEAD_BYTES: usize = 8;
const PLANE_BYTES: usize = 40;
const ANCHOR_BYTES: usize = 32;
/// Bytes of a unit before its checksum.
const BODY_BYTES: usize = PLACE_RECORD_BYTES - 4;
/// Planes the first unit holds at most.
const FIRST_UNIT_PLANES: usize = (BODY_BYTES - HEAD_BYTES) / PLANE_BYTES;
const _: () = assert!(
    HEAD_BYTES
        + MAX_MAP_PLANES.saturating_sub(FIRST_UNIT_PLANES) * PLANE_BYTES
        + MAX_ANCHORS * ANCHOR_BYTES
        <= BODY_BYTES
);

/// A normal or an up must be of unit length within this to be taken (a saved one is to a few
/// ulps).
const UNIT_TOLERANCE: f32 = 1e-3;

/// The planes and anchors of a run, to be saved (see the module documentation).
#[derive(Debug, Clone, Copy)]
pub struct World<'a> {
    /// The world's planes.
    pub planes: &'a PlaneMap,
    /// The objects placed on them.
    pub anchors: &'a Anchors,
}

impl World<'_> {
    /// The planes' and anchors' change counts ([`PlaneMap::changes`], [`Anchors::changes`]):
    /// equal counts of one system's world mean the same world.
    pub fn changes(&self) -> (u32, u32) {
        (self.planes.changes(), self.anchors.changes())
    }

    /// Unit `unit` (`0..WORLD_UNITS`) of the saved world, into `buf`. Cost: one pass over the
    /// planes and anchors.
    pub fn encode(&self, unit: usize, buf: &mut RecordBytes) {
        let planes = self.planes.planes();
        let (first, rest) = planes.split_at(planes.len().min(FIRST_UNIT_PLANES));
        let (planes, anchors) = if unit == 0 { (first, 0) } else { (rest, self.anchors.len()) };
        buf.fill(0);
        let mut w = Put { buf, at: 0 };
        w.bytes(&MAGIC);
        w.bytes(&[VERSION, unit as u8, planes.len() as u8, anchors as u8, 0, 0]);
        for m in planes {
            let p = &m.plane;
            for f in p.normal.iter().chain(&[p.offset_m]).chain(&p.centroid).chain(&[p.rms_m]) {
                w.bytes(&f.to_le_bytes());
            }
            w.bytes(&p.samples.to_le_bytes());
            w.bytes(&p.cells.to_le_bytes());
            w.bytes(&m.observations.to_le_bytes());
        }
        for a in self.anchors.iter().take(anchors) {
            w.bytes(&a.object.to_le_bytes());
            w.bytes(&[0, 0]);
            for f in a.p_w.iter().chain(&a.up_w).chain(&[a.scale]) {
                w.bytes(&f.to_le_bytes());
            }
        }
        seal(buf);
    }
}

/// Why saved world units cannot be taken; nothing of them is then.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum WorldError {
    /// The unit does not start with the world's magic: not a world unit.
    NotAWorld,
    /// A format version this build does not read.
    Version(u8),
    /// The unit's checksum does not match its bytes.
    Checksum,
    /// The unit is not the one expected next (its index).
    Order(u8),
    /// It holds more planes or anchors than fit, or than this build keeps.
    Counts,
    /// A plane that is not one (a field not finite, a normal not of unit length).
    Plane,
    /// An anchor that is not one (not finite, an up not of unit length, a scale not positive,
    /// an object placed twice, its reserved bytes not zero).
    Anchor,
    /// Fewer than [`WORLD_UNITS`] units were taken.
    Incomplete,
    /// Bytes that are 0 in every unit written (reserved, unused) are not.
    Padding,
}

impl core::fmt::Display for WorldError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::NotAWorld => write!(f, "not a world unit (no FW magic)"),
            Self::Version(v) => write!(f, "world format version {v}; this build reads {VERSION}"),
            Self::Checksum => write!(f, "a world unit's checksum does not match its bytes"),
            Self::Order(i) => write!(f, "world unit {i} where another was expected"),
            Self::Counts => write!(f, "a world unit holds more planes or anchors than fit"),
            Self::Plane => write!(f, "a saved plane is not a plane"),
            Self::Anchor => write!(f, "a saved anchor is not an anchor"),
            Self::Incomplete => write!(f, "the world's units are not all there"),
            Self::Padding => write!(f, "a world unit's reserved or unused bytes are not zero"),
        }
    }
}

impl core::error::Error for WorldError {}

/// A saved world read back, unit by unit ([`Self::take`]), then checked whole
/// ([`Self::whole`]). About 1.6 KiB.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SavedWorld {
    planes: Vec<MapPlane, MAX_MAP_PLANES>,
    anchors: Vec<Anchor, MAX_ANCHORS>,
    /// Units taken.
    units: u8,
}

impl SavedWorld {
    /// Nothing taken yet.
    pub const fn new() -> Self {
        Self { planes: Vec::new(), anchors: Vec::new(), units: 0 }
    }

    /// The world unit in `buf`, the next in order (see the module documentation). Cost: one
    /// pass over the unit.
    ///
    /// # Errors
    /// [`WorldError`]: what is wrong with the unit; what was taken before stays.
    pub fn take(&mut self, buf: &RecordBytes) -> Result<(), WorldError> {
        check_head(buf)?;
        let [_, _, _, index, planes, anchors, r0, r1] = head(buf);
        if index != self.units || usize::from(index) >= WORLD_UNITS {
            return Err(WorldError::Order(index));
        }
        let (planes, anchors) = (usize::from(planes), usize::from(anchors));
        let room = if index == 0 { FIRST_UNIT_PLANES } else { MAX_MAP_PLANES };
        let used = HEAD_BYTES + planes * PLANE_BYTES + anchors * ANCHOR_BYTES;
        // As `World::encode` lays them out, and no other way: a unit taken encodes back to
        // its own bytes.
        let laid_out = if index == 0 {
            anchors == 0
        } else {
            planes == 0 || self.planes.len() == FIRST_UNIT_PLANES
        };
        if used > BODY_BYTES
            || planes > room
            || self.planes.len() + planes > MAX_MAP_PLANES
            || anchors > MAX_ANCHORS
            || !laid_out
        {
            return Err(WorldError::Counts);
        }
        let unused = buf.get(used..BODY_BYTES).unwrap_or(&[]);
        if [r0, r1] != [0, 0] || unused.iter().any(|&b| b != 0) {
            return Err(WorldError::Padding);
        }
        let mut r = Get { buf, at: HEAD_BYTES };
        let mut taken = Self { units: self.units + 1, ..self.clone() };
        for _ in 0..planes {
            let plane = read_plane(&mut r).ok_or(WorldError::Plane)?;
            taken.planes.push(plane).map_err(|_| WorldError::Counts)?;
        }
        for _ in 0..anchors {
            let anchor = read_anchor(&mut r).ok_or(WorldError::Anchor)?;
            if taken.anchors.iter().any(|a| a.object == anchor.object) {
                return Err(WorldError::Anchor);
            }
            taken.anchors.push(anchor).map_err(|_| WorldError::Counts)?;
        }
        *self = taken;
        Ok(())
    }

    /// The world, when every unit was taken.
    ///
    /// # Errors
    /// [`WorldError::Incomplete`] otherwise.
    pub fn whole(self) -> Result<Self, WorldError> {
        if usize::from(self.units) == WORLD_UNITS { Ok(self) } else { Err(WorldError::Incomplete) }
    }

    /// The planes, in the order they were kept.
    pub fn planes(&self) -> &[MapPlane] {
        &self.planes
    }

    /// The anchors, in the order their objects were first placed.
    pub fn anchors(&self) -> &[Anchor] {
        &self.anchors
    }

    /// The planes and anchors as a run holds them again ([`PlaneMap::restored`],
    /// [`Anchors::restored`]): what a [`World`] of them saves is the bytes they were read from.
    pub fn restored(&self) -> (PlaneMap, Anchors) {
        (PlaneMap::restored(&self.planes), Anchors::restored(&self.anchors))
    }
}

/// Whether `buf` looks like a world unit (its magic): what tells one from a place record in a
/// store's slots before it is taken.
pub fn is_world_unit(buf: &RecordBytes) -> bool {
    buf.starts_with(&MAGIC)
}

/// The unit's first bytes.
fn head(buf: &RecordBytes) -> [u8; HEAD_BYTES] {
    Get { buf, at: 0 }.take()
}

fn check_head(buf: &RecordBytes) -> Result<(), WorldError> {
    let h = head(buf);
    if !is_world_unit(buf) {
        return Err(WorldError::NotAWorld);
    }
    if h[2] != VERSION {
        return Err(WorldError::Version(h[2]));
    }
    if !is_sealed(buf) {
        return Err(WorldError::Checksum);
    }
    Ok(())
}

fn read_plane(r: &mut Get<'_>) -> Option<MapPlane> {
    let mut f = [0.0f32; 8];
    f.iter_mut().for_each(|v| *v = r.f32());
    let samples = u32::from_le_bytes(r.take());
    let cells = u16::from_le_bytes(r.take());
    let observations = u16::from_le_bytes(r.take());
    let [n0, n1, n2, offset_m, c0, c1, c2, rms_m] = f;
    let plane =
        Plane { normal: [n0, n1, n2], offset_m, centroid: [c0, c1, c2], rms_m, cells, samples };
    let ok = f.iter().all(|v| v.is_finite()) && is_unit(&plane.normal) && rms_m >= 0.0;
    ok.then_some(MapPlane { plane, observations, track: 0 })
}

fn read_anchor(r: &mut Get<'_>) -> Option<Anchor> {
    let object = u16::from_le_bytes(r.take());
    let pad: [u8; 2] = r.take();
    let mut f = [0.0f32; 7];
    f.iter_mut().for_each(|v| *v = r.f32());
    let [p0, p1, p2, u0, u1, u2, scale] = f;
    let anchor = Anchor { object, p_w: [p0, p1, p2], up_w: [u0, u1, u2], scale };
    let ok = pad == [0, 0] && f.iter().all(|v| v.is_finite()) && is_unit(&anchor.up_w);
    (ok && Anchor::is_valid_scale(scale)).then_some(anchor)
}

fn is_unit(v: &[f32; 3]) -> bool {
    (dot(v, v) - 1.0).abs() <= UNIT_TOLERANCE
}
