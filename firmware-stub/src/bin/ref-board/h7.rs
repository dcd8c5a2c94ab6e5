//! A register-level minimum of the STM32H743 peripherals the wiring needs, as embedded-hal 1.0
//! and embedded-io implementations: GPIO input (frame-ready lines) and output (chip selects), SPI
//! master (polled, full duplex), I2C master (polled), USART transmitter, USART receiver into a
//! ring by DMA, a busy-wait delay and a DWT cycle clock.
//!
//! PLACEHOLDER FOR A REAL HAL. This exists so that the reference board's binary links the same
//! generic driver code with concrete types and the linker checks the memory map; it has never run
//! on hardware. Register offsets and bits follow the STM32H743 reference manual (RM0433), but
//! nothing here sets up the clock tree (PLL, 480 MHz), the pins' alternate functions and speeds,
//! the SPI baud rate (CFG1) or I2C timing (TIMINGR), or recovers from bus errors beyond reporting
//! them. A board bring-up replaces this module with embassy-stm32 or stm32h7xx-hal, whose types
//! implement the same traits, and nothing else changes.

use core::ptr;

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{self, InputPin};
use embedded_hal::i2c::{self, I2c, NoAcknowledgeSource, Operation as I2cOp, SevenBitAddress};
use embedded_hal::spi::{self, Operation as SpiOp, SpiDevice};
use ferroslam_core::wire::TickUnit;
use ferroslam_firmware::pipeline::TickClock;
use ferroslam_firmware::rx_ring::RingProducer;

/// The core clock the delay assumes, Hz (the H743 at full speed).
pub const CORE_HZ: u32 = 480_000_000;

/// Polls of a status flag before a bus operation gives up (~1 ms at 480 MHz).
const POLL_LIMIT: u32 = 100_000;

/// A volatile 32-bit read of the peripheral register at `addr` (this module's, and the flash
/// interface's of `h7_flash`).
pub(crate) fn read(addr: usize) -> u32 {
    // SAFETY: only called with addresses of the peripheral registers of this module and of
    // `h7_flash`, where volatile 32-bit reads are valid; the firmware owns those peripherals.
    unsafe { ptr::read_volatile(addr as *const u32) }
}

/// A volatile 32-bit write of `value` to the peripheral register at `addr` (as [`read`]).
pub(crate) fn write(addr: usize, value: u32) {
    // SAFETY: as in `read`.
    unsafe { ptr::write_volatile(addr as *mut u32, value) }
}

/// Waits until `(read(addr) & mask) != 0`, at most [`POLL_LIMIT`] polls.
fn wait_set(addr: usize, mask: u32) -> bool {
    (0..POLL_LIMIT).any(|_| read(addr) & mask != 0)
}

/// GPIO port base addresses (AHB4): GPIOA at 0x5802_0000, one port every 0x400.
const GPIOA: usize = 0x5802_0000;
const GPIO_IDR: usize = 0x10;
const GPIO_BSRR: usize = 0x18;

/// A GPIO pin: `port` 0 = A, 1 = B, ...; `pin` 0..=15.
#[derive(Debug, Clone, Copy)]
pub struct Pin {
    port: usize,
    pin: u32,
}

impl Pin {
    /// Pin `pin` of port `port` (0 = A). Its mode must already be input (reset state) or output.
    pub const fn new(port: usize, pin: u32) -> Self {
        Self { port, pin }
    }

    fn base(&self) -> usize {
        GPIOA + 0x400 * self.port
    }

    fn set(&self, high: bool) {
        let bit = if high { 1 << self.pin } else { 1 << (self.pin + 16) };
        write(self.base() + GPIO_BSRR, bit);
    }
}

impl digital::ErrorType for Pin {
    type Error = core::convert::Infallible;
}

impl InputPin for Pin {
    fn is_high(&mut self) -> Result<bool, Self::Error> {
        Ok(read(self.base() + GPIO_IDR) & (1 << self.pin) != 0)
    }

    fn is_low(&mut self) -> Result<bool, Self::Error> {
        self.is_high().map(|h| !h)
    }
}

