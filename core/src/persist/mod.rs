//! The map file: the long-term store's records ([`crate::map::PlaceRecord`], 1 KiB each) behind
//! a 20-byte header, so a map saved by one run can be loaded by the next.
//!
//! Layout (little-endian): `FSMP` (4 bytes), format version (1); the record layout the writer's
//! capacities gave: verification points per record (1), place key width and height in cells
//! (1 + 1), bytes per record (2), 0 (2); records (4), FNV-1a checksum of every record's bytes
//! (4); then the records, each as the store holds it (with its own checksum). A reader checks the header before it takes any record and
//! every record before the map is used, so a file from another format, truncated or with one bit
//! flipped is refused whole, with an error that names what is wrong ([`MapFileError`]).
//!
//! On a board the same records live in a NOR flash region ([`FlashStore`]): written as the map
//! grows, made the map a boot finds by a commit, safe against a power cut at any write, on flash
//! that erases a record at a time (the QEMU board's region) or large sectors (the reference
//! board's 128 KiB).

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

use crate::config::capacity::{PLACE_KEY_H, PLACE_KEY_W, PLACE_POINTS, PLACE_RECORD_BYTES};
use crate::map::{Fnv1a, PlaceRecord};

/// The file's first bytes.
pub const MAP_MAGIC: [u8; 4] = *b"FSMP";

/// The format version this build writes and reads (1: a 16-byte header without the layout).
pub const MAP_VERSION: u8 = 2;

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

/// A map file's header: how many records follow and their checksum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MapHeader {
    /// Records after the header.
    pub records: u32,
    /// FNV-1a of the records' bytes, in order ([`RecordsChecksum`]).
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
            &[0, 0],
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
    /// [`MapFileError::Layout`] or [`MapFileError::Reserved`]; the magic and the version are checked first, so a file of
    /// another version is named as such even when shorter than this version's header.
    pub fn decode(bytes: &[u8]) -> Result<Self, MapFileError> {
        let byte = |at: usize| bytes.get(at).copied().unwrap_or(0);
        let word =
            |at: usize| u32::from_le_bytes([byte(at), byte(at + 1), byte(at + 2), byte(at + 3)]);
        if bytes.len() >= 4 && bytes.get(..4) != Some(&MAP_MAGIC[..]) {
            return Err(MapFileError::NotAMap);
        }
        if bytes.len() > 4 && byte(4) != MAP_VERSION {
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
        if byte(10) != 0 || byte(11) != 0 {
            return Err(MapFileError::Reserved([byte(10), byte(11)]));
        }
        Ok(Self { records: word(12), checksum: word(16) })
    }

    /// Bytes of the whole file this header describes.
    pub fn file_bytes(&self) -> usize {
        MAP_HEADER_BYTES + self.records as usize * PLACE_RECORD_BYTES
    }
}

/// FNV-1a over the records' bytes as they are written or read, one record at a time (the
/// record checksum's hash).
pub type RecordsChecksum = Fnv1a;

/// Checks the map file `file` whole, for a store of `capacity` records: the header, the length,
/// the record count, the checksum over the records, then every record. Cost: every record
/// hashed once and decoded once.
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
    map_records(file).for_each(|r| checksum.add(r));
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
    Ok(header)
}

/// The records' bytes of a map file, in order (after [`check_map_file`]: every one decodes).
pub fn map_records(file: &[u8]) -> core::slice::ChunksExact<'_, u8> {
    file.get(MAP_HEADER_BYTES..).unwrap_or(&[]).chunks_exact(PLACE_RECORD_BYTES)
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
    /// The header's reserved bytes (10 and 11) are not zero: not a file this build wrote.
    Reserved([u8; 2]),
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
            Self::Version(v) => {
                write!(f, "map format version {v}; this build reads version {MAP_VERSION}")
            }
            Self::Reserved(b) => write!(
                f,
                "reserved header bytes {b:?} are not zero: not a map file this build wrote"
            ),
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
