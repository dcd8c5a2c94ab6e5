//! The place memory: keyframes that leave the active map are remembered in a long-term store
//! ([`crate::map::KeyframeStore`]), a frame the front end cannot track is relocalized in a
//! remembered place that geometric verification accepts, and a new keyframe that verifies in a
//! place the map is not connected to closes a loop.
//!
//! [`PlaceMemory`] implements the front end's port ([`crate::tracking::Places`]):
//! - **Remember** (a keyframe leaving the map): its pose, place key and up to
//!   [`PLACE_POINTS`] observed landmarks with a descriptor
//!   (in its camera frame) become a [`PlaceRecord`] in the next free slot. A full store thins
//!   itself: the new record replaces, among the stored ones that look most like it, the one
//!   nearest to it in pose (the most redundant), never failing and never growing. Its key's
//!   [`KeyBits`] go to a RAM index by slot (24 bytes a record).
//! - **Relocalize** (a lost frame): the index gives the [`SHORTLIST`] records nearest by key
//!   bits; their keys and every key of the active map's keyframes are compared with the frame's;
//!   the [`CANDIDATES`] nearest are verified (`verify.rs`: descriptor matches,
//!   3D-3D RANSAC with Horn/Umeyama, inlier count, spread and ratio); the best verified place
//!   gives the pose, unless another candidate verifies a different pose nearly as well (an
//!   ambiguous scene: nothing is returned). A false relocalization is worse than a missed one.
//!
//! - **Close a loop** (a new keyframe, see [`Places::close_loop`]): the same query, with the
//!   active map's keyframes made after tracking last restarted left out. A verified correction
//!   of at least [`LOOP_MIN_CORRECTION_M`] or [`LOOP_MIN_CORRECTION_RAD`] moves the map: at once
//!   when tracking restarted after the place was seen, else (the map was tracked through since)
//!   once [`HELD_LOOP_CONFIRMATIONS`] loops in a row of [`HELD_MIN_CORRECTION_M`] or
//!   [`HELD_MIN_CORRECTION_RAD`] agree.
//! - **Hold a localizing run on the map** (frozen, a loaded map): after a loop query that
//!   verified a place of the map, [`Places::map_points`] gives the query's inliers with the
//!   map's points (world frame), which the front end's landmarks move halfway to.
//!
//! Cost: a query passes over the index once, decodes [`SHORTLIST`] records and [`CANDIDATES`]
//! of them again, whatever the store holds; each verification is bounded by [`PLACE_POINTS`] x
//! the query's points descriptor comparisons and [`RANSAC_ITERATIONS`] minimal solves.
//! Deterministic: the RANSAC draws come from a generator seeded by the caller. Why this design:
//! docs/decisions.md, "Place memory: what a keyframe leaves behind".

mod verify;

#[cfg(test)]
mod tests;

use heapless::Vec;
use nalgebra::Point3;

use crate::ar::{SavedWorld, WORLD_UNITS, World, WorldError, is_world_unit};
use crate::config::STORE_READ_TRIES;
use crate::config::capacity::PLACE_POINTS;
use crate::geometry::{Pose, camera_gap};
use crate::map::{
    KEY_BITS_WORDS, KeyBits, KeyFrameId, KeyframeStore, Map, PlaceKey, PlacePoint, PlaceRecord,
    RecordBytes,
};
use crate::persist::{
    MapFileError, MapHeader, RecordsChecksum, check_map_file, map_records, map_world,
};
use crate::pose::TrackingRng;
use crate::tracking::{LoopClosure, PlaceQuery, Places};

pub use verify::{RANSAC_ITERATIONS, Verified, VerifyParams, inlier_pairs, verify};

/// Remembered places verified per query, the nearest by key.
pub const CANDIDATES: usize = 3;

/// Records a query reads in full, the nearest by their [`KeyBits`] in the RAM index; their
/// keys then rank them with the active map's keyframes. Bounds a query's reads of the store
/// whatever it holds.
pub const SHORTLIST: usize = 16;

/// Records the RAM index covers: the board's store (a larger store is used up to this many).
pub const INDEXED_RECORDS: usize = crate::config::capacity::BOARD_STORE_KEYFRAMES;

