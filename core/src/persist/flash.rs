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
//!
//! # Sectors larger than a record
//!
//! Flash that erases more than a record at a time (the reference board's STM32H743 erases
//! 128 KiB sectors and programs 32-byte words once each) takes the store in **sector mode**:
//! units are filled in order inside erased sectors and never erased one by one. There is no
//! table ring: a commit writes its table into the next erased unit like a record, and a boot
//! reads every unit once (a blank unit is free; the valid table of the highest generation is
//! the map). One sector is kept erased as the spare. When the other erased units run out, a
//! sector holding nothing the live or committed map uses is erased; when there is none, the
//! sector with the fewest records of either map is collected: its records are copied into the
//! spare, the committed table is written again there with their new units (the same map, the
//! next generation), and only then is the sector erased, so a cut at any step boots the last
//! committed map (see `FlashStore::collect`). The sectors other than the spare are at
//! most three quarters live ([`sector_capacity`]), so a collection copies at most three quarters
//! of a sector and frees the rest. Records that never change are not moved for wear here:
//! erases follow the sectors that hold the most stale records.

use embedded_storage::nor_flash::{NorFlash, NorFlashError, NorFlashErrorKind};
use heapless::Vec as HVec;

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

/// Record units an erase sector holds at most (sector mode: 128 KiB sectors).
pub const MAX_SECTOR_UNITS: usize = 128;

/// Bytes of flash a store of `records` slots needs: its tables, records and spare units.
pub const fn flash_bytes_for(records: usize) -> usize {
    (TABLE_UNITS + records + SPARE_UNITS) * PLACE_RECORD_BYTES
}

