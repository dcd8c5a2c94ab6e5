//! Reference board (STM32H743 class): the camera driver, the pipeline and the serial link linked
//! into the board's memory map.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod firmware;

/// On the host this binary only explains itself: it is firmware.
#[cfg(not(target_os = "none"))]
fn main() -> std::process::ExitCode {
    eprintln!("ref-board is firmware: build it with --target thumbv7em-none-eabihf");
    std::process::ExitCode::from(2)
}
