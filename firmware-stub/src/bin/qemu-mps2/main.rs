//! QEMU mps2-an386 (Cortex-M4F): replays recorded RGB-D frames through ferroslam's pipeline
//! within the reference board's RAM and sends every pose out of the emulated UART.
//!
//! Run by `cargo xtask firmware-replay DATASET --max-frames N --out DIR`, which writes the frames,
//! boots this binary, decodes the UART capture and compares every pose with the host's replay bit
//! for bit. By hand (from the workspace root; the runner is `firmware-stub/qemu-run.sh`):
//! `cargo run --release -p ferroslam-firmware --bin qemu-mps2 --target thumbv7em-none-eabihf --
//! FRAMES fx fy cx cy width height`.
//!
//! - Input: FRAMES, a host file of raw frame files back to back (see
//!   `ferroslam_firmware::frame_file`), read through semihosting and streamed two sensor rows at a
//!   time into the QVGA store (`ferroslam_firmware::semihost_source`): the VGA frame is never held.
//!   The camera intrinsics (at the processing resolution) follow on the command line.
//! - Processing: `ferroslam_firmware::pipeline::Pipeline` (the QVGA SLAM facade: front end, then
//!   one back-end step of a fixed quota), in a `static`, one `run_frame` per frame.
//! - Output: `ferroslam_core::wire` frames (pose and cost per frame, the cost in SysTick ticks of
//!   40 instructions for acquire, front end, back-end step and report; faults; a final status) on
//!   CMSDK UART0 (QEMU `-serial file:...`); defmt logs on the semihosting console; exit status 0
//!   or 1 through semihosting.
//! - Memory: `memory-qemu-mps2.x` gives the binary the reference board's 928 KiB of SRAM, so the
//!   link proves the fit on the board; the final status carries the peak stack (painted), and
//!   `cargo xtask budgets` checks statics and stack against the 512 KB budget of
//!   `memory-budget.md`.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod firmware;

/// On the host this binary only explains itself: it is firmware.
#[cfg(not(target_os = "none"))]
fn main() -> std::process::ExitCode {
    eprintln!("qemu-mps2 is firmware: build it with --target thumbv7em-none-eabihf");
    std::process::ExitCode::from(2)
}
