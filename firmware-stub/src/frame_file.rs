//! The raw frame file: one recorded RGB-D frame as the firmware reads it through semihosting.
//!
//! Layout (all integers little-endian; 32-byte header, then the pixels, no padding):
//!
//! | offset | size | field |
//! | ---: | ---: | --- |
//! | 0 | 4 | magic `b"FSRF"` (ferroslam raw frame) |
//! | 4 | 2 | format version, [`VERSION`] |
//! | 6 | 2 | header length in bytes, [`HEADER_LEN`] (32) |
//! | 8 | 4 | width in pixels (u32) |
//! | 12 | 4 | height in pixels (u32) |
//! | 16 | 4 | depth scale, raw depth units per metre, f32 bits (u32) |
//! | 20 | 4 | reserved, 0 |
//! | 24 | 8 | timestamp in seconds, f64 bits (u64) |
//! | 32 | w*h | gray, u8 per pixel, row-major, no stride padding |
//! | 32 + w*h | 2*w*h | depth, u16 per pixel (0 = no reading), row-major |
//!
//! The file is exactly `32 + 3 * w * h` bytes. Floats travel as bits so that the host and the
//! firmware see the very same values.

use core::fmt;

/// The four bytes every frame file starts with.
pub const MAGIC: [u8; 4] = *b"FSRF";

/// The format version this crate reads and writes.
pub const VERSION: u16 = 1;

/// Bytes in the header; the pixels start at this offset.
pub const HEADER_LEN: usize = 32;

/// Why a frame file (or part of one) could not be read or written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum FrameFileError {
    /// The file does not start with [`MAGIC`].
    BadMagic {
        /// The first four bytes found.
        found: [u8; 4],
    },
    /// The version is not [`VERSION`].
    UnsupportedVersion {
        /// The version found.
        found: u16,
    },
    /// The header length field is not [`HEADER_LEN`].
    BadHeaderLen {
        /// The header length found.
        found: u16,
    },
    /// Width or height is zero, or `3 * width * height` overflows.
    BadSize {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// The depth scale is not a finite positive number.
    InvalidDepthScale,
    /// The timestamp is not finite.
    InvalidTimestamp,
    /// A byte count does not match what the header implies.
    LengthMismatch {
        /// Bytes expected.
        expected: usize,
        /// Bytes given.
        got: usize,
    },
}

impl fmt::Display for FrameFileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::BadMagic { found } => write!(f, "not a frame file (magic {found:02x?})"),
            Self::UnsupportedVersion { found } => {
                write!(f, "frame file version {found}, only {VERSION} is supported")
            }
            Self::BadHeaderLen { found } => {
                write!(f, "frame header length {found}, expected {HEADER_LEN}")
            }
            Self::BadSize { width, height } => write!(f, "bad frame size {width}x{height}"),
            Self::InvalidDepthScale => write!(f, "depth scale must be finite and positive"),
            Self::InvalidTimestamp => write!(f, "timestamp must be finite"),
            Self::LengthMismatch { expected, got } => {
                write!(f, "{got} bytes where the frame header implies {expected}")
            }
        }
    }
}

impl core::error::Error for FrameFileError {}

/// The header of a frame file: size, depth scale and capture time of the frame.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct FrameHeader {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Raw depth units per metre (1000 for millimetres, 5000 for TUM).
    pub depth_scale: f32,
    /// Capture time in seconds on the recording's clock.
    pub timestamp_s: f64,
}

/// Reads a little-endian array of `N` bytes at `at`, or `None` past the end.
fn array_at<const N: usize>(bytes: &[u8], at: usize) -> Option<[u8; N]> {
    bytes.get(at..at.checked_add(N)?)?.try_into().ok()
}

