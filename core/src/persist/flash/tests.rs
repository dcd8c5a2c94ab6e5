//! Durable flash store tests: boots, commits, a power cut at every step of a save, wear.
//!
//! Test code only: compiled under #[cfg(test)] from `persist/flash.rs`.

extern crate std;

use std::vec::Vec;

use heapless::Vec as HVec;

use super::*;
use crate::features::Descriptor;
use crate::geometry::Pose;
use crate::map::{PlaceKey, PlacePoint, PlaceRecord};
use crate::persist::{CutFlash, SliceFlash};
use nalgebra::{Point3, Translation3, UnitQuaternion};

/// A record told apart by `n` (its seq, pose, key and points).
pub(super) fn record(n: u32) -> RecordBytes {
    let mut points = HVec::new();
    for i in 0..4u32 {
        let p = Point3::new(i as f32 * 0.1, n as f32 * 0.01, 1.0 + i as f32 * 0.05);
        let _ = points.push(PlacePoint { p_c: p, descriptor: Descriptor(u64::from(n * 31 + i)) });
    }
    let t_wc = Pose::from_parts(
        Translation3::new(n as f32 * 0.1, 0.0, 0.0),
        UnitQuaternion::from_euler_angles(0.0, n as f32 * 0.01, 0.0),
    );
    let mut key = PlaceKey::default();
    key.0.iter_mut().enumerate().for_each(|(i, k)| *k = (i as u32 * 7 + n) as u8);
    let r = PlaceRecord { seq: n, timestamp_s: f64::from(n), t_wc, key, points };
    let mut buf = [0; PLACE_RECORD_BYTES];
    r.encode(&mut buf);
    buf
}

/// What a boot on `image` finds: each held slot's bytes, in order.
fn boot(image: &mut [u8]) -> Vec<RecordBytes> {
    boot_on(SliceFlash::new(image))
}

/// What a boot on `flash` finds: each held slot's bytes, in order.
pub(super) fn boot_on<F: NorFlash>(flash: F) -> Vec<RecordBytes> {
    let mut store = FlashStore::mount(flash).unwrap();
    (0..store.held())
        .map(|slot| {
            let mut buf = [0; PLACE_RECORD_BYTES];
            store.read(slot, &mut buf).unwrap();
            buf
        })
        .collect()
}

/// A region for a store of `slots` records.
fn region(slots: usize) -> Vec<u8> {
    std::vec![0xFF; flash_bytes_for(slots)]
}

#[test]
fn a_blank_or_foreign_region_mounts_empty_and_a_commit_is_what_the_next_boot_finds() {
    for fill in [0xFF, 0x00, 0x5A] {
        let mut image = std::vec![fill; flash_bytes_for(6)];
        let mut store = FlashStore::mount(SliceFlash::new(&mut image)).unwrap();
        assert_eq!((store.held(), store.capacity(), store.generation()), (0, 6, 0));
        for n in 0..3 {
            store.write(n as usize, &record(n)).unwrap();
        }
        // Written but not committed: a boot now finds nothing.
        let mut copy = image_of(&store);
        assert!(boot(&mut copy).is_empty());
        store.commit(3).unwrap();
        let mut copy = image_of(&store);
        assert_eq!(boot(&mut copy), std::vec![record(0), record(1), record(2)]);
        // A commit of fewer slots drops the rest; slots are written in order.
        store.commit(2).unwrap();
        assert_eq!(boot(&mut image_of(&store)).len(), 2);
        assert_eq!(store.write(3, &record(9)), Err(FlashStoreError::SlotOutOfRange(3)));
        assert_eq!(store.write(6, &record(9)), Err(FlashStoreError::SlotOutOfRange(6)));
    }
}

fn image_of(store: &FlashStore<SliceFlash<'_>>) -> Vec<u8> {
    store.flash().bytes().to_vec()
}

