//! The long-term tier of the map: what the robot remembers of a keyframe once it leaves the
//! active map, a [`PlaceRecord`] of fixed size, kept behind a storage port ([`KeyframeStore`]):
//! RAM on the host ([`RamStore`]), a NOR flash region on a board (`persist::FlashStore`, a layer
//! up).
//!
//! A record holds the keyframe's creation number, timestamp and pose `t_wc`, its [`PlaceKey`]
//! (a thumbnail that ranks remembered places against a query) and up to
//! [`PLACE_POINTS`](capacity::PLACE_POINTS) verification points: landmarks it observed, in the
//! keyframe's camera frame, with their 64-bit descriptors. Camera-frame points move with the
//! keyframe when its pose is corrected later.
//!
//! # Layout
//!
//! [`PLACE_RECORD_BYTES`](capacity::PLACE_RECORD_BYTES) bytes, little endian: magic `b"FP"`,
//! version (1), point count, `seq` u32, timestamp f64, translation 3 x f32 (m), rotation
//! quaternion `i j k w` 4 x f32, the key's 192 bytes, then per point 3 x i16 (mm) and the
//! descriptor u64 (14 bytes), zeros after, and the FNV-1a checksum of all bytes before it in the
//! last 4. An erased slot (all `0xFF` on NOR flash, zeros in RAM) decodes as
//! [`RecordError::Empty`]; a record with a bad checksum as [`RecordError::Corrupt`].

use core::fmt;

use heapless::Vec;
use nalgebra::{Point3, Quaternion, Translation3, UnitQuaternion};

use crate::config::capacity::{PLACE_KEY_H, PLACE_KEY_W, PLACE_POINTS, PLACE_RECORD_BYTES};
use crate::features::Descriptor;
use crate::geometry::Pose;

/// Cells of a [`PlaceKey`].
pub const PLACE_KEY_CELLS: usize = PLACE_KEY_W * PLACE_KEY_H;

/// One stored record's bytes.
pub type RecordBytes = [u8; PLACE_RECORD_BYTES];

const MAGIC: [u8; 2] = *b"FP";
const VERSION: u8 = 1;
const HEADER_BYTES: usize = 2 + 1 + 1 + 4 + 8 + 12 + 16 + PLACE_KEY_CELLS;
const POINT_BYTES: usize = 3 * 2 + 8;
const CHECKSUM_AT: usize = PLACE_RECORD_BYTES - 4;
const _: () = assert!(HEADER_BYTES + PLACE_POINTS * POINT_BYTES <= CHECKSUM_AT);

/// A keyframe's place key: its image reduced to 16 x 12 cell means (gray levels), compared
/// zero-mean so that a global brightness change does not matter. A whole-image key in the
/// manner of PTAM's small blurry images (Klein and Murray 2008): a revisit seen from about the
/// same viewpoint ranks first, and geometric verification decides. Why: docs/decisions.md, "Place
/// key: a 16 x 12 thumbnail".
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct PlaceKey(pub [u8; PLACE_KEY_CELLS]);

impl Default for PlaceKey {
    fn default() -> Self {
        Self([0; PLACE_KEY_CELLS])
    }
}

impl fmt::Debug for PlaceKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "PlaceKey({} cells)", PLACE_KEY_CELLS)
    }
}

impl PlaceKey {
    /// The key of a gray image given as `pixels` (`width` x `height`, row-major; a small image
    /// of the frame): cell means over equal blocks, the right and bottom remainders left out.
    /// All zeros when the image is smaller than the key.
    pub fn of(pixels: &[u8], width: usize, height: usize) -> Self {
        let (bw, bh) = (width / PLACE_KEY_W, height / PLACE_KEY_H);
        let mut key = Self::default();
        if bw == 0 || bh == 0 || pixels.len() < width * height {
            return key;
        }
        let n = (bw * bh) as u32;
        for (c, out) in key.0.iter_mut().enumerate() {
            let (cx, cy) = (c % PLACE_KEY_W, c / PLACE_KEY_W);
            let mut sum = 0u32;
            for y in cy * bh..(cy + 1) * bh {
                let row = pixels.get(y * width + cx * bw..y * width + (cx + 1) * bw);
                sum += row.map_or(0, |r| r.iter().map(|&p| u32::from(p)).sum::<u32>());
            }
            *out = (sum / n) as u8;
        }
        key
    }