/// Fewest verification points for a keyframe to be remembered.
pub const MIN_RECORD_POINTS: usize = 12;

/// A second verified place whose pose differs from the best's by more than this (metres, or
/// radians of rotation) makes the query ambiguous when its inliers reach
/// [`AMBIGUITY_RATIO`] of the best's.
pub const AMBIGUITY_DISTANCE: f32 = 0.15;
/// See [`AMBIGUITY_DISTANCE`].
pub const AMBIGUITY_RATIO: f32 = 0.8;

/// A verified loop whose correction is below both this translation (metres) and
/// [`LOOP_MIN_CORRECTION_RAD`] is consistent with the map and corrects nothing: a single view's
/// verified pose is not more accurate than that.
pub const LOOP_MIN_CORRECTION_M: f32 = 0.10;
/// See [`LOOP_MIN_CORRECTION_M`] (radians, about 5 degrees).
pub const LOOP_MIN_CORRECTION_RAD: f32 = 0.087;

/// A loop held against a map tracked without a restart (see [`LoopStats::held`]) is applied
/// once this many held loops in a row, each of [`HELD_MIN_CORRECTION_M`] or more, agree (within
/// [`HELD_AGREE_M`] and [`HELD_AGREE_RAD`]): one view's verified pose may be a few centimetres
/// off, so one is not trusted over the tracked chain, but several views that agree on a large
/// correction show drift the chain has accumulated (ORB-SLAM likewise waits for three consistent
/// loop candidates). Why: docs/decisions.md, "Held loops applied once confirmed".
pub const HELD_LOOP_CONFIRMATIONS: u8 = 3;
/// A held loop counts towards [`HELD_LOOP_CONFIRMATIONS`] only when its correction is at least
/// this (metres) or [`HELD_MIN_CORRECTION_RAD`]: twice the loop threshold, as remembered places
/// of one real recording disagree with each other by up to about 14 cm (docs/decisions.md, "Held
/// loops applied once confirmed"), and a map tracked through is not moved by less.
pub const HELD_MIN_CORRECTION_M: f32 = 2.0 * LOOP_MIN_CORRECTION_M;
/// See [`HELD_MIN_CORRECTION_M`] (radians, about 10 degrees).
pub const HELD_MIN_CORRECTION_RAD: f32 = 2.0 * LOOP_MIN_CORRECTION_RAD;
/// Two held corrections agree when they put the new keyframe this close (metres) ...
pub const HELD_AGREE_M: f32 = 0.05;
/// ... and turned this close (radians, about 2 degrees).
pub const HELD_AGREE_RAD: f32 = 0.035;
/// Held loops in a row are those of keyframes at most this many creation numbers apart; a longer
/// gap starts the count again.
pub const HELD_MAX_GAP: u32 = 8;

/// What loop detection did, counted since the place memory was made (serializable for reports).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoopStats {
    /// New keyframes that looked for a loop (the store held an older place).
    pub queries: u32,
    /// Of those, the ones where a remembered place verified.
    pub detected: u32,
    /// Loops detected whose correction moved the map.
    pub accepted: u32,
    /// Loops detected that agreed with the map within a verification's accuracy.
    pub consistent: u32,
    /// Loops detected that disagreed with a map tracked without a restart since the place was
    /// seen: not applied alone (the tracked chain is trusted over one view's pose).
    pub held: u32,
    /// Of the accepted loops, those of a map tracked without a restart: the last of
    /// [`HELD_LOOP_CONFIRMATIONS`] held loops in a row that agreed.
    pub confirmed: u32,
    /// Queries refused because two places verified different poses.
    pub rejected: u32,
}

/// What the place memory did, counted since it was made (serializable for reports).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlaceStats {
    /// Keyframes written to the store.
    pub remembered: u32,
    /// Of those, written over a stored, redundant record (the store was full).
    pub thinned: u32,
    /// Keyframes leaving the map with too few verification points to be remembered.
    pub too_few_points: u32,
    /// Reads or writes the store failed, and records it held that did not decode.
    pub store_errors: u32,
    /// Queries of lost frames.
    pub queries: u32,
    /// Candidate places verified.
    pub verified: u32,
    /// Queries answered with a pose.
    pub relocalized: u32,
    /// Queries refused because two places verified different poses.
    pub ambiguous: u32,
}