/// SPI registers (RM0433 section 50): CR1, SR, IFCR, TXDR, RXDR.
const SPI_CR1: usize = 0x00;
const SPI_SR: usize = 0x14;
const SPI_IFCR: usize = 0x18;
const SPI_TXDR: usize = 0x20;
const SPI_RXDR: usize = 0x30;
const SPI_CR1_SPE: u32 = 1 << 0;
const SPI_CR1_CSTART: u32 = 1 << 9;
const SPI_SR_RXP: u32 = 1 << 0;
const SPI_SR_TXP: u32 = 1 << 1;
const SPI_SR_TXC: u32 = 1 << 12;

/// An SPI bus error of this placeholder.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SpiTimeout;

impl spi::Error for SpiTimeout {
    fn kind(&self) -> spi::ErrorKind {
        spi::ErrorKind::Other
    }
}

/// An SPI master (8-bit frames, polled) with a GPIO chip select: one [`SpiDevice`].
#[derive(Debug)]
pub struct SpiDev {
    base: usize,
    cs: Pin,
}

impl SpiDev {
    /// SPI1 (APB2, 0x4001_3000) with chip select `cs`.
    pub const fn spi1(cs: Pin) -> Self {
        Self { base: 0x4001_3000, cs }
    }

    /// One full-duplex byte.
    fn exchange(&self, out: u8) -> Result<u8, SpiTimeout> {
        if !wait_set(self.base + SPI_SR, SPI_SR_TXP) {
            return Err(SpiTimeout);
        }
        // SAFETY: 8-bit access to TXDR sends one 8-bit frame (data packing by access size).
        unsafe { ptr::write_volatile((self.base + SPI_TXDR) as *mut u8, out) };
        if !wait_set(self.base + SPI_SR, SPI_SR_RXP) {
            return Err(SpiTimeout);
        }
        // SAFETY: 8-bit access to RXDR takes one received frame.
        Ok(unsafe { ptr::read_volatile((self.base + SPI_RXDR) as *const u8) })
    }

    fn run(&self, operations: &mut [SpiOp<'_, u8>]) -> Result<(), SpiTimeout> {
        for op in operations {
            match op {
                SpiOp::Write(bytes) => {
                    for &b in bytes.iter() {
                        self.exchange(b)?;
                    }
                }
                SpiOp::Read(buf) => {
                    for b in buf.iter_mut() {
                        *b = self.exchange(0)?;
                    }
                }
                SpiOp::Transfer(rx, tx) => {
                    for (i, r) in rx.iter_mut().enumerate() {
                        *r = self.exchange(tx.get(i).copied().unwrap_or(0))?;
                    }
                }
                SpiOp::TransferInPlace(buf) => {
                    for b in buf.iter_mut() {
                        *b = self.exchange(*b)?;
                    }
                }
                SpiOp::DelayNs(ns) => cortex_m::asm::delay(cycles(*ns)),
            }
        }
        if wait_set(self.base + SPI_SR, SPI_SR_TXC) { Ok(()) } else { Err(SpiTimeout) }
    }
}

impl spi::ErrorType for SpiDev {
    type Error = SpiTimeout;
}

impl SpiDevice for SpiDev {
    fn transaction(&mut self, operations: &mut [SpiOp<'_, u8>]) -> Result<(), SpiTimeout> {
        self.cs.set(false);
        write(self.base + SPI_CR1, SPI_CR1_SPE);
        write(self.base + SPI_CR1, SPI_CR1_SPE | SPI_CR1_CSTART);
        let result = self.run(operations);
        write(self.base + SPI_CR1, 0);
        write(self.base + SPI_IFCR, 0xFFFF_FFFF);
        self.cs.set(true);
        result
    }
}

/// I2C registers (RM0433 section 47): CR2, ISR, ICR, RXDR, TXDR.
const I2C_CR2: usize = 0x04;
const I2C_ISR: usize = 0x18;
const I2C_ICR: usize = 0x1C;
const I2C_RXDR: usize = 0x24;
const I2C_TXDR: usize = 0x28;
const I2C_CR2_RD_WRN: u32 = 1 << 10;
const I2C_CR2_START: u32 = 1 << 13;
const I2C_CR2_AUTOEND: u32 = 1 << 25;
const I2C_ISR_TXIS: u32 = 1 << 1;
const I2C_ISR_RXNE: u32 = 1 << 2;
const I2C_ISR_NACKF: u32 = 1 << 4;
const I2C_ISR_STOPF: u32 = 1 << 5;
const I2C_ISR_TC: u32 = 1 << 6;

/// An I2C error of this placeholder.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum I2cError {
    /// The addressed device did not acknowledge.
    Nack,
    /// A flag never came (bus stuck, clock not set up).
    Timeout,
    /// An operation longer than 255 bytes (the placeholder does not reload NBYTES).
    TooLong,
}

impl i2c::Error for I2cError {
    fn kind(&self) -> i2c::ErrorKind {
        match self {
            Self::Nack => i2c::ErrorKind::NoAcknowledge(NoAcknowledgeSource::Unknown),
            Self::Timeout | Self::TooLong => i2c::ErrorKind::Other,
        }
    }
}

/// An I2C master (polled, 7-bit addresses).
#[derive(Debug)]
pub struct I2cBus {
    base: usize,
}

impl I2cBus {
    /// I2C1 (APB1, 0x4000_5400).
    pub const fn i2c1() -> Self {
        Self { base: 0x4000_5400 }
    }