    /// The zero-mean sum of absolute differences to `other`, in gray levels times the cell
    /// count (0: the same up to brightness). Exact integers: the same on every target.
    pub fn distance(&self, other: &Self) -> u32 {
        let n = PLACE_KEY_CELLS as i32;
        let sum = |k: &Self| k.0.iter().map(|&v| i32::from(v)).sum::<i32>();
        let (sa, sb) = (sum(self), sum(other));
        let mut d = 0u32;
        for (&a, &b) in self.0.iter().zip(&other.0) {
            d += ((i32::from(a) * n - sa) - (i32::from(b) * n - sb)).unsigned_abs();
        }
        d / PLACE_KEY_CELLS as u32
    }
}

/// Words of [`KeyBits`].
pub const KEY_BITS_WORDS: usize = PLACE_KEY_CELLS.div_ceil(32);

/// A [`PlaceKey`] reduced to one bit per cell: set where the cell is brighter than the key's mean.
/// What the place memory's index keeps in RAM for each record (24 bytes against the key's 192):
/// the Hamming distance between two of them ranks places roughly as the keys' distance does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct KeyBits(pub [u32; KEY_BITS_WORDS]);

impl KeyBits {
    /// Cells whose bit differs.
    pub fn distance(&self, other: &Self) -> u32 {
        self.0.iter().zip(&other.0).map(|(a, b)| (a ^ b).count_ones()).sum()
    }
}

impl PlaceKey {
    /// The key's [`KeyBits`] (exact integers: the same on every target).
    pub fn bits(&self) -> KeyBits {
        let n = PLACE_KEY_CELLS as u32;
        let sum: u32 = self.0.iter().map(|&v| u32::from(v)).sum();
        let mut bits = KeyBits::default();
        for (c, &v) in self.0.iter().enumerate() {
            if u32::from(v) * n > sum
                && let Some(w) = bits.0.get_mut(c / 32)
            {
                *w |= 1 << (c % 32);
            }
        }
        bits
    }
}

/// A verification point of a remembered keyframe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacePoint {
    /// Position in the keyframe's camera frame, metres (stored to the millimetre).
    pub p_c: Point3<f32>,
    /// The landmark's descriptor.
    pub descriptor: Descriptor,
}

/// A remembered keyframe (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct PlaceRecord {
    /// The keyframe's creation number in its map.
    pub seq: u32,
    /// Capture time, seconds.
    pub timestamp_s: f64,
    /// Camera-to-world pose.
    pub t_wc: Pose,
    /// The place key of its frame.
    pub key: PlaceKey,
    /// Its verification points.
    pub points: Vec<PlacePoint, PLACE_POINTS>,
}

/// Why a record could not be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RecordError {
    /// The slot holds no record (erased or never written).
    Empty,
    /// A record of another format version.
    Version(u8),
    /// The checksum does not match, or a field is out of range.
    Corrupt,
}

impl fmt::Display for RecordError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Empty => write!(f, "the slot holds no record"),
            Self::Version(v) => {
                write!(f, "a record of format version {v} (this build reads {VERSION})")
            }
            Self::Corrupt => write!(f, "the record's checksum does not match"),
        }
    }
}

impl core::error::Error for RecordError {}

/// FNV-1a (32-bit), fed in pieces: the record checksum, and the map file's over its records
/// (deterministic, no table).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fnv1a(u32);

impl Default for Fnv1a {
    fn default() -> Self {
        Self(0x811C_9DC5)
    }
}

impl Fnv1a {
    /// Adds `bytes` to what was fed so far.
    pub fn add(&mut self, bytes: &[u8]) {
        self.0 = bytes.iter().fold(self.0, |h, &b| (h ^ u32::from(b)).wrapping_mul(0x0100_0193));
    }

    /// The checksum of everything fed so far.
    pub fn value(&self) -> u32 {
        self.0
    }
}

