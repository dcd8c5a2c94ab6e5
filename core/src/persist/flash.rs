//! The long-term store on NOR flash ([`FlashStore`]), durable across power cycles and safe
//! against a power cut at any erase or write: a boot finds the map of the last commit whole.
//!
//! # Layout
//!
//! The flash is cut into units of one record ([`PLACE_RECORD_BYTES`]). The first
//! [`TABLE_UNITS`] hold tables, the rest records. A table says which unit holds each slot of the
//! map (`slot -> unit`), under a generation number and a checksum; the valid table of the
//! highest generation is the map a boot finds.
//!
//! - A record is never written over the unit that holds it: each write goes to a free unit
//!   (erased first), taken round robin over every record unit, so wear is spread over the
//!   whole region and no unit is rewritten per keyframe.
//! - Records that never change would keep their units out of the round: every
//!   [`RELOCATE_EVERY`] writes, the live record in the unit the round has reached is moved to a
//!   free one (while more than half the spare units are free), so every unit takes its turn.
//! - The units of the last committed table are not free until the next commit: a cut before a
//!   commit leaves that table and its records as they were.
//! - A commit writes the next table unit of the ring (the oldest table), never the newest. A cut
//!   in that erase or write leaves the newest intact, and the damaged one fails its checksum.
//!
//! A table unit (little-endian, 256 words of 4 bytes): `FT`, version, 0; generation (u32); slots
//! (u16), next unit to allocate (u16); [`TABLE_SLOTS`] units (u16); FNV-1a of the bytes before it.
//!
//! When writes run out of free units (more rewrites since the last commit than the region has
//! spare units), the store commits by itself before the write: a cut after that loads the map
//! of that commit.

use embedded_storage::nor_flash::{NorFlash, NorFlashError, NorFlashErrorKind};

use crate::config::STORE_READ_TRIES;
use crate::config::capacity::{BOARD_STORE_FLASH_BYTES, BOARD_STORE_KEYFRAMES, PLACE_RECORD_BYTES};
use crate::map::{Fnv1a, KeyframeStore, RecordBytes};

/// Units at the start of the region that hold tables, written in turn.
pub const TABLE_UNITS: usize = 4;

/// Record units kept free beyond the slots (the writes a store can take between commits while
/// full without committing by itself).
pub const SPARE_UNITS: usize = 8;

/// Slots a table holds: the most records a [`FlashStore`] keeps.
pub const TABLE_SLOTS: usize = (PLACE_RECORD_BYTES / 4 - 4) * 2;

/// Writes between two moves of a cold record (static wear levelling, see [`FlashStore`]).
pub const RELOCATE_EVERY: u32 = 4;

/// Record units a [`FlashStore`] uses at most (a larger region's tail is left alone).
pub const MAX_RECORD_UNITS: usize = 1024;

/// Bytes of flash a store of `records` slots needs: its tables, records and spare units.
pub const fn flash_bytes_for(records: usize) -> usize {
    (TABLE_UNITS + records + SPARE_UNITS) * PLACE_RECORD_BYTES
}

const TABLE_MAGIC: [u8; 2] = *b"FT";
const TABLE_VERSION: u8 = 1;
const TABLE_WORDS: usize = PLACE_RECORD_BYTES / 4;
/// Words of the table before the units.
const TABLE_HEAD_WORDS: usize = 3;
const BITS_WORDS: usize = MAX_RECORD_UNITS / 32;
const _: () = assert!(TABLE_HEAD_WORDS + TABLE_SLOTS / 2 + 1 == TABLE_WORDS);
const _: () = assert!(MAX_RECORD_UNITS <= u16::MAX as usize);
const _: () = assert!(flash_bytes_for(BOARD_STORE_KEYFRAMES) == BOARD_STORE_FLASH_BYTES);

/// One bit per record unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Units([u32; BITS_WORDS]);

impl Units {
    const NONE: Self = Self([0; BITS_WORDS]);

