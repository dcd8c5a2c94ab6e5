//! OMG CDR (XCDR1), as ROS 2 serializes messages: a 4-byte encapsulation header, then the fields
//! in order, each primitive aligned to its own size (at most 8) counted from just after the
//! header; strings are a `u32` length that counts a closing NUL, the bytes and the NUL; sequences
//! are a `u32` count and the elements. [`CdrReader`] reads either byte order (the header says
//! which); [`CdrWriter`] writes little-endian (`CDR_LE`), what ROS 2 writes on every common host.

/// The encapsulation header's first two bytes: plain CDR, big- and little-endian.
const CDR_BE: [u8; 2] = [0x00, 0x00];
const CDR_LE: [u8; 2] = [0x00, 0x01];
/// Bytes of the encapsulation header (kind, then two option bytes).
const HEADER_LEN: usize = 4;

/// Why CDR bytes could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum CdrError {
    /// The bytes end before the field does.
    #[error("truncated: {field} needs {needed} bytes at offset {offset}, {available} left")]
    Truncated {
        /// The field being read.
        field: &'static str,
        /// Bytes it needs (after alignment).
        needed: usize,
        /// Its offset after the encapsulation header.
        offset: usize,
        /// Bytes left there.
        available: usize,
    },
    /// The encapsulation header is not plain CDR (e.g. XCDR2 or PL_CDR, which ROS 2 does not
    /// write for these messages).
    #[error("encapsulation {kind:02x?} is not plain CDR (00 00 or 00 01)")]
    Encapsulation {
        /// The header's first two bytes.
        kind: [u8; 2],
    },
    /// A string is not NUL-terminated UTF-8.
    #[error("string {field} is not NUL-terminated UTF-8")]
    BadString {
        /// The field.
        field: &'static str,
    },
}

/// Reads CDR fields in order from a message's bytes.
#[derive(Debug)]
pub struct CdrReader<'a> {
    /// The bytes after the encapsulation header.
    body: &'a [u8],
    /// Offset of the next field in `body`.
    offset: usize,
    little_endian: bool,
}

impl<'a> CdrReader<'a> {
    /// A reader of `bytes`, a whole message with its encapsulation header.
    ///
    /// # Errors
    /// [`CdrError::Truncated`] below 4 bytes, [`CdrError::Encapsulation`] for another kind.
    pub fn new(bytes: &'a [u8]) -> Result<Self, CdrError> {
        let Some((header, body)) = bytes.split_first_chunk::<HEADER_LEN>() else {
            let available = bytes.len();
            return Err(CdrError::Truncated {
                field: "encapsulation header",
                needed: HEADER_LEN,
                offset: 0,
                available,
            });
        };
        let kind = [header[0], header[1]];
        let little_endian = match kind {
            CDR_LE => true,
            CDR_BE => false,
            _ => return Err(CdrError::Encapsulation { kind }),
        };
        Ok(Self { body, offset: 0, little_endian })
    }

    /// The offset of the next field, counted from just after the encapsulation header.
    pub fn offset(&self) -> usize {
        self.offset
    }

