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
//! - `heldout [--dataset DIR]...`: issue 4's 0.010 m bar on a real TUM sequence kept aside from
//!   tuning, with SLAM better than odometry (default: every recording with ground truth in
//!   `../shared/datasets` other than 7-Scenes; `ci` runs it, and says when there is none); see
//!   `heldout.rs`.
//! - `fuzz [--seconds N | --iterations N] [--target NAME[,NAME...]] [--seed S]`, `fuzz --target
//!   NAME --replay FILE`, `fuzz --write-corpus`: every parser and decoder (map file, flash mount,
//!   wire, calibration, lists, trajectory, image) and the SLAM pipeline on adversarial frames,
//!   under a deterministic mutation fuzzer (seed corpora in `fuzz/corpus/`); `ci` runs every
//!   target for a fixed number of inputs; see `fuzz.rs`.
//! - `faults [--frames A-B,...] [--rates P,Q] [--seed S] [--strict] [--json FILE] [--out DIR]`:
//!   the board's pipeline on 7-Scenes with each fault (frame source, serial link, store reads)
//!   injected at two rates, against the clean run; see `faults.rs`.
//! - `soak [--frames N] [--recording demo|7scenes|both] [--json FILE]`: the board's pipeline over
//!   recordings played in laps for N frames; see `soak.rs`.
//!
//! The depth-to-colour calibration estimator that `calibration/7scenes-kinect-v1.toml` came from
//! is a host-sim command, `ferroslam-sim calibrate-depth DATASET --out FILE` (it was `cargo xtask
//! calibrate-depth`); `ci` runs its check in process.
//!
//! Modules, top down (no module imports one above it): `main` parses the subcommand; `ci` runs
//! the pipeline and nothing imports it; each other subcommand has its module (`budgets`,
//! `profile`, `heldout`, `spread`, `bench`, `fuzz`, `faults`, `soak` (which uses `faults`' frame
//! loading), and `replay`, the firmware replay that
//! `budgets`, `profile` and `ci` run too), over the pieces they share: `budget_tables` and
//! `budget_doc` (`memory-budget.md`), `budget_figures` (what `budgets` measures and judges), `sim`
//! (host-sim's replay in process, held to an accuracy bar), `cost` (a firmware run's per-frame
//! costs), `firmware` (building it, running QEMU), `cargo` (running cargo), `stats`, and `paths`
//! (the workspace root, the 7-Scenes recording and its calibration, the output folders) at the
//! bottom.

mod bench;
mod board_runs;
mod budget_doc;
mod budget_figures;
mod budget_tables;
mod budgets;
mod cargo;
mod ci;
mod cost;
mod fast_demo;
mod faults;
mod firmware;
mod fuzz;
mod heldout;
mod page_check;
mod paths;
mod profile;
mod replay;
mod sim;
mod soak;
mod spread;
mod stats;

use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("ci") => ci::run_all(),
        Some("firmware-replay") => {
            let out = paths::xtask_out("firmware-replay");
            replay::ReplayOptions::parse(&args[1..], out)
                .and_then(|o| replay::run(&paths::root(), &o))
        }
        Some("bench-frontend") => bench::run(&args[1..]),
        Some("budgets") => budgets::run(&args[1..]),
        Some("profile-firmware") => profile::run(&args[1..]),
        Some("spread") => spread::run(&args[1..]),
        Some("heldout") => heldout::run(&args[1..]),
        Some("fuzz") => fuzz::run(&args[1..]),
        Some("faults") => faults::run(&args[1..]),
        Some("soak") => soak::run(&args[1..]),
        Some("page-check") => match &args[1..] {
            [dir] => {
                let dir = std::path::Path::new(dir);
                page_check::check(dir, &dir.join("report-page.png"))
            }
            _ => Err(anyhow::anyhow!("usage: cargo xtask page-check RUN_DIR")),
        },
        _ => {
            eprintln!(
                "usage: cargo xtask <ci | firmware-replay DATASET [--calibration FILE] [--max-frames N] \
                 [--out DIR] | \
                 budgets [--from DIR | --dataset DIR --frames N --out DIR] [--json FILE] \
                 [--write] [--strict] | \
                 profile-firmware [--dataset DIR] [--frames N] [--top K] [--out DIR] | \
                 bench-frontend [--dataset DIR] [--frames N] [--json FILE] [--max-median INSN] | \
                 spread [--dataset DIR] [--calibration FILE] [--seeds N] [--skips A,B,...] \
                 [--json FILE] [-- REPLAY ARGS] | heldout [--dataset DIR]... | \
                 fuzz [--seconds N | --iterations N] [--target NAME] [--seed S] [--replay FILE] \
                 [--write-corpus] | faults [--frames A-B,...] [--rates P,Q] [--seed S] [--strict] \
                 [--json FILE] [--out DIR] | soak [--frames N] [--recording demo|7scenes|both] [--json FILE] | \
                 page-check RUN_DIR> \
                 (the depth calibration estimator is `ferroslam-sim calibrate-depth`)"
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
