//! The transmit side of the Arm CMSDK APB UART (Cortex-M System Design Kit, ARM DDI0479C), the
//! UART of the MPS2 boards and of QEMU's `mps2-an385`/`mps2-an386` models, as an
//! [`embedded_io::Write`]. Only built for the Cortex-M target.
//!
//! Registers (32-bit, offsets from the base): DATA 0x000 (write: the byte to send), STATE 0x004
//! (bit 0: TX buffer full), CTRL 0x008 (bit 0: TX enable), BAUDDIV 0x010 (at least 16). On
//! mps2-an386, UART0 is at 0x4000_4000 (QEMU's `-serial` chardev 0).

use core::convert::Infallible;
use core::ptr;

/// Base address of UART0 on mps2-an385/an386.
pub const UART0_BASE: usize = 0x4000_4000;

const DATA: usize = 0x000;
const STATE: usize = 0x004;
const CTRL: usize = 0x008;
const BAUDDIV: usize = 0x010;
const STATE_TX_FULL: u32 = 1 << 0;
const CTRL_TX_ENABLE: u32 = 1 << 0;
/// The smallest divider the UART accepts (25 MHz / 16: the emulated line has no real rate).
const MIN_BAUDDIV: u32 = 16;

/// A CMSDK UART's transmitter.
#[derive(Debug)]
pub struct CmsdkUart {
    base: usize,
}

impl CmsdkUart {
    /// Takes UART0 of mps2-an386 and enables its transmitter.
    ///
    /// # Safety
    /// The caller must own UART0 (no other code touches its registers while this value lives),
    /// and the board must be an MPS2 (the address is its UART0).
    pub unsafe fn uart0() -> Self {
        let uart = Self { base: UART0_BASE };
        uart.write_reg(BAUDDIV, MIN_BAUDDIV);
        uart.write_reg(CTRL, CTRL_TX_ENABLE);
        uart
    }

    fn write_reg(&self, offset: usize, value: u32) {
        // SAFETY: `base + offset` is a register of the UART this value owns (see `uart0`), a
        // device address where volatile 32-bit accesses are the only valid kind.
        unsafe { ptr::write_volatile((self.base + offset) as *mut u32, value) }
    }

    fn read_reg(&self, offset: usize) -> u32 {
        // SAFETY: as in `write_reg`.
        unsafe { ptr::read_volatile((self.base + offset) as *const u32) }
    }

    /// Sends one byte, waiting while the transmit buffer is full.
    pub fn write_byte(&mut self, byte: u8) {
        while self.read_reg(STATE) & STATE_TX_FULL != 0 {}
        self.write_reg(DATA, u32::from(byte));
    }
}

impl embedded_io::ErrorType for CmsdkUart {
    type Error = Infallible;
}

impl embedded_io::Write for CmsdkUart {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        for &b in buf {
            self.write_byte(b);
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> Result<(), Self::Error> {
        while self.read_reg(STATE) & STATE_TX_FULL != 0 {}
        Ok(())
    }
}
