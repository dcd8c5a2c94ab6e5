//! One frame: [`encode`] a [`Message`] into its bytes on the wire, [`decode_frame`] one frame's
//! bytes (without the delimiter) back.

use core::fmt;

use super::message::Message;
use super::{CRC_BYTES, MAX_ENCODED_FRAME, MAX_PAYLOAD, SCHEMA_VERSION};

/// The frame check: CRC-32/ISO-HDLC (the CRC of zlib, Ethernet and PNG), written little-endian.
const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// The CRC-32 of `bytes` as the frame check computes it.
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

/// Why a message could not be encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum EncodeError {
    /// The output buffer is shorter than the encoded frame (give it [`MAX_ENCODED_FRAME`] bytes).
    BufferTooSmall {
        /// Bytes the output buffer has.
        got: usize,
    },
    /// postcard could not serialize the message (it is longer than [`MAX_PAYLOAD`]).
    Serialize,
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::BufferTooSmall { got } => {
                write!(f, "output buffer of {got} bytes is too small for a frame")
            }
            Self::Serialize => write!(f, "message does not serialize into {MAX_PAYLOAD} bytes"),
        }
    }
}

impl core::error::Error for EncodeError {}

/// Why one received frame was dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FrameError {
    /// More than [`MAX_ENCODED_FRAME`] bytes came without a delimiter.
    TooLong,
    /// The bytes are not valid COBS.
    Cobs,
    /// The payload is shorter than a version byte and a CRC.
    TooShort {
        /// Payload bytes.
        len: usize,
    },
    /// The CRC does not match the payload.
    Crc {
        /// CRC carried by the frame.
        received: u32,
        /// CRC computed over the payload.
        computed: u32,
    },
    /// The CRC matches but the schema version is not [`SCHEMA_VERSION`]: a message of another
    /// firmware, skipped.
    UnknownVersion {
        /// The version byte.
        found: u8,
    },
    /// The CRC and version match but the body is not a message of this schema.
    Body,
    /// The input ended inside a frame.
    Truncated {
        /// Bytes of the unfinished frame.
        len: usize,
    },
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooLong => write!(f, "frame longer than {MAX_ENCODED_FRAME} bytes"),
            Self::Cobs => write!(f, "invalid COBS encoding"),
            Self::TooShort { len } => write!(f, "payload of {len} bytes is too short"),
            Self::Crc { received, computed } => {
                write!(
                    f,
                    "CRC mismatch: frame says {received:#010x}, payload gives {computed:#010x}"
                )
            }
            Self::UnknownVersion { found } => {
                write!(f, "schema version {found}, this decoder reads {SCHEMA_VERSION}")
            }
            Self::Body => write!(f, "payload is not a message of this schema"),
            Self::Truncated { len } => write!(f, "input ended inside a frame ({len} bytes)"),
        }
    }
}

impl core::error::Error for FrameError {}

/// Encodes `message` as one frame into `out`: COBS of (version byte, postcard body, CRC-32 LE),
/// then the `0x00` delimiter. Returns the number of bytes written (at most
/// [`MAX_ENCODED_FRAME`]).
///
/// # Errors
/// [`EncodeError::Serialize`] when the body does not fit [`MAX_PAYLOAD`] (no message of this
/// schema is that long), [`EncodeError::BufferTooSmall`] when `out` is too short.
pub fn encode(message: &Message, out: &mut [u8]) -> Result<usize, EncodeError> {
    let mut payload = [0u8; MAX_PAYLOAD];
    let (version, rest) = payload.split_first_mut().ok_or(EncodeError::Serialize)?;
    *version = SCHEMA_VERSION;
    let body_len = postcard::to_slice(message, rest).map_err(|_| EncodeError::Serialize)?.len();
    let crc_at = 1 + body_len;
    let crc = crc32(payload.get(..crc_at).ok_or(EncodeError::Serialize)?);
    let crc_dst = payload.get_mut(crc_at..crc_at + CRC_BYTES).ok_or(EncodeError::Serialize)?;
    crc_dst.copy_from_slice(&crc.to_le_bytes());
    let payload = payload.get(..crc_at + CRC_BYTES).ok_or(EncodeError::Serialize)?;
    let too_small = EncodeError::BufferTooSmall { got: out.len() };
    let n = cobs::try_encode(payload, out).map_err(|_| too_small)?;
    *out.get_mut(n).ok_or(too_small)? = 0;
    Ok(n + 1)
}

/// Decodes one frame: `encoded` holds the COBS bytes between two delimiters (no `0x00`); it is
/// decoded in place.
///
/// # Errors
/// Every [`FrameError`] but `TooLong` and `Truncated` (which only a stream can tell).
pub fn decode_frame(encoded: &mut [u8]) -> Result<Message, FrameError> {
    let len = cobs::decode_in_place(encoded).map_err(|_| FrameError::Cobs)?;
    let payload = encoded.get(..len).ok_or(FrameError::Cobs)?;
    let Some(body_end) = len.checked_sub(CRC_BYTES).filter(|&n| n >= 1) else {
        return Err(FrameError::TooShort { len });
    };
    let (checked, crc_bytes) = payload.split_at(body_end);
    let received = u32::from_le_bytes(crc_bytes.try_into().map_err(|_| FrameError::Cobs)?);
    let computed = crc32(checked);
    if received != computed {
        return Err(FrameError::Crc { received, computed });
    }
    let (&version, body) = checked.split_first().ok_or(FrameError::TooShort { len })?;
    if version != SCHEMA_VERSION {
        return Err(FrameError::UnknownVersion { found: version });
    }
    match postcard::take_from_bytes::<Message>(body) {
        Ok((message, [])) => Ok(message),
        _ => Err(FrameError::Body),
    }
}
