//! `cargo xtask`: the project's automation. `cargo xtask ci` is the one command that runs every
//! check CI runs (the README's test command).
//!
//! Subcommands:
//! - `ci`: formatting, clippy (host and thumb), docs, host tests, the no-allocator thumb build of
//!   core and firmware (both binaries), the firmware in QEMU checked pose by pose against the host
//!   replay, the budgets of `memory-budget.md` on that same QEMU run, and replays of the real and
//!   synthetic data through the host simulator (a held-out TUM sequence too, when
//!   `../shared/datasets` holds one).
//! - `firmware-replay DATASET [--calibration FILE] [--max-frames N] [--out DIR]`: only the QEMU
//!   comparison (default 60 frames, `target/xtask/firmware-replay`; 7-Scenes with its registered
//!   calibration unless `--calibration` says otherwise); see `replay.rs`.
//! - `budgets [--from DIR | --dataset DIR --frames N --out DIR] [--json FILE] [--write]
//!   [--strict]`: RAM, flash, peak stack and instructions per frame of the firmware (QEMU's
//!   Cortex-M4F) against the budgets of `memory-budget.md`: prints budget vs measured, fails on
//!   a figure over its ceiling (over its bar when it has no ceiling; over any bar with
//!   `--strict`); `--write` regenerates the file's figures; see `budgets.rs`.
//! - `profile-firmware [--dataset DIR] [--frames N] [--top K] [--out DIR]`: the firmware's
//!   Cortex-M4 instructions by function, counted by a QEMU plugin on a firmware replay (default
//!   200 frames of 7-Scenes); see `profile.rs`.
//! - `bench-frontend [--dataset DIR] [--frames N] [--json FILE] [--max-median INSN]`: the front
//!   end's instructions per frame, in total and per stage, counted by callgrind on a replay
//!   (default: the first 200 frames of 7-Scenes); see `bench.rs`.
//! - `spread [--dataset DIR] [--calibration FILE] [--seeds N] [--skips A,B,...] [--json FILE]
//!   [-- REPLAY ARGS]`:
//!   the ATE of the odometry and SLAM replays over several RANSAC seeds and start frames (mean,
//!   median, range), to tell a real accuracy change from a lucky run; see `spread.rs`.
//! - `calibrate-depth [--dataset DIR] [--start N] [--step N] [--check FILE]`: estimates the
//!   colour intrinsics and the depth camera's offset of a recording whose depth is not registered
//!   to colour, from the images, and prints a calibration file
//!   (`calibration/7scenes-kinect-v1.toml` came from it; `--check FILE` compares the estimate
//!   with a file instead, as `ci` does); see `registration.rs`.
//! - `heldout [--dataset DIR]...`: issue 4's 0.010 m bar on a real TUM sequence kept aside from
//!   tuning, with SLAM better than odometry (default: every recording with ground truth in
//!   `../shared/datasets` other than 7-Scenes; `ci` runs it, and says when there is none); see
//!   `heldout.rs`.

mod bench;
mod budget_doc;
mod budget_tables;
mod budgets;
mod ci;
mod cost;
mod firmware;
mod heldout;
mod profile;
mod registration;
mod replay;
mod spread;
mod stats;

use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("ci") => ci::run_all(),
        Some("firmware-replay") => {
            let out = ci::root().join("target").join("xtask").join("firmware-replay");
            replay::ReplayOptions::parse(&args[1..], out).and_then(|o| replay::run(&ci::root(), &o))
        }
        Some("bench-frontend") => bench::run(&args[1..]),
        Some("budgets") => budgets::run(&args[1..]),
        Some("profile-firmware") => profile::run(&args[1..]),
        Some("spread") => spread::run(&args[1..]),
        Some("calibrate-depth") => registration::run(&args[1..]),
        Some("heldout") => heldout::run(&args[1..]),
        _ => {
            eprintln!(
                "usage: cargo xtask <ci | firmware-replay DATASET [--calibration FILE] [--max-frames N] \
                 [--out DIR] | \
                 budgets [--from DIR | --dataset DIR --frames N --out DIR] [--json FILE] \
                 [--write] [--strict] | \
                 profile-firmware [--dataset DIR] [--frames N] [--top K] [--out DIR] | \
                 bench-frontend [--dataset DIR] [--frames N] [--json FILE] [--max-median INSN] | \
                 spread [--dataset DIR] [--calibration FILE] [--seeds N] [--skips A,B,...] \
                 [--json FILE] [-- REPLAY ARGS] | calibrate-depth [--dataset DIR] [--start N] \
                 [--step N] [--check FILE] | heldout [--dataset DIR]...>"
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
