//! A slice of memory that behaves as NOR flash ([`SliceFlash`]): the QEMU board's stand-in for
//! the reference board's flash, where the long-term store lives ([`super::FlashStore`]), and the
//! host's view of a flash image read back from a board.
//!
//! NOR semantics, faithfully: erasing sets a sector's bytes to `0xFF`; programming can only clear
//! bits (a byte becomes `old & new`), so a write over an unerased slot corrupts it as real flash
//! would, and the store's checksum catches it. The geometry is a parameter: the default is the
//! QEMU board's (1 KiB sectors, 4-byte words); `SliceFlash<'_, { 128 * 1024 }, 32>` stands for
//! the STM32H743's internal flash, whose words carry error-correcting codes and so take one
//! program each between erases (words of more than 4 bytes are refused a second program here).

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// Sector size, bytes: one long-term store record.
pub const SECTOR_BYTES: usize = crate::config::capacity::PLACE_RECORD_BYTES;

/// A region of bytes standing for NOR flash of `SECTOR`-byte erase sectors and `WORD`-byte
/// program words (see the module documentation).
#[derive(Debug)]
pub struct SliceFlash<'a, const SECTOR: usize = SECTOR_BYTES, const WORD: usize = 4> {
    bytes: &'a mut [u8],
}

impl<'a> SliceFlash<'a> {
    /// The flash over `bytes` (its length a multiple of [`SECTOR_BYTES`]; a remainder is not
    /// used). Its content is taken as is: the store erases a slot before writing it.
    pub fn new(bytes: &'a mut [u8]) -> Self {
        Self::with_geometry(bytes)
    }

    /// A region of no bytes (`const`, for a place memory in a `static` that is attached to its
    /// region at run time).
    pub const fn empty() -> SliceFlash<'static> {
        SliceFlash { bytes: &mut [] }
    }
}

impl<'a, const SECTOR: usize, const WORD: usize> SliceFlash<'a, SECTOR, WORD> {
    /// The flash over `bytes`, sectors of `SECTOR` bytes and words of `WORD` (a remainder past
    /// the last whole sector is not used). Its content is taken as is.
    pub fn with_geometry(bytes: &'a mut [u8]) -> Self {
        let usable = bytes.len() - bytes.len() % SECTOR;
        let (bytes, _) = bytes.split_at_mut(usable);
        Self { bytes }
    }

    /// The region's bytes, as written (the host reads them back to compare).
    pub fn bytes(&self) -> &[u8] {
        self.bytes
    }

    /// The bytes `offset..offset + len`, when the region holds them.
    fn span(&mut self, offset: u32, len: usize) -> Result<&mut [u8], SliceFlashError> {
        let from = usize::try_from(offset).map_err(|_| SliceFlashError::OutOfBounds)?;
        let to = from.checked_add(len).ok_or(SliceFlashError::OutOfBounds)?;
        self.bytes.get_mut(from..to).ok_or(SliceFlashError::OutOfBounds)
    }
}

/// Why a [`SliceFlash`] operation failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SliceFlashError {
    /// Outside the region.
    OutOfBounds,
    /// An erase not on sector boundaries, or a write not on word boundaries.
    NotAligned,
    /// A second program of a word of more than 4 bytes since its erase (error-correcting
    /// words refuse it).
    Programmed,
}

impl NorFlashError for SliceFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            Self::NotAligned => NorFlashErrorKind::NotAligned,
            Self::Programmed => NorFlashErrorKind::Other,
        }
    }
}

impl<const SECTOR: usize, const WORD: usize> ErrorType for SliceFlash<'_, SECTOR, WORD> {
    type Error = SliceFlashError;
}

impl<const SECTOR: usize, const WORD: usize> ReadNorFlash for SliceFlash<'_, SECTOR, WORD> {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        bytes.copy_from_slice(self.span(offset, bytes.len())?);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.bytes.len()
    }
}

impl<const SECTOR: usize, const WORD: usize> NorFlash for SliceFlash<'_, SECTOR, WORD> {
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = SECTOR;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let aligned = |x: u32| (x as usize).is_multiple_of(SECTOR);
        if !aligned(from) || !aligned(to) || to < from {
            return Err(SliceFlashError::NotAligned);
        }
        self.span(from, (to - from) as usize)?.fill(0xFF);
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        if !(offset as usize).is_multiple_of(Self::WRITE_SIZE)
            || !bytes.len().is_multiple_of(Self::WRITE_SIZE)
        {
            return Err(SliceFlashError::NotAligned);
        }
        let span = self.span(offset, bytes.len())?;
        if WORD > 4 && span.chunks(WORD).any(|w| w.iter().any(|&b| b != 0xFF)) {
            return Err(SliceFlashError::Programmed);
        }
        for (cell, &b) in span.iter_mut().zip(bytes) {
            *cell &= b;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;

    #[test]
    fn behaves_as_nor_flash() {
        let mut backing = [0u8; 2 * SECTOR_BYTES + 5];
        let mut f = SliceFlash::new(&mut backing);
        assert_eq!(f.capacity(), 2 * SECTOR_BYTES);
        f.erase(0, SECTOR_BYTES as u32).unwrap();
        f.write(0, &[0xF0, 0x0F, 0xAA, 0x55]).unwrap();
        f.write(0, &[0xCC; 4]).unwrap();
        let mut out = [0; 4];
        f.read(0, &mut out).unwrap();
        assert_eq!(out, [0xC0, 0x0C, 0x88, 0x44], "programming only clears bits");
        assert_eq!(f.erase(1, 1024), Err(SliceFlashError::NotAligned));
        assert_eq!(f.write(2, &[0; 4]), Err(SliceFlashError::NotAligned));
        assert_eq!(f.read(2 * SECTOR_BYTES as u32, &mut out), Err(SliceFlashError::OutOfBounds));
    }

    #[test]
    fn words_with_error_correction_take_one_program_between_erases() {
        let mut backing = std::vec![0u8; 3 * 8192];
        let mut f = SliceFlash::<'_, 8192, 32>::with_geometry(&mut backing);
        assert_eq!(f.capacity(), 3 * 8192);
        f.erase(8192, 16384).unwrap();
        f.write(8192, &[0x0F; 32]).unwrap();
        assert_eq!(f.write(8192, &[0x0F; 32]), Err(SliceFlashError::Programmed));
        assert_eq!(f.write(8192 + 16, &[0; 32]), Err(SliceFlashError::NotAligned));
        assert_eq!(f.erase(1024, 8192), Err(SliceFlashError::NotAligned));
        f.erase(8192, 16384).unwrap();
        f.write(8192, &[0x0F; 32]).unwrap();
    }
}
