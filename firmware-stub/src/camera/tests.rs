//! The camera driver against embedded-hal-mock: the exact bus traffic of init and of a frame, and
//! every failure (bus errors, wrong chip, frame-ready timeout, short FIFO).

use std::boxed::Box;
use std::vec;
use std::vec::Vec;

use embedded_hal::spi::{ErrorKind as SpiErrorKind, ErrorType, Operation, SpiDevice};
use embedded_hal_mock::eh1::delay::{CheckedDelay, Transaction as DelayTx};
use embedded_hal_mock::eh1::digital::{Mock as PinMock, State, Transaction as PinTx};
use embedded_hal_mock::eh1::i2c::{Mock as I2cMock, Transaction as I2cTx};
use embedded_hal_mock::eh1::spi::{Mock as SpiMock, Transaction as SpiTx};
use ferroslam_core::frame::FrameSource;
use ferroslam_core::image::{
    GrayView, GrayViewMut, ImageView, ImageViewMut, downsample_depth_2x, downsample_gray_2x,
};

use super::*;

/// A 4x4 gray sensor for frame tests (16 FIFO bytes).
const SMALL_GRAY: SensorConfig = SensorConfig {
    i2c_address: 0x21,
    chip_id: [(0x0A, 0x77), (0x0B, 0x21)],
    reset: (0x12, 0x80),
    reset_delay_us: 1_000,
    init: &[(0x11, 0x01)],
    width: 4,
    height: 4,
    bytes_per_pixel: 1,
};

/// A 4x4 depth sensor (32 FIFO bytes).
const SMALL_DEPTH: SensorConfig = SensorConfig {
    i2c_address: 0x3D,
    chip_id: [(0x00, 0xD1), (0x01, 0x01)],
    reset: (0x10, 0x01),
    reset_delay_us: 5_000,
    init: &[(0x21, 0x01)],
    width: 4,
    height: 4,
    bytes_per_pixel: 2,
};

fn small_config() -> CameraConfig {
    CameraConfig {
        gray: SMALL_GRAY,
        depth: SMALL_DEPTH,
        depth_scale: 1000.0,
        frame_period_s: 0.5,
        ready_poll_us: 10,
        ready_timeout_us: 30,
    }
}

/// One chip-select cycle writing `bytes`.
fn spi_write(bytes: &[u8]) -> Vec<SpiTx<u8>> {
    vec![SpiTx::transaction_start(), SpiTx::write_vec(bytes.to_vec()), SpiTx::transaction_end()]
}

/// One chip-select cycle writing `cmd` then reading `response`.
fn spi_read(cmd: u8, response: &[u8]) -> Vec<SpiTx<u8>> {
    vec![
        SpiTx::transaction_start(),
        SpiTx::write_vec(vec![cmd]),
        SpiTx::read_vec(response.to_vec()),
        SpiTx::transaction_end(),
    ]
}

/// The I2C traffic of initializing `s`.
fn i2c_init(s: &SensorConfig) -> Vec<I2cTx> {
    let a = s.i2c_address;
    let mut t: Vec<I2cTx> =
        s.chip_id.iter().map(|&(r, v)| I2cTx::write_read(a, vec![r], vec![v])).collect();
    t.push(I2cTx::write(a, vec![s.reset.0, s.reset.1]));
    t.extend(s.init.iter().map(|&(r, v)| I2cTx::write(a, vec![r, v])));
    t
}

/// The FIFO traffic of the link check.
fn spi_link_check() -> Vec<SpiTx<u8>> {
    [spi_write(&[0x80, 0x55]), spi_read(0x00, &[0x55])].concat()
}

/// The FIFO traffic of arming a capture and reading a byte count of `len`.
fn spi_arm_and_len(len: u32) -> Vec<SpiTx<u8>> {
    let b = len.to_le_bytes();
    [
        spi_write(&[0x84, 0x01]),
        spi_write(&[0x84, 0x30]),
        spi_write(&[0x84, 0x02]),
        spi_read(0x42, &[b[0]]),
        spi_read(0x43, &[b[1]]),
        spi_read(0x44, &[b[2]]),
    ]
    .concat()
}

