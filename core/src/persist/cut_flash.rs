//! A fault-injecting NOR flash ([`CutFlash`]): wraps any [`NorFlash`] and cuts the power after a
//! given number of program or erase steps, leaving the step it cut half done as real flash
//! would. Seeded and deterministic: the tests of the durable store cut at every step of a save.

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// Erase counts kept per unit of [`CutFlash::erases`].
pub const COUNTED_UNITS: usize = 64;

/// `F` with a power cut after `steps` steps (see the module documentation). A step is one
/// program of `F::WRITE_SIZE` bytes or one sector erase. The step the power is cut in is left
/// half done: a program clears only some of the bits it would, an erase leaves the sector's bits
/// arbitrary (erased, then programmed with noise). Every operation after the cut fails.
#[derive(Debug)]
pub struct CutFlash<F> {
    inner: F,
    /// Steps left before the cut (`None`: never cut).
    left: Option<u64>,
    steps: u64,
    noise: u64,
    erases: [u32; COUNTED_UNITS],
    unit_bytes: usize,
}

/// The error of every operation after the cut, or the wrapped flash's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CutError<E> {
    /// The power is off.
    PowerCut,
    /// The wrapped flash's error.
    Flash(E),
}

impl<E: NorFlashError> NorFlashError for CutError<E> {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::PowerCut => NorFlashErrorKind::Other,
            Self::Flash(e) => e.kind(),
        }
    }
}

impl<F: NorFlash> CutFlash<F> {
    /// `inner` with the power cut after `cut_after` steps (`None`: never), its noise seeded by
    /// `seed`; erases are counted per `unit_bytes` of the region (the first
    /// [`COUNTED_UNITS`]).
    pub fn new(inner: F, cut_after: Option<u64>, seed: u64, unit_bytes: usize) -> Self {
        Self {
            inner,
            left: cut_after,
            steps: 0,
            noise: seed | 1,
            erases: [0; COUNTED_UNITS],
            unit_bytes: unit_bytes.max(1),
        }
    }

    /// Steps done (the cut's included).
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Whether the power was cut.
    pub fn cut(&self) -> bool {
        self.left == Some(0)
    }

    /// Erases per unit so far.
    pub fn erases(&self) -> &[u32; COUNTED_UNITS] {
        &self.erases
    }

    /// The wrapped flash.
    pub fn into_inner(self) -> F {
        self.inner
    }

    /// xorshift64: the noise of a half-done step.
    fn noise(&mut self) -> u64 {
        let mut x = self.noise;
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        self.noise = x;
        x
    }

    /// Takes one step: `Ok(true)` to do it whole, `Ok(false)` to do it half (the cut).
    fn step(&mut self) -> Result<bool, CutError<F::Error>> {
        match self.left {
            Some(0) => Err(CutError::PowerCut),
            Some(ref mut n) => {
                *n -= 1;
                self.steps += 1;
                Ok(*n > 0)
            }
            None => {
                self.steps += 1;
                Ok(true)
            }
        }
    }
}

impl<F: NorFlash> ErrorType for CutFlash<F> {
    type Error = CutError<F::Error>;
}

impl<F: NorFlash> ReadNorFlash for CutFlash<F> {
    const READ_SIZE: usize = F::READ_SIZE;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        if self.cut() {
            return Err(CutError::PowerCut);
        }
        self.inner.read(offset, bytes).map_err(CutError::Flash)
    }

    fn capacity(&self) -> usize {
        self.inner.capacity()
    }
}

impl<F: NorFlash> NorFlash for CutFlash<F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let mut at = from;
        while at < to {
            let end = at + F::ERASE_SIZE as u32;
            let whole = self.step()?;
            self.inner.erase(at, end).map_err(CutError::Flash)?;
            if let Some(n) = self.erases.get_mut(at as usize / self.unit_bytes) {
                *n += 1;
            }
            if !whole {
                // Arbitrary bits: the erase stopped part way (programs up to 64 bytes at a time).
                let n = F::WRITE_SIZE.clamp(1, 64);
                let mut p = at;
                while p < end {
                    let noise = self.noise().to_le_bytes();
                    let mut piece = [0u8; 64];
                    for (k, b) in piece.iter_mut().enumerate().take(n) {
                        *b = noise.get(k % 8).copied().unwrap_or(0);
                    }
                    self.inner.write(p, piece.get(..n).unwrap_or(&[])).map_err(CutError::Flash)?;
                    p += n as u32;
                }
            }
            at = end;
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        for (i, piece) in bytes.chunks(F::WRITE_SIZE).enumerate() {
            let at = offset + (i * F::WRITE_SIZE) as u32;
            if self.step()? {
                self.inner.write(at, piece).map_err(CutError::Flash)?;
            } else {
                // Half programmed: only some of the bits it clears are cleared.
                let mut half = [0u8; 64];
                let n = piece.len().min(half.len());
                for (h, &b) in half.iter_mut().zip(piece).take(n) {
                    *h = b | self.noise() as u8;
                }
                self.inner.write(at, half.get(..n).unwrap_or(&[])).map_err(CutError::Flash)?;
            }
        }
        Ok(())
    }
}
