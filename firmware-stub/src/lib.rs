//! ferroslam-firmware: ferroslam-core on a microcontroller.
//!
//! This library is board-independent and `#![no_std]`, tested on the host
//! (`cargo test -p ferroslam-firmware --lib`); the binaries under `src/bin/` wire it to a board:
//! `qemu-mps2` (QEMU's Cortex-M4F board, recorded frames through semihosting, poses out of the
//! emulated UART) and `ref-board` (the reference board's memory map, camera and UART).
//!
//! - [`camera`]: the RGB-D camera module (gray and depth sensors behind ArduCAM-style SPI frame
//!   FIFOs, configured over I2C, frame-ready lines), generic over embedded-hal 1.0 traits; a
//!   [`FrameSource`](ferroslam_core::frame::FrameSource).
//! - [`stream`]: the board's only frame store, a QVGA pair filled two sensor rows at a time.
//! - [`pipeline`]: the core's processing ([`pipeline::Pipeline`]) and the one step that wires a
//!   frame source, the pipeline and a telemetry sink ([`pipeline::run_frame`]).
//! - [`serial`]: the serial link, a [`TelemetrySink`](ferroslam_core::frame::TelemetrySink) over
//!   `embedded_io::Write` framing messages with postcard + CRC-32 + COBS (`ferroslam_core::wire`).
//! - [`commands`]: the serial link's receive side, anchor commands from the host
//!   ([`commands::LinkCommands`] over any `embedded_io` reader that says what has arrived).
//! - [`rx_ring`]: a UART's received bytes in a ring a DMA stream fills ([`rx_ring::RxRing`]), read
//!   without waiting: the reference board's receive side.
//! - [`faulty_link`]: a fault injector on the serial link (bytes dropped, bits flipped, frames
//!   cut short), wrapping any `embedded_io` writer or reader, for tests.
//! - [`frame_file`]: the raw frame file (header, gray u8, depth u16 LE) that recorded frames travel
//!   in from the host to the QEMU board, with its parser and its writer (used by the host too).
//! - Cortex-M only: `semihosting` (host files and the command line through ARM semihosting),
//!   `semihost_source` (recorded frames streamed from a host file), `cmsdk_uart` (the UART of
//!   QEMU's MPS2 boards), `systick` (a SysTick tick clock), `stack` (peak stack by painting).
#![no_std]
#![deny(unsafe_code)]
#![deny(missing_docs)]

#[cfg(test)]
extern crate std;

pub mod camera;
#[cfg(target_os = "none")]
#[allow(unsafe_code)]
pub mod cmsdk_uart;
pub mod commands;
pub mod faulty_link;
pub mod frame_file;
pub mod pipeline;
pub mod rx_ring;
#[cfg(target_os = "none")]
pub mod semihost_source;
#[cfg(target_os = "none")]
#[allow(unsafe_code)]
pub mod semihosting;
pub mod serial;
#[cfg(target_os = "none")]
#[allow(unsafe_code)]
pub mod stack;
pub mod stream;
#[cfg(target_os = "none")]
pub mod systick;

pub use frame_file::{FrameFile, FrameFileError, FrameHeader, decode_depth_le, write_frame};
