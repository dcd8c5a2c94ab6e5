//! The map file: the long-term store's records ([`crate::map::PlaceRecord`], 1 KiB each) behind
//! a 20-byte header, then the world's planes and anchors ([`crate::ar::World`], in
//! [`WORLD_UNITS`] units of a record's size), so a map saved by one run can be loaded by the
//! next.
//!
//! Layout (little-endian): `FSMP` (4 bytes), format version (1); the record layout the writer's
//! capacities gave: verification points per record (1), place key width and height in cells
//! (1 + 1), bytes per record (2); world units after the records (1: 0 or [`WORLD_UNITS`]), 0
//! (1); records (4), FNV-1a checksum of every record's and world unit's bytes (4); then the
//! records, each as the store holds it (with its own checksum), then the world units. A reader
//! checks the header before it takes any record and every record and world unit before the map
//! is used, so a file from another format, truncated or with one bit flipped is refused whole,
//! with an error that names what is wrong ([`MapFileError`]). Version 2 files (no world: the
//! byte was reserved, 0) are read as maps without planes or anchors.
//!
//! On a board the same records live in a NOR flash region ([`FlashStore`]): written as the map
//! grows, made the map a boot finds by a commit, safe against a power cut at any write, on flash
//! that erases a record at a time (the QEMU board's region) or large sectors (the reference
//! board's 128 KiB). The world units are its last slots.

use core::fmt;

mod cut_flash;
mod flash;
mod flip_flash;
mod slice_flash;

pub use cut_flash::{COUNTED_UNITS, CutError, CutFlash};
pub use flip_flash::FlipFlash;

pub use flash::{
    FlashStore, FlashStoreError, MAX_RECORD_UNITS, MAX_SECTOR_UNITS, RELOCATE_EVERY, SPARE_UNITS,
    TABLE_SLOTS, TABLE_UNITS, flash_bytes_for, sector_capacity,
};
pub use slice_flash::{SECTOR_BYTES, SliceFlash, SliceFlashError};

use crate::ar::{SavedWorld, WORLD_UNITS, WorldError};
use crate::config::capacity::{PLACE_KEY_H, PLACE_KEY_W, PLACE_POINTS, PLACE_RECORD_BYTES};
use crate::map::{Fnv1a, PlaceRecord, RecordBytes};

/// The file's first bytes.
pub const MAP_MAGIC: [u8; 4] = *b"FSMP";

/// The format version this build writes (1: a 16-byte header without the layout; 2: no world
/// units, still read).
pub const MAP_VERSION: u8 = 3;

/// The oldest format version this build reads.
pub const MAP_OLDEST_VERSION: u8 = 2;

/// Bytes of the header before the records.
pub const MAP_HEADER_BYTES: usize = 20;

/// The record layout this build's capacities give: what a map file's header must state.
pub const MAP_LAYOUT: RecordLayout = RecordLayout {
    record_bytes: PLACE_RECORD_BYTES as u16,
    points: PLACE_POINTS as u8,
    key: [PLACE_KEY_W as u8, PLACE_KEY_H as u8],
};

/// The capacities that shape a record: a file written by a build with other ones cannot be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RecordLayout {
    /// Bytes of one record.
    pub record_bytes: u16,
    /// Verification points a record holds at most.
    pub points: u8,
    /// The place key's width and height, cells.
    pub key: [u8; 2],
}

impl fmt::Display for RecordLayout {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [w, h] = self.key;
        write!(f, "records of {} bytes, {} points, a {w} x {h} key", self.record_bytes, self.points)
    }
}

/// A map file's header: how many records and world units follow and their checksum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MapHeader {
    /// Records after the header.
    pub records: u32,
    /// World units after the records: 0 or [`WORLD_UNITS`].
    pub world_units: u8,
    /// FNV-1a of the records' and world units' bytes, in order ([`RecordsChecksum`]).
    pub checksum: u32,
}

impl MapHeader {
    /// The header's bytes.
    pub fn encode(&self) -> [u8; MAP_HEADER_BYTES] {
        let mut out = [0u8; MAP_HEADER_BYTES];
        let l = MAP_LAYOUT;
        let fields: [&[u8]; 8] = [
            &MAP_MAGIC,
            &[MAP_VERSION],
            &[l.points],
            &l.key,
            &l.record_bytes.to_le_bytes(),
            &[self.world_units, 0],
            &self.records.to_le_bytes(),
            &self.checksum.to_le_bytes(),
        ];
        let mut at = 0;
        for f in fields {
            if let Some(dst) = out.get_mut(at..at + f.len()) {
                dst.copy_from_slice(f);
            }
            at += f.len();
        }
        out
    }

