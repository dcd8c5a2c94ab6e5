//! QEMU mps2-an386 (Cortex-M4F): reads one recorded RGB-D frame through semihosting and reports
//! the paper's W(I) at VGA and QVGA and a checksum of the QVGA depth, all computed by
//! ferroslam-core with no heap, for the host to compare bit for bit.
//!
//! Run it with `cargo run --release --target thumbv7em-none-eabihf -- FRAME [RESULT]` from
//! `firmware-stub/` (the runner is `firmware-stub/qemu-run.sh`), or through `cargo xtask
//! firmware-wi`. Arguments come from the semihosting command line (QEMU `-append`): FRAME is a raw
//! frame file (see `ferroslam_firmware::frame_file`, default `frame.fsrf`), RESULT the file the
//! result line is written to (default `wi-result.txt`); both relative to QEMU's working directory,
//! without spaces.
//!
//! Output channels, kept apart so that nothing corrupts the binary defmt stream:
//! - defmt log frames go to the semihosting console (QEMU's stdout, or the chardev given to
//!   `-semihosting-config`), nothing else is ever written there;
//! - the machine-readable result is one text line (`ferroslam-wi v1 ...`, see
//!   `ferroslam_firmware::WiReport`) in the RESULT file, written with SYS_OPEN/SYS_WRITE;
//! - the exit status goes back through semihosting: QEMU exits 0 on success, 1 on any failure
//!   (bad arguments, missing or corrupt frame, panic, hard fault).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod firmware;

/// On the host this binary only explains itself: it is firmware.
#[cfg(not(target_os = "none"))]
fn main() -> std::process::ExitCode {
    eprintln!("qemu-mps2 is firmware: build it with --target thumbv7em-none-eabihf");
    std::process::ExitCode::from(2)
}
