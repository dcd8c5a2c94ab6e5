//! The firmware proper: entry point, the replay loop, and the fault handlers.

use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m as _;
use cortex_m_rt::{ExceptionFrame, entry, exception};
use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};
use defmt_semihosting as _;
use ferroslam_core::config::capacity::BOARD_STORE_FLASH_BYTES;
use ferroslam_core::frame::TelemetrySink;
use ferroslam_core::geometry::PinholeCamera;
use ferroslam_core::loops::PlaceMemory;
use ferroslam_core::persist::{FlashStore, FlashStoreError, SliceFlash};
use ferroslam_core::system::SLAM_FRONTEND;
use ferroslam_core::wire::{FaultCode, FaultMessage, Message, PoseFlags};
use ferroslam_firmware::cmsdk_uart::CmsdkUart;
use ferroslam_firmware::commands::{Arrived, LinkCommands};
use ferroslam_firmware::pipeline::{FrameOutcome, Link, Pipeline, TickClock, run_frame};
use ferroslam_firmware::semihost_source::{SemihostFrames, SourceError};
use ferroslam_firmware::semihosting::{HostFile, Mode, SemihostingError, command_line};
use ferroslam_firmware::serial::{SerialError, SerialLink};
use ferroslam_firmware::stack;
use ferroslam_firmware::stream::HalfFrame;
use ferroslam_firmware::systick::{SysTickClock, on_systick_wrap};

unsafe extern "C" {
    /// The first byte of the region standing for the board's flash (memory-qemu-mps2.x): neither
    /// RAM nor the load image, so a boot finds what QEMU put there (a flash image given with
    /// `-device loader`, or zeros: a blank store).
    static mut __place_store_start: u8;
    /// The byte after the region.
    static mut __place_store_end: u8;
}

/// The place memory over the flash region's store.
type BoardPlaces = PlaceMemory<FlashStore<SliceFlash<'static>>>;

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
    Store(FlashStoreError),
    SaveFile(SemihostingError),
    Commands(SemihostingError),
}

/// Camera and input file from the semihosting command line:
/// `FRAMES fx fy cx cy width height [localize] [save=FILE] [commands=FILE]` (intrinsics at the
/// processing resolution, in pixels). `localize`: the map in the flash store is only localized
/// in (nothing is added to it). `save=FILE`: at the end the active map's keyframes are
/// remembered and the store committed (a save), then the flash region's bytes are written to the
/// host file FILE (a flash image a later boot is given). `commands=FILE`: the serial link's
/// received bytes, anchor commands the host sent (wire frames, each naming its frame): this
/// board's receive side.
struct Args<'a> {
    frames: &'a str,
    cam: PinholeCamera,
    localize: bool,
    save: Option<&'a str>,
    commands: Option<&'a str>,
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
    let (mut localize, mut save, mut commands) = (false, None, None);
    for word in words {
        if word == "localize" {
            localize = true;
        } else if let Some(path) = word.strip_prefix("save=") {
            save = Some(path);
        } else {
            commands = Some(word.strip_prefix("commands=").ok_or(Failure::Usage)?);
        }
    }
    Ok(Args { frames, cam, localize, save, commands })
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
        PlaceMemory::new(FlashStore::unmounted(SliceFlash::empty()), SLAM_FRONTEND.rng_seed);
    stack::paint();
    let (store, pipeline) = (STORE, PIPELINE);
    let start = core::ptr::addr_of_mut!(__place_store_start);
    let region =
        (core::ptr::addr_of_mut!(__place_store_end) as usize).saturating_sub(start as usize);
    // SAFETY: the linker script reserves the region for the store alone (nothing is linked
    // there) and it is at least BOARD_STORE_FLASH_BYTES long (checked); `main` runs once and is
    // the only code that names it, so this is the one reference to it.
    let place_store: &'static mut [u8] = if region >= BOARD_STORE_FLASH_BYTES {
        unsafe { core::slice::from_raw_parts_mut(start, BOARD_STORE_FLASH_BYTES) }
    } else {
        &mut []
    };
    defmt::info!(
        "ferroslam qemu-mps2: statics {} B frame store + {} B pipeline",
        core::mem::size_of::<HalfFrame>(),
        core::mem::size_of::<Pipeline>()
    );
    let places = PLACES;
    let Some(peripherals) = cortex_m::Peripherals::take() else { exit(EXIT_FAILURE) };
    let mut clock = SysTickClock::<INSTRUCTIONS_PER_TICK>::start(peripherals.SYST);
    let status = mount(places, pipeline, place_store, &mut clock)
        .and_then(|()| run(store, pipeline, places, &mut clock));
    let status = match status {
        Ok(()) => EXIT_SUCCESS,
        Err(e) => {
            defmt::error!("replay failed: {}", e);
            EXIT_FAILURE
        }
    };
    exit(status)
}