/// Map A: slots 0..5 committed. The save that makes map B: slots 1 and 3 rewritten (a full
/// store thins this way), 5..8 added, then the commit.
fn save_b(store: &mut FlashStore<impl NorFlash>) -> Result<(), FlashStoreError> {
    store.write(1, &record(101))?;
    store.write(3, &record(103))?;
    for n in 5..8 {
        store.write(n as usize, &record(n))?;
    }
    store.commit(8)
}

#[test]
fn a_power_cut_at_any_step_of_a_save_boots_the_previous_map_or_the_new_one() {
    let mut base = region(8);
    {
        let mut store = FlashStore::mount(SliceFlash::new(&mut base)).unwrap();
        for n in 0..5 {
            store.write(n as usize, &record(n)).unwrap();
        }
        store.commit(5).unwrap();
        // An earlier save's leftovers, so that the spare units are not all blank.
        store.write(4, &record(44)).unwrap();
        store.write(4, &record(4)).unwrap();
        store.commit(5).unwrap();
    }
    let map_a: Vec<RecordBytes> = (0..5).map(record).collect();
    let mut map_b = map_a.clone();
    map_b[1] = record(101);
    map_b[3] = record(103);
    map_b.extend((5..8).map(record));
    // The whole save, uncut: how many steps it takes.
    let mut whole = base.clone();
    let mut flash = CutFlash::new(SliceFlash::new(&mut whole), None, 1, PLACE_RECORD_BYTES);
    let steps = {
        let mut store = FlashStore::mount(&mut flash).unwrap();
        save_b(&mut store).unwrap();
        flash.steps()
    };
    assert_eq!(boot(&mut whole), map_b);
    let (mut previous, mut new) = (0, 0);
    for cut in 1..=steps {
        let mut image = base.clone();
        let mut flash = CutFlash::new(SliceFlash::new(&mut image), Some(cut), cut, 1024);
        {
            let mut store = FlashStore::mount(&mut flash).unwrap();
            let _ = save_b(&mut store);
        }
        assert!(flash.cut());
        let found = boot(&mut image);
        if found == map_a {
            previous += 1;
        } else if found == map_b {
            new += 1;
        } else {
            panic!(
                "a cut at step {cut} of {steps} booted a map that is neither: {} slots",
                found.len()
            );
        }
    }
    // Every cut, even in the commit's last program step (left half done), boots the previous
    // map; only the save that ran whole boots the new one (checked above).
    assert!(steps > 1500, "a save of 5 records and a table: {steps} steps");
    assert_eq!((previous, new), (steps, 0));
}

#[test]
fn a_full_store_spreads_its_erases_over_every_unit() {
    let mut image = region(8);
    let mut flash = CutFlash::new(SliceFlash::new(&mut image), None, 3, PLACE_RECORD_BYTES);
    let mut store = FlashStore::mount(&mut flash).unwrap();
    for n in 0..8 {
        store.write(n, &record(n as u32)).unwrap();
    }
    store.commit(8).unwrap();
    // A robot standing still: the same slot rewritten 2000 times, a commit every 5 writes; the
    // seven others never change.
    for i in 0..2000u32 {
        store.write(2, &record(1000 + i)).unwrap();
        if i % 5 == 4 {
            store.commit(8).unwrap();
        }
    }
    let held = store.held();
    let erases = flash.erases();
    let (tables, units) = erases.split_at(TABLE_UNITS);
    let units = &units[..16];
    let total: u32 = units.iter().sum();
    let (lo, hi) = (*units.iter().min().unwrap(), *units.iter().max().unwrap());
    // Without moving cold records, 7 units would be erased once and the other 9 take it all.
    assert!(total <= 2008 * 5 / 4 + 8, "one move every {RELOCATE_EVERY} writes at most: {total}");
    assert!(hi * 16 <= total * 5 / 4 && lo * 16 >= total * 3 / 4, "record unit erases {units:?}");
    assert!(tables.iter().all(|&t| (100..=101).contains(&t)), "401 commits, 4 tables: {tables:?}");
    assert_eq!(held, 0, "mounted on a blank region");
    let found = boot(&mut image);
    assert_eq!((found.len(), found[2]), (8, record(2999)));
}

