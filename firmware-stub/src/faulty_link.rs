//! [`FaultyLink`]: a fault injector on the serial link, wrapping any `embedded_io` writer (the
//! board's side) or reader (the receiver's side), in the style of smoltcp's fault-injecting
//! devices. It sees the link's frames by their `0x00` delimiters and hits a given share of them:
//! one byte dropped, one bit flipped, or the frame cut short. Seeded and deterministic.
//!
//! What the receiver makes of a hit frame is the wire format's documented behaviour
//! (`ferroslam_core::wire`): the frame is dropped and counted, the frames around it decode, and a
//! wrong value is never delivered (CRC-32 over every payload). A dropped delimiter merges two
//! frames, both dropped; a flipped bit that makes a `0x00` splits one, both halves dropped.

use ferroslam_core::pose::TrackingRng;
use ferroslam_core::wire::MAX_FRAME_ON_WIRE;

/// One kind of link fault, applied to a whole frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkFault {
    /// One byte of the frame (its delimiter included) is lost.
    DropByte,
    /// One bit of one byte of the frame (its delimiter included) is flipped.
    FlipBit,
    /// The frame is cut short at a random byte and ended there (a UART reset mid-frame).
    Truncate,
}

/// Which frames a [`FaultyLink`] hits: each with probability `per_mille / 1000`, drawn from a
/// generator seeded by `seed`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LinkPlan {
    /// The fault injected.
    pub fault: LinkFault,
    /// Frames hit per thousand, at most 1000.
    pub per_mille: u16,
    /// The generator's seed.
    pub seed: u64,
}

/// Bytes of the frame buffer: the longest frame the core sends, and room for a longer run of
/// bytes without a delimiter (garbage), which is passed on unchanged when it fills the buffer.
const BUFFER: usize = 2 * MAX_FRAME_ON_WIRE;

/// A serial link with the faults of a [`LinkPlan`] injected (see the module documentation):
/// `embedded_io::Write` when `T` is a writer, `embedded_io::Read` when `T` is a reader. RAM:
/// one frame buffer of about 260 bytes.
#[derive(Debug)]
pub struct FaultyLink<T> {
    inner: T,
    plan: LinkPlan,
    rng: TrackingRng,
    buf: [u8; BUFFER],
    /// Bytes of the frame in `buf`.
    len: usize,
    /// Reading: bytes of `buf` already handed out.
    served: usize,
    frames: u32,
    hit: u32,
}

impl<T> FaultyLink<T> {
    /// `inner` with the faults of `plan`.
    pub const fn new(inner: T, plan: LinkPlan) -> Self {
        Self {
            inner,
            plan,
            rng: TrackingRng::new(plan.seed),
            buf: [0; BUFFER],
            len: 0,
            served: 0,
            frames: 0,
            hit: 0,
        }
    }

    /// Frames seen whole (ended by their delimiter).
    pub fn frames(&self) -> u32 {
        self.frames
    }

    /// Frames hit.
    pub fn hit(&self) -> u32 {
        self.hit
    }

    /// The wrapped writer or reader.
    pub fn into_inner(self) -> T {
        self.inner
    }

    /// Takes the frame of `buf[..len]`, ended by its delimiter, through the plan.
    fn mangle(&mut self) {
        self.frames = self.frames.saturating_add(1);
        if self.len == 0 || self.rng.below(1000) >= usize::from(self.plan.per_mille) {
            return;
        }
        self.hit = self.hit.saturating_add(1);
        let at = self.rng.below(self.len);
        match self.plan.fault {
            LinkFault::DropByte => {
                self.buf.copy_within(at + 1..self.len, at);
                self.len -= 1;
            }
            LinkFault::FlipBit => {
                let bit = self.rng.below(8);
                if let Some(b) = self.buf.get_mut(at) {
                    *b ^= 1 << bit;
                }
            }
            LinkFault::Truncate => {
                if let Some(b) = self.buf.get_mut(at) {
                    *b = 0;
                }
                self.len = at + 1;
            }
        }
    }
}

impl<T: embedded_io::ErrorType> embedded_io::ErrorType for FaultyLink<T> {
    type Error = T::Error;
}

impl<W: embedded_io::Write> embedded_io::Write for FaultyLink<W> {
    fn write(&mut self, bytes: &[u8]) -> Result<usize, Self::Error> {
        for &b in bytes {
            if let Some(slot) = self.buf.get_mut(self.len) {
                *slot = b;
                self.len += 1;
            }
            if b == 0 {
                self.mangle();
            }
            if b == 0 || self.len == BUFFER {
                self.inner.write_all(self.buf.get(..self.len).unwrap_or_default())?;
                self.len = 0;
            }
        }
        Ok(bytes.len())
    }

    /// Passes on the bytes of an unfinished frame unchanged, then flushes the writer.
    fn flush(&mut self) -> Result<(), Self::Error> {
        self.inner.write_all(self.buf.get(..self.len).unwrap_or_default())?;
        self.len = 0;
        self.inner.flush()
    }
}

impl<R: embedded_io::Read> embedded_io::Read for FaultyLink<R> {
    fn read(&mut self, out: &mut [u8]) -> Result<usize, Self::Error> {
        if out.is_empty() {
            return Ok(0);
        }
        if self.served == self.len {
            (self.len, self.served) = (0, 0);
            // One frame in, up to its delimiter (or the end, or a full buffer).
            while self.len < BUFFER {
                let mut b = [0u8; 1];
                if self.inner.read(&mut b)? == 0 {
                    break;
                }
                if let Some(slot) = self.buf.get_mut(self.len) {
                    *slot = b[0];
                }
                self.len += 1;
                if b[0] == 0 {
                    self.mangle();
                    break;
                }
            }
        }
        let ready = self.buf.get(self.served..self.len).unwrap_or_default();
        let n = ready.len().min(out.len());
        if let (Some(dst), Some(src)) = (out.get_mut(..n), ready.get(..n)) {
            dst.copy_from_slice(src);
        }
        self.served += n;
        Ok(n)
    }
}

#[cfg(test)]
mod tests;
