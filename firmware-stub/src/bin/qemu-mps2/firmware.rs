//! The firmware proper: entry point, the replay loop, and the fault handlers.

use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m as _;
use cortex_m_rt::{ExceptionFrame, entry, exception};
use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};
use defmt_semihosting as _;
use ferroslam_core::config::capacity::{BOARD_STORE_KEYFRAMES, PLACE_RECORD_BYTES};
use ferroslam_core::frame::TelemetrySink;
use ferroslam_core::geometry::PinholeCamera;
use ferroslam_core::loops::PlaceMemory;
use ferroslam_core::map::FlashStore;
use ferroslam_core::system::SLAM_FRONTEND;
use ferroslam_core::wire::{FaultCode, FaultMessage, Message, PoseFlags};
use ferroslam_firmware::cmsdk_uart::CmsdkUart;
use ferroslam_firmware::flash_region::RegionFlash;
use ferroslam_firmware::pipeline::{FrameOutcome, Pipeline, run_frame};
use ferroslam_firmware::semihost_source::{SemihostFrames, SourceError};
use ferroslam_firmware::semihosting::{SemihostingError, command_line};
use ferroslam_firmware::serial::{SerialError, SerialLink};
use ferroslam_firmware::stack;
use ferroslam_firmware::stream::HalfFrame;
use ferroslam_firmware::systick::{SysTickClock, on_systick_wrap};

/// Bytes of the long-term store: the board's record count of 1 KiB records (512 KiB).
const STORE_BYTES: usize = BOARD_STORE_KEYFRAMES * PLACE_RECORD_BYTES;

/// The long-term store's bytes, in the region standing for the board's flash
/// (memory-qemu-mps2.x): neither RAM nor the load image. Taken once by `main`.
#[unsafe(link_section = ".place_store")]
static mut PLACE_STORE: [u8; STORE_BYTES] = [0xFF; STORE_BYTES];

/// The place memory over the flash region's store.
type BoardPlaces = PlaceMemory<FlashStore<RegionFlash<'static>>>;

/// Instructions per SysTick tick under QEMU `-icount shift=0` (1 GHz virtual instruction clock,
/// 25 MHz SysTick).
const INSTRUCTIONS_PER_TICK: u16 = 40;

/// Why the run failed as a whole (a bad frame is a fault message, not a failure).
#[derive(Debug, defmt::Format)]
enum Failure {
    CommandLine(SemihostingError),
    Usage,
    Camera,
    Source(SourceError),
    Link(SerialError<core::convert::Infallible>),
    StackOverflow,
}

/// Camera and input file from the semihosting command line:
/// `FRAMES fx fy cx cy width height` (intrinsics at the processing resolution, in pixels).
struct Args<'a> {
    frames: &'a str,
    cam: PinholeCamera,
}

fn parse_args(text: &str) -> Result<Args<'_>, Failure> {
    fn next<'t, T: core::str::FromStr>(
        words: &mut impl Iterator<Item = &'t str>,
    ) -> Result<T, Failure> {
        words.next().and_then(|w| w.parse().ok()).ok_or(Failure::Usage)
    }
    // Word 0 is the program (QEMU passes the kernel path).
    let mut words = text.split_whitespace().skip(1);
    let frames = words.next().ok_or(Failure::Usage)?;
    // Rust's f32 parsing is exact: the host prints each value with `Display`, which round-trips.
    let (fx, fy, cx, cy) =
        (next(&mut words)?, next(&mut words)?, next(&mut words)?, next(&mut words)?);
    let (w, h) = (next(&mut words)?, next(&mut words)?);
    let cam = PinholeCamera::new(fx, fy, cx, cy, w, h).map_err(|_| Failure::Camera)?;
    Ok(Args { frames, cam })
}

