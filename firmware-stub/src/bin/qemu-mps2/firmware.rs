//! The firmware proper: entry point, frame reading, the W(I) check, and the fault handlers.

use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m as _;
use cortex_m::peripheral::{SYST, syst::SystClkSource};
use cortex_m_rt::{ExceptionFrame, entry, exception};
use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};
use defmt_semihosting as _;
use ferroslam_core::image::{GrayView, ImageError, ImageView};
use ferroslam_firmware::frame_file::{FrameFileError, FrameHeader, HEADER_LEN, decode_depth_le};
use ferroslam_firmware::semihosting::{HostFile, Mode, SemihostingError, command_line};
use ferroslam_firmware::wi::{self, WiReport};

/// Largest frame the static buffers hold: VGA.
const MAX_PIXELS: usize = 640 * 480;
/// Half-resolution buffers: `(w / 2) * (h / 2) <= MAX_PIXELS / 4`.
const MAX_HALF_PIXELS: usize = MAX_PIXELS / 4;
/// Frame file read when the command line names none.
const DEFAULT_FRAME: &str = "frame.fsrf";
/// Result file written when the command line names none.
const DEFAULT_RESULT: &str = "wi-result.txt";
/// Depth bytes read per SYS_READ (on the stack).
const DEPTH_CHUNK_BYTES: usize = 4096;

/// Why the check failed.
#[derive(Debug, defmt::Format)]
enum Failure {
    Semihosting(SemihostingError),
    Frame(FrameFileError),
    Image(ImageError),
    FrameTooLarge { width: u32, height: u32 },
    ResultTooLong,
}

impl From<SemihostingError> for Failure {
    fn from(e: SemihostingError) -> Self {
        Self::Semihosting(e)
    }
}
impl From<FrameFileError> for Failure {
    fn from(e: FrameFileError) -> Self {
        Self::Frame(e)
    }
}
impl From<ImageError> for Failure {
    fn from(e: ImageError) -> Self {
        Self::Image(e)
    }
}

/// The frame and scratch buffers, statics handed out once by `main`.
struct Buffers {
    gray: &'static mut [u8; MAX_PIXELS],
    depth: &'static mut [u16; MAX_PIXELS],
    half_gray: &'static mut [u8; MAX_HALF_PIXELS],
    half_depth: &'static mut [u16; MAX_HALF_PIXELS],
}

#[entry]
fn main() -> ! {
    // cortex-m-rt turns these into `&'static mut` references, handed out once, safely; being
    // zero-initialized they live in .bss, not in the image.
    static mut GRAY: [u8; MAX_PIXELS] = [0; MAX_PIXELS];
    static mut DEPTH: [u16; MAX_PIXELS] = [0; MAX_PIXELS];
    static mut HALF_GRAY: [u8; MAX_HALF_PIXELS] = [0; MAX_HALF_PIXELS];
    static mut HALF_DEPTH: [u16; MAX_HALF_PIXELS] = [0; MAX_HALF_PIXELS];
    let buffers =
        Buffers { gray: GRAY, depth: DEPTH, half_gray: HALF_GRAY, half_depth: HALF_DEPTH };

    defmt::info!("ferroslam qemu-mps2: W(I) check, buffers for up to {} pixels", MAX_PIXELS);
    let status = match run(buffers) {
        Ok(()) => EXIT_SUCCESS,
        Err(e) => {
            defmt::error!("W(I) check failed: {}", e);
            EXIT_FAILURE
        }
    };
    exit(status)
}

/// Reads the frame named on the command line, runs the check, writes the result file.
fn run(buffers: Buffers) -> Result<(), Failure> {
    let mut line = [0u8; 512];
    let (frame_path, result_path) = match command_line(&mut line) {
        Ok(text) => {
            // Word 0 is the program (QEMU passes the kernel path); then FRAME and RESULT.
            let mut words = text.split_whitespace().skip(1);
            (words.next().unwrap_or(DEFAULT_FRAME), words.next().unwrap_or(DEFAULT_RESULT))
        }
        Err(e) => {
            defmt::warn!("no command line ({}), using the default file names", e);
            (DEFAULT_FRAME, DEFAULT_RESULT)
        }
    };
    defmt::info!("frame file: {=str}, result file: {=str}", frame_path, result_path);

    let Buffers { gray, depth, half_gray, half_depth } = buffers;
    let header = read_frame(frame_path, gray, depth)?;
    defmt::info!(
        "frame {}x{}, t = {} s, depth scale {} units/m",
        header.width,
        header.height,
        header.timestamp_s,
        header.depth_scale
    );
    let n = header.pixels()?;
    let (w, h) = (header.width as usize, header.height as usize);
    let gray_view = GrayView::packed(gray.get(..n).unwrap_or_default(), w, h)?;
    let depth_view = ImageView::packed(depth.get(..n).unwrap_or_default(), w, h)?;

    let start = systick_start();
    let report = wi::compute(&gray_view, &depth_view, half_gray, half_depth)?;
    let ticks = systick_elapsed(start);
    log_report(&report, ticks);
    write_result(result_path, &report)
}

