//! The RGB-D camera module: a gray sensor and a depth sensor, each behind an ArduCAM-style frame
//! FIFO, driven through embedded-hal 1.0 traits and read as the core's
//! [`FrameSource`].
//!
//! # Hardware model
//!
//! Each sensor is configured over a shared I2C bus and writes its frames into its own frame FIFO
//! (an ArduCAM-style SPI bridge with its own chip select). The FIFO raises a frame-ready line
//! (an [`InputPin`]) when a whole frame is stored. The board holds neither frame: it reads each
//! FIFO two sensor rows at a time and halves them into the [`HalfFrame`] store as they arrive.
//!
//! # Register protocol
//!
//! Sensor registers (I2C, 7-bit address, 8-bit register addresses and values):
//! - read: write `[reg]`, repeated start, read one byte (`I2c::write_read`);
//! - write: write `[reg, value]` (`I2c::write`).
//!
//! FIFO registers (SPI mode 0, one chip-select cycle each, `SpiDevice`):
//!
//! | register | address | use |
//! | --- | --- | --- |
//! | TEST | 0x00 | scratch: the link check writes 0x55 and reads it back |
//! | CONTROL | 0x04 | write-only: bit 0 clear capture-done, bit 1 start capture, bit 4 reset write pointer, bit 5 reset read pointer |
//! | SIZE0..2 | 0x42, 0x43, 0x44 | byte count of the stored frame, 23 bits, low byte first |
//! | BURST | 0x3C | command: the bytes clocked in after it are the next FIFO bytes |
//!
//! - register write: `[0x80 | reg, value]`; register read: `[reg]` then one byte read;
//! - burst read: `[0x3C]` then N bytes read, in one chip-select cycle; the read pointer carries
//!   over, so a frame is read as consecutive bursts (one per row pair here).
//!
//! # Sequences
//!
//! [`RgbdCamera::init`], for the gray sensor then the depth sensor:
//! 1. read both identity registers ([`SensorConfig::chip_id`]); a mismatch is
//!    [`CameraError::WrongChipId`];
//! 2. write the soft reset, wait [`SensorConfig::reset_delay_us`] (`DelayNs`);
//! 3. write the init table in order;
//! 4. FIFO link check: write TEST = 0x55, read TEST; anything else is
//!    [`CameraError::SpiLinkCheck`].
//!
//! Each frame ([`FrameSource::next_frame`]):
//! 1. arm both FIFOs: CONTROL = 0x01 (clear done), 0x30 (reset pointers), 0x02 (start);
//! 2. wait for each frame-ready line to read high: poll, then wait
//!    [`CameraConfig::ready_poll_us`], at most [`CameraConfig::ready_timeout_us`] in all, then
//!    [`CameraError::FrameReadyTimeout`] (never a hang);
//! 3. read each FIFO's byte count; fewer bytes than a frame is [`CameraError::ShortFrame`] (more
//!    are allowed: the bridge may pad; the tail is never read);
//! 4. for each of the `height / 2` row pairs: burst-read two gray rows and halve them (rounded
//!    2x2 mean), burst-read two depth rows and halve them (the core's depth rule).
//!
//! Every bus error ends the frame with the bus's own error inside [`CameraError`]; the next call
//! starts a fresh capture. Timestamps are the frame's index times
//! [`CameraConfig::frame_period_s`]: the nominal sensor clock (a board that has a timer captured
//! at the frame-ready edge would stamp from it instead).
//!
//! The register tables ([`GRAY_VGA_Y8`], [`DEPTH_VGA_Z16`]) are this project's configuration of
//! the sensor classes named there; the depth sensor's register map is a model of a generic VGA
//! depth module, not of a specific part. Both are to be checked against the parts fitted.

mod error;
mod protocol;
#[cfg(test)]
mod tests;

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::InputPin;
use embedded_hal::i2c::I2c;
use embedded_hal::spi::SpiDevice;
use ferroslam_core::frame::{FrameSource, RgbdFrame};

use crate::frame_file::decode_depth_le;
use crate::stream::{HalfFrame, MAX_SENSOR_WIDTH};
pub use error::{CameraError, SensorId};
pub use protocol::{
    DEPTH_UNITS_PER_M, DEPTH_VGA_Z16, FIFO_BURST_READ, FIFO_CONTROL, FIFO_CTRL_CLEAR_DONE,
    FIFO_CTRL_RESET_READ, FIFO_CTRL_RESET_WRITE, FIFO_CTRL_START, FIFO_SIZE_0, FIFO_SIZE_1,
    FIFO_SIZE_2, FIFO_TEST, FIFO_TEST_PATTERN, FIFO_WRITE_FLAG, GRAY_VGA_Y8, SensorConfig,
};
use protocol::{
    fifo_burst_read, fifo_len, fifo_read, fifo_start_capture, fifo_write, sensor_read, sensor_write,
};

