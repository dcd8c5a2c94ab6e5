//! The `ferroslam-sim` command line (the contract of `shared/design.md`).
//!
//! ```text
//! ferroslam-sim demo [--out DIR] [--mode odometry|data-path] [--frames N] [--depth-noise K]
//!                    [--holes F] [--blur N] [--shake A] [--fast-rotation] [--seed S]
//! ferroslam-sim replay DATASET --out DIR [--profile qvga|vga] [--mode odometry|data-path]
//!                      [--preset tum1|tum2|tum3] [--max-frames N] [--strict]
//! ferroslam-sim replay FILE.mcap --out DIR [--rgb-topic T] [--depth-topic T] [...]
//! ferroslam-sim convert DATASET --mcap OUT             a TUM folder as an MCAP recording
//! ferroslam-sim eval GROUNDTRUTH ESTIMATE [--json]     ATE/RPE, evo-compatible
//! ferroslam-sim decode-serial FILE [--tum]             the firmware's UART capture: poses, losses
//! ferroslam-sim calibrate-depth DATASET --out FILE [--check FILE] [--start N] [--step N]
//!                                                       depth-to-colour registration, from the images
//! ferroslam-sim map info FILE                          a saved map file: keyframes, points, checksum
//! ferroslam-sim map export FILE --ply OUT              a saved map file as a PLY point cloud
//! ```
//! Every error is printed with its causes (file and line where there is one) and the process exits
//! with status 1; usage errors exit with status 2.

pub mod args;
pub mod calibrate_depth;
pub mod convert;
pub mod decode_serial;
pub mod demo;
pub mod map;
pub mod replay;

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};

use crate::{eval, plot};

/// ferroslam host simulator: replay, evaluate and demo the SLAM core.
#[derive(Debug, Parser)]
#[command(name = "ferroslam-sim", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Render the built-in synthetic RGB-D sequence and run it through the core (no files needed).
    Demo(demo::DemoArgs),
    /// Run a recorded TUM-layout RGB-D folder or MCAP file through the core.
    Replay(replay::ReplayArgs),
    /// Write a TUM-layout RGB-D folder as an MCAP recording (ROS 2 messages in CDR) whose replay
    /// gives the same bits.
    Convert(convert::ConvertArgs),
    /// Evaluate an estimated trajectory against ground truth (ATE after SE(3) alignment, RPE).
    Eval(EvalArgs),
    /// Decode a capture of the firmware's UART: poses, other messages, frames dropped and bytes
    /// skipped.
    DecodeSerial(decode_serial::DecodeSerialArgs),
    /// Estimate the depth-to-colour registration of a sensor whose depth is not registered to
    /// colour (the colour intrinsics and the depth camera's offset), from the images; write it as
    /// a calibration file, or check one.
    CalibrateDepth(calibrate_depth::CalibrateDepthArgs),
    /// Inspect a saved map file (`replay --save-map`): what it holds (`info`), or its points as a
    /// PLY point cloud (`export --ply`).
    Map(map::MapArgs),
}

/// Arguments of `eval`.
#[derive(Debug, Args)]
struct EvalArgs {
    /// Ground truth, TUM format (`timestamp tx ty tz qx qy qz qw`, camera to world).
    groundtruth: PathBuf,
    /// Estimate, TUM format.
    estimate: PathBuf,
    /// Print the figures as JSON.
    #[arg(long)]
    json: bool,
    /// Maximum timestamp difference for association, seconds.
    #[arg(long, default_value_t = 0.02)]
    max_dt: f64,
    /// Also write trajectory.svg and ate.svg into this folder.
    #[arg(long)]
    plots: Option<PathBuf>,
}

fn run_eval(args: &EvalArgs) -> Result<()> {
    let report = eval::run_eval(&args.groundtruth, &args.estimate, args.max_dt)?;
    if let Some(dir) = &args.plots {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        plot::plot_report(&report, &dir.join("trajectory.svg"), &dir.join("ate.svg"), &[])?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!("{report}");
    }
    Ok(())
}

/// Entry point of the `ferroslam-sim` binary.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Demo(args) => demo::run(args),
        Command::Replay(args) => replay::run(args),
        Command::Convert(args) => convert::run(args),
        Command::Eval(args) => run_eval(args),
        Command::DecodeSerial(args) => decode_serial::run(args),
        Command::CalibrateDepth(args) => calibrate_depth::run(args),
        Command::Map(args) => map::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("ferroslam-sim: error: {}", describe(&e));
            ExitCode::FAILURE
        }
    }
}

/// `e` and its causes, joined by `": "` (one line), each message trimmed. A cause whose message
/// the text so far already holds is left out: most of our errors name their cause in their own
/// message (`cannot read FILE: CAUSE`) and also return it as their `source`, which `anyhow`'s
/// `{:#}` would print a second time.
fn describe(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        let text = text.trim();
        if out.contains(text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(text);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn causes_already_in_the_message_are_printed_once() {
        let io = || std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        // A message that names its source, as the dataset reader's errors do.
        let read = crate::dataset::DatasetError::Io { path: "a/b.toml".into(), source: io() };
        let e = anyhow::Error::new(read).context("frame 2");
        assert_eq!(describe(&e), "frame 2: cannot read a/b.toml: no such file");
        // A context that does not name its cause keeps it.
        let e = anyhow::Error::new(io()).context("creating out");
        assert_eq!(describe(&e), "creating out: no such file");
        // Messages are trimmed (some decoders end theirs with a newline).
        let e = anyhow::anyhow!("bad header\n").context("decoding x.png");
        assert_eq!(describe(&e), "decoding x.png: bad header");
    }
}
