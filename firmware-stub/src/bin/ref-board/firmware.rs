//! The reference board's firmware: statics in the H7's memory regions, the camera on SPI1/I2C1,
//! the serial link on USART1, the pipeline in between, and the place memory in flash bank 2
//! (the long-term store in sector mode), committed every [`COMMIT_EVERY_FRAMES`] frames.

use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m as _;
use cortex_m_rt::{ExceptionFrame, entry, exception};
use ferroslam_core::frame::TelemetrySink;
use ferroslam_core::geometry::PinholeCamera;
use ferroslam_core::loops::PlaceMemory;
use ferroslam_core::persist::FlashStore;
use ferroslam_core::system::SLAM_FRONTEND;
use ferroslam_core::wire::{FaultCode, FaultMessage, Message};
use ferroslam_firmware::camera::{CameraConfig, CameraError, FifoPort, RgbdCamera};
use ferroslam_firmware::commands::LinkCommands;
use ferroslam_firmware::pipeline::{FrameOutcome, Link, Pipeline, run_frame};
use ferroslam_firmware::rx_ring::RxRing;
use ferroslam_firmware::serial::SerialLink;
use ferroslam_firmware::stream::HalfFrame;

use crate::h7::{BusyDelay, CycleClock, I2cBus, Pin, RX_RING_BYTES, SpiDev, UsartRxDma, UsartTx};
use crate::h7_flash::Bank2Flash;

/// Frames between two commits of the place memory (about 10 s at 30 frames a second): a power cut
/// loses at most the places remembered since the last one. A commit writes one table (1 KiB) when
/// records changed, the world's two units (2 KiB) when its planes or anchors changed, nothing
/// otherwise.
const COMMIT_EVERY_FRAMES: u32 = 300;

/// The place memory on flash bank 2 (1 MiB: 500 keyframes, the place memory's index).
type BoardPlaces = PlaceMemory<FlashStore<Bank2Flash>>;

/// Fault detail of a place store that cannot be mounted (`STOR`).
const STORE_FAULT: u32 = u32::from_be_bytes(*b"STOR");

/// Camera intrinsics at the processing resolution (QVGA), pixels: the module's nominal values
/// (585 px focal length at VGA, halved), a placeholder until the module's calibration is read
/// from its EEPROM or flash.
const INTRINSICS_QVGA: (f32, f32, f32, f32) = (292.5, 292.5, 159.75, 119.75);

/// GPIO port numbers (0 = A).
const PORT_A: usize = 0;
const PORT_C: usize = 2;

/// The frame store, in SRAM1-3 (D2 domain): where a camera DMA would write (DTCM is out of the
/// DMA's reach), and the one region besides AXI SRAM large enough for it.
#[unsafe(link_section = ".sram123")]
static mut STORE: MaybeUninit<HalfFrame> = MaybeUninit::uninit();

/// The pipeline state (front end, map, back end), in AXI SRAM, the largest region (the 128 KiB
/// DTCM holds the stack).
#[unsafe(link_section = ".axisram")]
static mut PIPELINE: MaybeUninit<Pipeline> = MaybeUninit::uninit();

/// The serial link's receive ring, in SRAM1-3: DMA1 writes it (it does not reach DTCM).
#[unsafe(link_section = ".sram123")]
static mut RX_RING: MaybeUninit<[u8; RX_RING_BYTES]> = MaybeUninit::uninit();

/// Whether [`take_statics`] has handed the statics out.
static TAKEN: AtomicBool = AtomicBool::new(false);

/// The pipeline's initial state, in flash: copied into [`PIPELINE`] at start-up. (Writing
/// `Pipeline::new()` into place directly makes the compiler build the value on the stack first,
/// and it is larger than the whole DTCM.)
static PIPELINE_IMAGE: Pipeline = Pipeline::new();

/// The frame store, the pipeline and the receive ring, initialized in place, handed out once
/// (`None` after).
///
/// The sections are `NOLOAD`: cortex-m-rt neither zeroes nor copies them, so they are written
/// here, in place, before any reference to them exists.
#[allow(clippy::type_complexity)]
fn take_statics()
-> Option<(&'static mut HalfFrame, &'static mut Pipeline, &'static mut [u8; RX_RING_BYTES])> {
    if TAKEN.swap(true, Ordering::AcqRel) {
        return None;
    }
    // SAFETY: `TAKEN` makes this the only access to the three statics ever. Each is fully
    // written before the `&'static mut` to it is created: the store with zeros, which is exactly
    // `HalfFrame::new()` (integer arrays and an integer size, all 0), the pipeline with a byte
    // copy of a valid `Pipeline` (a plain-data value: no pointers, no drop), the ring with zeros.
    unsafe {
        let store = (&raw mut STORE).cast::<HalfFrame>();
        core::ptr::write_bytes(store, 0, 1);
        let pipeline = (&raw mut PIPELINE).cast::<Pipeline>();
        core::ptr::copy_nonoverlapping(&raw const PIPELINE_IMAGE, pipeline, 1);
        let ring = (&raw mut RX_RING).cast::<[u8; RX_RING_BYTES]>();
        core::ptr::write_bytes(ring, 0, 1);
        Some((&mut *store, &mut *pipeline, &mut *ring))
    }
}