    /// The header at the start of `bytes` (a whole file or its first [`MAP_HEADER_BYTES`]).
    ///
    /// # Errors
    /// [`MapFileError::Truncated`], [`MapFileError::NotAMap`], [`MapFileError::Version`] or
    /// [`MapFileError::Layout`], [`MapFileError::Reserved`] or [`MapFileError::WorldUnits`]; the
    /// magic and the version are checked first, so a file of another version is named as such
    /// even when shorter than this version's header.
    pub fn decode(bytes: &[u8]) -> Result<Self, MapFileError> {
        let byte = |at: usize| bytes.get(at).copied().unwrap_or(0);
        let word =
            |at: usize| u32::from_le_bytes([byte(at), byte(at + 1), byte(at + 2), byte(at + 3)]);
        if bytes.len() >= 4 && bytes.get(..4) != Some(&MAP_MAGIC[..]) {
            return Err(MapFileError::NotAMap);
        }
        if bytes.len() > 4 && !(MAP_OLDEST_VERSION..=MAP_VERSION).contains(&byte(4)) {
            return Err(MapFileError::Version(byte(4)));
        }
        if bytes.len() < MAP_HEADER_BYTES {
            return Err(MapFileError::Truncated { expected: MAP_HEADER_BYTES, found: bytes.len() });
        }
        let layout = RecordLayout {
            points: byte(5),
            key: [byte(6), byte(7)],
            record_bytes: u16::from_le_bytes([byte(8), byte(9)]),
        };
        if layout != MAP_LAYOUT {
            return Err(MapFileError::Layout(layout));
        }
        let (version, world_units) = (byte(4), byte(10));
        if byte(11) != 0 || (version < 3 && world_units != 0) {
            return Err(MapFileError::Reserved([world_units, byte(11)]));
        }
        if world_units != 0 && usize::from(world_units) != WORLD_UNITS {
            return Err(MapFileError::WorldUnits(world_units));
        }
        Ok(Self { records: word(12), world_units, checksum: word(16) })
    }

    /// Bytes of the whole file this header describes.
    pub fn file_bytes(&self) -> usize {
        let units = self.records as usize + usize::from(self.world_units);
        MAP_HEADER_BYTES + units * PLACE_RECORD_BYTES
    }
}

/// FNV-1a over the records' bytes as they are written or read, one record at a time (the
/// record checksum's hash).
pub type RecordsChecksum = Fnv1a;

/// Checks the map file `file` whole, for a store of `capacity` records: the header, the length,
/// the record count, the checksum over the records and world units, then every record and the
/// world. Cost: every unit hashed once and decoded once.
///
/// # Errors
/// The first check that fails.
pub fn check_map_file(file: &[u8], capacity: usize) -> Result<MapHeader, MapFileError> {
    let header = MapHeader::decode(file)?;
    let expected = header.file_bytes();
    if file.len() < expected {
        return Err(MapFileError::Truncated { expected, found: file.len() });
    }
    if file.len() > expected {
        return Err(MapFileError::TrailingBytes { expected, found: file.len() });
    }
    if header.records as usize > capacity {
        return Err(MapFileError::TooManyRecords { records: header.records, capacity });
    }
    let mut checksum = RecordsChecksum::default();
    map_units(file).for_each(|r| checksum.add(r));
    if checksum.value() != header.checksum {
        return Err(MapFileError::Checksum { stored: header.checksum, computed: checksum.value() });
    }
    let mut buf = [0u8; PLACE_RECORD_BYTES];
    for (index, r) in (0u32..).zip(map_records(file)) {
        buf.copy_from_slice(r);
        if PlaceRecord::decode(&buf).is_err() {
            return Err(MapFileError::Record { index });
        }
    }
    map_world(file)?;
    Ok(header)
}