/// The place memory over store `S` (see the module documentation).
#[derive(Debug, Clone)]
pub struct PlaceMemory<S> {
    store: S,
    /// Slots `0..len` hold records.
    len: usize,
    params: VerifyParams,
    rng: TrackingRng,
    stats: PlaceStats,
    loops: LoopStats,
    /// The index: each held record's [`KeyBits`], by slot (`0..len`).
    index: [KeyBits; INDEXED_RECORDS],
    /// One record's bytes, read or written.
    buf: RecordBytes,
    /// The slot of a remembered record still in `buf`, not yet written ([`Places::flush`]).
    pending: Option<usize>,
    /// Whether keyframes leaving the map are left unremembered ([`Self::freeze`]).
    frozen: bool,
    /// The creation number after every record's ([`Places::first_free_seq`]).
    next_seq: u32,
    /// The first slot of the world units the store holds (as attached or last committed), until
    /// a record is written over them ([`Self::held_world`]).
    world_at: Option<usize>,
    /// The change counts of the world last committed there ([`World::changes`]); `None` when
    /// unknown (attached or loaded).
    world_saved: Option<(u32, u32)>,
    /// The last held loop (its correction and keyframe creation number) and how many held loops
    /// in a row agreed with it, itself included ([`HELD_LOOP_CONFIRMATIONS`]).
    held_run: Option<HeldRun>,
    /// While frozen: the stored place the last loop query verified (its slot) and the pose it
    /// gave the keyframe, for [`Places::map_points`].
    map_place: Option<(usize, Pose)>,
}

/// Held loops in a row that agree (see [`PlaceMemory`]'s `held_run`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct HeldRun {
    correction: Pose,
    keyframe_seq: u32,
    count: u8,
}

/// Why [`PlaceMemory::save`] stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SaveError<E> {
    /// The writer's error.
    Write(E),
    /// The store could not give a record.
    Map(MapFileError),
}

impl<S: KeyframeStore> PlaceMemory<S> {
    /// A place memory over an empty `store`, its RANSAC seeded by `seed`.
    pub const fn new(store: S, seed: u64) -> Self {
        Self {
            store,
            len: 0,
            params: VerifyParams::DEFAULT,
            rng: TrackingRng::new(seed),
            stats: PlaceStats {
                remembered: 0,
                thinned: 0,
                too_few_points: 0,
                store_errors: 0,
                queries: 0,
                verified: 0,
                relocalized: 0,
                ambiguous: 0,
            },
            loops: LoopStats {
                queries: 0,
                detected: 0,
                accepted: 0,
                consistent: 0,
                held: 0,
                confirmed: 0,
                rejected: 0,
            },
            index: [KeyBits([0; KEY_BITS_WORDS]); INDEXED_RECORDS],
            buf: [0; crate::config::capacity::PLACE_RECORD_BYTES],
            pending: None,
            frozen: false,
            next_seq: 0,
            world_at: None,
            world_saved: None,
            held_run: None,
            map_place: None,
        }
    }

    /// Attaches the memory to `store` in place of its own, forgetting what it held, and takes the
    /// records `store` held when opened (a flash region's last committed map) into its index;
    /// world units after them (a commit's [`World`]) are left for [`Self::held_world`]. For a
    /// memory made `const` in a `static` before its store exists, and for a boot. Cost: each
    /// held record read once; one that does not decode is counted in
    /// [`PlaceStats::store_errors`] and kept in its slot, ranked last.
    pub fn attach(&mut self, store: S) {
        self.store = store;
        self.pending = None;
        self.held_run = None;
        self.len = self.store.held().min(self.store.capacity());
        self.world_at = None;
        self.world_saved = None;
        if let Some(at) = self.len.checked_sub(WORLD_UNITS)
            && self.store.read(at, &mut self.buf).is_ok()
            && is_world_unit(&self.buf)
        {
            self.len = at;
            self.world_at = Some(at);
        }
        self.len = self.len.min(self.places_capacity());
        self.next_seq = 0;
        for slot in 0..self.len {
            match self.read(slot) {
                Some(r) => self.index_record(slot, &r),
                None => {
                    if let Some(b) = self.index.get_mut(slot) {
                        *b = KeyBits([u32::MAX; KEY_BITS_WORDS]);
                    }
                }
            }
        }
    }