/// Reads a whole frame file into the static buffers, returning its header.
fn read_frame(
    path: &str,
    gray: &mut [u8; MAX_PIXELS],
    depth: &mut [u16; MAX_PIXELS],
) -> Result<FrameHeader, Failure> {
    let mut file = HostFile::open(path, Mode::Read)?;
    let file_len = file.len()?;
    let mut head = [0u8; HEADER_LEN];
    file.read_exact(&mut head)?;
    let header = FrameHeader::decode(&head)?;
    let n = header.pixels()?;
    if n > MAX_PIXELS {
        return Err(Failure::FrameTooLarge { width: header.width, height: header.height });
    }
    let expected = header.file_len()?;
    if file_len != expected {
        return Err(FrameFileError::LengthMismatch { expected, got: file_len }.into());
    }
    file.read_exact(gray.get_mut(..n).unwrap_or_default())?;
    // Depth arrives as little-endian bytes: read a chunk at a time and decode it in place, so
    // the u16 buffer is filled without reinterpreting memory and without a second full buffer.
    let mut chunk = [0u8; DEPTH_CHUNK_BYTES];
    for samples in depth.get_mut(..n).unwrap_or_default().chunks_mut(DEPTH_CHUNK_BYTES / 2) {
        let bytes = chunk.get_mut(..2 * samples.len()).unwrap_or_default();
        file.read_exact(bytes)?;
        decode_depth_le(bytes, samples)?;
    }
    Ok(header)
}

/// Logs the result; `ticks` are SysTick counts of the computation (with QEMU `-icount shift=0`,
/// one tick per 40 emulated instructions on this board's 25 MHz clock; wall-clock otherwise).
fn log_report(report: &WiReport, ticks: u32) {
    defmt::info!(
        "W(I): vga = {=u64}, qvga = {=u64}, qvga depth FNV-1a = {=u64:#x}",
        report.wi_vga,
        report.wi_qvga,
        report.depth_qvga_fnv1a
    );
    defmt::info!("compute: {=u32} SysTick ticks", ticks);
}

/// Writes the result line (and a newline) to `path`.
fn write_result(path: &str, report: &WiReport) -> Result<(), Failure> {
    let mut buf = [0u8; 160];
    let text = wi::format_into(&mut buf, report).ok_or(Failure::ResultTooLong)?;
    let mut file = HostFile::open(path, Mode::WriteTruncate)?;
    file.write_all(text.as_bytes())?;
    file.write_all(b"\n")?;
    defmt::info!("result written to {=str}", path);
    Ok(())
}

/// Starts SysTick free-running from its maximum (24-bit) reload on the core clock.
fn systick_start() -> u32 {
    // Taking the peripherals twice is impossible; a second call just measures nothing.
    let Some(mut p) = cortex_m::Peripherals::take() else {
        return 0;
    };
    p.SYST.set_clock_source(SystClkSource::Core);
    p.SYST.set_reload(0x00ff_ffff);
    p.SYST.clear_current();
    p.SYST.enable_counter();
    SYST::get_current()
}

/// SysTick ticks since `start` (the counter counts down; modulo 2^24, so spans up to 16.7 M).
fn systick_elapsed(start: u32) -> u32 {
    start.wrapping_sub(SYST::get_current()) & 0x00ff_ffff
}

/// Ends the QEMU session with `status`; on a debugger that resumes the core, it waits forever.
fn exit(status: debug::ExitStatus) -> ! {
    debug::exit(status);
    loop {
        cortex_m::asm::wfi();
    }
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