/// Mounts the flash region's store and attaches the place memory to it: the last committed map,
/// if the region holds one, is what the run starts in, its planes and anchors given to
/// `pipeline` (saved ones that do not decode are left out, with a warning). Out of line: the
/// store's mount works on the stack (the table and bitmaps, 1.4 KB) only here, not under the
/// frame loop.
#[inline(never)]
fn mount(
    places: &mut BoardPlaces,
    pipeline: &mut Pipeline,
    place_store: &'static mut [u8],
    clock: &mut SysTickClock<INSTRUCTIONS_PER_TICK>,
) -> Result<(), Failure> {
    let before = clock.now();
    let flash = FlashStore::mount(SliceFlash::new(place_store)).map_err(Failure::Store)?;
    places.attach(flash);
    match pipeline.restore_world(places) {
        Ok(Some((planes, anchors))) => {
            defmt::info!("saved world: {} planes, {} anchors", planes, anchors);
        }
        Ok(None) => {}
        Err(e) => defmt::warn!("saved planes and anchors left out: {}", e),
    }
    let ticks = clock.now().wrapping_sub(before);
    defmt::info!(
        "place store: {} keyframes held (table generation {}), mounted and indexed in {} \
         instructions",
        places.len(),
        places.store().generation(),
        u64::from(ticks) * u64::from(INSTRUCTIONS_PER_TICK)
    );
    Ok(())
}

/// Streams every recorded frame through the pipeline and out of UART0, then sends the status.
fn run(
    store: &'static mut HalfFrame,
    pipeline: &'static mut Pipeline,
    places: &mut BoardPlaces,
    clock: &mut SysTickClock<INSTRUCTIONS_PER_TICK>,
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
    places.freeze(args.localize);
    let mut received = match args.commands {
        Some(path) => {
            let file = HostFile::open(path, Mode::Read).map_err(Failure::Commands)?;
            defmt::info!("anchor commands: {=str}", path);
            Some(LinkCommands::new(Arrived(file)))
        }
        None => None,
    };
    loop {
        let link_sides = Link { tx: &mut link, rx: &mut received };
        let outcome = run_frame(
            &mut source,
            pipeline,
            places,
            &args.cam,
            link_sides,
            clock,
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
    let planes = pipeline.slam().planes();
    defmt::info!(
        "planes: {} kept of {} detections, {} dropped, fingerprint {=u32}",
        planes.map().planes().len(),
        planes.detections(),
        planes.map().dropped(),
        planes.fingerprint()
    );
    let anchors = pipeline.slam().anchors();
    defmt::info!("anchors: {} placed, fingerprint {=u32}", anchors.len(), anchors.fingerprint());
    link.send(&Message::Status(status)).map_err(Failure::Link)?;
    if let Some(path) = args.save {
        save(pipeline, places, &args.cam, path)?;
    }
    Ok(())
}

/// Saves the map: the back end's work finished, the active map's keyframes remembered (unless
/// localizing), the store committed, then the flash region's bytes written to the host file
/// `path`.
fn save(
    pipeline: &mut Pipeline,
    places: &mut BoardPlaces,
    cam: &PinholeCamera,
    path: &str,
) -> Result<(), Failure> {
    pipeline.remember_map_in(cam, places);
    pipeline.commit(places).map_err(Failure::Store)?;
    defmt::info!(
        "map saved: {} keyframes, table generation {}; flash image to {=str}",
        places.len(),
        places.store().generation(),
        path
    );
    let mut file = HostFile::open(path, Mode::WriteTruncate).map_err(Failure::SaveFile)?;
    file.write_all(places.store().flash().bytes()).map_err(Failure::SaveFile)
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