    /// The next `len` bytes, after aligning to `align`.
    fn take(
        &mut self,
        field: &'static str,
        align: usize,
        len: usize,
    ) -> Result<&'a [u8], CdrError> {
        let start = self.offset.next_multiple_of(align);
        let bytes = start.checked_add(len).and_then(|end| self.body.get(start..end)).ok_or(
            CdrError::Truncated {
                field,
                needed: len,
                offset: start,
                available: self.body.len().saturating_sub(start),
            },
        )?;
        self.offset = start + len;
        Ok(bytes)
    }

    /// The next `N` bytes of a primitive of size `N`, aligned to `N`, in host order.
    fn primitive<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], CdrError> {
        let mut out = [0u8; N];
        out.copy_from_slice(self.take(field, N, N)?);
        if !self.little_endian {
            out.reverse();
        }
        Ok(out)
    }

    /// A `uint8` (or `bool`, `char`).
    pub fn u8(&mut self, field: &'static str) -> Result<u8, CdrError> {
        Ok(self.primitive::<1>(field)?[0])
    }

    /// A `uint32`.
    pub fn u32(&mut self, field: &'static str) -> Result<u32, CdrError> {
        self.primitive(field).map(u32::from_le_bytes)
    }

    /// An `int32`.
    pub fn i32(&mut self, field: &'static str) -> Result<i32, CdrError> {
        self.primitive(field).map(i32::from_le_bytes)
    }

    /// A `float64`.
    pub fn f64(&mut self, field: &'static str) -> Result<f64, CdrError> {
        self.primitive(field).map(f64::from_le_bytes)
    }

    /// A `string`: its length (counting the closing NUL), its bytes and the NUL.
    pub fn string(&mut self, field: &'static str) -> Result<&'a str, CdrError> {
        let len = self.u32(field)? as usize;
        let bytes = self.take(field, 1, len)?;
        let Some((&0, text)) = bytes.split_last() else {
            return Err(CdrError::BadString { field });
        };
        std::str::from_utf8(text).map_err(|_| CdrError::BadString { field })
    }

    /// A `sequence<uint8>`: its count, then the bytes, borrowed.
    pub fn bytes(&mut self, field: &'static str) -> Result<&'a [u8], CdrError> {
        let len = self.u32(field)? as usize;
        self.take(field, 1, len)
    }

    /// A `sequence<float64>`.
    pub fn f64_sequence(&mut self, field: &'static str) -> Result<Vec<f64>, CdrError> {
        let len = self.u32(field)? as usize;
        // The count cannot exceed what the bytes left hold: no allocation a header can inflate.
        if len > self.body.len().saturating_sub(self.offset) / 8 {
            let available = self.body.len().saturating_sub(self.offset);
            let (needed, offset) = (len.saturating_mul(8), self.offset);
            return Err(CdrError::Truncated { field, needed, offset, available });
        }
        (0..len).map(|_| self.f64(field)).collect()
    }

    /// A `float64[N]`.
    pub fn f64_array<const N: usize>(&mut self, field: &'static str) -> Result<[f64; N], CdrError> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64(field)?;
        }
        Ok(out)
    }
}

/// Writes CDR fields in order, little-endian, after the `CDR_LE` encapsulation header.
#[derive(Debug, Clone)]
pub struct CdrWriter {
    bytes: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    /// An empty message: the encapsulation header alone.
    pub fn new() -> Self {
        let mut bytes = Vec::with_capacity(64);
        bytes.extend_from_slice(&CDR_LE);
        bytes.extend_from_slice(&[0, 0]);
        Self { bytes }
    }

    /// Pads with zeros to a multiple of `align` after the header.
    fn align(&mut self, align: usize) {
        let offset = self.bytes.len() - HEADER_LEN;
        self.bytes.resize(HEADER_LEN + offset.next_multiple_of(align), 0);
    }

    /// A `uint8` (or `bool`).
    pub fn u8(&mut self, v: u8) {
        self.bytes.push(v);
    }

    /// A `uint32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    /// An `int32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    /// A `float64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    /// A `string` (its length counts the closing NUL written after it).
    pub fn string(&mut self, s: &str) {
        self.u32(len_u32(s.len() + 1));
        self.bytes.extend_from_slice(s.as_bytes());
        self.bytes.push(0);
    }

    /// A `sequence<uint8>`.
    pub fn bytes(&mut self, data: &[u8]) {
        self.u32(len_u32(data.len()));
        self.bytes.extend_from_slice(data);
    }

    /// A `sequence<float64>`.
    pub fn f64_sequence(&mut self, values: &[f64]) {
        self.u32(len_u32(values.len()));
        values.iter().for_each(|&v| self.f64(v));
    }

    /// A `float64[N]` (no count).
    pub fn f64_array(&mut self, values: &[f64]) {
        values.iter().for_each(|&v| self.f64(v));
    }

    /// The message's bytes, header included.
    pub fn finish(self) -> Vec<u8> {
        self.bytes
    }
}