#[entry]
fn main() -> ! {
    // cortex-m-rt turns these into `&'static mut` references, handed out once, safely. The frame
    // store is all zeros (.bss); the pipeline is copied from its `const` image in flash by the
    // reset handler (.data): neither is ever built on the stack (the pipeline alone is larger
    // than the stack).
    static mut STORE: HalfFrame = HalfFrame::new();
    static mut PIPELINE: Pipeline = Pipeline::new();
    // The place memory (its RAM index is 12 KiB): a static too, attached to the flash region
    // below.
    static mut PLACES: BoardPlaces =
        PlaceMemory::new(FlashStore::new(RegionFlash::empty()), SLAM_FRONTEND.rng_seed);
    stack::paint();
    let (store, pipeline) = (STORE, PIPELINE);
    // SAFETY: `main` runs once and is the only code that names PLACE_STORE, so this is the one
    // reference to it, for the rest of the program.
    let place_store: &'static mut [u8] = unsafe { &mut *core::ptr::addr_of_mut!(PLACE_STORE) };
    defmt::info!(
        "ferroslam qemu-mps2: statics {} B frame store + {} B pipeline",
        core::mem::size_of::<HalfFrame>(),
        core::mem::size_of::<Pipeline>()
    );
    let places = PLACES;
    places.attach(FlashStore::new(RegionFlash::new(place_store)));
    let status = match run(store, pipeline, places) {
        Ok(()) => EXIT_SUCCESS,
        Err(e) => {
            defmt::error!("replay failed: {}", e);
            EXIT_FAILURE
        }
    };
    exit(status)
}

/// Streams every recorded frame through the pipeline and out of UART0, then sends the status.
fn run(
    store: &'static mut HalfFrame,
    pipeline: &'static mut Pipeline,
    places: &mut BoardPlaces,
) -> Result<(), Failure> {
    let mut line = [0u8; 512];
    let args = parse_args(command_line(&mut line).map_err(Failure::CommandLine)?)?;
    defmt::info!("frames: {=str}", args.frames);
    // SAFETY: this is the only code that touches UART0.
    let mut link = SerialLink::new(unsafe { CmsdkUart::uart0() });
    let mut source = match SemihostFrames::open(args.frames, store) {
        Ok(s) => s,
        Err(e) => {
            let fault =
                FaultMessage { frame_index: 0, code: FaultCode::Configuration, detail: e.code() };
            link.send(&Message::Fault(fault)).map_err(Failure::Link)?;
            return Err(Failure::Source(e));
        }
    };
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        return Err(Failure::Usage);
    };
    let mut clock = SysTickClock::<INSTRUCTIONS_PER_TICK>::start(peripherals.SYST);
    loop {
        let outcome = run_frame(
            &mut source,
            pipeline,
            places,
            &args.cam,
            &mut link,
            &mut clock,
            SourceError::code,
        )
        .map_err(Failure::Link)?;
        match outcome {
            FrameOutcome::Processed { pose, cost } => defmt::info!(
                "frame {}: {} inliers, {} matches, tracked {}, keyframe {}; ticks: acquire {}, \
                 front end {}, back end {}, report {}",
                pose.frame_index,
                pose.inliers,
                pose.matches,
                pose.flags.contains(PoseFlags::TRACKED),
                pose.flags.contains(PoseFlags::KEYFRAME),
                cost.acquire_ticks,
                cost.frontend_ticks,
                cost.backend_ticks,
                cost.report_ticks
            ),
            FrameOutcome::Fault(f) => defmt::warn!("frame {}: fault {}", f.frame_index, f),
            FrameOutcome::End => break,
        }
        if stack::overflowed() {
            let fault = FaultMessage {
                frame_index: pipeline.next_index(),
                code: FaultCode::StackOverflow,
                detail: 0,
            };
            link.send(&Message::Fault(fault)).map_err(Failure::Link)?;
            return Err(Failure::StackOverflow);
        }
    }
    let mut status = pipeline.status();
    status.stack_peak_bytes = stack::peak_bytes();
    defmt::info!("status: {}", status);
    link.send(&Message::Status(status)).map_err(Failure::Link)
}

/// Ends the QEMU session with `status`; on a debugger that resumes the core, it waits forever.
fn exit(status: debug::ExitStatus) -> ! {
    debug::exit(status);
    loop {
        cortex_m::asm::wfi();
    }
}

#[exception]
fn SysTick() {
    on_systick_wrap();
}

/// Set by the first panic, so that a panic while logging does not recurse into the logger.
static PANICKING: AtomicBool = AtomicBool::new(false);

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    if !PANICKING.swap(true, Ordering::Relaxed) {
        defmt::error!("panic: {}", defmt::Display2Format(info));
    }
    exit(EXIT_FAILURE)
}

#[defmt::panic_handler]
fn defmt_panic() -> ! {
    exit(EXIT_FAILURE)
}

#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    // No logging here: the fault may have hit inside the logger.
    exit(EXIT_FAILURE)
}
