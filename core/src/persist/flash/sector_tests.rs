//! Sector mode of the durable flash store (erase sectors larger than a record): boots, the
//! collection of sectors, a power cut at every step of a save that collects, wear, and the
//! reference board's geometry.
//!
//! Test code only: compiled under #[cfg(test)] from `persist/flash.rs`.

extern crate std;

use std::vec::Vec;

use super::tests::{boot_on, record};
use super::*;
use crate::persist::{CutFlash, SliceFlash};

/// Small sectors (16 units) with 32-byte words programmed once each: every path of sector mode
/// at a size a test can cut at every step.
type Small<'a> = SliceFlash<'a, 16384, 32>;
const SMALL_SECTOR: usize = 16384;
/// Records a store holds on 4 small sectors.
const SMALL_SLOTS: usize = 36;
/// The STM32H743's internal flash: 128 KiB sectors, 32-byte words.
type H7<'a> = SliceFlash<'a, { 128 * 1024 }, 32>;

#[test]
fn capacity_keeps_a_spare_sector_and_a_quarter_of_each_other() {
    assert_eq!(sector_capacity(4, 8), 18);
    assert_eq!(sector_capacity(4, 16), SMALL_SLOTS);
    assert_eq!(sector_capacity(4, 128), 288);
    // The H743's bank 2 (1 MiB): every slot a table holds.
    assert_eq!(sector_capacity(8, 128), TABLE_SLOTS);
    assert_eq!((sector_capacity(1, 128), sector_capacity(4, 2)), (0, 0));
    let mut image = std::vec![0xFF; 4 * 128 * 1024];
    let store = FlashStore::mount(H7::with_geometry(&mut image)).unwrap();
    assert_eq!((store.capacity(), store.held(), store.generation()), (288, 0, 0));
    let mut small = std::vec![0xFF; 128 * 1024 + 1024];
    let store = FlashStore::mount(H7::with_geometry(&mut small)).unwrap();
    assert_eq!(store.capacity(), 0, "one sector: no spare");
}

#[test]
fn a_blank_or_foreign_region_mounts_empty_and_a_commit_is_what_the_next_boot_finds() {
    for fill in [0xFF, 0x00, 0x5A] {
        let mut image = std::vec![fill; 4 * SMALL_SECTOR];
        let mut store = FlashStore::mount(Small::with_geometry(&mut image)).unwrap();
        assert_eq!((store.held(), store.capacity()), (0, SMALL_SLOTS));
        for n in 0..3 {
            store.write(n as usize, &record(n)).unwrap();
        }
        let mut copy = store.flash().bytes().to_vec();
        assert!(boot_on(Small::with_geometry(&mut copy)).is_empty(), "not committed yet");
        store.commit(3).unwrap();
        let mut copy = store.flash().bytes().to_vec();
        assert_eq!(boot_on(Small::with_geometry(&mut copy)), [record(0), record(1), record(2)]);
    }
}

/// Fills `store`'s first `slots` slots (slot `n` with `record(n)`) and commits, then rewrites
/// slot `(i * stride) % slots` with `rewritten(slot, i)` for each `i < rewrites`, committing
/// after every `commit_every`-th rewrite and at the end.
fn fill_then_rewrite(
    store: &mut FlashStore<impl NorFlash>,
    slots: usize,
    (rewrites, stride, commit_every): (u32, usize, u32),
    rewritten: impl Fn(usize, u32) -> RecordBytes,
) {
    for n in 0..slots {
        store.write(n, &record(n as u32)).unwrap();
    }
    store.commit(slots).unwrap();
    for i in 0..rewrites {
        let slot = (i as usize * stride) % slots;
        store.write(slot, &rewritten(slot, i)).unwrap();
        if i % commit_every == commit_every - 1 {
            store.commit(slots).unwrap();
        }
    }
    store.commit(slots).unwrap();
}

/// A store of `slots` records on 4 small sectors, committed, then `rewrites` rewrites of its
/// slots in turn with a commit every 3: old sectors are collected on the way.
fn worn_small(slots: usize, rewrites: u32) -> Vec<u8> {
    let mut image = std::vec![0xFF; 4 * SMALL_SECTOR];
    let mut store = FlashStore::mount(Small::with_geometry(&mut image)).unwrap();
    fill_then_rewrite(&mut store, slots, (rewrites, 7, 3), |slot, _| record(slot as u32));
    image
}

/// The slots the save that makes map B rewrites.
const REWRITTEN: [usize; 5] = [2, 29, 3, 15, 34];

/// Map A as `worn_small(SMALL_SLOTS, ..)` left it; the save that makes map B rewrites five
/// slots, drops the last and commits.
fn save_b(store: &mut FlashStore<impl NorFlash>) -> Result<(), FlashStoreError> {
    for slot in REWRITTEN {
        store.write(slot, &record(100 + slot as u32))?;
    }
    store.commit(SMALL_SLOTS - 1)
}

