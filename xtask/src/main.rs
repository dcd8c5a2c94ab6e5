//! `cargo xtask`: the project's automation. `cargo xtask ci` is the one command that runs every
//! check CI runs (the README's test command).
//!
//! Subcommands:
//! - `ci`: formatting, clippy (host and thumb), docs, host tests, the no-allocator thumb build of core
//!   and firmware, the QEMU run of the firmware checked bit for bit against the host, and replays of
//!   the real and synthetic data through the host simulator.
//! - `firmware-wi [DATASET]`: only the QEMU check (frame 0 of DATASET, default 7-Scenes).
//! - `bench-frontend [--dataset DIR] [--frames N] [--json FILE] [--max-median INSN]`: the front
//!   end's instructions per frame, in total and per stage, counted by callgrind on a replay
//!   (default: the first 200 frames of 7-Scenes); see `bench.rs`.

mod bench;
mod ci;
mod firmware;

use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("ci") => ci::run_all(),
        Some("firmware-wi") => ci::firmware_wi(args.get(1).map(String::as_str)),
        Some("bench-frontend") => bench::run(&args[1..]),
        _ => {
            eprintln!(
                "usage: cargo xtask <ci | firmware-wi [DATASET] | bench-frontend [--dataset DIR] \
                 [--frames N] [--json FILE] [--max-median INSN]>"
            );
            return ExitCode::from(2);
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