    fn has(&self, unit: u16) -> bool {
        let u = usize::from(unit);
        self.0.get(u / 32).is_some_and(|w| w & (1 << (u % 32)) != 0)
    }

    fn set(&mut self, unit: u16, on: bool) {
        let u = usize::from(unit);
        if let Some(w) = self.0.get_mut(u / 32) {
            if on {
                *w |= 1 << (u % 32);
            } else {
                *w &= !(1 << (u % 32));
            }
        }
    }
}

/// A [`KeyframeStore`] on a NOR flash region, durable and power-cut safe (see the module
/// documentation). Any `embedded-storage` [`NorFlash`] whose erase and write sizes divide a
/// record (checked at compile time). RAM: the live table (2 bytes a slot) and two unit bitmaps,
/// about 1.3 KiB.
#[derive(Debug)]
pub struct FlashStore<F> {
    flash: F,
    /// Record units in use by this store (`0..units`, after the tables).
    units: u16,
    /// Slots of the live map (`0..len` hold records).
    len: u16,
    /// The unit of each live slot.
    table: [u16; TABLE_SLOTS],
    /// Units the live map uses.
    live: Units,
    /// Units the last committed table uses: not free until the next commit.
    committed: Units,
    /// Slots when the store was mounted.
    held: u16,
    /// Generation of the last committed table (0: none yet) and the table unit holding it.
    generation: u32,
    table_unit: u8,
    /// The record unit the next allocation tries first.
    cursor: u16,
    /// Whether the live map differs from the last committed one.
    dirty: bool,
    /// Writes since mounted.
    writes: u32,
}

/// Why a [`FlashStore`] operation failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FlashStoreError {
    /// The slot is beyond the store's capacity, or past the end of what it holds.
    SlotOutOfRange(usize),
    /// Every record unit holds a slot of the live or committed map (the region is too small).
    Full,
    /// The flash refused an unaligned erase or write.
    NotAligned,
    /// The flash refused an access beyond its end.
    OutOfBounds,
    /// The flash failed otherwise (its driver's error).
    Flash,
}

impl FlashStoreError {
    fn of(e: &impl NorFlashError) -> Self {
        match e.kind() {
            NorFlashErrorKind::NotAligned => Self::NotAligned,
            NorFlashErrorKind::OutOfBounds => Self::OutOfBounds,
            _ => Self::Flash,
        }
    }
}

impl<F: NorFlash> FlashStore<F> {
    /// A store over `flash` that holds nothing and is not mounted (`const`, for a `static`
    /// attached to its region at run time with [`Self::mount`]).
    pub const fn unmounted(flash: F) -> Self {
        Self {
            flash,
            units: 0,
            len: 0,
            table: [0; TABLE_SLOTS],
            live: Units::NONE,
            committed: Units::NONE,
            held: 0,
            generation: 0,
            table_unit: (TABLE_UNITS - 1) as u8,
            cursor: 0,
            dirty: false,
            writes: 0,
        }
    }

    /// The store on `flash` as the last commit left it: the valid table of the highest
    /// generation (in serial-number order, so that generations may wrap), or an empty store when
    /// there is none (a blank or foreign region; a region too small for a table and a record
    /// gives a store of no slots). A table that reads damaged is read again, up to
    /// [`STORE_READ_TRIES`] times. Cost: every table unit read once to check it (4 KiB; a
    /// damaged one up to three times), the one taken read again for its slots;
    /// no record is read.
    ///
    /// # Errors
    /// A read the flash refused.
    pub fn mount(flash: F) -> Result<Self, FlashStoreError> {
        const {
            assert!(PLACE_RECORD_BYTES.is_multiple_of(F::ERASE_SIZE));
            assert!(PLACE_RECORD_BYTES.is_multiple_of(F::WRITE_SIZE));
        }
        let mut s = Self::unmounted(flash);
        let units = (s.flash.capacity() / PLACE_RECORD_BYTES).saturating_sub(TABLE_UNITS);
        if units == 0 {
            // Too small for a table and a record: a store of no slots.
            return Ok(s);
        }
        s.units = units.min(MAX_RECORD_UNITS) as u16;
        let mut found = [None; TABLE_UNITS];
        for (t, g) in (0..TABLE_UNITS as u8).zip(&mut found) {
            *g = s.read_table_again(t, false)?;
        }
        // The newest valid table, in serial-number order (the generation after u32::MAX is 0);
        // one that does not read valid again when taken is passed over for the next newest.
        while let Some((t, generation)) = newest(&found) {
            if s.read_table_again(t, true)? == Some(generation) {
                s.generation = generation;
                s.table_unit = t;
                s.committed = s.live;
                s.held = s.len;
                break;
            }
            if let Some(g) = found.get_mut(usize::from(t)) {
                *g = None;
            }
        }
        Ok(s)
    }

