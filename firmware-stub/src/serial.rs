//! The serial link: the [`TelemetrySink`] of the board, writing [`wire`]
//! frames (postcard body, CRC-32, COBS, `0x00` delimiter) to any [`embedded_io::Write`] (a UART).

use core::fmt;

use ferroslam_core::frame::TelemetrySink;
use ferroslam_core::wire::{self, EncodeError, MAX_FRAME_ON_WIRE, Message};

/// Why a message was not sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum SerialError<E> {
    /// The message could not be encoded (nothing was written).
    Encode(EncodeError),
    /// The writer failed; part of the frame may be on the line (the receiver drops it).
    Write(E),
}

impl<E: fmt::Debug> fmt::Display for SerialError<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Encode(e) => write!(f, "encoding a message: {e}"),
            Self::Write(e) => write!(f, "writing to the serial port: {e:?}"),
        }
    }
}

impl<E: fmt::Debug> core::error::Error for SerialError<E> {}

/// Frames messages onto a byte writer. The frame is built on the stack
/// ([`MAX_FRAME_ON_WIRE`] bytes) and written with one `write_all`.
#[derive(Debug)]
pub struct SerialLink<W> {
    writer: W,
    frames_sent: u32,
    bytes_sent: u32,
}

impl<W> SerialLink<W> {
    /// A link writing to `writer`.
    pub const fn new(writer: W) -> Self {
        Self { writer, frames_sent: 0, bytes_sent: 0 }
    }

    /// Frames written whole.
    pub fn frames_sent(&self) -> u32 {
        self.frames_sent
    }

    /// Bytes of the frames written whole, delimiters included.
    pub fn bytes_sent(&self) -> u32 {
        self.bytes_sent
    }

    /// The writer, to reclaim it.
    pub fn into_inner(self) -> W {
        self.writer
    }
}

impl<W: embedded_io::Write> TelemetrySink for SerialLink<W> {
    type Error = SerialError<W::Error>;

    fn send(&mut self, message: &Message) -> Result<(), Self::Error> {
        let mut frame = [0u8; MAX_FRAME_ON_WIRE];
        let n = wire::encode(message, &mut frame).map_err(SerialError::Encode)?;
        let bytes = frame.get(..n).unwrap_or_default();
        self.writer.write_all(bytes).map_err(SerialError::Write)?;
        self.frames_sent = self.frames_sent.saturating_add(1);
        self.bytes_sent = self.bytes_sent.saturating_add(n as u32);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferroslam_core::wire::{FaultCode, FaultMessage, StatusMessage, StreamDecoder};
    use std::vec::Vec;

    /// A byte sink that fails after `capacity` bytes, like a UART whose driver gave up.
    struct Capture {
        bytes: Vec<u8>,
        capacity: usize,
    }

    impl embedded_io::ErrorType for Capture {
        type Error = embedded_io::ErrorKind;
    }

    impl embedded_io::Write for Capture {
        fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
            let room = self.capacity - self.bytes.len();
            if room == 0 {
                return Err(embedded_io::ErrorKind::Other);
            }
            let n = buf.len().min(room);
            self.bytes.extend_from_slice(&buf[..n]);
            Ok(n)
        }

        fn flush(&mut self) -> Result<(), Self::Error> {
            Ok(())
        }
    }

    fn messages() -> [Message; 2] {
        [
            Message::Status(StatusMessage { frames: 3, ..StatusMessage::default() }),
            Message::Fault(FaultMessage {
                frame_index: 2,
                code: FaultCode::FrameSource,
                detail: 7,
            }),
        ]
    }

    #[test]
    fn frames_written_decode_back() {
        let mut link = SerialLink::new(Capture { bytes: Vec::new(), capacity: 1 << 16 });
        for m in messages() {
            link.send(&m).unwrap();
        }
        assert_eq!(link.frames_sent(), 2);
        let bytes = link.into_inner().bytes;
        let mut d: StreamDecoder = StreamDecoder::new();
        let got: Vec<Message> =
            bytes.iter().filter_map(|&b| d.push(b)).map(Result::unwrap).collect();
        assert_eq!(got, messages());
    }

    #[test]
    fn a_failing_writer_is_an_error_and_the_receiver_drops_the_partial_frame() {
        let mut first = [0u8; MAX_FRAME_ON_WIRE];
        let n = wire::encode(&messages()[0], &mut first).unwrap();
        // Room for the first frame and half of the second.
        let mut link = SerialLink::new(Capture { bytes: Vec::new(), capacity: n + 4 });
        link.send(&messages()[0]).unwrap();
        let err = link.send(&messages()[1]).unwrap_err();
        assert_eq!(err, SerialError::Write(embedded_io::ErrorKind::Other));
        assert_eq!((link.frames_sent(), link.bytes_sent()), (1, n as u32));
        let bytes = link.into_inner().bytes;
        let mut d: StreamDecoder = StreamDecoder::new();
        let got: Vec<_> = bytes.iter().filter_map(|&b| d.push(b)).collect();
        assert_eq!(got, [Ok(messages()[0])]);
        assert!(d.finish().is_some(), "the partial frame is counted as dropped");
        assert_eq!(d.stats().bytes_skipped, 4);
    }
}
