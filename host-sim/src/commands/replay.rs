//! `ferroslam-sim replay DATASET --out DIR`: a TUM-layout folder or an MCAP file through the core: its
//! arguments, turned into [`ReplayOptions`] for the library's [`Replay`], and the console lines.

use std::ffi::OsString;
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use super::args::{ArArgs, ModeArg, ProfileArg, SlamArgs, depth_level_parser, parse_args};
use crate::dataset::mcap::McapTopics;
use crate::dataset::selection::FrameSelection;
use crate::dataset::{CalibrationOrigin, CalibrationSource, DatasetOptions};
use crate::replay::{
    Replay, ReplayOptions, SKIPPED_FRAMES_SHOWN, skipped_frames_text, unused_depth_text,
};
use crate::report::{RunOutputs, summary};
use crate::run::MapFiles;

/// Arguments of `replay`.
#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// A TUM RGB-D folder (rgb.txt, depth.txt, optional groundtruth.txt, calibration.toml), or
    /// an MCAP file (ROS 2 bag) of sensor_msgs/msg/Image and CameraInfo in CDR.
    pub dataset: PathBuf,
    /// The MCAP file's colour topic (rgb8, bgr8, mono8). Default: the only image topic of such
    /// images.
    #[arg(long, value_name = "TOPIC")]
    pub rgb_topic: Option<String>,
    /// The MCAP file's depth topic (16UC1 millimetres, 32FC1 metres). Default: the only image
    /// topic of such images.
    #[arg(long, value_name = "TOPIC")]
    pub depth_topic: Option<String>,
    /// Output folder (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Processing resolution.
    #[arg(long, value_enum, default_value = "qvga")]
    pub profile: ProfileArg,
    /// TUM intrinsics (tum1, tum2, tum3) instead of the folder's calibration.toml.
    #[arg(long, conflicts_with = "calibration")]
    pub preset: Option<String>,
    /// A calibration file to use instead of the folder's calibration.toml (same format; its
    /// optional `[depth]` table registers depth to colour), or of an MCAP file's own. For
    /// 7-Scenes, whose own file holds the nominal depth intrinsics only:
    /// `calibration/7scenes-kinect-v1.toml`.
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// Skip this many frames at the start (before `--max-frames`).
    #[arg(long, default_value_t = 0)]
    pub skip_frames: usize,
    /// Process at most this many frames (the earliest, after `--skip-frames`).
    #[arg(long)]
    pub max_frames: Option<usize>,
    /// Play these ranges of the recording's frames in this order, e.g. `0-999,998-0` (out and
    /// back) or `0-700,100-999` (carried back to a place seen before); frame indices from 0, a
    /// range may run backwards. Timestamps are renumbered to keep increasing and the ground truth
    /// follows its frames. `--skip-frames` and `--max-frames` apply to the frames played.
    #[arg(long, value_name = "A-B,C-D,...")]
    pub frames: Option<FrameSelection>,
    /// What runs on each frame.
    #[arg(long, value_enum, default_value = "slam")]
    pub mode: ModeArg,
    /// How SLAM mode runs its back end.
    #[command(flatten)]
    pub slam: SlamArgs,
    /// Seed of the front end's RANSAC (default: the core's). Runs with other seeds show how
    /// much of an accuracy figure is chance (`cargo xtask spread`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Keep the depth coarser than the gray image by this many halvings (0-2; the core's
    /// `DepthView` level). Default: the resolution's (`Resolution::depth_level`), what the firmware
    /// keeps: 1 at QVGA (a 160x120 depth), 0 at VGA.
    #[arg(long, value_parser = depth_level_parser())]
    pub depth_level: Option<u8>,
    /// Start in this saved map (SLAM mode): frames have no pose until one relocalizes in it,
    /// and the run goes on in its world frame (report.json: the first pose is `relocalized`).
    #[arg(long, value_name = "FILE")]
    pub load_map: Option<PathBuf>,
    /// Save the map at the end (SLAM mode): every remembered keyframe and those of the active
    /// map, in the versioned, checksummed map format of `ferroslam_core::persist`.
    #[arg(long, value_name = "FILE")]
    pub save_map: Option<PathBuf>,
    /// Localization only, in the map of `--load-map`: nothing is added to its store (a map saved
    /// after is the loaded one), and the run is held on the map: at each keyframe that sees one of
    /// its places, the landmarks matched to the place's points move halfway to them.
    #[arg(long, requires = "load_map")]
    pub localize: bool,
    /// Fail (exit status 1, nothing run) when a frame listed in rgb.txt would be skipped: its
    /// image missing, or no depth image within 0.02 s of it. Without it such frames are left
    /// out with a warning, and report.json counts and lists them.
    #[arg(long)]
    pub strict: bool,
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