    /// The flash.
    pub fn flash(&self) -> &F {
        &self.flash
    }

    /// Generation of the last committed table (0: nothing committed on this region yet).
    pub fn generation(&self) -> u32 {
        self.generation
    }

    /// Byte offset of unit `unit` of the region (tables first).
    fn offset(unit: usize) -> u32 {
        (unit * PLACE_RECORD_BYTES) as u32
    }

    /// [`Self::read_table`], up to [`STORE_READ_TRIES`] times while it reads as a damaged table
    /// (its magic right, the rest not): a blank or foreign unit is read once.
    fn read_table_again(&mut self, t: u8, take: bool) -> Result<Option<u32>, FlashStoreError> {
        let mut read = self.read_table(t, take)?;
        for _ in 1..STORE_READ_TRIES {
            if !matches!(read, TableRead::Damaged) {
                break;
            }
            read = self.read_table(t, take)?;
        }
        Ok(match read {
            TableRead::Valid(g) => Some(g),
            TableRead::NotATable | TableRead::Damaged => None,
        })
    }

    /// Reads table unit `t`: its generation when it is a valid table. With `take`, also takes
    /// its slots as the live map. Cost: one unit read, in 64-byte pieces.
    fn read_table(&mut self, t: u8, take: bool) -> Result<TableRead, FlashStoreError> {
        let mut hash = Fnv1a::default();
        let mut head = [0u32; TABLE_HEAD_WORDS];
        let mut stored = 0u32;
        let mut bad = false;
        let mut used = Units::NONE;
        let mut chunk = [0u8; 64];
        for c in 0..PLACE_RECORD_BYTES / chunk.len() {
            let at = Self::offset(usize::from(t)) + (c * chunk.len()) as u32;
            self.flash.read(at, &mut chunk).map_err(|e| FlashStoreError::of(&e))?;
            for (i, w) in chunk.chunks_exact(4).enumerate() {
                let word_at = c * chunk.len() / 4 + i;
                let word = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
                if word_at == TABLE_WORDS - 1 {
                    stored = word;
                    continue;
                }
                hash.add(w);
                if let Some(h) = head.get_mut(word_at) {
                    *h = word;
                    continue;
                }
                let len = usize::from(head[2] as u16);
                for (k, unit) in [word as u16, (word >> 16) as u16].into_iter().enumerate() {
                    let slot = (word_at - TABLE_HEAD_WORDS) * 2 + k;
                    if slot >= len {
                        continue;
                    }
                    bad |= unit >= self.units || used.has(unit);
                    used.set(unit, true);
                    if take && let Some(e) = self.table.get_mut(slot) {
                        *e = unit;
                    }
                }
            }
        }
        if head[0].to_le_bytes() != [TABLE_MAGIC[0], TABLE_MAGIC[1], TABLE_VERSION, 0] {
            return Ok(TableRead::NotATable);
        }
        let len = head[2] as u16;
        if stored != hash.value() || usize::from(len) > TABLE_SLOTS || bad {
            return Ok(TableRead::Damaged);
        }
        if take {
            self.len = len;
            self.cursor = ((head[2] >> 16) as u16).min(self.units.saturating_sub(1));
            self.live = used;
        }
        Ok(TableRead::Valid(head[1]))
    }

