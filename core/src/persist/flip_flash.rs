//! A fault-injecting NOR flash ([`FlipFlash`]): wraps any [`NorFlash`] and flips one bit in a
//! given share of reads, as a worn or disturbed cell reads wrong once. The bits stored are not
//! changed: the next read of the same bytes may be right. Seeded and deterministic.

use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};

use crate::pose::TrackingRng;

/// `F` with one bit flipped in `per_mille` of every thousand reads (see the module
/// documentation). Programs and erases pass through unchanged.
#[derive(Debug)]
pub struct FlipFlash<F> {
    inner: F,
    per_mille: u16,
    rng: TrackingRng,
    reads: u64,
    flipped: u64,
}

impl<F> FlipFlash<F> {
    /// `inner` with a bit flipped in `per_mille` reads of a thousand (1000: every read), drawn
    /// from a generator seeded by `seed`.
    pub const fn new(inner: F, per_mille: u16, seed: u64) -> Self {
        Self { inner, per_mille, rng: TrackingRng::new(seed), reads: 0, flipped: 0 }
    }

    /// Reads done.
    pub fn reads(&self) -> u64 {
        self.reads
    }

    /// Reads that came back with a bit flipped.
    pub fn flipped(&self) -> u64 {
        self.flipped
    }

    /// The wrapped flash.
    pub fn into_inner(self) -> F {
        self.inner
    }
}

impl<F: NorFlash> ErrorType for FlipFlash<F> {
    type Error = F::Error;
}

impl<F: NorFlash> ReadNorFlash for FlipFlash<F> {
    const READ_SIZE: usize = F::READ_SIZE;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.inner.read(offset, bytes)?;
        self.reads += 1;
        if !bytes.is_empty() && self.rng.below(1000) < usize::from(self.per_mille) {
            let bit = self.rng.below(bytes.len() * 8);
            if let Some(b) = bytes.get_mut(bit / 8) {
                *b ^= 1 << (bit % 8);
                self.flipped += 1;
            }
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.inner.capacity()
    }
}

impl<F: NorFlash> NorFlash for FlipFlash<F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.inner.erase(from, to)
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.inner.write(offset, bytes)
    }
}