/// How the camera is run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraConfig {
    /// The gray sensor.
    pub gray: SensorConfig,
    /// The depth sensor (same size as the gray one).
    pub depth: SensorConfig,
    /// Raw depth units per metre.
    pub depth_scale: f32,
    /// Time between frames, seconds (timestamps are `index * frame_period_s`).
    pub frame_period_s: f64,
    /// Wait between two polls of a frame-ready line, microseconds (at least 1).
    pub ready_poll_us: u32,
    /// Longest wait for a frame-ready line, microseconds.
    pub ready_timeout_us: u32,
}

impl CameraConfig {
    /// The reference module: VGA gray and depth, 30 frames per second, 100 ms to a frame.
    pub const VGA: Self = Self {
        gray: GRAY_VGA_Y8,
        depth: DEPTH_VGA_Z16,
        depth_scale: DEPTH_UNITS_PER_M,
        frame_period_s: 1.0 / 30.0,
        ready_poll_us: 100,
        ready_timeout_us: 100_000,
    };
}

/// One sensor's FIFO: its SPI device (own chip select) and frame-ready line.
#[derive(Debug)]
pub struct FifoPort<SPI, PIN> {
    /// The FIFO bridge on the SPI bus.
    pub spi: SPI,
    /// High when a whole frame is stored.
    pub ready: PIN,
}

/// The error type of an [`RgbdCamera`] over these buses.
pub type CameraErrorOf<I2C, SPI, PIN> = CameraError<
    <I2C as embedded_hal::i2c::ErrorType>::Error,
    <SPI as embedded_hal::spi::ErrorType>::Error,
    <PIN as embedded_hal::digital::ErrorType>::Error,
>;

/// The camera module: both sensors, their FIFOs, and the half-resolution frame store it fills.
#[derive(Debug)]
pub struct RgbdCamera<'b, I2C, SPI, PIN, D> {
    i2c: I2C,
    gray: FifoPort<SPI, PIN>,
    depth: FifoPort<SPI, PIN>,
    delay: D,
    config: CameraConfig,
    store: &'b mut HalfFrame,
    frames: u32,
    /// Two sensor rows as read from a FIFO (gray: 2 x width bytes; depth: 4 x width).
    rows: [u8; 4 * MAX_SENSOR_WIDTH],
    /// Two depth rows decoded.
    depth_rows: [u16; 2 * MAX_SENSOR_WIDTH],
}

