//! The STM32H743's flash bank 2 as an `embedded-storage` [`NorFlash`]: the long-term store's
//! region on the reference board (1 MiB at 0x0810_0000, eight sectors of 128 KiB, programmed in
//! 32-byte flash words). The firmware's code and data are linked into bank 1 (`memory-ref-board.x`),
//! so a sector erase here never stalls the code being fetched.
//!
//! PLACEHOLDER FOR A REAL HAL, like `h7`: register offsets, keys and bits follow the STM32H743
//! reference manual (RM0433, section 4: the embedded flash memory), but this has never run on
//! hardware. It does not handle what a bring-up must: a flash word left half programmed by a power
//! cut reads with an uncorrectable ECC error, which the H7 reports as a bus fault (a boot that
//! reads such a record must mask or catch it, or check `DBECCERR` first); the data cache, if
//! enabled, must be invalidated over an erased or programmed range; and the programming voltage
//! range (`PSIZE`) is set for a 3.3 V supply. The store above it (`persist::FlashStore` in sector
//! mode) is tested on a simulated flash of this geometry, power cuts included.

use core::ptr;

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

use crate::h7::{read as reg_read, write as reg_write};

/// Bank 2's first byte in the address map.
const BANK2_BASE: usize = 0x0810_0000;
/// Bank 2's size, bytes: eight sectors.
pub const BANK2_BYTES: usize = 1024 * 1024;
/// Erase sector, bytes.
const SECTOR_BYTES: usize = 128 * 1024;
/// Flash word, bytes: the unit of one program (256 bits, with ECC).
const FLASH_WORD_BYTES: usize = 32;

/// Flash interface registers (RM0433 4.9), bank 2's set.
const FLASH: usize = 0x5200_2000;
const KEYR2: usize = FLASH + 0x104;
const CR2: usize = FLASH + 0x10C;
const SR2: usize = FLASH + 0x110;
const CCR2: usize = FLASH + 0x114;
/// The key sequence that unlocks `CR2`.
const KEY1: u32 = 0x4567_0123;
const KEY2: u32 = 0xCDEF_89AB;
/// `CR2` bits.
const CR_LOCK: u32 = 1 << 0;
const CR_PG: u32 = 1 << 1;
const CR_SER: u32 = 1 << 2;
/// Program and erase parallelism x64 (`PSIZE` = 0b11): a 2.7-3.6 V supply.
const CR_PSIZE_X64: u32 = 0b11 << 4;
const CR_START: u32 = 1 << 7;
const CR_SNB_SHIFT: u32 = 8;
/// `SR2` bits: busy, write buffer not empty, operation queued, and the error flags (write
/// protection, programming sequence, strobe, inconsistency, operation, read protection, read
/// secure, single and double ECC).
const SR_BSY: u32 = 1 << 0;
const SR_WBNE: u32 = 1 << 1;
const SR_QW: u32 = 1 << 2;
const SR_ERRORS: u32 = (1 << 17)
    | (1 << 18)
    | (1 << 19)
    | (1 << 21)
    | (1 << 22)
    | (1 << 23)
    | (1 << 24)
    | (1 << 25)
    | (1 << 26);
/// `CCR2`: clears every flag above and end of operation (bit 16).
const CCR_ALL: u32 = SR_ERRORS | (1 << 16);

/// Polls of the busy flags before an operation gives up: a sector erase takes up to about 4 s
/// (RM0433's maximum at x64), about 4 x 10^8 polls at 480 MHz.
const ERASE_POLLS: u32 = 600_000_000;
/// The same for one flash word's program (about 100 us at most).
const PROGRAM_POLLS: u32 = 100_000;

/// Why an operation on bank 2 failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlashError {
    /// Outside the bank.
    OutOfBounds,
    /// An erase not on sector boundaries, or a program not on flash-word boundaries.
    NotAligned,
    /// The interface stayed busy past its poll limit.
    Timeout,
    /// The interface reported an error (its `SR2` flags).
    Interface(u32),
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            Self::NotAligned => NorFlashErrorKind::NotAligned,
            Self::Timeout | Self::Interface(_) => NorFlashErrorKind::Other,
        }
    }
}

