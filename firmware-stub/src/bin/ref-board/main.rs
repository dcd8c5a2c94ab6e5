//! Reference board (STM32H743 class): the camera driver, the pipeline and the serial link linked
//! into the board's memory map, with the frame store and pipeline state placed in AXI SRAM and the
//! stack in DTCM, so that the link proves the per-region fit.
//!
//! Build: `cargo build --release -p ferroslam-firmware --bin ref-board --target
//! thumbv7em-none-eabihf`; the memory map is `memory-ref-board.x`. The peripheral layer (`h7`) is a
//! register-level placeholder for a real HAL: it links, it has never run on hardware (see its
//! documentation for what it leaves out). Everything above it (camera driver, pipeline, serial
//! link) is the tested, board-independent library code.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod firmware;
#[cfg(target_os = "none")]
#[allow(unsafe_code)]
mod h7;
#[cfg(target_os = "none")]
#[allow(unsafe_code)]
mod h7_flash;

/// On the host this binary only explains itself: it is firmware.
#[cfg(not(target_os = "none"))]
fn main() -> std::process::ExitCode {
    eprintln!("ref-board is firmware: build it with --target thumbv7em-none-eabihf");
    std::process::ExitCode::from(2)
}