impl FrameHeader {
    /// Checks the fields: non-zero size whose file length fits `usize`, finite positive depth
    /// scale, finite timestamp.
    ///
    /// # Errors
    /// [`FrameFileError::BadSize`], [`FrameFileError::InvalidDepthScale`] or
    /// [`FrameFileError::InvalidTimestamp`].
    pub fn validate(&self) -> Result<(), FrameFileError> {
        self.file_len()?;
        if !(self.depth_scale.is_finite() && self.depth_scale > 0.0) {
            return Err(FrameFileError::InvalidDepthScale);
        }
        if !self.timestamp_s.is_finite() {
            return Err(FrameFileError::InvalidTimestamp);
        }
        Ok(())
    }

    /// Pixels in the frame, `width * height`.
    ///
    /// # Errors
    /// [`FrameFileError::BadSize`] for a zero size or one whose file length overflows `usize`.
    pub fn pixels(&self) -> Result<usize, FrameFileError> {
        let bad = FrameFileError::BadSize { width: self.width, height: self.height };
        let w = usize::try_from(self.width).map_err(|_| bad)?;
        let h = usize::try_from(self.height).map_err(|_| bad)?;
        let n = w.checked_mul(h).filter(|&n| n > 0).ok_or(bad)?;
        // The whole file length must be representable too.
        n.checked_mul(3).and_then(|b| b.checked_add(HEADER_LEN)).ok_or(bad)?;
        Ok(n)
    }

    /// Bytes in the whole file, `32 + 3 * width * height`.
    ///
    /// # Errors
    /// As [`FrameHeader::pixels`].
    pub fn file_len(&self) -> Result<usize, FrameFileError> {
        // `pixels` has checked that this cannot overflow.
        Ok(HEADER_LEN + 3 * self.pixels()?)
    }

    /// The 32 header bytes for this header (fields are not validated; see [`write_frame`]).
    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let mut h = [0u8; HEADER_LEN];
        let fields: [(usize, &[u8]); 6] = [
            (0, &MAGIC),
            (4, &VERSION.to_le_bytes()),
            (6, &(HEADER_LEN as u16).to_le_bytes()),
            (8, &self.width.to_le_bytes()),
            (12, &self.height.to_le_bytes()),
            (16, &self.depth_scale.to_bits().to_le_bytes()),
        ];
        for (at, bytes) in fields {
            if let Some(dst) = h.get_mut(at..at + bytes.len()) {
                dst.copy_from_slice(bytes);
            }
        }
        if let Some(dst) = h.get_mut(24..32) {
            dst.copy_from_slice(&self.timestamp_s.to_bits().to_le_bytes());
        }
        h
    }

    /// Parses and validates the header at the start of `bytes` (at least [`HEADER_LEN`] bytes).
    ///
    /// # Errors
    /// [`FrameFileError::LengthMismatch`] for fewer than 32 bytes, [`FrameFileError::BadMagic`],
    /// [`FrameFileError::UnsupportedVersion`], [`FrameFileError::BadHeaderLen`], or the errors of
    /// [`FrameHeader::validate`].
    pub fn decode(bytes: &[u8]) -> Result<Self, FrameFileError> {
        let short = FrameFileError::LengthMismatch { expected: HEADER_LEN, got: bytes.len() };
        let h: [u8; HEADER_LEN] = array_at(bytes, 0).ok_or(short)?;
        let u16_at = |at| array_at(&h, at).map(u16::from_le_bytes).ok_or(short);
        let u32_at = |at| array_at(&h, at).map(u32::from_le_bytes).ok_or(short);
        let found: [u8; 4] = array_at(&h, 0).ok_or(short)?;
        if found != MAGIC {
            return Err(FrameFileError::BadMagic { found });
        }
        let version = u16_at(4)?;
        if version != VERSION {
            return Err(FrameFileError::UnsupportedVersion { found: version });
        }
        let header_len = u16_at(6)?;
        if usize::from(header_len) != HEADER_LEN {
            return Err(FrameFileError::BadHeaderLen { found: header_len });
        }
        let header = Self {
            width: u32_at(8)?,
            height: u32_at(12)?,
            depth_scale: f32::from_bits(u32_at(16)?),
            timestamp_s: f64::from_bits(array_at(&h, 24).map(u64::from_le_bytes).ok_or(short)?),
        };
        header.validate()?;
        Ok(header)
    }
}

