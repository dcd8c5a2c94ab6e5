//! The `ferroslam-sim` command line (the contract of `shared/design.md`).
//!
//! ```text
//! ferroslam-sim demo [--out DIR] [--mode odometry|data-path] [--frames N] [--depth-noise K]
//!                    [--holes F] [--blur N] [--shake A] [--fast-rotation] [--seed S]
//! ferroslam-sim replay DATASET --out DIR [--profile qvga|vga] [--mode odometry|data-path]
//!                      [--preset tum1|tum2|tum3] [--max-frames N]
//! ferroslam-sim eval GROUNDTRUTH ESTIMATE [--json]     ATE/RPE, evo-compatible
//! ferroslam-sim decode-serial FILE [--tum]             the firmware's UART capture: poses, losses
//! ```
//! Every error is printed with its causes (file and line where there is one) and the process exits
//! with status 1; usage errors exit with status 2.

pub mod datapath;
pub mod decode_serial;
pub mod demo;
pub mod replay;
pub mod report;
pub mod slam;

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
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
    /// Run a recorded TUM-layout RGB-D folder through the core.
    Replay(replay::ReplayArgs),
    /// Evaluate an estimated trajectory against ground truth (ATE after SE(3) alignment, RPE).
    Eval(EvalArgs),
    /// Decode a capture of the firmware's UART: poses, other messages, frames dropped and bytes
    /// skipped.
    DecodeSerial(decode_serial::DecodeSerialArgs),
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
        std::fs::create_dir_all(dir)?;
        plot::plot_report(&report, &dir.join("trajectory.svg"), &dir.join("ate.svg"))?;
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
        Command::Eval(args) => run_eval(args),
        Command::DecodeSerial(args) => decode_serial::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("ferroslam-sim: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
