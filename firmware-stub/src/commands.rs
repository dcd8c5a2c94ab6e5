//! The serial link's receive side: anchor commands from the host ([`CommandMessage`], the same
//! framing and CRC as the telemetry the board sends), read from any `embedded_io` reader that
//! says what has arrived ([`embedded_io::ReadReady`]): the UART's received bytes in a ring
//! ([`crate::rx_ring::RxRing`], the reference board's), or all of them at once ([`Arrived`]: on
//! the QEMU board a host file of what the host sent).
//!
//! The frame loop never waits for the link: each frame reads the bytes that have arrived and no
//! more, and a command frame cut by the end of what arrived is finished by a later frame's bytes
//! (the decoder's state, about 140 bytes, is kept between frames).
//!
//! A command names the frame it applies in; the board applies it after that frame's front end
//! ([`crate::pipeline::run_frame`]), so a replay applies every command in the same frame on the
//! board and on the host whatever the bytes' timing. Commands arrive in the order they apply:
//! the reader holds one that is not due yet until its frame comes.

use embedded_io::{ErrorType, Read, ReadReady};
use ferroslam_core::wire::{CommandMessage, FrameError, MAX_ENCODED_FRAME, Message, StreamDecoder};

/// Why a command frame gave no command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum CommandError {
    /// The frame was dropped: corrupted, cut short or of another schema version.
    Frame(FrameError),
    /// The frame held a message that is not a command (the host sends only commands).
    NotACommand,
}

impl CommandError {
    /// A number naming the variant, for a fault message's detail (0: the frame did not decode,
    /// as the wire's fault code documents; 9: not a command, past the anchor errors' codes).
    pub fn code(&self) -> u32 {
        match self {
            Self::Frame(_) => 0,
            Self::NotACommand => 9,
        }
    }
}

/// Where a board's anchor commands come from.
pub trait CommandSource {
    /// The next command due in frame `frame_index` (one whose frame is `frame_index` or earlier),
    /// in the order received; `None` when no more is due in this frame.
    ///
    /// # Errors
    /// A frame of the link that gave no command ([`CommandError`]); the next call goes on with
    /// the following frame.
    fn next_due(&mut self, frame_index: u32) -> Option<Result<CommandMessage, CommandError>>;
}

/// No commands: a board without a receive side, or a run without commands.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoCommands;

impl CommandSource for NoCommands {
    fn next_due(&mut self, _: u32) -> Option<Result<CommandMessage, CommandError>> {
        None
    }
}

/// A receive side that may be absent (`None`: no commands).
impl<C: CommandSource> CommandSource for Option<C> {
    fn next_due(&mut self, frame_index: u32) -> Option<Result<CommandMessage, CommandError>> {
        self.as_mut()?.next_due(frame_index)
    }
}

/// Commands decoded from the bytes of `reader` as they arrive, one frame at a time, as they come
/// due. State: the reader, the decoder's partial frame, and one command not due yet.
#[derive(Debug)]
pub struct LinkCommands<R> {
    reader: R,
    decoder: StreamDecoder<MAX_ENCODED_FRAME>,
    pending: Option<CommandMessage>,
    /// The reader ended or failed: nothing more comes.
    ended: bool,
}

impl<R: Read + ReadReady> LinkCommands<R> {
    /// Commands from `reader`.
    pub const fn new(reader: R) -> Self {
        Self { reader, decoder: StreamDecoder::new(), pending: None, ended: false }
    }

    /// The next frame's message from the bytes arrived so far; `None` when they hold no whole
    /// frame more (the partial one is kept for the next call), or at the reader's end (or a
    /// read error: a link that fails gives nothing more). Cost: one read call per byte.
    fn read_frame(&mut self) -> Option<Result<Message, FrameError>> {
        let mut byte = [0u8; 1];
        while !self.ended {
            match self.reader.read_ready() {
                Ok(true) => {}
                // The rest has not arrived: a later frame reads it.
                Ok(false) => return None,
                Err(_) => {
                    self.ended = true;
                    break;
                }
            }
            match self.reader.read(&mut byte) {
                Ok(1) => {
                    if let Some(m) = self.decoder.push(byte[0]) {
                        return Some(m);
                    }
                }
                _ => self.ended = true,
            }
        }
        // At the end, bytes after the last delimiter are a frame cut short (named once).
        let len = self.decoder.pending_bytes();
        self.decoder = StreamDecoder::new();
        (len > 0).then_some(Err(FrameError::TooShort { len }))
    }
}