/// A whole frame file held in memory, checked and split into its parts.
#[derive(Debug, Clone, Copy)]
pub struct FrameFile<'a> {
    /// The header.
    pub header: FrameHeader,
    /// Gray pixels, `width * height` bytes, row-major.
    pub gray: &'a [u8],
    /// Depth pixels as little-endian bytes, `2 * width * height`; see [`decode_depth_le`].
    pub depth_le: &'a [u8],
}

impl<'a> FrameFile<'a> {
    /// Parses a complete frame file.
    ///
    /// # Errors
    /// The errors of [`FrameHeader::decode`], and [`FrameFileError::LengthMismatch`] when `bytes`
    /// is not exactly as long as the header implies.
    pub fn parse(bytes: &'a [u8]) -> Result<Self, FrameFileError> {
        let header = FrameHeader::decode(bytes)?;
        let n = header.pixels()?;
        let expected = header.file_len()?;
        if bytes.len() != expected {
            return Err(FrameFileError::LengthMismatch { expected, got: bytes.len() });
        }
        let pixels = bytes.get(HEADER_LEN..).unwrap_or_default();
        let (gray, depth_le) = pixels.split_at_checked(n).unwrap_or_default();
        Ok(Self { header, gray, depth_le })
    }
}

/// Decodes little-endian depth bytes into samples: `src` must be exactly `2 * dst.len()` bytes.
/// Callers may decode a frame's depth in chunks of any even length.
///
/// # Errors
/// [`FrameFileError::LengthMismatch`] when the lengths disagree.
pub fn decode_depth_le(src: &[u8], dst: &mut [u16]) -> Result<(), FrameFileError> {
    let (pairs, rest) = src.as_chunks::<2>();
    if pairs.len() != dst.len() || !rest.is_empty() {
        return Err(FrameFileError::LengthMismatch { expected: 2 * dst.len(), got: src.len() });
    }
    for (d, &p) in dst.iter_mut().zip(pairs) {
        *d = u16::from_le_bytes(p);
    }
    Ok(())
}