    /// The planes and anchors the store held after its records when attached ([`Self::attach`]),
    /// read and checked (`None`: it held none, or a record was written over them since). Read
    /// them before the first frame. Cost: [`WORLD_UNITS`] reads; about 3 KiB of stack.
    ///
    /// # Errors
    /// [`WorldError`]: what is wrong with them (a failed read is [`WorldError::Incomplete`]).
    pub fn held_world(&mut self) -> Option<Result<SavedWorld, WorldError>> {
        let at = self.world_at?;
        self.write_pending();
        let mut world = SavedWorld::new();
        for slot in at..at + WORLD_UNITS {
            if self.store.read(slot, &mut self.buf).is_err() {
                return Some(Err(WorldError::Incomplete));
            }
            if let Err(e) = world.take(&self.buf) {
                return Some(Err(e));
            }
        }
        Some(world.whole())
    }

    /// Makes the records held, then `world`'s planes and anchors (in the [`WORLD_UNITS`] slots
    /// after them), the store's map as one step: on a flash store, what a boot finds after a
    /// power cut ([`KeyframeStore::commit`]). A save on a board is
    /// `MapAccess::remember_all_in` then this. A world of the same system unchanged since the
    /// last commit ([`World::changes`]) and still where it was is not written again, so a
    /// periodic commit of an unchanged map writes nothing.
    ///
    /// # Errors
    /// The store's, counted in [`PlaceStats::store_errors`]; the last commit stands then.
    pub fn commit(&mut self, world: Option<&World<'_>>) -> Result<(), S::Error> {
        self.write_pending();
        let mut slots = self.len;
        if let Some(world) = world {
            let held = self.world_at == Some(self.len) && self.world_saved == Some(world.changes());
            for unit in 0..WORLD_UNITS {
                if !held {
                    world.encode(unit, &mut self.buf);
                    if let Err(e) = self.store.write(slots, &self.buf) {
                        self.stats.store_errors = self.stats.store_errors.saturating_add(1);
                        self.world_at = None;
                        return Err(e);
                    }
                }
                slots += 1;
            }
            self.world_at = Some(self.len);
            self.world_saved = Some(world.changes());
        }
        let done = self.store.commit(slots);
        if done.is_err() {
            self.stats.store_errors = self.stats.store_errors.saturating_add(1);
        }
        done
    }

    /// Writes the held records, then `world`'s planes and anchors, as a map file
    /// ([`crate::persist`]) through `write`, called with the header's bytes, then each record's
    /// in slot order, then each world unit's. Cost: every record read twice (the checksum
    /// first), the world encoded twice.
    ///
    /// # Errors
    /// `write`'s first error; a record the store cannot read is a [`MapFileError::Record`]
    /// (wrapped in [`SaveError::Map`]).
    pub fn save<E>(
        &mut self,
        world: Option<&World<'_>>,
        mut write: impl FnMut(&[u8]) -> Result<(), E>,
    ) -> Result<(), SaveError<E>> {
        self.write_pending();
        let mut checksum = RecordsChecksum::default();
        let world_units = if world.is_some() { WORLD_UNITS } else { 0 };
        for pass in [false, true] {
            if pass {
                let header = MapHeader {
                    records: self.len as u32,
                    world_units: world_units as u8,
                    checksum: checksum.value(),
                };
                write(&header.encode()).map_err(SaveError::Write)?;
            }
            for slot in 0..self.len + world_units {
                match world.filter(|_| slot >= self.len) {
                    Some(w) => w.encode(slot - self.len, &mut self.buf),
                    None => {
                        if self.store.read(slot, &mut self.buf).is_err() {
                            let index = slot as u32;
                            return Err(SaveError::Map(MapFileError::Record { index }));
                        }
                    }
                }
                if pass {
                    write(&self.buf).map_err(SaveError::Write)?;
                } else {
                    checksum.add(&self.buf);
                }
            }
        }
        Ok(())
    }

