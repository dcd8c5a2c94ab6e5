//! `ferroslam-sim demo`: the built-in synthetic sequence through the core, with evaluation: its
//! arguments, turned into [`DemoOptions`] for the library's [`demo`], and the console lines.

use std::ffi::OsString;
use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;

use super::args::{ArArgs, ModeArg, ProfileArg, SlamArgs, depth_level_parser, parse_args};
use crate::demo::{DemoOptions, demo, write_dataset};
use crate::report::{RunOutputs, summary};
use crate::synth::{SynthError, SynthOptions};

/// Arguments of `demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Output folder (created if missing).
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// Frames to render (30 per second of path).
    #[arg(long, default_value_t = SynthOptions::default().frames)]
    pub frames: usize,
    /// The sensor's size the frames are rendered at, `WIDTHxHEIGHT` (even numbers; the focal
    /// length follows the width: 525 px at 640): e.g. `848x480` for a RealSense-class sensor,
    /// which `--profile qvga` processes at 424x240.
    #[arg(long, default_value = "640x480", value_parser = parse_size)]
    pub size: (usize, usize),
    /// Processing resolution: the sensor's frames halved once (`qvga`) or not (`vga`).
    #[arg(long, value_enum, default_value = "qvga")]
    pub profile: ProfileArg,
    /// Depth noise: sigma = K * z^2 metres (Kinect v1 is about 0.0015). The core is told it
    /// (with a floor of 2e-4 for the exact depth's quantization and sampling).
    #[arg(long, default_value_t = 0.0)]
    pub depth_noise: f64,
    /// Fraction of pixels whose depth is removed in random blobs (0 to 0.9).
    #[arg(long, default_value_t = 0.0)]
    pub holes: f64,
    /// Motion blur: renders averaged over the exposure (1 = none).
    #[arg(long, default_value_t = 1)]
    pub blur: usize,
    /// Camera shake amplitude (1 = about 4 mm and 0.4 degrees at 5-11 Hz; part of the ground truth).
    #[arg(long, default_value_t = 0.0)]
    pub shake: f64,
    /// Sweep yaw about three times faster.
    #[arg(long)]
    pub fast_rotation: bool,
    /// Skip this many rendered frames at the start: the run starts that many frames into the
    /// path (the ground truth covers every frame). `cargo xtask spread --demo` runs the demo
    /// from several start frames.
    #[arg(long, default_value_t = 0)]
    pub skip_frames: usize,
    /// Seed of the noise, holes and shake.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// What runs on each frame: SLAM (front end, map, back end), the odometry front end alone,
    /// or the data path only (which evaluates a simulated dead-reckoning baseline instead of an
    /// estimate).
    #[arg(long, value_enum, default_value = "slam")]
    pub mode: ModeArg,
    /// How SLAM mode runs its back end.
    #[command(flatten)]
    pub slam: SlamArgs,
    /// Keep the depth coarser than the gray image by this many halvings (0-2; the core's
    /// `DepthView` level). Default: the resolution's (`Resolution::depth_level`), what the firmware
    /// keeps: 1 at QVGA (a 160x120 depth), 0 at VGA.
    #[arg(long, value_parser = depth_level_parser())]
    pub depth_level: Option<u8>,
    /// Write the rendered sequence (as `--frames`, `--depth-noise`, `--holes`, `--blur`,
    /// `--shake`, `--fast-rotation` and `--seed` make it) into this folder as a TUM RGB-D
    /// recording (gray and depth PNGs, rgb.txt, depth.txt, groundtruth.txt, calibration.toml)
    /// instead of running it: `replay`, `cargo xtask firmware-replay` and `cargo xtask budgets`
    /// then run on it like on any recording.
    #[arg(long, value_name = "DIR")]
    pub write_dataset: Option<PathBuf>,
    /// The virtual objects it places (SLAM mode).
    #[command(flatten)]
    pub ar: ArArgs,
    /// Also write the run's results as an MCAP file of Foxglove messages (JSON) that Foxglove
    /// and other MCAP tools open: camera poses and /tf, the trajectory, the map's points,
    /// keyframes, planes, AR objects, events, the aligned ground truth (odometry and SLAM
    /// modes).
    #[arg(long, value_name = "OUT.mcap")]
    pub mcap: Option<PathBuf>,
}

impl DemoArgs {
    /// The arguments of `ferroslam-sim demo ARGS`, parsed as the command line parses them: for a
    /// caller that takes demo arguments from its user (`cargo xtask spread --demo`).
    ///
    /// # Errors
    /// The command line's usage error (its `Display` is the message the CLI prints).
    pub fn from_args<I, T>(args: I) -> Result<Self, clap::Error>
    where
        I: IntoIterator<Item = T>,
        T: Into<OsString> + Clone,
    {
        parse_args("demo", args)
    }

