//! The register protocol of the camera module: sensor registers over I2C, the frame FIFO over SPI
//! (see the [module documentation](super) for the whole sequence).

use embedded_hal::i2c::I2c;
use embedded_hal::spi::{Operation, SpiDevice};

/// FIFO register: scratch register, written and read back to check the SPI link.
pub const FIFO_TEST: u8 = 0x00;
/// FIFO register: capture control (write-only command bits, see `FIFO_CTRL_*`).
pub const FIFO_CONTROL: u8 = 0x04;
/// `FIFO_CONTROL` bit: clear the capture-done flag (and release the frame-ready line).
pub const FIFO_CTRL_CLEAR_DONE: u8 = 1 << 0;
/// `FIFO_CONTROL` bit: capture the next whole frame from the sensor into the FIFO.
pub const FIFO_CTRL_START: u8 = 1 << 1;
/// `FIFO_CONTROL` bit: reset the FIFO write pointer.
pub const FIFO_CTRL_RESET_WRITE: u8 = 1 << 4;
/// `FIFO_CONTROL` bit: reset the FIFO read pointer.
pub const FIFO_CTRL_RESET_READ: u8 = 1 << 5;
/// FIFO register: bits 7:0 of the byte count of the captured frame.
pub const FIFO_SIZE_0: u8 = 0x42;
/// FIFO register: bits 15:8 of the byte count.
pub const FIFO_SIZE_1: u8 = 0x43;
/// FIFO register: bits 22:16 of the byte count (bit 7 reads 0).
pub const FIFO_SIZE_2: u8 = 0x44;
/// FIFO command: burst read; every byte clocked in after it is the next FIFO byte.
pub const FIFO_BURST_READ: u8 = 0x3C;
/// Set in the address byte of a register write.
pub const FIFO_WRITE_FLAG: u8 = 0x80;
/// What the link check writes to [`FIFO_TEST`].
pub const FIFO_TEST_PATTERN: u8 = 0x55;

/// One image sensor of the module: its I2C identity, initialization and frame format.
///
/// The register values of the tables below are this project's configuration for the sensor class
/// named, written against its register map; check them against the datasheet of the exact part
/// fitted before trusting the image format on hardware.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SensorConfig {
    /// 7-bit I2C address.
    pub i2c_address: u8,
    /// Identity registers and the values they must read: `(register, value)`.
    pub chip_id: [(u8, u8); 2],
    /// Soft-reset `(register, value)`: written first, then [`SensorConfig::reset_delay_us`].
    pub reset: (u8, u8),
    /// Wait after the soft reset, microseconds.
    pub reset_delay_us: u32,
    /// `(register, value)` writes after the reset, in order.
    pub init: &'static [(u8, u8)],
    /// Frame width, pixels.
    pub width: u16,
    /// Frame height, pixels.
    pub height: u16,
    /// Bytes per pixel in the FIFO (1: 8-bit gray; 2: 16-bit depth, little-endian).
    pub bytes_per_pixel: u8,
}

impl SensorConfig {
    /// Bytes of one sensor row in the FIFO.
    pub const fn row_bytes(&self) -> usize {
        self.width as usize * self.bytes_per_pixel as usize
    }

    /// Bytes of one whole frame in the FIFO.
    pub const fn frame_bytes(&self) -> u32 {
        self.width as u32 * self.height as u32 * self.bytes_per_pixel as u32
    }
}

/// The gray camera: an OV7725-class VGA sensor (I2C address 0x21, product id 0x77 0x21 at
/// registers 0x0A/0x0B, soft reset by COM7 (0x12) = 0x80) set to VGA, luminance only (Y8), one
/// byte per pixel, 30 frames per second. The identity and reset follow the OV7725 register map;
/// the init values are this project's, unverified on hardware.
pub const GRAY_VGA_Y8: SensorConfig = SensorConfig {
    i2c_address: 0x21,
    chip_id: [(0x0A, 0x77), (0x0B, 0x21)],
    reset: (0x12, 0x80),
    reset_delay_us: 1_000,
    init: &[
        // Project configuration, to be checked against the fitted part's datasheet: VGA YUV
        // output with luminance first (the bridge keeps the Y bytes: one byte per pixel), clock
        // prescaler for 30 fps, automatic gain/white balance/exposure, PLL.
        (0x12, 0x00), // COM7
        (0x0C, 0x10), // COM3
        (0x11, 0x01), // CLKRC
        (0x13, 0xFF), // COM8
        (0x0D, 0x41), // COM4
    ],
    width: 640,
    height: 480,
    bytes_per_pixel: 1,
};

