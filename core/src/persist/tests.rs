//! Map file header tests. Test code only: compiled under #[cfg(test)] from `persist/mod.rs`.
//! (Saving and loading a place memory: `loops/tests.rs`.)

extern crate std;

use std::string::ToString;

use super::*;

#[test]
fn a_header_round_trips_and_a_wrong_one_says_what_is_wrong() {
    let h = MapHeader { records: 300, world_units: 2, checksum: 0xDEAD_BEEF };
    let bytes = h.encode();
    assert_eq!(&bytes[..4], b"FSMP");
    assert_eq!(
        &bytes[4..12],
        &[3, 48, 16, 12, 0, 4, 2, 0],
        "version, points, key, record bytes, world"
    );
    assert_eq!(MapHeader::decode(&bytes), Ok(h));
    assert_eq!(h.file_bytes(), 20 + 302 * 1024);
    assert_eq!(
        MapHeader::decode(&bytes[..10]),
        Err(MapFileError::Truncated { expected: 20, found: 10 })
    );
    let mut other = bytes;
    other[0] = b'X';
    assert_eq!(MapHeader::decode(&other), Err(MapFileError::NotAMap));
    // A version 1 file (16-byte header) is named by its version, not as truncated.
    let mut other = bytes;
    other[4] = 1;
    assert_eq!(MapHeader::decode(&other[..16]), Err(MapFileError::Version(1)));
    let mut other = bytes;
    other[5] = 32;
    other[8..10].copy_from_slice(&512u16.to_le_bytes());
    let layout = RecordLayout { record_bytes: 512, points: 32, key: [16, 12] };
    assert_eq!(MapHeader::decode(&other), Err(MapFileError::Layout(layout)));
    let mut other = bytes;
    other[11] = 0x15;
    assert_eq!(MapHeader::decode(&other), Err(MapFileError::Reserved([2, 0x15])));
    let mut other = bytes;
    other[10] = 1;
    assert_eq!(MapHeader::decode(&other), Err(MapFileError::WorldUnits(1)));
    // Version 2 had no world: its byte 10 was reserved.
    let mut other = bytes;
    other[4] = 2;
    assert_eq!(MapHeader::decode(&other), Err(MapFileError::Reserved([2, 0])));
    other[10] = 0;
    assert_eq!(MapHeader::decode(&other), Ok(MapHeader { world_units: 0, ..h }));
    assert_eq!(
        MapFileError::Layout(layout).to_string(),
        "written by a build with other capacities: records of 512 bytes, 32 points, a 16 x 12 \
         key; this build's are records of 1024 bytes, 48 points, a 16 x 12 key"
    );
}

#[test]
fn the_checksum_is_fnv_1a_over_every_record_in_order() {
    let mut a = RecordsChecksum::default();
    a.add(b"ab");
    a.add(b"c");
    let mut b = RecordsChecksum::default();
    b.add(b"abc");
    // FNV-1a 32 of "abc".
    assert_eq!((a.value(), b.value()), (0x1A47_E90B, 0x1A47_E90B));
}