    /// Replaces what the memory holds by the map file `file` ([`crate::persist`]) and returns the
    /// planes and anchors it holds after its records (`None`: a file without them; give them to
    /// `Slam::restore_world`). The header, the length, the checksum, every record and the world
    /// are checked first, and nothing is taken unless all hold. Cost: every record decoded
    /// twice (checked, then indexed) and written to the store once; the world decoded twice.
    ///
    /// # Errors
    /// What is wrong with the file ([`MapFileError`]); the memory is unchanged then. A store that
    /// fails a write is counted in [`PlaceStats::store_errors`] and keeps what was written.
    pub fn load(&mut self, file: &[u8]) -> Result<Option<SavedWorld>, MapFileError> {
        check_map_file(file, self.places_capacity())?;
        let world = map_world(file)?;
        self.pending = None;
        self.held_run = None;
        self.len = 0;
        self.next_seq = 0;
        self.world_at = None;
        self.world_saved = None;
        for r in map_records(file) {
            self.buf.copy_from_slice(r);
            let Ok(record) = PlaceRecord::decode(&self.buf) else { continue };
            if self.store.write(self.len, &self.buf).is_err() {
                self.stats.store_errors = self.stats.store_errors.saturating_add(1);
                break;
            }
            self.index_record(self.len, &record);
            self.len += 1;
        }
        Ok(world)
    }

    /// Stops (or resumes) remembering: keyframes leaving the map are not written to the store
    /// while frozen (localization in a loaded map adds nothing to it).
    pub fn freeze(&mut self, frozen: bool) {
        self.frozen = frozen;
    }

    /// Records the memory holds at most: the store's slots (up to [`INDEXED_RECORDS`]) but the
    /// [`WORLD_UNITS`] a commit writes the world's planes and anchors to.
    pub fn places_capacity(&self) -> usize {
        self.store.capacity().min(INDEXED_RECORDS).saturating_sub(WORLD_UNITS)
    }

    /// Records held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no record is held.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Running totals.
    pub fn stats(&self) -> PlaceStats {
        self.stats
    }

    /// Loop detection's running totals.
    pub fn loop_stats(&self) -> LoopStats {
        self.loops
    }

    /// The store.
    pub fn store(&self) -> &S {
        &self.store
    }

    /// The record in slot `slot`, or `None` (counted as a store error) when it cannot be read or
    /// decoded in [`STORE_READ_TRIES`] reads.
    fn read(&mut self, slot: usize) -> Option<PlaceRecord> {
        self.write_pending();
        let record = (0..STORE_READ_TRIES).find_map(|_| {
            self.store.read(slot, &mut self.buf).ok()?;
            PlaceRecord::decode(&self.buf).ok()
        });
        if record.is_none() {
            self.stats.store_errors = self.stats.store_errors.saturating_add(1);
        }
        record
    }

    /// Takes `record`, held in slot `slot`, into the index and the creation numbers in use.
    fn index_record(&mut self, slot: usize, record: &PlaceRecord) {
        if let Some(bits) = self.index.get_mut(slot) {
            *bits = record.key.bits();
        }
        self.next_seq = self.next_seq.max(record.seq.saturating_add(1));
    }

    /// Writes the record [`Places::remember`] left in `buf`, if any (counted in
    /// [`PlaceStats::store_errors`] when the store fails).
    fn write_pending(&mut self) {
        let Some(slot) = self.pending.take() else { return };
        if self.world_at.is_some_and(|at| (at..at + WORLD_UNITS).contains(&slot)) {
            self.world_at = None;
            self.world_saved = None;
        }
        if self.store.write(slot, &self.buf).is_err() {
            self.stats.store_errors = self.stats.store_errors.saturating_add(1);
        }
    }