/// A test frame: gray ramp and depth with holes and a depth edge, as FIFO bytes.
fn frame_bytes(seed: u8) -> (Vec<u8>, Vec<u16>, Vec<u8>) {
    let gray: Vec<u8> = (0..16u8).map(|i| i.wrapping_mul(17).wrapping_add(seed)).collect();
    let depth: Vec<u16> = (0..16u16)
        .map(|i| if i % 3 == 0 { 0 } else { 1000 + 700 * (i % 4) + u16::from(seed) })
        .collect();
    let depth_le: Vec<u8> = depth.iter().flat_map(|d| d.to_le_bytes()).collect();
    (gray, depth, depth_le)
}

type TestCamera<'b> = RgbdCamera<'b, I2cMock, SpiMock<u8>, PinMock, CheckedDelay>;

struct Rig {
    i2c: I2cMock,
    gray_spi: SpiMock<u8>,
    depth_spi: SpiMock<u8>,
    gray_ready: PinMock,
    depth_ready: PinMock,
    delay: CheckedDelay,
}

impl Rig {
    fn new(
        i2c: &[I2cTx],
        gray_spi: &[SpiTx<u8>],
        depth_spi: &[SpiTx<u8>],
        gray_ready: &[PinTx],
        depth_ready: &[PinTx],
        delay: &[DelayTx],
    ) -> Self {
        Self {
            i2c: I2cMock::new(i2c),
            gray_spi: SpiMock::new(gray_spi),
            depth_spi: SpiMock::new(depth_spi),
            gray_ready: PinMock::new(gray_ready),
            depth_ready: PinMock::new(depth_ready),
            delay: CheckedDelay::new(delay),
        }
    }

    /// A camera over clones of the mocks (they share their expectations with the rig).
    fn camera<'b>(&self, config: CameraConfig, store: &'b mut HalfFrame) -> TestCamera<'b> {
        let gray = FifoPort { spi: self.gray_spi.clone(), ready: self.gray_ready.clone() };
        let depth = FifoPort { spi: self.depth_spi.clone(), ready: self.depth_ready.clone() };
        RgbdCamera::new(self.i2c.clone(), gray, depth, self.delay.clone(), config, store).unwrap()
    }

    /// Asserts every expectation was met.
    fn done(mut self) {
        self.i2c.done();
        self.gray_spi.done();
        self.depth_spi.done();
        self.gray_ready.done();
        self.depth_ready.done();
        self.delay.done();
    }
}

#[test]
fn init_of_the_reference_module_sends_exactly_the_documented_traffic() {
    let i2c = [i2c_init(&GRAY_VGA_Y8), i2c_init(&DEPTH_VGA_Z16)].concat();
    // Spelled out once for the gray sensor, as a reader of the datasheet would check it.
    assert_eq!(
        i2c[..3],
        [
            I2cTx::write_read(0x21, vec![0x0A], vec![0x77]),
            I2cTx::write_read(0x21, vec![0x0B], vec![0x21]),
            I2cTx::write(0x21, vec![0x12, 0x80]),
        ]
    );
    let delays = [DelayTx::delay_us(1_000), DelayTx::delay_us(5_000)];
    let rig = Rig::new(&i2c, &spi_link_check(), &spi_link_check(), &[], &[], &delays);
    let mut store = Box::new(HalfFrame::new());
    let mut cam = rig.camera(CameraConfig::VGA, &mut store);
    cam.init().unwrap();
    drop(cam);
    assert_eq!(store.size(), (320, 240));
    rig.done();
}

#[test]
fn a_frame_is_read_in_row_pair_bursts_and_halved_exactly() {
    let (gray, depth, depth_le) = frame_bytes(3);
    // Gray: armed, ready on the second poll, 16 bytes (a padded count of 18 is fine), two bursts
    // of two 4-pixel rows. Depth: ready at once, exactly 32 bytes, two bursts of 16 bytes.
    let gray_spi =
        [spi_arm_and_len(18), spi_read(0x3C, &gray[..8]), spi_read(0x3C, &gray[8..])].concat();
    let depth_spi =
        [spi_arm_and_len(32), spi_read(0x3C, &depth_le[..16]), spi_read(0x3C, &depth_le[16..])]
            .concat();
    let rig = Rig::new(
        &[],
        &gray_spi,
        &depth_spi,
        &[PinTx::get(State::Low), PinTx::get(State::High)],
        &[PinTx::get(State::High)],
        &[DelayTx::delay_us(10)],
    );
    let mut store = Box::new(HalfFrame::new());
    let mut cam = rig.camera(small_config(), &mut store);
    let frame = cam.next_frame().unwrap().unwrap();

    let mut want_g = [0u8; 4];
    let mut want_d = [0u16; 4];
    let src = GrayView::packed(&gray, 4, 4).unwrap();
    downsample_gray_2x(&src, &mut GrayViewMut::packed(&mut want_g, 2, 2).unwrap()).unwrap();
    let src = ImageView::packed(&depth, 4, 4).unwrap();
    downsample_depth_2x(&src, &mut ImageViewMut::packed(&mut want_d, 2, 2).unwrap()).unwrap();
    // The depth is halved once more (the store keeps it at level 1).
    let mut want_d2 = [0u16; 1];
    let src = ImageView::packed(&want_d, 2, 2).unwrap();
    downsample_depth_2x(&src, &mut ImageViewMut::packed(&mut want_d2, 1, 1).unwrap()).unwrap();
    assert!(frame.gray.rows().flatten().copied().eq(want_g));
    assert_eq!(frame.depth.level(), 1);
    assert!(frame.depth.raw().rows().flatten().copied().eq(want_d2));
    assert_eq!((frame.timestamp_s, frame.depth.depth_scale()), (0.0, 1000.0));
    assert_eq!(cam.frames(), 1);
    drop(cam);
    rig.done();
}

