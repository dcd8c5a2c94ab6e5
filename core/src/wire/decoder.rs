//! [`StreamDecoder`]: frames out of a byte stream that may be corrupted, truncated or joined
//! mid-frame, with exact counts of what was lost.

use heapless::Vec;

use super::MAX_ENCODED_FRAME;
use super::codec::{FrameError, decode_frame};
use super::message::Message;

/// What a [`StreamDecoder`] has seen. Every byte pushed is either in a delivered frame
/// (`bytes_delivered`), skipped (`bytes_skipped`), or still pending in the decoder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DecoderStats {
    /// Bytes pushed.
    pub bytes_received: u64,
    /// Bytes of delivered frames, delimiters included.
    pub bytes_delivered: u64,
    /// Bytes of dropped and unknown-version frames (delimiters included), and delimiters that
    /// ended an empty frame.
    pub bytes_skipped: u64,
    /// Frames decoded into a [`Message`].
    pub frames_decoded: u64,
    /// Non-empty frames dropped as corrupt (COBS, CRC, body, too long, truncated).
    pub frames_dropped: u64,
    /// Frames with a valid CRC but another schema version, skipped.
    pub frames_unknown_version: u64,
}

/// Splits a byte stream at the `0x00` delimiters and decodes each frame (see the
/// [module documentation](super)).
///
/// Resynchronization is at the next delimiter: a corrupted frame costs only itself, a frame whose
/// delimiter was lost is joined to the next one and both are dropped (the CRC catches it). `N` is
/// the longest frame kept (bytes between delimiters); a longer run is dropped as
/// [`FrameError::TooLong`] when its delimiter arrives.
#[derive(Debug, Clone)]
pub struct StreamDecoder<const N: usize = MAX_ENCODED_FRAME> {
    frame: Vec<u8, N>,
    /// Bytes of the current frame beyond `N` (the frame is dropped at its delimiter).
    overflow: usize,
    stats: DecoderStats,
}

impl<const N: usize> Default for StreamDecoder<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> StreamDecoder<N> {
    /// A decoder at the start of a stream.
    pub const fn new() -> Self {
        Self {
            frame: Vec::new(),
            overflow: 0,
            stats: DecoderStats {
                bytes_received: 0,
                bytes_delivered: 0,
                bytes_skipped: 0,
                frames_decoded: 0,
                frames_dropped: 0,
                frames_unknown_version: 0,
            },
        }
    }

    /// The counts so far.
    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Bytes received since the last delimiter.
    pub fn pending_bytes(&self) -> usize {
        self.frame.len() + self.overflow
    }

    /// Takes one byte. At a delimiter that ends a non-empty frame it returns the frame's message,
    /// or why the frame was dropped; otherwise `None`.
    pub fn push(&mut self, byte: u8) -> Option<Result<Message, FrameError>> {
        self.stats.bytes_received += 1;
        if byte != 0 {
            if self.frame.push(byte).is_err() {
                self.overflow += 1;
            }
            return None;
        }
        let frame_bytes = (self.pending_bytes() + 1) as u64;
        if self.pending_bytes() == 0 {
            // An empty frame: a lone delimiter.
            self.stats.bytes_skipped += 1;
            return None;
        }
        let result = if self.overflow > 0 {
            Err(FrameError::TooLong)
        } else {
            decode_frame(&mut self.frame)
        };
        self.frame.clear();
        self.overflow = 0;
        match result {
            Ok(_) => {
                self.stats.frames_decoded += 1;
                self.stats.bytes_delivered += frame_bytes;
            }
            Err(FrameError::UnknownVersion { .. }) => {
                self.stats.frames_unknown_version += 1;
                self.stats.bytes_skipped += frame_bytes;
            }
            Err(_) => {
                self.stats.frames_dropped += 1;
                self.stats.bytes_skipped += frame_bytes;
            }
        }
        Some(result)
    }

    /// Ends the stream: bytes after the last delimiter are an unfinished frame, dropped and
    /// counted (`Some(FrameError::Truncated)`); `None` when there were none.
    pub fn finish(&mut self) -> Option<FrameError> {
        let len = self.pending_bytes();
        self.frame.clear();
        self.overflow = 0;
        if len == 0 {
            return None;
        }
        self.stats.frames_dropped += 1;
        self.stats.bytes_skipped += len as u64;
        Some(FrameError::Truncated { len })
    }
}