    /// The slot a new record at `t_wc` with key `key` goes to: the next free one, or when the
    /// store is full, among the [`SHORTLIST`] records nearest by key bits (the views most like
    /// it), the one whose pose is nearest (translation in metres plus rotation in radians).
    /// Cost: a pass over the index and at most [`SHORTLIST`] record reads, however full.
    fn slot_for(&mut self, t_wc: &Pose, key: &PlaceKey) -> Option<usize> {
        if self.len < self.places_capacity() {
            return Some(self.len);
        }
        let mut best: Option<(f32, usize)> = None;
        for (_, slot) in self.shortlist(&key.bits()) {
            let Some(r) = self.read(slot) else { return Some(slot) };
            let d = pose_distance(&r.t_wc, t_wc);
            if best.is_none_or(|(b, _)| d < b) {
                best = Some((d, slot));
            }
        }
        best.map(|(_, slot)| slot)
    }
}

impl<S> PlaceMemory<S> {
    /// The [`SHORTLIST`] held records whose key bits are nearest `bits` (`(distance, slot)`; the
    /// nearest kept on ties in slot order), in slot order.
    fn shortlist(&self, bits: &KeyBits) -> Vec<(u32, usize), SHORTLIST> {
        let mut short: Vec<(u32, usize), SHORTLIST> = Vec::new();
        for (slot, b) in self.index.iter().enumerate().take(self.len) {
            let d = b.distance(bits);
            let at = short.iter().position(|&(e, _)| d < e).unwrap_or(short.len());
            if at < SHORTLIST {
                if short.is_full() {
                    let _ = short.pop();
                }
                let _ = short.insert(at, (d, slot));
            }
        }
        short.sort_unstable_by_key(|&(_, slot)| slot);
        short
    }
}

/// Translation distance (m) plus rotation angle (rad) between two poses.
fn pose_distance(a: &Pose, b: &Pose) -> f32 {
    let d = a.inverse() * b;
    d.translation.vector.norm() + d.rotation.angle()
}

impl<S: KeyframeStore> Places for PlaceMemory<S> {
    fn relocalizes(&self) -> bool {
        true
    }

    fn holds_places(&self) -> bool {
        self.len > 0
    }

    fn first_free_seq(&self) -> u32 {
        self.next_seq
    }

    fn flush(&mut self) {
        self.write_pending();
    }

    fn map_points(&mut self, query: &PlaceQuery<'_>, mut f: impl FnMut(usize, Point3<f32>)) {
        let Some((slot, t_wc)) = self.map_place.take() else { return };
        let Some(r) = self.read(slot) else { return };
        let t_rq = r.t_wc.inverse() * t_wc;
        inlier_pairs(query, &r.points, &self.params, &t_rq, |qi, pi| {
            if let Some(p) = r.points.get(pi) {
                f(qi, r.t_wc * p.p_c);
            }
        });
    }

    fn remember<const K: usize, const L: usize>(&mut self, map: &Map<K, L>, kf: KeyFrameId) {
        if self.frozen {
            return;
        }
        let Some(record) = record_of(map, kf) else {
            self.stats.too_few_points = self.stats.too_few_points.saturating_add(1);
            return;
        };
        let Some(slot) = self.slot_for(&record.t_wc, &record.key) else { return };
        // Written by the next flush (the back end's step) or before the next read.
        self.write_pending();
        record.encode(&mut self.buf);
        self.pending = Some(slot);
        self.index_record(slot, &record);
        if slot == self.len {
            self.len += 1;
        } else {
            self.stats.thinned = self.stats.thinned.saturating_add(1);
        }
        self.stats.remembered = self.stats.remembered.saturating_add(1);
    }

    fn relocalize<const K: usize, const L: usize>(
        &mut self,
        query: &PlaceQuery<'_>,
        map: &Map<K, L>,
    ) -> Option<Pose> {
        self.stats.queries = self.stats.queries.saturating_add(1);
        match self.locate(query, map, Candidates::All) {
            Located::At(t_wc, ..) => {
                self.stats.relocalized = self.stats.relocalized.saturating_add(1);
                Some(t_wc)
            }
            Located::Ambiguous => {
                self.stats.ambiguous = self.stats.ambiguous.saturating_add(1);
                None
            }
            Located::Nowhere => None,
        }
    }