#[test]
fn rewrites_beyond_the_spare_units_commit_by_themselves() {
    let mut image = region(12);
    let mut store = FlashStore::mount(SliceFlash::new(&mut image)).unwrap();
    for n in 0..12 {
        store.write(n, &record(n as u32)).unwrap();
    }
    store.commit(12).unwrap();
    let g = store.generation();
    // 12 committed units stay pinned while slots are rewritten: with 20 units, at most 8
    // rewrites of distinct slots fit before the store must commit first.
    for n in 0..=SPARE_UNITS {
        store.write(n, &record(50 + n as u32)).unwrap();
    }
    assert!(store.generation() > g, "committed by itself");
    let found = boot(&mut image_of(&store));
    assert_eq!(found.len(), 12);
    for (n, r) in found.iter().enumerate() {
        assert!(*r == record(n as u32) || *r == record(50 + n as u32), "slot {n}");
    }
    assert_eq!(found[0], record(50));
}

/// What a boot through `flash` found: the generation, and per held slot whether its record read
/// back as `expected`'s (or was refused by its checksum: `None`).
fn boot_through<F: NorFlash>(flash: F) -> (u32, Vec<Option<bool>>) {
    let mut store = FlashStore::mount(flash).unwrap();
    let records = (0..store.held())
        .map(|slot| {
            let mut buf = [0; PLACE_RECORD_BYTES];
            store.read(slot, &mut buf).unwrap();
            PlaceRecord::decode(&buf).ok().map(|_| buf == record(slot as u32 + 100))
        })
        .collect();
    (store.generation(), records)
}

#[test]
fn bit_flips_on_read_never_give_a_wrong_table_or_record() {
    // Generation 1 holds records 0..6, generation 2 records 100..106.
    let mut image = region(12);
    let mut store = FlashStore::mount(SliceFlash::new(&mut image)).unwrap();
    for n in 0..6 {
        store.write(n, &record(n as u32)).unwrap();
    }
    store.commit(6).unwrap();
    for n in 0..6 {
        store.write(n, &record(n as u32 + 100)).unwrap();
    }
    store.commit(6).unwrap();
    let image = image_of(&store);
    let (mut newest, mut refused, mut read_right) = ([0; 3], 0, 0);
    for (k, per_mille) in [10, 100, 1000].into_iter().enumerate() {
        for seed in 0..300 {
            let mut copy = image.clone();
            let flash = crate::persist::FlipFlash::new(SliceFlash::new(&mut copy), per_mille, seed);
            let (generation, records) = boot_through(flash);
            // A table with a flipped bit is never taken: the newest (read again) or an older
            // one, or none when every read flips.
            assert!(generation <= 2, "{per_mille} {seed}");
            newest[k] += usize::from(generation == 2);
            for r in &records {
                match r {
                    // A record that passes its checksum is the one written.
                    Some(right) => {
                        assert!(*right || generation == 1, "a wrong record, seed {seed}");
                        read_right += 1;
                    }
                    None => refused += 1,
                }
            }
            if per_mille == 1000 {
                assert_eq!(generation, 0, "every read flips: no table is valid");
            }
        }
    }
    // A table is read in 16 pieces: at 1% of reads flipped a pass over it sees a flip 15% of the
    // time, and a read again finds it whole; at 10%, 81% of the time, and a boot may fall back
    // to the older map (never a wrong one).
    std::eprintln!("boots of the newest map of 300, at 1%, 10%, 100% of reads flipped: {newest:?}");
    assert!(newest[0] >= 295 && newest[1] >= 50 && newest[2] == 0, "{newest:?}");
    assert!(refused > 0 && read_right > refused, "{read_right} right, {refused} refused");
}