    /// Word `w` of the live map's table under generation `generation` (the checksum word
    /// excepted).
    fn table_word(&self, generation: u32, w: usize) -> u32 {
        match w {
            0 => u32::from_le_bytes([TABLE_MAGIC[0], TABLE_MAGIC[1], TABLE_VERSION, 0]),
            1 => generation,
            2 => u32::from(self.len) | u32::from(self.cursor) << 16,
            _ => {
                let slot = (w - TABLE_HEAD_WORDS) * 2;
                let unit = |s: usize| {
                    if s < usize::from(self.len) {
                        u32::from(self.table.get(s).copied().unwrap_or(0))
                    } else {
                        0
                    }
                };
                unit(slot) | unit(slot + 1) << 16
            }
        }
    }

    /// Free record units.
    fn free_units(&self) -> u32 {
        let used = self.live.0.iter().zip(&self.committed.0).map(|(l, c)| (l | c).count_ones());
        u32::from(self.units).saturating_sub(used.sum())
    }

    /// Moves the live record in the unit at the cursor, if any, to a free unit: static wear
    /// levelling (a record that never changes does not keep its unit out of the round). Copied
    /// through a 64-byte buffer; the old unit is free once no committed table holds it.
    fn relocate_cold(&mut self) -> Result<(), FlashStoreError> {
        let unit = self.cursor;
        if !self.live.has(unit) || self.free_units() <= (SPARE_UNITS / 2) as u32 {
            return Ok(());
        }
        let len = usize::from(self.len);
        let Some(slot) = self.table.iter().take(len).position(|&u| u == unit) else {
            return Ok(());
        };
        let Some(to) = self.free_unit() else { return Ok(()) };
        let (src, dst) = (
            Self::offset(TABLE_UNITS + usize::from(unit)),
            Self::offset(TABLE_UNITS + usize::from(to)),
        );
        self.flash
            .erase(dst, dst + PLACE_RECORD_BYTES as u32)
            .map_err(|e| FlashStoreError::of(&e))?;
        let mut chunk = [0u8; 64];
        for at in (0..PLACE_RECORD_BYTES as u32).step_by(chunk.len()) {
            self.flash.read(src + at, &mut chunk).map_err(|e| FlashStoreError::of(&e))?;
            self.flash.write(dst + at, &chunk).map_err(|e| FlashStoreError::of(&e))?;
        }
        if let Some(e) = self.table.get_mut(slot) {
            *e = to;
        }
        self.live.set(unit, false);
        self.live.set(to, true);
        self.cursor = (to + 1) % self.units;
        self.dirty = true;
        Ok(())
    }

    /// A free record unit (neither live nor committed), the first from the cursor on.
    fn free_unit(&self) -> Option<u16> {
        (0..self.units)
            .map(|i| (self.cursor + i) % self.units)
            .find(|&u| !self.live.has(u) && !self.committed.has(u))
    }
}

/// What a table unit read as.
enum TableRead {
    /// A valid table of this generation.
    Valid(u32),
    /// The table magic, but a checksum or contents that do not hold.
    Damaged,
    /// Not a table: blank, foreign, or its magic damaged.
    NotATable,
}

/// The table unit and generation of the newest of `found` (each table unit's generation when
/// valid), in serial-number order.
fn newest(found: &[Option<u32>; TABLE_UNITS]) -> Option<(u8, u32)> {
    let mut best: Option<(u8, u32)> = None;
    for (t, g) in (0..TABLE_UNITS as u8).zip(found) {
        if let Some(g) = *g
            && best.is_none_or(|(_, b)| (g.wrapping_sub(b) as i32) > 0)
        {
            best = Some((t, g));
        }
    }
    best
}

impl<F: NorFlash> KeyframeStore for FlashStore<F> {
    type Error = FlashStoreError;

