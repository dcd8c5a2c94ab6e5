//! The serial wire format: a versioned message schema shared by the firmware and the host, in both
//! directions (telemetry from the device; anchor commands to it, [`CommandMessage`]), with
//! framing that survives a noisy or truncated link.
//!
//! # Frame
//!
//! ```text
//! on the wire:  COBS(payload) 0x00
//! payload:      version (1 byte) | postcard body (a Message) | CRC-32 (4 bytes, little-endian)
//! ```
//!
//! - **Version**: [`SCHEMA_VERSION`], a raw byte before the body, so a decoder can recognize (and
//!   skip) a message of another schema without understanding it.
//! - **Body**: the [`Message`] serialized by postcard (varint integers, enum discriminants as
//!   varints, floats as their little-endian IEEE-754 bits: bit-exact).
//! - **CRC**: CRC-32/ISO-HDLC (zlib's) over version and body.
//! - **COBS** removes every `0x00` from the payload, so `0x00` only ever ends a frame: after any
//!   corruption the decoder is back in step at the next delimiter.
//!
//! A payload is at most [`MAX_PAYLOAD`] bytes; a frame on the wire at most [`MAX_ENCODED_FRAME`]
//! plus the delimiter.
//!
//! # Decoding a stream
//!
//! [`StreamDecoder`] takes bytes one at a time and returns, at each delimiter that ends a
//! non-empty frame, the message or why the frame was dropped ([`FrameError`]). It counts frames
//! decoded, dropped and of an unknown version, and bytes delivered and skipped
//! ([`DecoderStats`]): what a corrupted byte, a lost delimiter or garbage between frames cost is
//! exact. Nothing in it allocates or panics.
//!
//! # Compatibility
//!
//! Changing any message (a field, its type or order, a variant) changes the postcard body, so it
//! needs a new [`SCHEMA_VERSION`]; old captures then decode as unknown-version frames (counted and
//! skipped), never as wrong values.

mod codec;
mod decoder;
mod message;

#[cfg(test)]
mod tests;

pub use codec::{EncodeError, FrameError, crc32, decode_frame, encode};
pub use decoder::{DecoderStats, StreamDecoder};
pub use message::{
    AnchorMessage, CommandMessage, CostMessage, FaultCode, FaultMessage, Message, PoseFlags,
    PoseMessage, StatusMessage, TickUnit, TrackingState,
};

/// The schema version this crate writes and reads (the first payload byte).
///
/// - 1: the first schema.
/// - 2: [`CostMessage`] times the front end and the back-end step apart (`frontend_ticks`,
///   `backend_ticks`, replacing version 1's `process_ticks`).
/// - 3: [`StatusMessage`] counts re-initialisations and relocalizations; [`PoseFlags::RELOCALIZED`]
///   marks a relocalized frame.
/// - 4: [`PoseFlags::LOOP_CLOSED`] marks a frame on which a loop closed.
/// - 5: the link is two-way: [`CommandMessage`] (host to device, an anchor command) and
///   [`AnchorMessage`] (a placed object after each pose); [`FaultCode::Command`].
pub const SCHEMA_VERSION: u8 = 5;

/// Bytes of the CRC at the end of a payload.
pub const CRC_BYTES: usize = 4;

/// The longest payload (version, body, CRC), bytes. The longest message of version 3, a
/// [`PoseMessage`], is under 60.
pub const MAX_PAYLOAD: usize = 128;

/// The longest COBS-encoded frame, without its delimiter, bytes.
pub const MAX_ENCODED_FRAME: usize = cobs::max_encoding_length(MAX_PAYLOAD);

/// Bytes a buffer for [`encode`] needs: the longest frame and its delimiter.
pub const MAX_FRAME_ON_WIRE: usize = MAX_ENCODED_FRAME + 1;