#[test]
fn wrong_chip_and_i2c_errors_stop_init() {
    let rig = Rig::new(
        &[
            I2cTx::write_read(0x21, vec![0x0A], vec![0x77]),
            I2cTx::write_read(0x21, vec![0x0B], vec![0x42]),
        ],
        &[],
        &[],
        &[],
        &[],
        &[],
    );
    let mut store = Box::new(HalfFrame::new());
    let mut cam = rig.camera(small_config(), &mut store);
    let err = cam.init().unwrap_err();
    assert_eq!(
        err,
        CameraError::WrongChipId {
            sensor: SensorId::Gray,
            register: 0x0B,
            expected: 0x21,
            found: 0x42
        }
    );
    assert_eq!(err.code(), 4);
    drop(cam);
    rig.done();

    // The bus error itself comes back, with the sensor it was addressed to.
    use embedded_hal::i2c::{ErrorKind, NoAcknowledgeSource};
    let nack = ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address);
    let mut i2c = i2c_init(&SMALL_GRAY);
    i2c.push(I2cTx::write_read(0x3D, vec![0x00], vec![0]).with_error(nack));
    let rig = Rig::new(&i2c, &spi_link_check(), &[], &[], &[], &[DelayTx::delay_us(1_000)]);
    let mut store = Box::new(HalfFrame::new());
    let mut cam = rig.camera(small_config(), &mut store);
    let err = cam.init().unwrap_err();
    assert_eq!(err, CameraError::I2c { sensor: SensorId::Depth, source: nack });
    assert_eq!(err.code(), 16 + 1);
    drop(cam);
    rig.done();
}

#[test]
fn a_frame_ready_line_that_stays_low_times_out() {
    // Poll 10 us, timeout 30 us: four reads (at 0, 10, 20, 30 us) and three waits, then the error.
    let low: Vec<PinTx> = (0..4).map(|_| PinTx::get(State::Low)).collect();
    let rig = Rig::new(
        &[],
        &spi_arm_and_len(0)[..9],
        &spi_arm_and_len(0)[..9],
        &low,
        &[],
        &[DelayTx::delay_us(10), DelayTx::delay_us(10), DelayTx::delay_us(10)],
    );
    let mut store = Box::new(HalfFrame::new());
    let mut cam = rig.camera(small_config(), &mut store);
    let err = cam.next_frame().map(|_| ()).unwrap_err();
    assert_eq!(err, CameraError::FrameReadyTimeout { sensor: SensorId::Gray, waited_us: 30 });
    drop(cam);
    rig.done();
}

#[test]
fn a_short_fifo_is_an_error_and_nothing_is_read() {
    let rig = Rig::new(
        &[],
        &spi_arm_and_len(16),
        &spi_arm_and_len(31),
        &[PinTx::get(State::High)],
        &[PinTx::get(State::High)],
        &[],
    );
    let mut store = Box::new(HalfFrame::new());
    let mut cam = rig.camera(small_config(), &mut store);
    let err = cam.next_frame().map(|_| ()).unwrap_err();
    assert_eq!(
        err,
        CameraError::ShortFrame { sensor: SensorId::Depth, expected_bytes: 32, fifo_bytes: 31 }
    );
    drop(cam);
    rig.done();
}