impl<'b, I2C, SPI, PIN, D> RgbdCamera<'b, I2C, SPI, PIN, D>
where
    I2C: I2c,
    SPI: SpiDevice,
    PIN: InputPin,
    D: DelayNs,
{
    /// A camera over these buses writing into `store`. Nothing is sent until
    /// [`RgbdCamera::init`].
    ///
    /// # Errors
    /// [`CameraError::Config`] when the sensors differ in size, a sensor is larger than VGA or
    /// smaller than 2x2, or the pixel formats are not 1-byte gray and 2-byte depth.
    pub fn new(
        i2c: I2C,
        gray: FifoPort<SPI, PIN>,
        depth: FifoPort<SPI, PIN>,
        delay: D,
        config: CameraConfig,
        store: &'b mut HalfFrame,
    ) -> Result<Self, CameraErrorOf<I2C, SPI, PIN>> {
        let (g, d) = (&config.gray, &config.depth);
        let same_size = (g.width, g.height) == (d.width, d.height);
        let formats = g.bytes_per_pixel == 1 && d.bytes_per_pixel == 2;
        if !same_size || !formats || config.ready_poll_us == 0 {
            return Err(CameraError::Config);
        }
        store
            .start(usize::from(g.width), usize::from(g.height))
            .map_err(|_| CameraError::Config)?;
        let (rows, depth_rows) = ([0; 4 * MAX_SENSOR_WIDTH], [0; 2 * MAX_SENSOR_WIDTH]);
        Ok(Self { i2c, gray, depth, delay, config, store, frames: 0, rows, depth_rows })
    }

    /// Identifies, resets and configures both sensors and checks both FIFO links (see the
    /// module documentation).
    ///
    /// # Errors
    /// A bus error, [`CameraError::WrongChipId`] or [`CameraError::SpiLinkCheck`].
    pub fn init(&mut self) -> Result<(), CameraErrorOf<I2C, SPI, PIN>> {
        for id in [SensorId::Gray, SensorId::Depth] {
            let sensor = *self.sensor(id);
            let i2c_err = |source| CameraError::I2c { sensor: id, source };
            for (register, expected) in sensor.chip_id {
                let found = sensor_read(&mut self.i2c, &sensor, register).map_err(i2c_err)?;
                if found != expected {
                    return Err(CameraError::WrongChipId { sensor: id, register, expected, found });
                }
            }
            let (reg, value) = sensor.reset;
            sensor_write(&mut self.i2c, &sensor, reg, value).map_err(i2c_err)?;
            self.delay.delay_us(sensor.reset_delay_us);
            for &(reg, value) in sensor.init {
                sensor_write(&mut self.i2c, &sensor, reg, value).map_err(i2c_err)?;
            }
            let spi = &mut self.port(id).spi;
            let spi_err = |source| CameraError::Spi { sensor: id, source };
            fifo_write(spi, FIFO_TEST, FIFO_TEST_PATTERN).map_err(spi_err)?;
            let found = fifo_read(spi, FIFO_TEST).map_err(spi_err)?;
            if found != FIFO_TEST_PATTERN {
                return Err(CameraError::SpiLinkCheck { sensor: id, found });
            }
        }
        Ok(())
    }

    /// Frames captured so far.
    pub fn frames(&self) -> u32 {
        self.frames
    }

    /// Gives the buses back.
    pub fn release(self) -> (I2C, FifoPort<SPI, PIN>, FifoPort<SPI, PIN>, D) {
        (self.i2c, self.gray, self.depth, self.delay)
    }

    fn sensor(&self, id: SensorId) -> &SensorConfig {
        match id {
            SensorId::Gray => &self.config.gray,
            SensorId::Depth => &self.config.depth,
        }
    }

    fn port(&mut self, id: SensorId) -> &mut FifoPort<SPI, PIN> {
        match id {
            SensorId::Gray => &mut self.gray,
            SensorId::Depth => &mut self.depth,
        }
    }

    /// Waits for `id`'s frame-ready line, polling every `ready_poll_us` up to
    /// `ready_timeout_us`.
    fn wait_ready(&mut self, id: SensorId) -> Result<(), CameraErrorOf<I2C, SPI, PIN>> {
        let (poll_us, timeout_us) = (self.config.ready_poll_us, self.config.ready_timeout_us);
        let mut waited_us = 0u32;
        loop {
            let pin = &mut self.port(id).ready;
            if pin.is_high().map_err(|source| CameraError::Pin { sensor: id, source })? {
                return Ok(());
            }
            if waited_us >= timeout_us {
                return Err(CameraError::FrameReadyTimeout { sensor: id, waited_us });
            }
            self.delay.delay_us(poll_us);
            waited_us = waited_us.saturating_add(poll_us);
        }
    }

    /// Checks that `id`'s FIFO holds at least a whole frame.
    fn check_fifo_len(&mut self, id: SensorId) -> Result<(), CameraErrorOf<I2C, SPI, PIN>> {
        let expected_bytes = self.sensor(id).frame_bytes();
        let spi = &mut self.port(id).spi;
        let fifo_bytes = fifo_len(spi).map_err(|source| CameraError::Spi { sensor: id, source })?;
        if fifo_bytes < expected_bytes {
            return Err(CameraError::ShortFrame { sensor: id, expected_bytes, fifo_bytes });
        }
        Ok(())
    }

    /// Captures one frame into the store (steps 1-4 of the module documentation).
    fn capture(&mut self) -> Result<(), CameraErrorOf<I2C, SPI, PIN>> {
        for id in [SensorId::Gray, SensorId::Depth] {
            let spi = &mut self.port(id).spi;
            fifo_start_capture(spi).map_err(|source| CameraError::Spi { sensor: id, source })?;
        }
        for id in [SensorId::Gray, SensorId::Depth] {
            self.wait_ready(id)?;
            self.check_fifo_len(id)?;
        }
        let width = usize::from(self.config.gray.width);
        let pairs = usize::from(self.config.gray.height) / 2;
        let config_err = |_| CameraError::Config;
        for row in 0..pairs {
            let bytes = self.rows.get_mut(..2 * width).ok_or(CameraError::Config)?;
            fifo_burst_read(&mut self.gray.spi, bytes)
                .map_err(|source| CameraError::Spi { sensor: SensorId::Gray, source })?;
            let (top, bottom) = bytes.split_at(width);
            self.store.put_gray_rows(row, top, bottom).map_err(config_err)?;

            let bytes = self.rows.get_mut(..4 * width).ok_or(CameraError::Config)?;
            fifo_burst_read(&mut self.depth.spi, bytes)
                .map_err(|source| CameraError::Spi { sensor: SensorId::Depth, source })?;
            let samples = self.depth_rows.get_mut(..2 * width).ok_or(CameraError::Config)?;
            decode_depth_le(bytes, samples).map_err(|_| CameraError::Config)?;
            let (top, bottom) = samples.split_at(width);
            self.store.put_depth_rows(row, top, bottom).map_err(config_err)?;
        }
        Ok(())
    }
}

impl<I2C, SPI, PIN, D> FrameSource for RgbdCamera<'_, I2C, SPI, PIN, D>
where
    I2C: I2c,
    SPI: SpiDevice,
    PIN: InputPin,
    D: DelayNs,
{
    type Error = CameraErrorOf<I2C, SPI, PIN>;

    /// Captures and returns the next frame (never `Ok(None)`: a camera does not run out).
    fn next_frame(&mut self) -> Result<Option<RgbdFrame<'_>>, Self::Error> {
        self.capture()?;
        let timestamp_s = f64::from(self.frames) * self.config.frame_period_s;
        self.frames = self.frames.saturating_add(1);
        let frame = self.store.frame(timestamp_s, self.config.depth_scale);
        frame.map(Some).map_err(|_| CameraError::Config)
    }
}