/// Every unit after a map file's header: its records, then its world units.
fn map_units(file: &[u8]) -> core::slice::ChunksExact<'_, u8> {
    file.get(MAP_HEADER_BYTES..).unwrap_or(&[]).chunks_exact(PLACE_RECORD_BYTES)
}

/// The records' bytes of a map file, in order (after [`check_map_file`]: every one decodes).
pub fn map_records(file: &[u8]) -> core::iter::Take<core::slice::ChunksExact<'_, u8>> {
    let records = MapHeader::decode(file).map_or(0, |h| h.records as usize);
    map_units(file).take(records)
}

/// The planes and anchors a map file holds after its records (`None`: a file without them).
/// Cost: each world unit decoded once; about 1.6 KiB on the caller's stack.
///
/// # Errors
/// [`MapFileError::World`]: a world unit does not decode (or the header cannot be read).
pub fn map_world(file: &[u8]) -> Result<Option<SavedWorld>, MapFileError> {
    let header = MapHeader::decode(file)?;
    if header.world_units == 0 {
        return Ok(None);
    }
    let mut world = SavedWorld::new();
    let mut buf: RecordBytes = [0; PLACE_RECORD_BYTES];
    for unit in map_units(file).skip(header.records as usize) {
        buf.copy_from_slice(unit);
        world.take(&buf).map_err(MapFileError::World)?;
    }
    world.whole().map(Some).map_err(MapFileError::World)
}

/// Why a map file cannot be loaded; nothing of it is loaded then.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum MapFileError {
    /// The file is shorter than its header says (or than a header).
    Truncated {
        /// Bytes a whole file would have.
        expected: usize,
        /// Bytes it has.
        found: usize,
    },
    /// It is longer than its header says.
    TrailingBytes {
        /// Bytes a whole file would have.
        expected: usize,
        /// Bytes it has.
        found: usize,
    },
    /// It does not start with [`MAP_MAGIC`]: not a map file.
    NotAMap,
    /// A format version this build does not read.
    Version(u8),
    /// Records of another layout: a build with other capacities wrote it (its layout).
    Layout(RecordLayout),
    /// The header's reserved bytes (10 and 11 in version 2, 11 in version 3) are not zero: not a
    /// file this build wrote.
    Reserved([u8; 2]),
    /// The header states a number of world units other than 0 and [`WORLD_UNITS`].
    WorldUnits(u8),
    /// The world's planes and anchors after the records do not decode.
    World(WorldError),
    /// The records' checksum does not match the header's: bytes changed since it was written.
    Checksum {
        /// The header's.
        stored: u32,
        /// The records'.
        computed: u32,
    },
    /// A record does not decode (its own checksum or format).
    Record {
        /// Its index in the file.
        index: u32,
    },
    /// More records than the store holds.
    TooManyRecords {
        /// Records in the file.
        records: u32,
        /// Records the store holds.
        capacity: usize,
    },
}

impl fmt::Display for MapFileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::Truncated { expected, found } => {
                write!(f, "truncated: {found} bytes where the header says {expected}")
            }
            Self::TrailingBytes { expected, found } => {
                write!(f, "{found} bytes where the header says {expected}: trailing bytes")
            }
            Self::NotAMap => write!(f, "not a ferroslam map file (no FSMP magic)"),
            Self::Version(v) => write!(
                f,
                "map format version {v}; this build reads versions {MAP_OLDEST_VERSION} to \
                 {MAP_VERSION}"
            ),
            Self::Reserved(b) => write!(
                f,
                "reserved header bytes {b:?} are not zero: not a map file this build wrote"
            ),
            Self::WorldUnits(n) => {
                write!(f, "{n} world units; a map has 0 or {WORLD_UNITS}")
            }
            Self::World(e) => write!(f, "planes and anchors: {e}"),
            Self::Layout(l) => write!(
                f,
                "written by a build with other capacities: {l}; this build's are {MAP_LAYOUT}"
            ),
            Self::Checksum { stored, computed } => write!(
                f,
                "checksum {computed:#010x} of the records, {stored:#010x} in the header: the \
                 file changed since it was written"
            ),
            Self::Record { index } => write!(f, "record {index} does not decode"),
            Self::TooManyRecords { records, capacity } => {
                write!(f, "{records} records, more than the store's {capacity}")
            }
        }
    }
}

impl core::error::Error for MapFileError {}

#[cfg(test)]
mod tests;