/// The depth camera: a VGA depth sensor on the same kind of bridge (I2C address 0x3D, identity
/// 0xD1 0x01 at registers 0x00/0x01, soft reset by register 0x10 = 0x01), set to 16-bit depth in
/// millimetres (0 = no reading), little-endian, 30 frames per second, registered to the gray
/// camera.
pub const DEPTH_VGA_Z16: SensorConfig = SensorConfig {
    i2c_address: 0x3D,
    chip_id: [(0x00, 0xD1), (0x01, 0x01)],
    reset: (0x10, 0x01),
    reset_delay_us: 5_000,
    init: &[
        (0x20, 0x00), // mode: VGA
        (0x21, 0x01), // output: Z16, millimetres
        (0x22, 0x1E), // frame rate: 30 fps
        (0x23, 0x01), // registration to the colour camera: on
        (0x11, 0x01), // streaming: on
    ],
    width: 640,
    height: 480,
    bytes_per_pixel: 2,
};

/// Raw depth units per metre of [`DEPTH_VGA_Z16`] (millimetres).
pub const DEPTH_UNITS_PER_M: f32 = 1000.0;

/// Reads sensor register `reg` (write the address, repeated start, read one byte).
pub fn sensor_read<I: I2c>(i2c: &mut I, sensor: &SensorConfig, reg: u8) -> Result<u8, I::Error> {
    let mut value = [0u8];
    i2c.write_read(sensor.i2c_address, &[reg], &mut value)?;
    Ok(value[0])
}

/// Writes sensor register `reg`.
pub fn sensor_write<I: I2c>(
    i2c: &mut I,
    sensor: &SensorConfig,
    reg: u8,
    value: u8,
) -> Result<(), I::Error> {
    i2c.write(sensor.i2c_address, &[reg, value])
}

/// Writes FIFO register `reg`: one chip-select cycle of `[reg | 0x80, value]`.
pub fn fifo_write<S: SpiDevice>(spi: &mut S, reg: u8, value: u8) -> Result<(), S::Error> {
    spi.write(&[reg | FIFO_WRITE_FLAG, value])
}

/// Reads FIFO register `reg`: one chip-select cycle of `[reg & 0x7F]` out, one byte in.
pub fn fifo_read<S: SpiDevice>(spi: &mut S, reg: u8) -> Result<u8, S::Error> {
    let mut value = [0u8];
    spi.transaction(&mut [
        Operation::Write(&[reg & !FIFO_WRITE_FLAG]),
        Operation::Read(&mut value),
    ])?;
    Ok(value[0])
}

/// The byte count of the captured frame (three register reads, low byte first).
pub fn fifo_len<S: SpiDevice>(spi: &mut S) -> Result<u32, S::Error> {
    let b0 = fifo_read(spi, FIFO_SIZE_0)?;
    let b1 = fifo_read(spi, FIFO_SIZE_1)?;
    let b2 = fifo_read(spi, FIFO_SIZE_2)? & 0x7F;
    Ok(u32::from_le_bytes([b0, b1, b2, 0]))
}

/// Arms a capture: clear the done flag, reset both FIFO pointers, start.
pub fn fifo_start_capture<S: SpiDevice>(spi: &mut S) -> Result<(), S::Error> {
    fifo_write(spi, FIFO_CONTROL, FIFO_CTRL_CLEAR_DONE)?;
    fifo_write(spi, FIFO_CONTROL, FIFO_CTRL_RESET_WRITE | FIFO_CTRL_RESET_READ)?;
    fifo_write(spi, FIFO_CONTROL, FIFO_CTRL_START)
}

/// Reads the next `buf.len()` FIFO bytes in one burst (one chip-select cycle: the command, then
/// the data; the read pointer carries over to the next burst).
pub fn fifo_burst_read<S: SpiDevice>(spi: &mut S, buf: &mut [u8]) -> Result<(), S::Error> {
    spi.transaction(&mut [Operation::Write(&[FIFO_BURST_READ]), Operation::Read(buf)])
}