#[entry]
fn main() -> ! {
    // The place memory (its RAM index is 12 KiB), in DTCM: cortex-m-rt hands it out once as a
    // `&'static mut`, copied from its `const` image by the reset handler.
    static mut PLACES: BoardPlaces =
        PlaceMemory::new(FlashStore::unmounted(Bank2Flash::new()), SLAM_FRONTEND.rng_seed);
    let Some((store, pipeline, ring)) = take_statics() else { halt() };
    let Some(core) = cortex_m::Peripherals::take() else { halt() };
    let mut link = SerialLink::new(UsartTx::usart1());
    // Anchor commands: the bytes USART1 receives, in a ring by DMA, read each frame as far as
    // they have arrived (the frame loop never waits for the link).
    let mut received = LinkCommands::new(RxRing::new(UsartRxDma::start(ring)));
    // The last committed map, if bank 2 holds one: the run starts in it.
    let places = PLACES;
    match FlashStore::mount(Bank2Flash::new()) {
        Ok(flash) => places.attach(flash),
        Err(_) => report_and_halt(&mut link, STORE_FAULT),
    }
    // Its planes and anchors: saved ones that do not decode are left out (the records stay).
    let _ = pipeline.restore_world(places);
    // Gray FIFO: SPI1 with chip select PA4, frame-ready on PC0; depth FIFO: SPI1 with chip select
    // PA15, frame-ready on PC1 (the two share the bus type and so the driver's SPI type).
    let gray = FifoPort { spi: SpiDev::spi1(Pin::new(PORT_A, 4)), ready: Pin::new(PORT_C, 0) };
    let depth = FifoPort { spi: SpiDev::spi1(Pin::new(PORT_A, 15)), ready: Pin::new(PORT_C, 1) };
    let camera = RgbdCamera::new(I2cBus::i2c1(), gray, depth, BusyDelay, CameraConfig::VGA, store);
    let mut camera = match camera {
        Ok(c) => c,
        Err(e) => report_and_halt(&mut link, e.code()),
    };
    if let Err(e) = camera.init() {
        report_and_halt(&mut link, e.code());
    }
    let (fx, fy, cx, cy) = INTRINSICS_QVGA;
    let Ok(cam) = PinholeCamera::new(fx, fy, cx, cy, 320, 240) else { halt() };
    let mut clock = CycleClock::start(core.DCB, core.DWT);
    let mut frames: u32 = 0;
    loop {
        let code = |e: &CameraError<_, _, _>| e.code();
        let sides = Link { tx: &mut link, rx: &mut received };
        match run_frame(&mut camera, pipeline, places, &cam, sides, &mut clock, code) {
            Ok(FrameOutcome::Processed { .. } | FrameOutcome::Fault(_)) => {}
            // A camera never ends; a dead link leaves nothing to report to.
            Ok(FrameOutcome::End) | Err(_) => halt(),
        }
        frames = frames.wrapping_add(1);
        if frames.is_multiple_of(COMMIT_EVERY_FRAMES) {
            // The keyframes the map has retired, then the planes and anchors (when they changed),
            // become what a boot finds (keyframes still in the active map are not written, to
            // spare the flash). A failed commit is counted by the place memory
            // (`PlaceStats::store_errors`); the last commit stands.
            let _ = pipeline.commit(places);
        }
    }
}

/// Sends a configuration fault (best effort) and stops.
fn report_and_halt(link: &mut impl TelemetrySink, detail: u32) -> ! {
    let fault = FaultMessage { frame_index: 0, code: FaultCode::Configuration, detail };
    let _ = link.send(&Message::Fault(fault));
    halt()
}

/// Stops the core (a watchdog, once configured, would reset it).
fn halt() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(_info: &core::panic::PanicInfo<'_>) -> ! {
    halt()
}

#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    halt()
}