/// Bank 2 of the H743's flash (see the module documentation). One value owns the bank: the
/// firmware's place memory.
#[derive(Debug)]
pub struct Bank2Flash(());

impl Bank2Flash {
    /// The bank (`const`, for a `static`); its interface is unlocked at the first erase or
    /// program.
    pub const fn new() -> Self {
        Self(())
    }

    /// Unlocks `CR2` with the key sequence, when it is locked (after reset).
    fn unlock() {
        if reg_read(CR2) & CR_LOCK != 0 {
            reg_write(KEYR2, KEY1);
            reg_write(KEYR2, KEY2);
        }
    }

    /// Waits for the queued operation to end, then checks and clears the error flags.
    fn finish(polls: u32) -> Result<(), FlashError> {
        let idle = (0..polls).any(|_| reg_read(SR2) & (SR_BSY | SR_QW | SR_WBNE) == 0);
        let errors = reg_read(SR2) & SR_ERRORS;
        reg_write(CCR2, CCR_ALL);
        match (idle, errors) {
            (false, _) => Err(FlashError::Timeout),
            (true, 0) => Ok(()),
            (true, e) => Err(FlashError::Interface(e)),
        }
    }

    /// `offset..offset + len` within the bank.
    fn check(offset: u32, len: usize) -> Result<usize, FlashError> {
        let from = offset as usize;
        match from.checked_add(len) {
            Some(to) if to <= BANK2_BYTES => Ok(from),
            _ => Err(FlashError::OutOfBounds),
        }
    }
}

impl ErrorType for Bank2Flash {
    type Error = FlashError;
}

impl ReadNorFlash for Bank2Flash {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let from = Self::check(offset, bytes.len())?;
        for (i, b) in bytes.iter_mut().enumerate() {
            // SAFETY: the byte is inside bank 2 (checked), memory-mapped and always readable.
            *b = unsafe { ptr::read_volatile((BANK2_BASE + from + i) as *const u8) };
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        BANK2_BYTES
    }
}

impl NorFlash for Bank2Flash {
    const WRITE_SIZE: usize = FLASH_WORD_BYTES;
    const ERASE_SIZE: usize = SECTOR_BYTES;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let aligned = |x: u32| (x as usize).is_multiple_of(SECTOR_BYTES);
        if !aligned(from) || !aligned(to) || to < from {
            return Err(FlashError::NotAligned);
        }
        let first = Self::check(from, (to - from) as usize)? / SECTOR_BYTES;
        Self::unlock();
        for sector in first..first + (to - from) as usize / SECTOR_BYTES {
            Self::finish(PROGRAM_POLLS)?;
            let snb = (sector as u32) << CR_SNB_SHIFT;
            reg_write(CR2, CR_SER | CR_PSIZE_X64 | snb);
            reg_write(CR2, CR_SER | CR_PSIZE_X64 | snb | CR_START);
            let done = Self::finish(ERASE_POLLS);
            reg_write(CR2, 0);
            done?;
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        if !(offset as usize).is_multiple_of(FLASH_WORD_BYTES)
            || !bytes.len().is_multiple_of(FLASH_WORD_BYTES)
        {
            return Err(FlashError::NotAligned);
        }
        let from = Self::check(offset, bytes.len())?;
        Self::unlock();
        for (i, word) in bytes.chunks_exact(FLASH_WORD_BYTES).enumerate() {
            Self::finish(PROGRAM_POLLS)?;
            reg_write(CR2, CR_PG | CR_PSIZE_X64);
            let at = BANK2_BASE + from + i * FLASH_WORD_BYTES;
            for (k, w) in word.chunks_exact(4).enumerate() {
                let value = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
                // SAFETY: the word is inside bank 2 (checked) and `PG` is set: the write buffer
                // takes the flash word as eight sequential 32-bit writes (RM0433 4.3.9).
                unsafe { ptr::write_volatile((at + 4 * k) as *mut u32, value) };
            }
            cortex_m::asm::dsb();
            let done = Self::finish(PROGRAM_POLLS);
            reg_write(CR2, 0);
            done?;
        }
        Ok(())
    }
}