    fn close_loop<const K: usize, const L: usize>(
        &mut self,
        query: &PlaceQuery<'_>,
        map: &Map<K, L>,
        kf: KeyFrameId,
        track_start: u32,
    ) -> Option<LoopClosure> {
        self.map_place = None;
        let k = map.keyframe(kf)?;
        let (seq, t_wc_now) = (k.seq, k.t_wc);
        if self.len == 0 && track_start == 0 {
            return None;
        }
        self.loops.queries = self.loops.queries.saturating_add(1);
        let (t_wc, record_seq, record_timestamp_s) =
            match self.locate(query, map, Candidates::Before(track_start)) {
                Located::At(t_wc, s, ts, slot) => {
                    // Localizing: the loaded map's place, for `map_points`.
                    self.map_place = slot.filter(|_| self.frozen).map(|slot| (slot, t_wc));
                    (t_wc, s, ts)
                }
                Located::Ambiguous => {
                    self.loops.rejected = self.loops.rejected.saturating_add(1);
                    return None;
                }
                Located::Nowhere => return None,
            };
        self.loops.detected = self.loops.detected.saturating_add(1);
        // New world from old: what moves the keyframe to where the place puts it.
        let correction = t_wc * t_wc_now.inverse();
        let (d, angle) = (correction.translation.vector.norm(), correction.rotation.angle());
        if d < LOOP_MIN_CORRECTION_M && angle < LOOP_MIN_CORRECTION_RAD {
            self.loops.consistent = self.loops.consistent.saturating_add(1);
            self.held_run = None;
            return None;
        }
        if record_seq >= track_start {
            // Tracked without a restart since that place: the map's own chain is trusted over
            // one view's verified pose, until enough views in a row agree.
            self.loops.held = self.loops.held.saturating_add(1);
            if d < HELD_MIN_CORRECTION_M && angle < HELD_MIN_CORRECTION_RAD {
                self.held_run = None;
                return None;
            }
            if !self.confirm_held(correction, seq, &t_wc_now) {
                return None;
            }
            self.loops.confirmed = self.loops.confirmed.saturating_add(1);
        }
        self.held_run = None;
        self.loops.accepted = self.loops.accepted.saturating_add(1);
        Some(LoopClosure { record_seq, record_timestamp_s, keyframe_seq: seq, correction })
    }
}

/// Which places a query considers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Candidates {
    /// Every record and every keyframe of the active map (relocalization).
    All,
    /// Every record, and the keyframes of the active map made before this creation number
    /// (loops: the map tracked since a re-initialization is not connected to what came before).
    Before(u32),
}

/// Where a query put the frame.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Located {
    /// At `t_wc`, verified in the place of this keyframe creation number (and timestamp); the
    /// place's slot when it is a stored record.
    At(Pose, u32, f64, Option<usize>),
    /// Two places verified different poses.
    Ambiguous,
    /// No place verified.
    Nowhere,
}

impl<S: KeyframeStore> PlaceMemory<S> {
    /// Counts a held loop of keyframe `seq` (at `t_wc_now`) with `correction` into the run of
    /// agreeing ones; whether the run reached [`HELD_LOOP_CONFIRMATIONS`]. Corrections are
    /// compared by where they put the keyframe (its position and orientation), not as world
    /// motions: a small turn about a far origin moves the world a lot and the keyframe little.
    fn confirm_held(&mut self, correction: Pose, seq: u32, t_wc_now: &Pose) -> bool {
        let agrees = self.held_run.is_some_and(|run| {
            let (moved, turned) =
                camera_gap(&(correction * t_wc_now), &(run.correction * t_wc_now));
            seq.wrapping_sub(run.keyframe_seq) <= HELD_MAX_GAP
                && moved <= HELD_AGREE_M
                && turned <= HELD_AGREE_RAD
        });
        let count = match self.held_run {
            Some(run) if agrees => run.count.saturating_add(1),
            _ => 1,
        };
        self.held_run = Some(HeldRun { correction, keyframe_seq: seq, count });
        count >= HELD_LOOP_CONFIRMATIONS
    }