    fn capacity(&self) -> usize {
        usize::from(self.units).saturating_sub(SPARE_UNITS).min(TABLE_SLOTS)
    }

    fn held(&self) -> usize {
        usize::from(self.held)
    }

    fn read(&mut self, slot: usize, buf: &mut RecordBytes) -> Result<(), Self::Error> {
        let unit = match self.table.get(slot) {
            Some(&u) if slot < usize::from(self.len) => u,
            _ => return Err(FlashStoreError::SlotOutOfRange(slot)),
        };
        let at = Self::offset(TABLE_UNITS + usize::from(unit));
        self.flash.read(at, buf).map_err(|e| FlashStoreError::of(&e))
    }

    /// Writes to a free unit; the slot's old unit is free once no committed table holds it.
    /// Slots are written in order: `slot` is at most the number held.
    fn write(&mut self, slot: usize, buf: &RecordBytes) -> Result<(), Self::Error> {
        if slot > usize::from(self.len) || slot >= self.capacity() {
            return Err(FlashStoreError::SlotOutOfRange(slot));
        }
        self.writes = self.writes.wrapping_add(1);
        if self.writes.is_multiple_of(RELOCATE_EVERY) {
            self.relocate_cold()?;
        }
        let unit = match self.free_unit() {
            Some(u) => u,
            None => {
                self.commit(usize::from(self.len))?;
                self.free_unit().ok_or(FlashStoreError::Full)?
            }
        };
        let from = Self::offset(TABLE_UNITS + usize::from(unit));
        let to = from + PLACE_RECORD_BYTES as u32;
        self.flash.erase(from, to).map_err(|e| FlashStoreError::of(&e))?;
        self.flash.write(from, buf).map_err(|e| FlashStoreError::of(&e))?;
        if slot < usize::from(self.len) {
            let old = self.table.get(slot).copied().unwrap_or(0);
            self.live.set(old, false);
        } else {
            self.len += 1;
        }
        if let Some(e) = self.table.get_mut(slot) {
            *e = unit;
        }
        self.live.set(unit, true);
        self.cursor = (unit + 1) % self.units;
        self.dirty = true;
        Ok(())
    }

    /// Writes the table of slots `0..records` to the next table unit of the ring; from then
    /// on a boot finds that map, and the units only the previous table held are free.
    fn commit(&mut self, records: usize) -> Result<(), Self::Error> {
        if records > usize::from(self.len) {
            return Err(FlashStoreError::SlotOutOfRange(records));
        }
        for slot in records..usize::from(self.len) {
            let unit = self.table.get(slot).copied().unwrap_or(0);
            self.live.set(unit, false);
            self.dirty = true;
        }
        self.len = records as u16;
        if !self.dirty {
            return Ok(());
        }
        let generation = self.generation.wrapping_add(1);
        let t = (usize::from(self.table_unit) + 1) % TABLE_UNITS;
        let from = Self::offset(t);
        self.flash
            .erase(from, from + PLACE_RECORD_BYTES as u32)
            .map_err(|e| FlashStoreError::of(&e))?;
        let mut hash = Fnv1a::default();
        let mut chunk = [0u8; 64];
        for c in 0..PLACE_RECORD_BYTES / chunk.len() {
            for (i, w) in chunk.chunks_exact_mut(4).enumerate() {
                let word_at = c * 16 + i;
                let word = if word_at == TABLE_WORDS - 1 {
                    hash.value()
                } else {
                    self.table_word(generation, word_at)
                };
                w.copy_from_slice(&word.to_le_bytes());
                if word_at != TABLE_WORDS - 1 {
                    hash.add(w);
                }
            }
            let at = from + (c * chunk.len()) as u32;
            self.flash.write(at, &chunk).map_err(|e| FlashStoreError::of(&e))?;
        }
        self.generation = generation;
        self.table_unit = t as u8;
        self.committed = self.live;
        self.dirty = false;
        Ok(())
    }
}

#[cfg(test)]
mod tests;