    /// Waits for `flag`, or a NACK.
    fn wait(&self, flag: u32) -> Result<(), I2cError> {
        for _ in 0..POLL_LIMIT {
            let isr = read(self.base + I2C_ISR);
            if isr & I2C_ISR_NACKF != 0 {
                write(self.base + I2C_ICR, I2C_ISR_NACKF | I2C_ISR_STOPF);
                return Err(I2cError::Nack);
            }
            if isr & flag != 0 {
                return Ok(());
            }
        }
        Err(I2cError::Timeout)
    }

    /// Starts (or restarts) a transfer of `len` bytes; `last` ends it with a stop.
    fn start(&self, address: u8, len: usize, read_dir: bool, last: bool) -> Result<(), I2cError> {
        let nbytes = u32::try_from(len).ok().filter(|&n| n <= 255).ok_or(I2cError::TooLong)?;
        let mut cr2 = (u32::from(address) << 1) | (nbytes << 16) | I2C_CR2_START;
        if read_dir {
            cr2 |= I2C_CR2_RD_WRN;
        }
        if last {
            cr2 |= I2C_CR2_AUTOEND;
        }
        write(self.base + I2C_CR2, cr2);
        Ok(())
    }
}

impl i2c::ErrorType for I2cBus {
    type Error = I2cError;
}

impl I2c<SevenBitAddress> for I2cBus {
    fn transaction(&mut self, address: u8, operations: &mut [I2cOp<'_>]) -> Result<(), I2cError> {
        let count = operations.len();
        for (i, op) in operations.iter_mut().enumerate() {
            let last = i + 1 == count;
            match op {
                I2cOp::Write(bytes) => {
                    self.start(address, bytes.len(), false, last)?;
                    for &b in bytes.iter() {
                        self.wait(I2C_ISR_TXIS)?;
                        write(self.base + I2C_TXDR, u32::from(b));
                    }
                }
                I2cOp::Read(buf) => {
                    self.start(address, buf.len(), true, last)?;
                    for b in buf.iter_mut() {
                        self.wait(I2C_ISR_RXNE)?;
                        *b = (read(self.base + I2C_RXDR) & 0xFF) as u8;
                    }
                }
            }
            self.wait(if last { I2C_ISR_STOPF } else { I2C_ISR_TC })?;
        }
        write(self.base + I2C_ICR, I2C_ISR_STOPF);
        Ok(())
    }
}

/// USART registers (RM0433 section 48): ISR and TDR.
const USART_ISR: usize = 0x1C;
const USART_TDR: usize = 0x28;
const USART_ISR_TXFNF: u32 = 1 << 7;
const USART_ISR_TC: u32 = 1 << 6;

/// A USART transmitter (polled), the telemetry link's byte sink.
#[derive(Debug)]
pub struct UsartTx {
    base: usize,
}

impl UsartTx {
    /// USART1 (APB2, 0x4001_1000).
    pub const fn usart1() -> Self {
        Self { base: 0x4001_1000 }
    }
}

/// The transmitter never signalled room for a byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UsartTimeout;

impl embedded_io::Error for UsartTimeout {
    fn kind(&self) -> embedded_io::ErrorKind {
        embedded_io::ErrorKind::TimedOut
    }
}

impl embedded_io::ErrorType for UsartTx {
    type Error = UsartTimeout;
}

impl embedded_io::Write for UsartTx {
    fn write(&mut self, buf: &[u8]) -> Result<usize, UsartTimeout> {
        for &b in buf {
            if !wait_set(self.base + USART_ISR, USART_ISR_TXFNF) {
                return Err(UsartTimeout);
            }
            write(self.base + USART_TDR, u32::from(b));
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> Result<(), UsartTimeout> {
        if wait_set(self.base + USART_ISR, USART_ISR_TC) { Ok(()) } else { Err(UsartTimeout) }
    }
}

/// USART1's registers beyond the transmitter's (RM0433 section 48): CR1 (UE, RE), CR3 (DMAR,
/// OVRDIS), RDR.
const USART1: usize = 0x4001_1000;
const USART_CR1: usize = 0x00;
const USART_CR3: usize = 0x08;
const USART_RDR: usize = 0x24;
const USART_CR1_UE: u32 = 1 << 0;
const USART_CR1_RE: u32 = 1 << 2;
const USART_CR3_DMAR: u32 = 1 << 6;
const USART_CR3_OVRDIS: u32 = 1 << 12;

/// RCC's AHB1 clock enable register and its DMA1 bit (RM0433 section 8).
const RCC_AHB1ENR: usize = 0x5802_44D8;
const RCC_AHB1ENR_DMA1EN: u32 = 1 << 0;

/// DMA1 stream 0 (RM0433 section 15: SxCR, SxNDTR, SxPAR, SxM0AR, SxFCR) and the DMAMUX1 channel
/// that feeds it (channel 0, section 17), with USART1's receive request (DMAREQ_ID 41).
const DMA1_S0CR: usize = 0x4002_0010;
const DMA1_S0NDTR: usize = 0x4002_0014;
const DMA1_S0PAR: usize = 0x4002_0018;
const DMA1_S0M0AR: usize = 0x4002_001C;
const DMA1_S0FCR: usize = 0x4002_0024;
const DMA1_LIFCR: usize = 0x4002_0008;
const DMAMUX1_C0CR: usize = 0x4002_0800;
const DMAMUX_USART1_RX: u32 = 41;
/// SxCR: EN, CIRC, MINC, PL high (peripheral to memory, bytes both sides).
const DMA_SXCR_EN: u32 = 1 << 0;
const DMA_SXCR_CIRC: u32 = 1 << 8;
const DMA_SXCR_MINC: u32 = 1 << 10;
const DMA_SXCR_PL_HIGH: u32 = 2 << 16;
/// Every flag of stream 0 in LIFCR.
const DMA_LIFCR_STREAM0: u32 = 0x3D;

/// Bytes of the receive ring: more than 115,200 baud brings between two frames (about 390 bytes
/// in 33 ms), so a frame loop that reads it once a frame never falls a lap behind.
pub const RX_RING_BYTES: usize = 1024;

/// USART1's receiver writing into a ring by DMA1 stream 0 in circular mode, as a
/// [`RingProducer`]: no interrupt, no wait; the write position is the ring's length less the
/// stream's remaining count. The ring must be where DMA1 reaches (not DTCM: AXI SRAM or SRAM1-3)
/// and not cached: this firmware leaves the D-cache off (with it on, the ring needs a
/// non-cacheable MPU region).
#[derive(Debug)]
pub struct UsartRxDma {
    ring: *const u8,
}

impl UsartRxDma {
    /// Starts USART1's receiver into `ring`: DMA1's clock on, DMAMUX1 channel 0 on USART1's
    /// receive request, stream 0 circular from RDR into the ring, then the USART (disabled while
    /// CR3 changes) with its receiver and DMA on and overrun detection off (a byte the DMA could
    /// not take is overwritten, never a stop). The baud rate and pins are the transmitter's.
    pub fn start(ring: &'static mut [u8; RX_RING_BYTES]) -> Self {
        let at = ring.as_mut_ptr();
        write(RCC_AHB1ENR, read(RCC_AHB1ENR) | RCC_AHB1ENR_DMA1EN);
        write(DMA1_S0CR, 0);
        let _ = wait_set_clear(DMA1_S0CR, DMA_SXCR_EN);
        write(DMA1_LIFCR, DMA_LIFCR_STREAM0);
        write(DMAMUX1_C0CR, DMAMUX_USART1_RX);
        write(DMA1_S0PAR, (USART1 + USART_RDR) as u32);
        write(DMA1_S0M0AR, at as u32);
        write(DMA1_S0NDTR, RX_RING_BYTES as u32);
        // Direct mode (no FIFO): each byte goes to the ring as it arrives.
        write(DMA1_S0FCR, 0);
        write(DMA1_S0CR, DMA_SXCR_CIRC | DMA_SXCR_MINC | DMA_SXCR_PL_HIGH);
        write(DMA1_S0CR, DMA_SXCR_CIRC | DMA_SXCR_MINC | DMA_SXCR_PL_HIGH | DMA_SXCR_EN);
        let cr1 = read(USART1 + USART_CR1);
        write(USART1 + USART_CR1, cr1 & !USART_CR1_UE);
        write(USART1 + USART_CR3, read(USART1 + USART_CR3) | USART_CR3_DMAR | USART_CR3_OVRDIS);
        write(USART1 + USART_CR1, cr1 | USART_CR1_RE | USART_CR1_UE);
        Self { ring: at }
    }
}

impl RingProducer for UsartRxDma {
    fn len(&self) -> usize {
        RX_RING_BYTES
    }

    fn written_to(&self) -> usize {
        let remaining = read(DMA1_S0NDTR) as usize;
        RX_RING_BYTES.saturating_sub(remaining) % RX_RING_BYTES
    }

    fn byte(&self, at: usize) -> u8 {
        // SAFETY: `ring` is the start of the `'static` ring `start` took (so alive and not
        // aliased by safe code); `at % RX_RING_BYTES` is inside it; volatile, as the DMA writes
        // it behind the compiler's back.
        unsafe { ptr::read_volatile(self.ring.add(at % RX_RING_BYTES)) }
    }
}

/// Waits until `(read(addr) & mask) == 0`, at most [`POLL_LIMIT`] polls.
fn wait_set_clear(addr: usize, mask: u32) -> bool {
    (0..POLL_LIMIT).any(|_| read(addr) & mask == 0)
}

/// Core cycles of `ns` nanoseconds at [`CORE_HZ`].
fn cycles(ns: u32) -> u32 {
    u32::try_from(u64::from(ns) * u64::from(CORE_HZ) / 1_000_000_000).unwrap_or(u32::MAX)
}

/// A busy-wait delay on the core clock.
#[derive(Debug, Clone, Copy, Default)]
pub struct BusyDelay;

impl DelayNs for BusyDelay {
    fn delay_ns(&mut self, ns: u32) {
        cortex_m::asm::delay(cycles(ns));
    }
}

/// The DWT cycle counter as the cost clock: one tick per core cycle.
#[derive(Debug)]
pub struct CycleClock;

impl CycleClock {
    /// Enables the trace unit and the cycle counter.
    pub fn start(mut dcb: cortex_m::peripheral::DCB, mut dwt: cortex_m::peripheral::DWT) -> Self {
        dcb.enable_trace();
        dwt.enable_cycle_counter();
        Self
    }
}

impl TickClock for CycleClock {
    const UNIT: TickUnit = TickUnit::CoreCycle;

    fn now(&mut self) -> u32 {
        cortex_m::peripheral::DWT::cycle_count()
    }
}
