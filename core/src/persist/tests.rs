//! Map file header tests. Test code only: compiled under #[cfg(test)] from `persist/mod.rs`.
//! (Saving and loading a place memory: `loops/tests.rs`.)

use super::*;

#[test]
fn a_header_round_trips_and_a_wrong_one_says_what_is_wrong() {
    let h = MapHeader { records: 300, checksum: 0xDEAD_BEEF };
    let bytes = h.encode();
    assert_eq!(&bytes[..4], b"FSMP");
    assert_eq!(MapHeader::decode(&bytes), Ok(h));
    assert_eq!(h.file_bytes(), 16 + 300 * 1024);
    assert_eq!(
        MapHeader::decode(&bytes[..10]),
        Err(MapFileError::Truncated { expected: 16, found: 10 })
    );
    let mut other = bytes;
    other[0] = b'X';
    assert_eq!(MapHeader::decode(&other), Err(MapFileError::NotAMap));
    let mut other = bytes;
    other[4] = 9;
    assert_eq!(MapHeader::decode(&other), Err(MapFileError::Version(9)));
    let mut other = bytes;
    other[6..8].copy_from_slice(&512u16.to_le_bytes());
    assert_eq!(MapHeader::decode(&other), Err(MapFileError::RecordBytes(512)));
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