/// A reader whose bytes have all arrived (a file, a slice): always ready, its end the link's.
#[derive(Debug, Clone, Copy)]
pub struct Arrived<R>(pub R);

impl<R: ErrorType> ErrorType for Arrived<R> {
    type Error = R::Error;
}

impl<R: Read> Read for Arrived<R> {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        self.0.read(buf)
    }
}

impl<R: Read> ReadReady for Arrived<R> {
    fn read_ready(&mut self) -> Result<bool, Self::Error> {
        Ok(true)
    }
}

impl<R: Read + ReadReady> CommandSource for LinkCommands<R> {
    fn next_due(&mut self, frame_index: u32) -> Option<Result<CommandMessage, CommandError>> {
        if self.pending.is_none() {
            self.pending = match self.read_frame()? {
                Ok(Message::Command(c)) => Some(c),
                Ok(_) => return Some(Err(CommandError::NotACommand)),
                Err(e) => return Some(Err(CommandError::Frame(e))),
            };
        }
        let due = self.pending.filter(|c| c.frame_index <= frame_index)?;
        self.pending = None;
        Some(Ok(due))
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use ferroslam_core::ar::AnchorCommand;
    use ferroslam_core::wire::{MAX_FRAME_ON_WIRE, encode};
    use std::vec::Vec;

    /// `messages` as the bytes on the wire, one frame each (for this crate's tests).
    pub(crate) fn wire(messages: &[Message]) -> Vec<u8> {
        let mut bytes = Vec::new();
        for m in messages {
            let mut buf = [0u8; MAX_FRAME_ON_WIRE];
            let n = encode(m, &mut buf).unwrap();
            bytes.extend_from_slice(&buf[..n]);
        }
        bytes
    }

    fn command(frame_index: u32, object: u16) -> Message {
        Message::Command(CommandMessage {
            frame_index,
            command: AnchorCommand::Place { object, pixel: [10.0, 20.0], scale: 1.5 },
        })
    }

    #[test]
    fn commands_come_in_their_frames_and_bad_frames_are_named() {
        let mut bytes = wire(&[command(2, 0), command(2, 1), command(5, 2)]);
        // A frame with a byte changed (never to the delimiter), a message that is no command, one
        // more command, then a frame cut short.
        let mut bad = wire(&[command(6, 3)]);
        bad[3] = bad[3].wrapping_add(1).max(1);
        bytes.extend_from_slice(&bad);
        let status = Message::Status(Default::default());
        bytes.extend_from_slice(&wire(&[status, command(9, 4)]));
        bytes.extend_from_slice(&wire(&[command(9, 5)])[..6]);
        let mut link = LinkCommands::new(Arrived(&bytes[..]));
        let objects = |link: &mut LinkCommands<Arrived<&[u8]>>, frame| {
            let mut got = Vec::new();
            while let Some(c) = link.next_due(frame) {
                got.push(c.map(|c| c.command.object()));
            }
            got
        };
        assert_eq!(objects(&mut link, 0), []);
        assert_eq!(objects(&mut link, 1), []);
        assert_eq!(objects(&mut link, 2), [Ok(0), Ok(1)]);
        // Frames the board skipped: the command due in one applies in the next it processes.
        let got = objects(&mut link, 7);
        assert_eq!(got.len(), 3, "{got:?}");
        assert_eq!(got[0], Ok(2));
        assert!(matches!(got[1], Err(CommandError::Frame(FrameError::Crc { .. }))), "{got:?}");
        assert_eq!(got[2], Err(CommandError::NotACommand));
        let got = objects(&mut link, 9);
        assert_eq!(got[0], Ok(4));
        assert_eq!(got[1], Err(CommandError::Frame(FrameError::TooShort { len: 6 })));
        assert_eq!(objects(&mut link, 100), []);
    }
}