    /// Ranks the `candidates` by key distance to the query's, verifies the [`CANDIDATES`]
    /// nearest, and returns the best verified pose unless a rival verifies a different one
    /// nearly as well (see the module documentation).
    fn locate<const K: usize, const L: usize>(
        &mut self,
        query: &PlaceQuery<'_>,
        map: &Map<K, L>,
        candidates: Candidates,
    ) -> Located {
        // The nearest keys, ascending (ties: the store before the map, each in slot order).
        let mut nearest: Vec<(u32, Place), CANDIDATES> = Vec::new();
        let mut offer = |d: u32, place: Place| {
            let at = nearest.iter().position(|&(e, _)| d < e).unwrap_or(nearest.len());
            if at < CANDIDATES {
                if nearest.is_full() {
                    let _ = nearest.pop();
                }
                let _ = nearest.insert(at, (d, place));
            }
        };
        for (_, slot) in self.shortlist(&query.key.bits()) {
            let Some(r) = self.read(slot) else { continue };
            offer(r.key.distance(&query.key), Place::Stored(slot));
        }
        let before = match candidates {
            Candidates::All => u32::MAX,
            Candidates::Before(seq) => seq,
        };
        for (id, k) in map.keyframes().filter(|(_, k)| k.seq < before) {
            offer(k.place_key.distance(&query.key), Place::Active(id));
        }
        let mut found: Vec<(Verified, Pose, u32, f64, Option<usize>), CANDIDATES> = Vec::new();
        for &(_, place) in &nearest {
            let record = match place {
                Place::Stored(slot) => self.read(slot),
                Place::Active(id) => record_of(map, id),
            };
            let Some(r) = record else { continue };
            if let Some(v) = verify(query, &r.points, &self.params, &mut self.rng) {
                self.stats.verified = self.stats.verified.saturating_add(1);
                let slot = match place {
                    Place::Stored(slot) => Some(slot),
                    Place::Active(_) => None,
                };
                let _ = found.push((v, r.t_wc * v.t_rq, r.seq, r.timestamp_s, slot));
            }
        }
        let Some((best, t_wc, seq, ts, slot)) =
            found.iter().copied().max_by_key(|(v, ..)| v.inliers)
        else {
            return Located::Nowhere;
        };
        let rival = found.iter().any(|(v, t, ..)| {
            pose_distance(t, &t_wc) > AMBIGUITY_DISTANCE
                && v.inliers as f32 >= AMBIGUITY_RATIO * best.inliers as f32
        });
        if rival { Located::Ambiguous } else { Located::At(t_wc, seq, ts, slot) }
    }
}

/// A candidate place: a record of the store, or a keyframe of the active map.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Place {
    Stored(usize),
    Active(KeyFrameId),
}

/// What is remembered of keyframe `kf` of `map`: its pose, key and up to [`PLACE_POINTS`]
/// observed landmarks with a descriptor, in its camera frame: first those it made (a descriptor
/// is taken where its landmark is made, so theirs describe this view), then the tracked ones it
/// observed, each in observation order. `None` when it has fewer than [`MIN_RECORD_POINTS`] of
/// them (or is not in the map).
fn record_of<const K: usize, const L: usize>(
    map: &Map<K, L>,
    kf: KeyFrameId,
) -> Option<PlaceRecord> {
    let k = map.keyframe(kf)?;
    let t_cw = k.t_wc.inverse();
    let mut points: Vec<PlacePoint, PLACE_POINTS> = Vec::new();
    // The landmarks it made first: their descriptors were taken in its own view.
    for own in [true, false] {
        for obs in &k.observations {
            let Some(lm) = map.landmark(obs.landmark) else { continue };
            let Some(descriptor) = lm.descriptor else { continue };
            if (lm.host == kf) != own {
                continue;
            }
            if points.push(PlacePoint { p_c: t_cw * lm.p_w, descriptor }).is_err() {
                break;
            }
        }
    }
    (points.len() >= MIN_RECORD_POINTS).then_some(PlaceRecord {
        seq: k.seq,
        timestamp_s: k.timestamp_s,
        t_wc: k.t_wc,
        key: k.place_key,
        points,
    })
}
