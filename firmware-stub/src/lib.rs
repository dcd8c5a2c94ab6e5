//! ferroslam-firmware: ferroslam-core on a microcontroller.
//!
//! This library is board-independent and `#![no_std]`, tested on the host
//! (`cargo test -p ferroslam-firmware --lib`); the binaries under `src/bin/` wire it to a board.
//!
//! - [`frame_file`]: the raw frame file (header, gray u8, depth u16 LE) that recorded frames travel
//!   in from the host to the QEMU board, with its parser and its writer (used by the host too).
//! - [`wi`]: the W(I) check (paper Eq. 3 at full and half resolution, and a checksum of the
//!   half-resolution depth) and its one-line text result, computed identically here and on the host.
//! - `semihosting` (Cortex-M only): host files and the command line through ARM semihosting.
#![no_std]
#![deny(unsafe_code)]
#![deny(missing_docs)]

#[cfg(test)]
extern crate std;

pub mod frame_file;
#[cfg(target_os = "none")]
#[allow(unsafe_code)]
pub mod semihosting;
pub mod wi;

pub use frame_file::{FrameFile, FrameFileError, FrameHeader, decode_depth_le, write_frame};
pub use wi::WiReport;
