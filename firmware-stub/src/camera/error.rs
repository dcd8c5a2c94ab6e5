//! Why the camera could not be set up or could not give a frame.

use core::fmt;

/// Which sensor of the module.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum SensorId {
    /// The gray (intensity) sensor.
    Gray,
    /// The depth sensor.
    Depth,
}

impl fmt::Display for SensorId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Gray => "gray sensor",
            Self::Depth => "depth sensor",
        })
    }
}

/// A camera error, carrying the buses' own errors (`I2cE`, `SpiE`, `PinE`: the `Error` types of
/// the embedded-hal implementations the camera runs on).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum CameraError<I2cE, SpiE, PinE> {
    /// The I2C bus failed talking to a sensor.
    I2c {
        /// The sensor addressed.
        sensor: SensorId,
        /// The bus error.
        source: I2cE,
    },
    /// The SPI bus failed talking to a sensor's FIFO.
    Spi {
        /// The FIFO's sensor.
        sensor: SensorId,
        /// The bus error.
        source: SpiE,
    },
    /// A frame-ready line could not be read.
    Pin {
        /// The line's sensor.
        sensor: SensorId,
        /// The pin error.
        source: PinE,
    },
    /// An identity register read a value other than the sensor's.
    WrongChipId {
        /// The sensor addressed.
        sensor: SensorId,
        /// The identity register.
        register: u8,
        /// The value the sensor must read.
        expected: u8,
        /// The value read.
        found: u8,
    },
    /// The FIFO's scratch register did not read back the test pattern (SPI wiring or mode).
    SpiLinkCheck {
        /// The FIFO's sensor.
        sensor: SensorId,
        /// The value read back.
        found: u8,
    },
    /// A frame-ready line stayed low for the whole timeout.
    FrameReadyTimeout {
        /// The line's sensor.
        sensor: SensorId,
        /// How long the driver waited, microseconds.
        waited_us: u32,
    },
    /// A FIFO holds fewer bytes than a frame.
    ShortFrame {
        /// The FIFO's sensor.
        sensor: SensorId,
        /// Bytes of a whole frame.
        expected_bytes: u32,
        /// Bytes the FIFO reported.
        fifo_bytes: u32,
    },
    /// The configuration is unusable (sensor sizes differ or exceed VGA, unknown pixel formats).
    Config,
}

impl<I2cE: fmt::Debug, SpiE: fmt::Debug, PinE: fmt::Debug> fmt::Display
    for CameraError<I2cE, SpiE, PinE>
{
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::I2c { sensor, source } => write!(f, "I2C error on the {sensor}: {source:?}"),
            Self::Spi { sensor, source } => {
                write!(f, "SPI error on the {sensor}'s FIFO: {source:?}")
            }
            Self::Pin { sensor, source } => {
                write!(f, "the {sensor}'s frame-ready line cannot be read: {source:?}")
            }
            Self::WrongChipId { sensor, register, expected, found } => write!(
                f,
                "{sensor}: identity register {register:#04x} reads {found:#04x}, expected \
                 {expected:#04x}"
            ),
            Self::SpiLinkCheck { sensor, found } => {
                write!(f, "{sensor}'s FIFO: test register reads {found:#04x}, expected 0x55")
            }
            Self::FrameReadyTimeout { sensor, waited_us } => {
                write!(f, "{sensor}: no frame after {waited_us} us")
            }
            Self::ShortFrame { sensor, expected_bytes, fifo_bytes } => {
                write!(f, "{sensor}: FIFO holds {fifo_bytes} bytes, a frame is {expected_bytes}")
            }
            Self::Config => write!(f, "unusable camera configuration"),
        }
    }
}

impl<I2cE: fmt::Debug, SpiE: fmt::Debug, PinE: fmt::Debug> core::error::Error
    for CameraError<I2cE, SpiE, PinE>
{
}

impl<I2cE, SpiE, PinE> CameraError<I2cE, SpiE, PinE> {
    /// A small number naming the variant, for a [`FaultMessage`](ferroslam_core::wire::FaultMessage)
    /// detail (bus errors have no portable code): 1 I2C, 2 SPI, 3 pin, 4 chip id, 5 link check,
    /// 6 timeout, 7 short frame, 8 configuration; plus 16 for the depth sensor.
    pub fn code(&self) -> u32 {
        let (code, sensor) = match self {
            Self::I2c { sensor, .. } => (1, Some(*sensor)),
            Self::Spi { sensor, .. } => (2, Some(*sensor)),
            Self::Pin { sensor, .. } => (3, Some(*sensor)),
            Self::WrongChipId { sensor, .. } => (4, Some(*sensor)),
            Self::SpiLinkCheck { sensor, .. } => (5, Some(*sensor)),
            Self::FrameReadyTimeout { sensor, .. } => (6, Some(*sensor)),
            Self::ShortFrame { sensor, .. } => (7, Some(*sensor)),
            Self::Config => (8, None),
        };
        code + if sensor == Some(SensorId::Depth) { 16 } else { 0 }
    }
}