impl ReplayArgs {
    /// The arguments of `ferroslam-sim replay ARGS`, parsed as the command line parses them: for
    /// a caller that takes replay arguments from its user (`cargo xtask spread -- REPLAY ARGS`).
    ///
    /// # Errors
    /// The command line's usage error (its `Display` is the message the CLI prints).
    pub fn from_args<I, T>(args: I) -> Result<Self, clap::Error>
    where
        I: IntoIterator<Item = T>,
        T: Into<OsString> + Clone,
    {
        parse_args("replay", args)
    }

    /// The replay these arguments ask for, with a progress bar.
    ///
    /// # Errors
    /// The `--anchors` script cannot be read or is invalid.
    pub fn options(&self) -> Result<ReplayOptions> {
        let profile = self.profile.profile();
        let dataset = DatasetOptions {
            calibration: match (&self.preset, &self.calibration) {
                (Some(name), _) => CalibrationSource::Preset(name.clone()),
                (None, Some(path)) => CalibrationSource::Path(path.clone()),
                (None, None) => CalibrationSource::File,
            },
            profile,
            skip_frames: self.skip_frames,
            max_frames: self.max_frames,
            frames: self.frames.clone(),
            depth_level: self.depth_level,
            topics: McapTopics { rgb: self.rgb_topic.clone(), depth: self.depth_topic.clone() },
            ..DatasetOptions::default()
        };
        Ok(ReplayOptions {
            dataset,
            seed: self.seed,
            maps: MapFiles {
                load: self.load_map.clone(),
                save: self.save_map.clone(),
                localize: self.localize,
            },
            strict: self.strict,
            ar: self.ar.plan(profile.downsample_levels)?,
            mcap: self.mcap.clone(),
            ..ReplayOptions::new(self.mode.track_mode(&self.slam))
        })
    }
}

/// Runs `replay`: the library's [`Replay`], and its summary on stdout; on stderr, before the
/// run, a warning naming the frames skipped, a note on the depth images not used, and a note
/// when the calibration was chosen by the folder's name.
///
/// # Errors
/// Any dataset error (it names the file and line); with `--strict`, a frame skipped; a file that
/// cannot be written.
pub fn run(args: &ReplayArgs) -> Result<()> {
    let replay = Replay::open(&args.dataset, args.options()?)?;
    if let Some(text) = skipped_frames_text(replay.dataset(), SKIPPED_FRAMES_SHOWN) {
        eprintln!("warning: {text}\n  (report.json lists them; --strict refuses to run instead)");
    }
    if let Some(text) = unused_depth_text(replay.dataset()) {
        eprintln!("note: {text}");
    }
    if let CalibrationOrigin::FolderName(_) = replay.dataset().calibration_origin() {
        eprintln!("note: {}", replay.calibration_note());
    }
    let RunOutputs { report, wall_s, .. } = replay.run(&args.out)?;
    let dataset = args.dataset.display();
    if args.mode != ModeArg::DataPath {
        println!("replay {dataset}: {}", summary(&report, wall_s));
        if let Some(path) = &args.mcap {
            println!("  wrote {}", path.display());
        }
        return Ok(());
    }
    println!("replay {dataset}: {}", report.note);
    println!(
        "  W(I) median {:.0}, depth coverage {:.1}%, frames listed in rgb.txt but skipped: {}; \
         wrote {}",
        report.total_variation_median,
        100.0 * report.valid_depth_fraction_mean,
        report.skipped_frames,
        args.out.join("report.json").display()
    );
    Ok(())
}
