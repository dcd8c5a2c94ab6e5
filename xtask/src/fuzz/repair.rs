//! Checksum repairs: a mutated input with its checksums (and the map file's record count)
//! recomputed, so that a mutation reaches the checks behind the checksum instead of being refused
//! by it every time. The mutator applies a target's repair to one mutated input in two; the
//! other half exercises the checksum checks themselves.
//!
//! The layouts repaired are the documented ones: the map file and the record
//! ([`ferroslam_core::persist`], [`ferroslam_core::map`]: FNV-1a of a record's bytes but its last
//! 4, in its last 4), the flash store's table units (`persist::FlashStore`: the same scheme), the
//! wire frame ([`ferroslam_core::wire`]: COBS of version, body and CRC-32) and PNG (each chunk's
//! CRC-32, big-endian, over its type and data).

use ferroslam_core::config::capacity::PLACE_RECORD_BYTES;
use ferroslam_core::map::Fnv1a;
use ferroslam_core::persist::{MAP_HEADER_BYTES, TABLE_UNITS};
use ferroslam_core::wire::{CRC_BYTES, crc32};

/// Where a map file's header holds the record count (u32) and the records' checksum (u32).
const MAP_COUNT_AT: usize = 12;
const MAP_CHECKSUM_AT: usize = 16;

/// The PNG signature's length: chunks start after it.
const PNG_SIGNATURE_BYTES: usize = 8;

/// FNV-1a of `bytes`.
fn fnv(bytes: &[u8]) -> u32 {
    let mut h = Fnv1a::default();
    h.add(bytes);
    h.value()
}

/// Recomputes the checksum of a unit (a record or a flash table: FNV-1a of its bytes but the last
/// 4, in the last 4) when it starts with `magic`; an erased or foreign unit is left alone.
fn repair_unit(unit: &mut [u8], magic: &[u8]) {
    if !unit.starts_with(magic) || unit.len() < 4 {
        return;
    }
    let (body, sum) = unit.split_at_mut(unit.len() - 4);
    sum.copy_from_slice(&fnv(body).to_le_bytes());
}

/// A map file: cut to whole units, each record's and world unit's checksum, the header's count
/// (less the world units its byte 10 states) and checksum.
pub fn map_file(data: &mut Vec<u8>) {
    if data.len() < MAP_HEADER_BYTES {
        return;
    }
    let records = (data.len() - MAP_HEADER_BYTES) / PLACE_RECORD_BYTES;
    data.truncate(MAP_HEADER_BYTES + records * PLACE_RECORD_BYTES);
    let (header, body) = data.split_at_mut(MAP_HEADER_BYTES);
    body.chunks_exact_mut(PLACE_RECORD_BYTES).for_each(|r| {
        repair_unit(r, b"FP");
        repair_unit(r, b"FW");
    });
    // Byte 10: the world units after the records.
    let world = usize::from(header.get(10).copied().unwrap_or(0));
    let count = u32::try_from(records.saturating_sub(world)).unwrap_or(u32::MAX);
    if let Some(dst) = header.get_mut(MAP_COUNT_AT..MAP_COUNT_AT + 4) {
        dst.copy_from_slice(&count.to_le_bytes());
    }
    if let Some(dst) = header.get_mut(MAP_CHECKSUM_AT..MAP_CHECKSUM_AT + 4) {
        dst.copy_from_slice(&fnv(body).to_le_bytes());
    }
}

/// A flash region: the checksum of each table unit (magic `FT`) and of each record unit.
#[allow(clippy::ptr_arg, reason = "every repair has the signature of `Shape::repair`")]
pub fn flash(data: &mut Vec<u8>) {
    for (i, unit) in data.chunks_exact_mut(PLACE_RECORD_BYTES).enumerate() {
        if i < TABLE_UNITS {
            repair_unit(unit, b"FT");
        } else {
            repair_unit(unit, b"FP");
            repair_unit(unit, b"FW");
        }
    }
}

/// A capture: each frame between delimiters that is valid COBS gets the CRC of its payload and
/// is encoded again.
pub fn wire(data: &mut Vec<u8>) {
    let mut out = Vec::with_capacity(data.len() + 8);
    for (i, frame) in data.split(|&b| b == 0).enumerate() {
        if i > 0 {
            out.push(0);
        }
        out.extend_from_slice(&wire_frame(frame));
    }
    *data = out;
}

/// One frame's bytes (no delimiter), its CRC recomputed when it decodes.
fn wire_frame(frame: &[u8]) -> Vec<u8> {
    let mut payload = frame.to_vec();
    let Ok(len) = cobs::decode_in_place(&mut payload) else { return frame.to_vec() };
    let Some(body) = len.checked_sub(CRC_BYTES).filter(|&b| b >= 1) else {
        return frame.to_vec();
    };
    let crc = crc32(payload.get(..body).unwrap_or(&[]));
    if let Some(dst) = payload.get_mut(body..len) {
        dst.copy_from_slice(&crc.to_le_bytes());
    }
    let mut encoded = vec![0; cobs::max_encoding_length(len)];
    let n = cobs::encode(payload.get(..len).unwrap_or(&[]), &mut encoded);
    encoded.truncate(n);
    encoded
}

/// A PNG: each whole chunk's CRC, in order, until a chunk runs past the end.
#[allow(clippy::ptr_arg, reason = "every repair has the signature of `Shape::repair`")]
pub fn png(data: &mut Vec<u8>) {
    let mut at = PNG_SIGNATURE_BYTES;
    while let Some(len) = data.get(at..at + 4) {
        let len = u32::from_be_bytes([len[0], len[1], len[2], len[3]]) as usize;
        let Some(crc_at) = (at + 8).checked_add(len).filter(|&c| c + 4 <= data.len()) else {
            return;
        };
        let crc = crc32(data.get(at + 4..crc_at).unwrap_or(&[]));
        if let Some(dst) = data.get_mut(crc_at..crc_at + 4) {
            dst.copy_from_slice(&crc.to_be_bytes());
        }
        at = crc_at + 4;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferroslam_core::wire::{FaultCode, FaultMessage, MAX_FRAME_ON_WIRE, Message, encode};

    #[test]
    fn a_repaired_wire_frame_decodes_again_after_a_flipped_bit() {
        let m = Message::Fault(FaultMessage {
            frame_index: 3,
            code: FaultCode::FrameSource,
            detail: 9,
        });
        let mut frame = [0u8; MAX_FRAME_ON_WIRE];
        let n = encode(&m, &mut frame).unwrap();
        let mut bytes = frame[..n].to_vec();
        // A bit of the CRC, never making a delimiter.
        let at = n - 3;
        bytes[at] ^= if bytes[at] == 0x10 { 0x20 } else { 0x10 };
        assert!(ferroslam_sim::serial::decode_capture(&bytes).messages.is_empty());
        wire(&mut bytes);
        let capture = ferroslam_sim::serial::decode_capture(&bytes);
        assert_eq!(capture.messages.len(), 1, "{:?}", capture.dropped);
    }

    #[test]
    fn repairs_take_any_bytes() {
        for len in [0, 1, 7, 8, 12, 20, 21, 1043, 1044, 4096, 5000] {
            let mut data: Vec<u8> = (0..len).map(|i| (i * 7) as u8).collect();
            for repair in [map_file, flash, wire, png] {
                repair(&mut data);
            }
        }
    }
}