/// A length as CDR's `u32`; the messages written here stay far below 4 GiB (an image of the
/// largest calibrated size, 8192 x 8192 x 3 bytes, is 192 MiB).
fn len_u32(len: usize) -> u32 {
    u32::try_from(len).unwrap_or(u32::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_of_every_field_kind() {
        let mut w = CdrWriter::new();
        w.i32(-7);
        w.u32(42);
        w.string("frame");
        w.u8(1);
        w.f64(0.25);
        w.bytes(&[1, 2, 3]);
        w.f64_sequence(&[1.5, -2.0]);
        w.f64_array(&[3.0; 3]);
        let bytes = w.finish();
        let mut r = CdrReader::new(&bytes).unwrap();
        assert_eq!(r.i32("a").unwrap(), -7);
        assert_eq!(r.u32("b").unwrap(), 42);
        assert_eq!(r.string("c").unwrap(), "frame");
        assert_eq!(r.u8("d").unwrap(), 1);
        assert_eq!(r.f64("e").unwrap(), 0.25);
        assert_eq!(r.bytes("f").unwrap(), &[1, 2, 3]);
        assert_eq!(r.f64_sequence("g").unwrap(), vec![1.5, -2.0]);
        assert_eq!(r.f64_array::<3>("h").unwrap(), [3.0; 3]);
        assert_eq!(r.offset(), bytes.len() - HEADER_LEN);
    }

    #[test]
    fn alignment_counts_from_after_the_header() {
        // u8 at 0, a u32 padded to 4, a u32 at 8, an f64 padded to 16: offsets after the header.
        let mut w = CdrWriter::new();
        w.u8(9);
        w.u32(0x0102_0304);
        w.u32(5);
        w.f64(1.0);
        let bytes = w.finish();
        assert_eq!(&bytes[..4], &[0, 1, 0, 0]);
        assert_eq!(&bytes[4..8], &[9, 0, 0, 0]);
        assert_eq!(&bytes[8..12], &[4, 3, 2, 1]);
        assert_eq!(&bytes[12..16], &[5, 0, 0, 0]);
        assert_eq!(&bytes[16..20], &[0; 4], "padding to the f64's 8-byte boundary");
        assert_eq!(&bytes[20..28], &1.0f64.to_le_bytes());
        let mut r = CdrReader::new(&bytes).unwrap();
        assert_eq!((r.u8("a").unwrap(), r.u32("b").unwrap()), (9, 0x0102_0304));
        assert_eq!((r.u32("c").unwrap(), r.f64("d").unwrap()), (5, 1.0));
        // A string of 5 bytes + NUL leaves the next u32 at offset 12, not 10.
        let mut w = CdrWriter::new();
        w.string("abcde");
        w.u32(7);
        let bytes = w.finish();
        assert_eq!(bytes.len(), HEADER_LEN + 16);
    }

    #[test]
    fn big_endian_messages_are_read() {
        let mut bytes = vec![0, 0, 0, 0];
        bytes.extend_from_slice(&[0, 0, 0, 5]);
        bytes.extend_from_slice(&[0; 4]);
        bytes.extend_from_slice(&2.5f64.to_be_bytes());
        let mut r = CdrReader::new(&bytes).unwrap();
        assert_eq!(r.u32("n").unwrap(), 5);
        assert_eq!(r.f64("x").unwrap(), 2.5);
    }

    #[test]
    fn truncated_input_is_an_error_not_a_panic() {
        let mut w = CdrWriter::new();
        w.string("frame_id");
        w.bytes(&[7; 16]);
        w.f64_sequence(&[1.0, 2.0]);
        let bytes = w.finish();
        for len in 0..bytes.len() {
            let read = |b: &[u8]| -> Result<(), CdrError> {
                let mut r = CdrReader::new(b)?;
                r.string("s")?;
                r.bytes("b")?;
                r.f64_sequence("d")?;
                Ok(())
            };
            let err = read(&bytes[..len]).unwrap_err();
            assert!(matches!(err, CdrError::Truncated { .. }), "{len}: {err}");
        }
        // A count far beyond the bytes is refused before allocating.
        let mut w = CdrWriter::new();
        w.u32(u32::MAX);
        let bytes = w.finish();
        let err = CdrReader::new(&bytes).unwrap().f64_sequence("d").unwrap_err();
        assert!(err.to_string().starts_with("truncated: d needs"), "{err}");
    }

    #[test]
    fn bad_headers_and_strings_are_errors() {
        let err = CdrReader::new(&[0, 7, 0, 0]).unwrap_err();
        assert_eq!(err, CdrError::Encapsulation { kind: [0, 7] });
        // Length 2 without a closing NUL.
        let bytes = [0, 1, 0, 0, 2, 0, 0, 0, b'a', b'b'];
        let err = CdrReader::new(&bytes).unwrap().string("frame_id").unwrap_err();
        assert_eq!(err, CdrError::BadString { field: "frame_id" });
    }
}