/// Records a store in sector mode keeps on a region of `sectors` erase sectors of
/// `sector_units` units each (see the module documentation): every sector but the spare at most
/// three quarters live (at most all but two units, on sectors of under 8 units), and at most
/// [`TABLE_SLOTS`]; 0 with fewer than two sectors.
pub const fn sector_capacity(sectors: usize, sector_units: usize) -> usize {
    let headroom = if sector_units / 4 > 2 { sector_units / 4 } else { 2 };
    if sectors < 2 || sector_units <= headroom {
        return 0;
    }
    let records = (sectors - 1) * (sector_units - headroom);
    if records < TABLE_SLOTS { records } else { TABLE_SLOTS }
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
/// documentation). Any `embedded-storage` [`NorFlash`] whose erase size divides a record or is a
/// whole number of records (sector mode), and whose write size divides 64 bytes (checked at
/// compile time). RAM: the live table (2 bytes a slot) and three unit bitmaps, about 1.4 KiB.
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
    /// Sector mode: units programmed since their sector was last erased (not free).
    written: Units,
    /// Sector mode: the unit holding the last committed table.
    table_at: u16,
    /// Sector mode: a collection is under way (its commit may write into the spare).
    collecting: bool,
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
    /// Record units per erase sector: 1 when the flash erases a record or less at a time (each
    /// unit erased before it is written), else the sector's units (sector mode).
    const SECTOR_UNITS: usize =
        if F::ERASE_SIZE > PLACE_RECORD_BYTES { F::ERASE_SIZE / PLACE_RECORD_BYTES } else { 1 };
    /// Whether the store runs in sector mode (see the module documentation).
    const SECTORED: bool = Self::SECTOR_UNITS > 1;
    /// Units before the first record unit: the table ring, none in sector mode.
    const TABLES: usize = if Self::SECTORED { 0 } else { TABLE_UNITS };

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
            written: Units::NONE,
            table_at: 0,
            collecting: false,
        }
    }

    /// The store on `flash` as the last commit left it: the valid table of the highest
    /// generation (in serial-number order, so that generations may wrap), or an empty store when
    /// there is none (a blank or foreign region; a region too small for a table and a record,
    /// or in sector mode for two sectors, gives a store of no slots). A table that reads damaged
    /// is read again, up to [`STORE_READ_TRIES`] times. Cost: every table unit read once to
    /// check it (4 KiB; a damaged one up to three times), the one taken read again for its
    /// slots; no record is read. In sector mode every unit of the region is read once (to know
    /// the blank ones, and to find the tables among the records).
    ///
    /// # Errors
    /// A read the flash refused.
    pub fn mount(flash: F) -> Result<Self, FlashStoreError> {
        const {
            assert!(
                PLACE_RECORD_BYTES.is_multiple_of(F::ERASE_SIZE)
                    || F::ERASE_SIZE.is_multiple_of(PLACE_RECORD_BYTES)
            );
            // Tables and moved records are written in pieces of 64 bytes.
            assert!(64usize.is_multiple_of(F::WRITE_SIZE));
            assert!(F::ERASE_SIZE <= MAX_SECTOR_UNITS * PLACE_RECORD_BYTES);
        }
        let mut s = Self::unmounted(flash);
        if Self::SECTORED {
            s.mount_sectors()?;
            return Ok(s);
        }
        let units = (s.flash.capacity() / PLACE_RECORD_BYTES).saturating_sub(TABLE_UNITS);
        if units == 0 {
            // Too small for a table and a record: a store of no slots.
            return Ok(s);
        }
        s.units = units.min(MAX_RECORD_UNITS) as u16;
        let mut found = [None; TABLE_UNITS];
        for (t, g) in (0..TABLE_UNITS).zip(&mut found) {
            *g = s.read_table_again(Self::offset(t), false)?.generation();
        }
        // The newest valid table, in serial-number order (the generation after u32::MAX is 0);
        // one that does not read valid again when taken is passed over for the next newest.
        while let Some((t, generation)) = newest(&found) {
            if s.read_table_again(Self::offset(usize::from(t)), true)?.generation()
                == Some(generation)
            {
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

    /// Byte offset of record unit `unit` (after the table ring, when there is one).
    fn unit_offset(unit: u16) -> u32 {
        Self::offset(Self::TABLES + usize::from(unit))
    }

    /// [`Self::mount`] in sector mode: every unit read once, blank ones free, the newest valid
    /// table taken (see the module documentation).
    fn mount_sectors(&mut self) -> Result<(), FlashStoreError> {
        let su = Self::SECTOR_UNITS;
        let sectors = (self.flash.capacity() / PLACE_RECORD_BYTES).min(MAX_RECORD_UNITS) / su;
        if sector_capacity(sectors, su) == 0 {
            return Ok(());
        }
        self.units = (sectors * su) as u16;
        // The newest few valid tables: the next is taken when the newest reads damaged then.
        let mut found: HVec<(u16, u32), 4> = HVec::new();
        for unit in 0..self.units {
            match self.read_table_again(Self::unit_offset(unit), false)? {
                TableRead::Blank => continue,
                TableRead::Valid(g) => keep_newest(&mut found, unit, g),
                TableRead::NotATable | TableRead::Damaged => {}
            }
            self.written.set(unit, true);
        }
        while let Some(i) = newest_of(found.iter().map(|&(_, g)| g)) {
            let (unit, generation) = found.swap_remove(i);
            let read = self.read_table_again(Self::unit_offset(unit), true)?;
            if read.generation() == Some(generation) {
                self.generation = generation;
                self.table_at = unit;
                self.committed = self.live;
                self.committed.set(unit, true);
                self.held = self.len;
                break;
            }
        }
        Ok(())
    }

    /// [`Self::read_table`], up to [`STORE_READ_TRIES`] times while it reads as a damaged table
    /// (its magic right, the rest not): a blank or foreign unit is read once.
    fn read_table_again(&mut self, at: u32, take: bool) -> Result<TableRead, FlashStoreError> {
        let mut read = self.read_table(at, take)?;
        for _ in 1..STORE_READ_TRIES {
            if read != TableRead::Damaged {
                break;
            }
            read = self.read_table(at, take)?;
        }
        Ok(read)
    }

    /// Reads the unit at byte offset `at` as a table: its generation when it is a valid one.
    /// With `take`, also takes its slots as the live map. Cost: one unit read, in 64-byte
    /// pieces.
    fn read_table(&mut self, at: u32, take: bool) -> Result<TableRead, FlashStoreError> {
        let mut hash = Fnv1a::default();
        let mut head = [0u32; TABLE_HEAD_WORDS];
        let mut stored = 0u32;
        let mut bad = false;
        let mut used = Units::NONE;
        let mut blank = true;
        let mut chunk = [0u8; 64];
        for c in 0..PLACE_RECORD_BYTES / chunk.len() {
            let piece_at = at + (c * chunk.len()) as u32;
            self.flash.read(piece_at, &mut chunk).map_err(|e| FlashStoreError::of(&e))?;
            blank &= chunk.iter().all(|&b| b == 0xFF);
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
        if blank {
            return Ok(TableRead::Blank);
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
        let Ok(slot) = self.slot_of(unit) else { return Ok(()) };
        let Some(to) = self.free_unit() else { return Ok(()) };
        let dst = Self::unit_offset(to);
        self.flash
            .erase(dst, dst + PLACE_RECORD_BYTES as u32)
            .map_err(|e| FlashStoreError::of(&e))?;
        self.move_record(slot, unit, to)?;
        self.cursor = (to + 1) % self.units;
        Ok(())
    }

    /// Copies slot `slot`'s record from unit `from` to the erased unit `to` (through a 64-byte
    /// buffer) and points the slot at it.
    fn move_record(&mut self, slot: usize, from: u16, to: u16) -> Result<(), FlashStoreError> {
        self.copy_unit(from, to)?;
        if let Some(e) = self.table.get_mut(slot) {
            *e = to;
        }
        self.live.set(from, false);
        self.live.set(to, true);
        self.dirty = true;
        Ok(())
    }

    /// A free record unit (neither live nor committed), the first from the cursor on.
    fn free_unit(&self) -> Option<u16> {
        (0..self.units)
            .map(|i| (self.cursor + i) % self.units)
            .find(|&u| !self.live.has(u) && !self.committed.has(u))
    }

    /// Sector mode: the units of sector `sector`.
    fn sector_units(sector: u16) -> core::ops::Range<u16> {
        let su = Self::SECTOR_UNITS as u16;
        sector * su..(sector + 1) * su
    }

    /// Sector mode: the sectors in turn from the cursor's on.
    fn sectors_from_cursor(&self) -> impl Iterator<Item = u16> {
        let (su, count) = (Self::SECTOR_UNITS as u16, self.units / Self::SECTOR_UNITS as u16);
        (0..count).map(move |i| (self.cursor / su + i) % count)
    }

    /// Sector mode: the spare, the first blank sector from the cursor's on (`None`: none is
    /// blank, after a cut in a collection or on a region that was not blank).
    fn spare_sector(&self) -> Option<u16> {
        self.sectors_from_cursor().find(|&s| Self::sector_units(s).all(|u| !self.written.has(u)))
    }

    /// Sector mode: the first erased unit from the cursor on, outside the spare sector unless
    /// `spare_too`.
    fn erased_unit(&self, spare_too: bool) -> Option<u16> {
        let spare = if spare_too { None } else { self.spare_sector() };
        let su = Self::SECTOR_UNITS as u16;
        (0..self.units)
            .map(|i| (self.cursor + i) % self.units)
            .find(|&u| !self.written.has(u) && Some(u / su) != spare)
    }

    /// Sector mode: an erased unit to write, marked written before the program (a unit a failed
    /// program left half written is not free): outside the spare sector; when there is none, a
    /// written sector holding nothing of the live or committed map is erased, or else a sector
    /// is collected. Only the commit of a collection writes into the spare, which it collects
    /// into.
    fn take_erased(&mut self) -> Result<u16, FlashStoreError> {
        let unit = self.find_erased()?;
        self.written.set(unit, true);
        Ok(unit)
    }

    /// The unit [`Self::take_erased`] takes.
    fn find_erased(&mut self) -> Result<u16, FlashStoreError> {
        // No blank sector (a cut in a collection, or a region that was not blank): one holding
        // nothing of the maps is erased first, so that a spare is there before it is needed.
        if !self.collecting && self.spare_sector().is_none() {
            self.erase_unused_sector()?;
        }
        for _ in 0..3 {
            if let Some(u) = self.erased_unit(false) {
                return Ok(u);
            }
            if self.erase_unused_sector()? {
                continue;
            }
            if self.collecting {
                return self.erased_unit(true).ok_or(FlashStoreError::Full);
            }
            self.collect()?;
        }
        self.erased_unit(false).ok_or(FlashStoreError::Full)
    }

    /// Sector mode: erases the first written sector from the cursor's on that holds nothing of
    /// the live or committed map; whether there was one.
    fn erase_unused_sector(&mut self) -> Result<bool, FlashStoreError> {
        let unused = self.sectors_from_cursor().find(|&s| {
            let mut units = Self::sector_units(s);
            units.clone().any(|u| self.written.has(u))
                && units.all(|u| !self.live.has(u) && !self.committed.has(u))
        });
        let Some(sector) = unused else { return Ok(false) };
        self.erase_sector(sector)?;
        Ok(true)
    }

    /// Sector mode: erases sector `sector`, whose units are then free.
    fn erase_sector(&mut self, sector: u16) -> Result<(), FlashStoreError> {
        let units = Self::sector_units(sector);
        let (from, to) = (Self::unit_offset(units.start), Self::unit_offset(units.end));
        self.flash.erase(from, to).map_err(|e| FlashStoreError::of(&e))?;
        units.for_each(|u| self.written.set(u, false));
        Ok(())
    }

    /// Sector mode: collects a sector into the spare (see the module documentation): the
    /// sector (other than the spare) holding the fewest records of the live or the committed
    /// map, the first from the cursor's on. Its records are copied into the spare, the committed
    /// table is written again there with their new units (the same map, the next generation),
    /// and only then is the sector erased: a cut at any step boots the committed map. When the
    /// two maps differ too much for any sector's records to fit the spare, the sector with the
    /// fewest live records is collected and the live map committed with it instead (the store
    /// commits by itself, as when a unit-mode store runs out of spare units).
    fn collect(&mut self) -> Result<(), FlashStoreError> {
        let target = self.spare_sector().ok_or(FlashStoreError::Full)?;
        let old_table = (self.generation != 0).then_some(self.table_at);
        let kept = |s: &Self, u: u16| (s.live.has(u) || s.committed.has(u)) && Some(u) != old_table;
        let live = |s: &Self, u: u16| s.live.has(u);
        let fewest = |s: &Self, keep: &dyn Fn(&Self, u16) -> bool| {
            s.sectors_from_cursor()
                .filter(|&sec| sec != target)
                .map(|sec| (sec, Self::sector_units(sec).filter(|&u| keep(s, u)).count()))
                .min_by_key(|&(_, n)| n)
        };
        let (victim, moving) = fewest(self, &kept).ok_or(FlashStoreError::Full)?;
        // A collection must leave a unit of the spare free beyond what it writes there.
        if moving + usize::from(old_table.is_some()) < Self::SECTOR_UNITS {
            let before = self.committed;
            let (moved, next) = self.copy_sector(victim, target, &kept)?;
            if let Some(old) = old_table {
                let first = Self::sector_units(victim).start;
                let base = Self::sector_units(target).start;
                let remap = |u: u16| {
                    if !moved.has(u) {
                        return u;
                    }
                    base + (first..u).filter(|&v| moved.has(v)).count() as u16
                };
                if let Err(e) = self.rewrite_table(old, next, remap) {
                    self.committed = before;
                    return Err(e);
                }
                self.committed.set(old, false);
                self.committed.set(next, true);
                self.table_at = next;
                self.generation = self.generation.wrapping_add(1);
            }
            return self.erase_sector(victim);
        }
        let (victim, moving) = fewest(self, &live).ok_or(FlashStoreError::Full)?;
        if moving + 1 >= Self::SECTOR_UNITS {
            return Err(FlashStoreError::Full);
        }
        self.copy_sector(victim, target, &live)?;
        self.collecting = true;
        let committed = self.commit(usize::from(self.len));
        self.collecting = false;
        committed?;
        self.erase_sector(victim)
    }

    /// Copies the units of `victim` that `keep` names, in order, to the blank `target`'s
    /// first units: a live record moves its slot with it, a committed one its committed bit.
    /// Returns the units moved and the first of `target` left.
    fn copy_sector(
        &mut self,
        victim: u16,
        target: u16,
        keep: &dyn Fn(&Self, u16) -> bool,
    ) -> Result<(Units, u16), FlashStoreError> {
        let mut moved = Units::NONE;
        let mut to = Self::sector_units(target).start;
        for from in Self::sector_units(victim) {
            if !keep(self, from) {
                continue;
            }
            if self.live.has(from) {
                self.move_record(self.slot_of(from)?, from, to)?;
            } else {
                self.copy_unit(from, to)?;
            }
            if self.committed.has(from) {
                self.committed.set(from, false);
                self.committed.set(to, true);
            }
            moved.set(from, true);
            to += 1;
        }
        Ok((moved, to))
    }

    /// The live slot held in unit `unit`.
    fn slot_of(&self, unit: u16) -> Result<usize, FlashStoreError> {
        let len = usize::from(self.len);
        self.table.iter().take(len).position(|&u| u == unit).ok_or(FlashStoreError::Full)
    }

    /// Copies unit `from` to the erased unit `to`, through a 64-byte buffer.
    fn copy_unit(&mut self, from: u16, to: u16) -> Result<(), FlashStoreError> {
        let (src, dst) = (Self::unit_offset(from), Self::unit_offset(to));
        self.written.set(to, Self::SECTORED);
        let mut chunk = [0u8; 64];
        for at in (0..PLACE_RECORD_BYTES as u32).step_by(chunk.len()) {
            self.flash.read(src + at, &mut chunk).map_err(|e| FlashStoreError::of(&e))?;
            self.flash.write(dst + at, &chunk).map_err(|e| FlashStoreError::of(&e))?;
        }
        Ok(())
    }

    /// Writes the table in unit `old` again into the erased unit `to` under the next
    /// generation, each slot's unit through `remap`. The old table is checked (read again while
    /// damaged) first, and its checksum again as it is copied: when the copy read differently,
    /// the new table is left failing its checksum and the read is the error.
    fn rewrite_table(
        &mut self,
        old: u16,
        to: u16,
        remap: impl Fn(u16) -> u16,
    ) -> Result<(), FlashStoreError> {
        let (src, dst) = (Self::unit_offset(old), Self::unit_offset(to));
        if self.read_table_again(src, false)?.generation() != Some(self.generation) {
            return Err(FlashStoreError::Flash);
        }
        self.written.set(to, true);
        let generation = self.generation.wrapping_add(1);
        let (mut old_hash, mut new_hash) = (Fnv1a::default(), Fnv1a::default());
        let mut len = 0;
        let mut chunk = [0u8; 64];
        for c in 0..PLACE_RECORD_BYTES / chunk.len() {
            let at = (c * chunk.len()) as u32;
            self.flash.read(src + at, &mut chunk).map_err(|e| FlashStoreError::of(&e))?;
            let mut intact = true;
            for (i, w) in chunk.chunks_exact_mut(4).enumerate() {
                let word_at = c * 16 + i;
                let word = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
                if word_at == TABLE_WORDS - 1 {
                    intact = word == old_hash.value();
                    let sum = new_hash.value();
                    w.copy_from_slice(&if intact { sum } else { !sum }.to_le_bytes());
                    continue;
                }
                old_hash.add(w);
                let new = match word_at {
                    1 => generation,
                    0 => word,
                    2 => {
                        len = usize::from(word as u16);
                        word
                    }
                    _ => {
                        let slot = (word_at - TABLE_HEAD_WORDS) * 2;
                        let unit = |k: usize, u: u16| if slot + k < len { remap(u) } else { u };
                        u32::from(unit(0, word as u16))
                            | u32::from(unit(1, (word >> 16) as u16)) << 16
                    }
                };
                w.copy_from_slice(&new.to_le_bytes());
                new_hash.add(w);
            }
            self.flash.write(dst + at, &chunk).map_err(|e| FlashStoreError::of(&e))?;
            if !intact {
                return Err(FlashStoreError::Flash);
            }
        }
        Ok(())
    }
}

/// Keeps `(unit, generation)` in `found` when it is among the newest few.
fn keep_newest<const N: usize>(found: &mut HVec<(u16, u32), N>, unit: u16, generation: u32) {
    if found.push((unit, generation)).is_ok() {
        return;
    }
    let oldest = found.iter().enumerate().min_by(|a, b| serial_order(a.1.1, b.1.1)).map(|(i, _)| i);
    if let Some(i) = oldest
        && let Some(e) = found.get_mut(i)
        && serial_order(generation, e.1).is_gt()
    {
        *e = (unit, generation);
    }
}

/// Generations in serial-number order (the generation after `u32::MAX` is 0): `Greater` when `a`
/// is newer than `b`.
fn serial_order(a: u32, b: u32) -> core::cmp::Ordering {
    (a.wrapping_sub(b) as i32).cmp(&0)
}

/// Index of the newest of `generations`, in serial-number order.
fn newest_of(generations: impl Iterator<Item = u32>) -> Option<usize> {
    let mut best: Option<(usize, u32)> = None;
    for (i, g) in generations.enumerate() {
        if best.is_none_or(|(_, b)| serial_order(g, b).is_gt()) {
            best = Some((i, g));
        }
    }
    best.map(|(i, _)| i)
}

/// What a table unit read as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TableRead {
    /// A valid table of this generation.
    Valid(u32),
    /// The table magic, but a checksum or contents that do not hold.
    Damaged,
    /// Not a table: foreign, or its magic damaged.
    NotATable,
    /// Every byte erased.
    Blank,
}

impl TableRead {
    /// The generation of a valid table.
    fn generation(self) -> Option<u32> {
        match self {
            Self::Valid(g) => Some(g),
            Self::Damaged | Self::NotATable | Self::Blank => None,
        }
    }
}

/// The table unit and generation of the newest of `found` (each table unit's generation when
/// valid), in serial-number order.
fn newest(found: &[Option<u32>; TABLE_UNITS]) -> Option<(u8, u32)> {
    let valid = || found.iter().enumerate().filter_map(|(t, g)| g.map(|g| (t as u8, g)));
    newest_of(valid().map(|(_, g)| g)).and_then(|i| valid().nth(i))
}

impl<F: NorFlash> KeyframeStore for FlashStore<F> {
    type Error = FlashStoreError;

    fn capacity(&self) -> usize {
        let units = usize::from(self.units);
        if Self::SECTORED {
            return sector_capacity(units / Self::SECTOR_UNITS, Self::SECTOR_UNITS);
        }
        units.saturating_sub(SPARE_UNITS).min(TABLE_SLOTS)
    }

    fn held(&self) -> usize {
        usize::from(self.held)
    }

    fn read(&mut self, slot: usize, buf: &mut RecordBytes) -> Result<(), Self::Error> {
        let unit = match self.table.get(slot) {
            Some(&u) if slot < usize::from(self.len) => u,
            _ => return Err(FlashStoreError::SlotOutOfRange(slot)),
        };
        self.flash.read(Self::unit_offset(unit), buf).map_err(|e| FlashStoreError::of(&e))
    }

    /// Writes to a free unit; the slot's old unit is free once no committed table holds it (in
    /// sector mode, once its sector is erased). Slots are written in order: `slot` is at most
    /// the number held.
    fn write(&mut self, slot: usize, buf: &RecordBytes) -> Result<(), Self::Error> {
        if slot > usize::from(self.len) || slot >= self.capacity() {
            return Err(FlashStoreError::SlotOutOfRange(slot));
        }
        self.writes = self.writes.wrapping_add(1);
        let unit = if Self::SECTORED {
            self.take_erased()?
        } else {
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
            let from = Self::unit_offset(unit);
            let to = from + PLACE_RECORD_BYTES as u32;
            self.flash.erase(from, to).map_err(|e| FlashStoreError::of(&e))?;
            unit
        };
        let from = Self::unit_offset(unit);
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

    /// Writes the table of slots `0..records` to the next table unit of the ring (in sector
    /// mode, to an erased unit); from then on a boot finds that map, and the units only the
    /// previous table held are free (in sector mode, once their sector is erased).
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
        let t = (usize::from(self.table_unit) + 1) % TABLE_UNITS;
        // Taken before the generation is: taking a unit may collect a sector, which commits.
        let (from, table_at) = if Self::SECTORED {
            let unit = self.take_erased()?;
            (Self::unit_offset(unit), unit)
        } else {
            let from = Self::offset(t);
            self.flash
                .erase(from, from + PLACE_RECORD_BYTES as u32)
                .map_err(|e| FlashStoreError::of(&e))?;
            (from, 0)
        };
        let generation = self.generation.wrapping_add(1);
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
        if Self::SECTORED {
            self.table_at = table_at;
            self.committed.set(table_at, true);
        }
        self.dirty = false;
        Ok(())
    }
}

#[cfg(test)]
mod sector_tests;
#[cfg(test)]
mod tests;