/// Writes a whole frame file through `sink` (called with consecutive pieces of the file; a host
/// passes `|b| file.write_all(b)` or `|b| { vec.extend_from_slice(b); Ok(()) }`).
///
/// # Errors
/// `Err(Ok(e))` for a header that does not validate or pixel buffers that are not
/// `width * height` long (nothing written then), `Err(Err(e))` for the sink's error.
pub fn write_frame<E>(
    header: &FrameHeader,
    gray: &[u8],
    depth: &[u16],
    mut sink: impl FnMut(&[u8]) -> Result<(), E>,
) -> Result<(), Result<FrameFileError, E>> {
    header.validate().map_err(Ok)?;
    let n = header.pixels().map_err(Ok)?;
    for len in [gray.len(), depth.len()] {
        if len != n {
            return Err(Ok(FrameFileError::LengthMismatch { expected: n, got: len }));
        }
    }
    sink(&header.encode()).map_err(Err)?;
    sink(gray).map_err(Err)?;
    // Depth goes out in fixed chunks: no heap, a small stack buffer.
    let mut buf = [0u8; 512];
    for chunk in depth.chunks(buf.len() / 2) {
        for (dst, &d) in buf.as_chunks_mut::<2>().0.iter_mut().zip(chunk) {
            *dst = d.to_le_bytes();
        }
        sink(buf.get(..2 * chunk.len()).unwrap_or_default()).map_err(Err)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    fn header(w: u32, h: u32) -> FrameHeader {
        FrameHeader { width: w, height: h, depth_scale: 5000.0, timestamp_s: 1305031102.175304 }
    }

    fn encode(h: &FrameHeader, gray: &[u8], depth: &[u16]) -> Vec<u8> {
        let mut out = Vec::new();
        write_frame::<()>(h, gray, depth, |b| {
            out.extend_from_slice(b);
            Ok(())
        })
        .unwrap();
        out
    }

    #[test]
    fn round_trip() {
        let h = header(3, 2);
        let gray = [1, 2, 3, 4, 5, 6];
        let depth = [0, 1, 0x1234, 65535, 700, 8];
        let bytes = encode(&h, &gray, &depth);
        assert_eq!(bytes.len(), 32 + 18);
        assert_eq!(&bytes[..8], b"FSRF\x01\x00\x20\x00");
        assert_eq!(&bytes[32 + 6 + 4..32 + 6 + 6], &[0x34, 0x12]);
        let f = FrameFile::parse(&bytes).unwrap();
        assert_eq!(f.header, h);
        assert_eq!(f.header.timestamp_s.to_bits(), h.timestamp_s.to_bits());
        assert_eq!(f.gray, gray);
        let mut d = [0u16; 6];
        decode_depth_le(f.depth_le, &mut d).unwrap();
        assert_eq!(d, depth);
    }

    #[test]
    fn depth_longer_than_one_chunk_round_trips() {
        let h = header(300, 2);
        let gray: Vec<u8> = (0..600).map(|i| i as u8).collect();
        let depth: Vec<u16> = (0..600).map(|i| (i * 97) as u16).collect();
        let bytes = encode(&h, &gray, &depth);
        let f = FrameFile::parse(&bytes).unwrap();
        let mut d = std::vec![0u16; 600];
        // In two chunks, as the firmware reads it.
        decode_depth_le(&f.depth_le[..400], &mut d[..200]).unwrap();
        decode_depth_le(&f.depth_le[400..], &mut d[200..]).unwrap();
        assert_eq!(d, depth);
    }

    #[test]
    fn bad_files_are_errors() {
        let bytes = encode(&header(2, 2), &[0; 4], &[0; 4]);
        let mut bad = bytes.clone();
        bad[0] = b'X';
        assert_eq!(
            FrameFile::parse(&bad).unwrap_err(),
            FrameFileError::BadMagic { found: *b"XSRF" }
        );
        let mut bad = bytes.clone();
        bad[4] = 2;
        assert_eq!(
            FrameFile::parse(&bad).unwrap_err(),
            FrameFileError::UnsupportedVersion { found: 2 }
        );
        assert_eq!(
            FrameFile::parse(&bytes[..bytes.len() - 1]).unwrap_err(),
            FrameFileError::LengthMismatch { expected: 44, got: 43 }
        );
        assert_eq!(
            FrameFile::parse(&bytes[..10]).unwrap_err(),
            FrameFileError::LengthMismatch { expected: 32, got: 10 }
        );
        let mut bad = bytes.clone();
        bad[8..12].copy_from_slice(&0u32.to_le_bytes());
        assert_eq!(
            FrameFile::parse(&bad).unwrap_err(),
            FrameFileError::BadSize { width: 0, height: 2 }
        );
        let mut bad = bytes.clone();
        bad[16..20].copy_from_slice(&f32::NAN.to_bits().to_le_bytes());
        assert_eq!(FrameFile::parse(&bad).unwrap_err(), FrameFileError::InvalidDepthScale);
        let huge = FrameHeader { width: u32::MAX, height: u32::MAX, ..header(1, 1) };
        assert!(matches!(FrameHeader::decode(&huge.encode()), Err(FrameFileError::BadSize { .. })));
    }

    #[test]
    fn writer_checks_buffers() {
        let r = write_frame::<()>(&header(2, 2), &[0; 3], &[0; 4], |_| Ok(()));
        assert_eq!(r, Err(Ok(FrameFileError::LengthMismatch { expected: 4, got: 3 })));
        let r = write_frame::<()>(&header(2, 2), &[0; 4], &[0; 4], |_| Err(()));
        assert_eq!(r, Err(Err(())));
        assert!(decode_depth_le(&[0; 3], &mut [0; 1]).is_err());
    }
}
