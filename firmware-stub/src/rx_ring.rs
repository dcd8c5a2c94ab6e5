//! A UART's received bytes in a ring a producer fills behind the program's back (a DMA stream in
//! circular mode, or an interrupt handler), read without waiting ([`RxRing`]): the serial link's
//! receive side on a board whose frame loop must never block on the link.
//!
//! The producer's side is a [`RingProducer`]: the ring's bytes and how far it has written. The
//! reader keeps its own position; what lies between is what has arrived. The ring cannot tell a
//! lap from nothing: a producer that writes a whole ring more than the reader has read loses
//! those bytes silently here, and the frames they were in are then dropped by the wire's CRC
//! (counted as undecodable command frames). Size the ring for the bytes that can arrive between
//! two reads: one frame apart, 115,200 baud brings about 390 bytes in 33 ms.

use embedded_io::{ErrorType, Read, ReadReady};

/// A ring's producer: its bytes and its write position.
pub trait RingProducer {
    /// Bytes of the ring.
    fn len(&self) -> usize;

    /// Whether the ring has no bytes (then nothing ever arrives).
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Where the producer writes next, `0..len()` (a DMA stream: the length less its remaining
    /// transfer count).
    fn written_to(&self) -> usize;

    /// The byte at `at`, `0..len()`, as the producer left it.
    fn byte(&self, at: usize) -> u8;
}

/// What has arrived in a producer's ring, as an `embedded_io` reader that never ends
/// ([`ReadReady`] says whether a read would wait).
#[derive(Debug)]
pub struct RxRing<P> {
    producer: P,
    /// Where the next byte is read.
    read_at: usize,
}

impl<P: RingProducer> RxRing<P> {
    /// A reader of `producer`'s ring, from where it writes now (bytes before were not for it).
    pub fn new(producer: P) -> Self {
        let read_at = producer.written_to();
        Self { producer, read_at }
    }

    /// Bytes arrived and not read yet.
    pub fn arrived(&self) -> usize {
        let len = self.producer.len();
        if len == 0 {
            return 0;
        }
        (self.producer.written_to() % len + len - self.read_at) % len
    }
}

impl<P> ErrorType for RxRing<P> {
    type Error = core::convert::Infallible;
}

impl<P: RingProducer> Read for RxRing<P> {
    /// Copies up to `buf.len()` of the bytes arrived, waiting (spinning) for one when none has:
    /// call it when [`ReadReady::read_ready`] says so.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        let len = self.producer.len();
        if buf.is_empty() || len == 0 {
            return Ok(0);
        }
        let mut arrived = self.arrived();
        while arrived == 0 {
            core::hint::spin_loop();
            arrived = self.arrived();
        }
        let n = arrived.min(buf.len());
        for b in buf.iter_mut().take(n) {
            *b = self.producer.byte(self.read_at);
            self.read_at = (self.read_at + 1) % len;
        }
        Ok(n)
    }
}

impl<P: RingProducer> ReadReady for RxRing<P> {
    fn read_ready(&mut self) -> Result<bool, Self::Error> {
        Ok(self.arrived() > 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::commands::tests::wire;
    use crate::commands::{CommandSource, LinkCommands};
    use ferroslam_core::ar::AnchorCommand;
    use ferroslam_core::wire::{CommandMessage, Message};
    use std::cell::RefCell;
    use std::rc::Rc;
    use std::vec::Vec;

    /// A ring of `N` bytes a test writes into, as a DMA stream would.
    #[derive(Debug, Clone)]
    struct TestRing<const N: usize>(Rc<RefCell<([u8; N], usize)>>);

    impl<const N: usize> TestRing<N> {
        fn new() -> Self {
            Self(Rc::new(RefCell::new(([0; N], 0))))
        }

        /// The producer receives `bytes`.
        fn receive(&self, bytes: &[u8]) {
            let mut ring = self.0.borrow_mut();
            for &b in bytes {
                let at = ring.1;
                ring.0[at] = b;
                ring.1 = (at + 1) % N;
            }
        }
    }

    impl<const N: usize> RingProducer for TestRing<N> {
        fn len(&self) -> usize {
            N
        }

        fn written_to(&self) -> usize {
            self.0.borrow().1
        }

        fn byte(&self, at: usize) -> u8 {
            self.0.borrow().0[at]
        }
    }

    fn command(frame_index: u32, object: u16) -> Message {
        Message::Command(CommandMessage { frame_index, command: AnchorCommand::Remove { object } })
    }

    #[test]
    fn bytes_arrive_around_the_ring_and_are_read_once() {
        let ring = TestRing::<8>::new();
        ring.receive(&[1, 2, 3]);
        let mut rx = RxRing::new(ring.clone());
        assert_eq!(rx.read_ready(), Ok(false), "bytes before the reader are not for it");
        ring.receive(&[4, 5, 6, 7, 8, 9]);
        let mut buf = [0; 4];
        assert_eq!((rx.read(&mut buf), buf), (Ok(4), [4, 5, 6, 7]));
        assert_eq!(rx.arrived(), 2);
        ring.receive(&[10]);
        let mut buf = [0; 8];
        assert_eq!(rx.read(&mut buf), Ok(3));
        assert_eq!(&buf[..3], &[8, 9, 10]);
        assert_eq!(rx.read_ready(), Ok(false));
    }

    #[test]
    fn commands_split_across_frames_by_their_arrival_come_whole_and_in_their_frames() {
        let bytes = wire(&[command(3, 0), command(4, 1), command(9, 2)]);
        let ring = TestRing::<64>::new();
        let mut link = LinkCommands::new(RxRing::new(ring.clone()));
        let mut got = Vec::new();
        // The bytes arrive 7 a frame (a frame cut anywhere), the ring read once a frame.
        for (frame, chunk) in (0u32..).zip(bytes.chunks(7).chain([&[][..]; 12])) {
            ring.receive(chunk);
            while let Some(c) = link.next_due(frame) {
                got.push((frame, c.map(|c| c.command.object())));
            }
        }
        let first = |object| got.iter().find(|(_, c)| *c == Ok(object)).map(|&(f, _)| f);
        assert_eq!(got.len(), 3, "{got:?}");
        // Each applies in its frame, or in the first frame after it by which it had arrived.
        let arrived_by = |k: usize| (wire(&[command(0, 0)]).len() * (k + 1)).div_ceil(7) as u32 - 1;
        assert_eq!(first(0), Some(3.max(arrived_by(0))));
        assert_eq!(first(1), Some(4.max(arrived_by(1))));
        assert_eq!(first(2), Some(9.max(arrived_by(2))));
    }
}