    /// The options that shape the rendered sequence, as command-line flags (for the README of a
    /// written dataset).
    fn synth_flags(&self) -> String {
        let mut flags = format!("--frames {} --seed {}", self.frames, self.seed);
        if self.size != (640, 480) {
            flags.push_str(&format!(" --size {}x{}", self.size.0, self.size.1));
        }
        for (name, value, default) in [
            ("--depth-noise", self.depth_noise, 0.0),
            ("--holes", self.holes, 0.0),
            ("--shake", self.shake, 0.0),
        ] {
            if value != default {
                flags.push_str(&format!(" {name} {value}"));
            }
        }
        if self.blur != 1 {
            flags.push_str(&format!(" --blur {}", self.blur));
        }
        if self.fast_rotation {
            flags.push_str(" --fast-rotation");
        }
        flags.push_str(" --write-dataset DIR");
        flags
    }

    /// Checks the options that shape the rendered sequence ([`SynthOptions::validate`]), naming
    /// the command-line option at fault and its value as typed (`--holes 5: must be finite, 0
    /// to 0.9`) rather than the library's field.
    ///
    /// # Errors
    /// The first option out of its range.
    pub fn check(&self) -> Result<()> {
        let Err(e) = self.synth_options().validate() else { return Ok(()) };
        let SynthError::InvalidOption { name, reason } = &e else { return Err(e.into()) };
        let (flag, value) = match *name {
            "frames" => ("--frames", self.frames.to_string()),
            "width" | "height" => ("--size", format!("{}x{}", self.size.0, self.size.1)),
            "depth_noise_k" => ("--depth-noise", self.depth_noise.to_string()),
            "hole_fraction" => ("--holes", self.holes.to_string()),
            "motion_blur_samples" => ("--blur", self.blur.to_string()),
            "shake" => ("--shake", self.shake.to_string()),
            // The options the command line does not set keep their valid defaults.
            _ => return Err(e.into()),
        };
        bail!("{flag} {value}: {reason}")
    }

    /// The demo these arguments ask for, with a progress bar.
    ///
    /// # Errors
    /// The `--anchors` script cannot be read or is invalid.
    pub fn options(&self) -> Result<DemoOptions> {
        let profile = self.profile.profile();
        Ok(DemoOptions {
            synth: self.synth_options(),
            profile,
            skip_frames: self.skip_frames,
            depth_level: self.depth_level,
            ar: self.ar.plan(profile.downsample_levels)?,
            mcap: self.mcap.clone(),
            ..DemoOptions::new(self.mode.track_mode(&self.slam))
        })
    }

    /// The rendered sequence these arguments ask for.
    fn synth_options(&self) -> SynthOptions {
        SynthOptions {
            frames: self.frames,
            depth_noise_k: self.depth_noise,
            hole_fraction: self.holes,
            motion_blur_samples: self.blur,
            shake: self.shake,
            fast_rotation: self.fast_rotation,
            seed: self.seed,
            width: self.size.0,
            height: self.size.1,
            ..SynthOptions::default()
        }
    }
}

/// Runs `demo`: the library's [`demo`], and its summary on stdout.
///
/// # Errors
/// Invalid options (naming the command-line option), or a file that cannot be written.
pub fn run(args: &DemoArgs) -> Result<()> {
    args.check()?;
    if let Some(dir) = &args.write_dataset {
        let made_by = format!("ferroslam-sim demo {}", args.synth_flags());
        let frames = write_dataset(dir, &args.options()?, &made_by)?;
        println!("demo: wrote {frames} rendered frames as a TUM RGB-D folder in {}", dir.display());
        return Ok(());
    }
    let out = &args.out;
    let RunOutputs { report, evaluation, wall_s } = demo(out, &args.options()?)?;
    if args.mode != ModeArg::DataPath {
        println!("demo: {}", summary(&report, wall_s));
        println!("  wrote {}", out.display());
        if let Some(path) = &args.mcap {
            println!("  wrote {}", path.display());
        }
        return Ok(());
    }
    println!("demo: {}.", report.note);
    println!(
        "  rendering + data path: {wall_s:.1} s; W(I) median {:.0}; depth coverage {:.1}%",
        report.total_variation_median,
        100.0 * report.valid_depth_fraction_mean
    );
    if let Some(baseline) = evaluation {
        println!(
            "  simulated dead reckoning vs exact ground truth: ATE RMSE {:.4} m over {} poses, \
             RPE {:.4} m/s (evaluation as evo computes it)",
            baseline.ate.rmse,
            baseline.matched_poses,
            baseline.rpe_per_second.map_or(f64::NAN, |r| r.trans.rmse),
        );
    }
    println!("  wrote {}", out.display());
    Ok(())
}

/// The parser of `--size`: `WIDTHxHEIGHT`, both even and at least 16.
fn parse_size(text: &str) -> Result<(usize, usize), String> {
    let bad =
        || format!("`{text}` is not a size WIDTHxHEIGHT of even numbers of pixels, e.g. 848x480");
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    let (w, h) = (
        w.trim().parse::<usize>().map_err(|_| bad())?,
        h.trim().parse::<usize>().map_err(|_| bad())?,
    );
    if w < 16 || h < 16 || w % 2 != 0 || h % 2 != 0 {
        return Err(bad());
    }
    Ok((w, h))
}
