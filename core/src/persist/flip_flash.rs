//! A fault-injecting NOR flash ([`FlipFlash`]): wraps any [`NorFlash`] and flips one bit in a
//! given share of reads, as a worn or disturbed cell reads wrong once. The bits stored are not
//! changed: the next read of the same bytes may be right. Seeded and deterministic.

use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};

/// `F` with one bit flipped in `per_mille` of every thousand reads (see the module
/// documentation). Programs and erases pass through unchanged.
#[derive(Debug)]
pub struct FlipFlash<F> {
    inner: F,
    per_mille: u16,
    rng: u64,
    reads: u64,
    flipped: u64,
}

impl<F> FlipFlash<F> {
    /// `inner` with a bit flipped in `per_mille` reads of a thousand (1000: every read), drawn
    /// from a generator seeded by `seed`.
    pub const fn new(inner: F, per_mille: u16, seed: u64) -> Self {
        Self { inner, per_mille, rng: seed ^ 0x9e37_79b9_7f4a_7c15, reads: 0, flipped: 0 }
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

    /// splitmix64: the next 64 random bits.
    fn next_u64(&mut self) -> u64 {
        self.rng = self.rng.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.rng;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
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
        if !bytes.is_empty() && self.next_u64() % 1000 < u64::from(self.per_mille) {
            let bit = self.next_u64() as usize % (bytes.len() * 8);
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