/// FNV-1a over `bytes`.
fn fnv1a(bytes: &[u8]) -> u32 {
    let mut h = Fnv1a::default();
    h.add(bytes);
    h.value()
}

/// A writer of little-endian fields into a record (nothing past its end).
pub(crate) struct Put<'a> {
    pub(crate) buf: &'a mut RecordBytes,
    pub(crate) at: usize,
}

impl Put<'_> {
    pub(crate) fn bytes(&mut self, b: &[u8]) {
        if let Some(dst) = self.buf.get_mut(self.at..self.at + b.len()) {
            dst.copy_from_slice(b);
        }
        self.at += b.len();
    }
}

/// A reader of little-endian fields from a record (zeros past its end).
pub(crate) struct Get<'a> {
    pub(crate) buf: &'a RecordBytes,
    pub(crate) at: usize,
}

impl Get<'_> {
    pub(crate) fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0; N];
        if let Some(src) = self.buf.get(self.at..self.at + N) {
            out.copy_from_slice(src);
        }
        self.at += N;
        out
    }

    pub(crate) fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.take())
    }
}

/// Writes the checksum of `buf`'s bytes before its last four into them: what closes a record
/// (and a world unit, `ar::world`).
pub(crate) fn seal(buf: &mut RecordBytes) {
    let sum = fnv1a(buf.get(..CHECKSUM_AT).unwrap_or(&[]));
    if let Some(dst) = buf.get_mut(CHECKSUM_AT..) {
        dst.copy_from_slice(&sum.to_le_bytes());
    }
}

/// Whether `buf`'s last four bytes are the checksum of the bytes before them ([`seal`]).
pub(crate) fn is_sealed(buf: &RecordBytes) -> bool {
    let stored = u32::from_le_bytes(
        buf.get(CHECKSUM_AT..).and_then(|s| s.try_into().ok()).unwrap_or([0; 4]),
    );
    stored == fnv1a(buf.get(..CHECKSUM_AT).unwrap_or(&[]))
}

impl PlaceRecord {
    /// The record's bytes (see the module documentation). Points past the millimetre range of
    /// an i16 (32.7 m) are clamped to it.
    pub fn encode(&self, buf: &mut RecordBytes) {
        buf.fill(0);
        let mut w = Put { buf, at: 0 };
        w.bytes(&MAGIC);
        w.bytes(&[VERSION, self.points.len() as u8]);
        w.bytes(&self.seq.to_le_bytes());
        w.bytes(&self.timestamp_s.to_le_bytes());
        for v in self.t_wc.translation.vector.iter() {
            w.bytes(&v.to_le_bytes());
        }
        for v in self.t_wc.rotation.coords.iter() {
            w.bytes(&v.to_le_bytes());
        }
        w.bytes(&self.key.0);
        for p in &self.points {
            for v in p.p_c.coords.iter() {
                let mm = libm::roundf(v * 1000.0).clamp(f32::from(i16::MIN), f32::from(i16::MAX));
                w.bytes(&(mm as i16).to_le_bytes());
            }
            w.bytes(&p.descriptor.0.to_le_bytes());
        }
        seal(buf);
    }

    /// The record in `buf`.
    ///
    /// # Errors
    /// [`RecordError::Empty`] for an erased or unwritten slot, [`RecordError::Version`] for
    /// another format, [`RecordError::Corrupt`] for a bad checksum or a non-finite pose.
    pub fn decode(buf: &RecordBytes) -> Result<Self, RecordError> {
        let mut r = Get { buf, at: 0 };
        if r.take::<2>() != MAGIC {
            return Err(RecordError::Empty);
        }
        let [version, count] = r.take::<2>();
        if version != VERSION {
            return Err(RecordError::Version(version));
        }
        if !is_sealed(buf) || usize::from(count) > PLACE_POINTS {
            return Err(RecordError::Corrupt);
        }
        let seq = u32::from_le_bytes(r.take());
        let timestamp_s = f64::from_le_bytes(r.take());
        let t = [r.f32(), r.f32(), r.f32()];
        let q = [r.f32(), r.f32(), r.f32(), r.f32()];
        if !t.iter().chain(&q).all(|v| v.is_finite()) {
            return Err(RecordError::Corrupt);
        }
        let rotation = UnitQuaternion::new_unchecked(Quaternion::new(q[3], q[0], q[1], q[2]));
        let t_wc = Pose::from_parts(Translation3::new(t[0], t[1], t[2]), rotation);
        let key = PlaceKey(r.take());
        let mut points = Vec::new();
        for _ in 0..count {
            let [x, y, z] =
                [r.take(), r.take(), r.take()].map(|b| f32::from(i16::from_le_bytes(b)) / 1000.0);
            let descriptor = Descriptor(u64::from_le_bytes(r.take()));
            // Cannot fail: `count` was checked against the capacity.
            let _ = points.push(PlacePoint { p_c: Point3::new(x, y, z), descriptor });
        }
        Ok(Self { seq, timestamp_s, t_wc, key, points })
    }
}