#[test]
fn a_pin_error_is_reported_with_its_sensor() {
    use embedded_hal_mock::eh1::MockError;
    let io = MockError::Io(std::io::ErrorKind::BrokenPipe);
    let rig = Rig::new(
        &[],
        &spi_arm_and_len(16),
        &spi_arm_and_len(0)[..9],
        &[PinTx::get(State::High)],
        &[PinTx::get(State::High).with_error(io.clone())],
        &[],
    );
    let mut store = Box::new(HalfFrame::new());
    let mut cam = rig.camera(small_config(), &mut store);
    let err = cam.next_frame().map(|_| ()).unwrap_err();
    assert!(matches!(err, CameraError::Pin { sensor: SensorId::Depth, .. }), "{err:?}");
    drop(cam);
    rig.done();
}

/// An SPI device that fails its `fail_at`-th transaction (0-based) and passes the others to a
/// mock: embedded-hal-mock's SPI mock cannot inject errors.
struct FailingSpi {
    inner: SpiMock<u8>,
    fail_at: usize,
    count: usize,
}

impl ErrorType for FailingSpi {
    type Error = SpiErrorKind;
}

impl SpiDevice for FailingSpi {
    fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), SpiErrorKind> {
        self.count += 1;
        if self.count - 1 == self.fail_at {
            return Err(SpiErrorKind::Overrun);
        }
        self.inner.transaction(ops)
    }
}

#[test]
fn an_spi_error_mid_frame_ends_the_frame_with_the_bus_error() {
    let (gray, _, depth_le) = frame_bytes(0);
    // Transactions per FIFO: 3 arm + 3 length, then bursts. The depth FIFO's first burst
    // (transaction 6) fails after the gray FIFO's first burst went through.
    let mut gray_mock = SpiMock::new(&[spi_arm_and_len(16), spi_read(0x3C, &gray[..8])].concat());
    let mut depth_mock = SpiMock::new(&spi_arm_and_len(32));
    let mut gray_pin = PinMock::new(&[PinTx::get(State::High)]);
    let mut depth_pin = PinMock::new(&[PinTx::get(State::High)]);
    let mut i2c = I2cMock::new(&[]);
    let mut delay = CheckedDelay::new(&[]);
    let mut store = Box::new(HalfFrame::new());
    let mut cam = RgbdCamera::new(
        i2c.clone(),
        FifoPort {
            spi: FailingSpi { inner: gray_mock.clone(), fail_at: usize::MAX, count: 0 },
            ready: gray_pin.clone(),
        },
        FifoPort {
            spi: FailingSpi { inner: depth_mock.clone(), fail_at: 6, count: 0 },
            ready: depth_pin.clone(),
        },
        delay.clone(),
        small_config(),
        &mut store,
    )
    .unwrap();
    let err = cam.next_frame().map(|_| ()).unwrap_err();
    assert_eq!(err, CameraError::Spi { sensor: SensorId::Depth, source: SpiErrorKind::Overrun });
    assert_eq!(err.code(), 16 + 2);
    assert_eq!(depth_le.len(), 32);
    drop(cam);
    gray_mock.done();
    depth_mock.done();
    gray_pin.done();
    depth_pin.done();
    i2c.done();
    delay.done();
}

#[test]
fn unusable_configurations_are_rejected() {
    let rig = Rig::new(&[], &[], &[], &[], &[], &[]);
    let mut store = Box::new(HalfFrame::new());
    let bad = [
        CameraConfig { depth: SensorConfig { width: 6, ..SMALL_DEPTH }, ..small_config() },
        CameraConfig { gray: SensorConfig { bytes_per_pixel: 2, ..SMALL_GRAY }, ..small_config() },
        CameraConfig {
            gray: SensorConfig { width: 1280, ..SMALL_GRAY },
            depth: SensorConfig { width: 1280, ..SMALL_DEPTH },
            ..small_config()
        },
        CameraConfig { ready_poll_us: 0, ..small_config() },
    ];
    for config in bad {
        let gray = FifoPort { spi: rig.gray_spi.clone(), ready: rig.gray_ready.clone() };
        let depth = FifoPort { spi: rig.depth_spi.clone(), ready: rig.depth_ready.clone() };
        let r =
            RgbdCamera::new(rig.i2c.clone(), gray, depth, rig.delay.clone(), config, &mut store);
        assert!(matches!(r, Err(CameraError::Config)), "{config:?}");
    }
    rig.done();
}