#[test]
fn a_power_cut_at_any_step_of_a_save_that_collects_boots_the_previous_map_or_the_new_one() {
    let map_a: Vec<RecordBytes> = (0..SMALL_SLOTS as u32).map(record).collect();
    let mut map_b = map_a.clone();
    map_b.truncate(SMALL_SLOTS - 1);
    for slot in REWRITTEN {
        map_b[slot] = record(100 + slot as u32);
    }
    let (mut cuts, mut collecting) = (0u64, 0);
    // Starting points after 0..=11 rewrites: the save collects at different moments.
    for worn in (0..36).step_by(3) {
        let base = worn_small(SMALL_SLOTS, worn);
        assert_eq!(boot_on(Small::with_geometry(&mut base.clone())), map_a);
        let mut whole = base.clone();
        let mut flash = CutFlash::new(Small::with_geometry(&mut whole), None, 1, SMALL_SECTOR);
        let (steps, erases) = {
            let mut store = FlashStore::mount(&mut flash).unwrap();
            save_b(&mut store).unwrap();
            (flash.steps(), flash.erases().iter().sum::<u32>())
        };
        assert_eq!(boot_on(Small::with_geometry(&mut whole)), map_b);
        collecting += usize::from(erases > 0);
        for cut in 1..=steps {
            let mut image = base.clone();
            let mut flash =
                CutFlash::new(Small::with_geometry(&mut image), Some(cut), cut, SMALL_SECTOR);
            {
                let mut store = FlashStore::mount(&mut flash).unwrap();
                let _ = save_b(&mut store);
            }
            assert!(flash.cut());
            let found = boot_on(Small::with_geometry(&mut image));
            assert!(
                found == map_a || found == map_b,
                "start {worn}: a cut at step {cut} of {steps} booted neither map ({} slots)",
                found.len()
            );
            // The store on a cut image keeps working: a save after the cut commits.
            let mut store = FlashStore::mount(Small::with_geometry(&mut image)).unwrap();
            save_b(&mut store).unwrap();
            let again = boot_on(Small::with_geometry(&mut image));
            let wrong: Vec<usize> =
                (0..again.len().min(map_b.len())).filter(|&i| again[i] != map_b[i]).collect();
            assert!(
                again == map_b,
                "start {worn}, cut {cut}: the save after the cut booted {} slots, wrong {wrong:?}",
                again.len()
            );
            cuts += 1;
        }
    }
    std::eprintln!("{cuts} cuts, {collecting} of 12 saves erased a sector");
    assert!(cuts > 3000, "{cuts} cuts");
    assert!(collecting >= 4, "saves that erased a sector: {collecting} of 12");
}

#[test]
fn a_full_store_collects_sectors_for_ever_and_spreads_their_erases() {
    let mut image = std::vec![0xFF; 4 * SMALL_SECTOR];
    let mut flash = CutFlash::new(Small::with_geometry(&mut image), None, 3, SMALL_SECTOR);
    let mut store = FlashStore::mount(&mut flash).unwrap();
    // A full store thinning: a slot rewritten per keyframe, a commit every 5.
    fill_then_rewrite(&mut store, SMALL_SLOTS, (3000, 5, 5), |_, i| record(1000 + i));
    let erases: Vec<u32> = flash.erases()[..4].to_vec();
    let total: u32 = erases.iter().sum();
    // 3,000 records and 600 tables in 16-unit sectors: at least 225 sectors' worth written,
    // and a collection frees at least a unit.
    std::eprintln!("sector erases over 3,000 rewrites: {erases:?}");
    assert!((225..=3600).contains(&total), "sector erases {erases:?}");
    let (lo, hi) = (*erases.iter().min().unwrap(), *erases.iter().max().unwrap());
    assert!(lo * 2 >= hi, "sector erases {erases:?}");
    let found = boot_on(Small::with_geometry(&mut image));
    assert_eq!(found.len(), SMALL_SLOTS);
    assert_eq!(found[(2999 * 5) % SMALL_SLOTS], record(3999));
}

#[test]
fn the_reference_boards_bank_holds_a_full_map_and_a_second_boot_finds_it() {
    // Bank 2 of the H743: 8 sectors of 128 KiB.
    let mut image = std::vec![0xFF; 8 * 128 * 1024];
    let mut store = FlashStore::mount(H7::with_geometry(&mut image)).unwrap();
    let slots = store.capacity();
    assert_eq!(slots, TABLE_SLOTS);
    fill_then_rewrite(&mut store, slots, (1500, 13, 10), |_, i| record(10_000 + i));
    let found = boot_on(H7::with_geometry(&mut image));
    assert_eq!(found.len(), slots);
    assert_eq!(found[(1499 * 13) % slots], record(11_499));
}