/// The long-term store's port: fixed-size records in numbered slots (`0..capacity`), in the
/// embedded-hal manner (one small trait, the implementation's own error type). On a board it
/// wraps a flash region; [`RamStore`] is the host's.
pub trait KeyframeStore {
    /// Why a read or a write failed.
    type Error: fmt::Debug;

    /// Slots the store has.
    fn capacity(&self) -> usize;

    /// Reads slot `slot` into `buf` (an unwritten slot reads as zeros or `0xFF`).
    ///
    /// # Errors
    /// The implementation's, e.g. a slot out of range or a failed bus transfer.
    fn read(&mut self, slot: usize, buf: &mut RecordBytes) -> Result<(), Self::Error>;

    /// Writes `buf` to slot `slot`, replacing what it held.
    ///
    /// # Errors
    /// The implementation's.
    fn write(&mut self, slot: usize, buf: &RecordBytes) -> Result<(), Self::Error>;

    /// Records the store held when it was opened, in slots `0..held` (a store that keeps them
    /// across power cycles, as `persist::FlashStore`); 0 for one that starts empty.
    fn held(&self) -> usize {
        0
    }

    /// Makes slots `0..records` the store's map as one step, durable where the store is (what a
    /// boot finds after a power cut); the slots past `records` are dropped. Nothing to do for a
    /// store that does not outlive its run.
    ///
    /// # Errors
    /// The implementation's.
    fn commit(&mut self, records: usize) -> Result<(), Self::Error> {
        let _ = records;
        Ok(())
    }
}

/// A slot out of a store's range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlotOutOfRange(pub usize);

/// A [`KeyframeStore`] of `N` records in RAM (1 KiB each): the host's store.
#[derive(Clone)]
pub struct RamStore<const N: usize> {
    records: [RecordBytes; N],
}

impl<const N: usize> fmt::Debug for RamStore<N> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "RamStore<{N}>")
    }
}

impl<const N: usize> Default for RamStore<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> RamStore<N> {
    /// An empty store (`const`, for a `static`).
    pub const fn new() -> Self {
        Self { records: [[0; PLACE_RECORD_BYTES]; N] }
    }
}

impl<const N: usize> KeyframeStore for RamStore<N> {
    type Error = SlotOutOfRange;

    fn capacity(&self) -> usize {
        N
    }

    fn read(&mut self, slot: usize, buf: &mut RecordBytes) -> Result<(), Self::Error> {
        *buf = *self.records.get(slot).ok_or(SlotOutOfRange(slot))?;
        Ok(())
    }

    fn write(&mut self, slot: usize, buf: &RecordBytes) -> Result<(), Self::Error> {
        *self.records.get_mut(slot).ok_or(SlotOutOfRange(slot))? = *buf;
        Ok(())
    }
}

/// A store of no slots: a system that remembers nothing past its active map.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoStore;

impl KeyframeStore for NoStore {
    type Error = SlotOutOfRange;

    fn capacity(&self) -> usize {
        0
    }

    fn read(&mut self, slot: usize, _: &mut RecordBytes) -> Result<(), Self::Error> {
        Err(SlotOutOfRange(slot))
    }

    fn write(&mut self, slot: usize, _: &RecordBytes) -> Result<(), Self::Error> {
        Err(SlotOutOfRange(slot))
    }
}
