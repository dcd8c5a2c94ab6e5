//! Command-line arguments `replay` and `demo` share: the profile, the mode, SLAM's back-end
//! options and the depth level; and the parser of one subcommand's arguments alone.

use std::ffi::OsString;

use clap::{Args, FromArgMatches, ValueEnum};
use ferroslam_core::config::{QVGA, Resolution, VGA};

use crate::anchor_script::AnchorScript;
use crate::run::{ArPlan, MapScale, Schedule, TrackMode};

/// The processing resolution.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ProfileArg {
    /// 320x240: the sensor's 640x480 frames halved once (the reference board).
    Qvga,
    /// 640x480: full resolution.
    Vga,
}

impl ProfileArg {
    /// The core's processing resolution.
    pub fn profile(self) -> Resolution {
        match self {
            Self::Qvga => QVGA,
            Self::Vga => VGA,
        }
    }
}

/// What `replay` and `demo` run on each frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ModeArg {
    /// The data path only: decoding, the profile's downsampling and the core's image statistics.
    DataPath,
    /// The data path, then the core's frame-to-map front end alone (depth fused into the
    /// landmarks; no bundle adjustment).
    Odometry,
    /// Front end, map and back end (local and segmented global bundle adjustment), the back end
    /// getting a fixed work quota after every frame (deterministic).
    Slam,
}

impl ModeArg {
    /// The tracker mode, run in SLAM mode as `slam` says; `None` for the data path alone.
    pub fn track_mode(self, slam: &SlamArgs) -> Option<TrackMode> {
        match self {
            Self::DataPath => None,
            Self::Odometry => Some(TrackMode::Odometry),
            Self::Slam => Some(TrackMode::Slam {
                quota: slam.backend_quota,
                schedule: slam.schedule,
                map: slam.map,
                window_levels: slam.window_levels,
                places: !slam.no_places,
            }),
        }
    }
}

/// The back-end options of SLAM mode.
#[derive(Debug, Args)]
pub struct SlamArgs {
    /// Back-end work units after each frame (SLAM mode); the same quota gives the same bits.
    #[arg(long, default_value_t = ferroslam_core::system::DEFAULT_BACKEND_QUOTA)]
    pub backend_quota: u32,
    /// How the back end runs beside the front end (SLAM mode).
    #[arg(long, value_enum, default_value = "threaded")]
    pub schedule: Schedule,
    /// The capacities of the map and the back end (SLAM mode).
    #[arg(long, value_enum, default_value = "board")]
    pub map: MapScale,
    /// Covisibility levels a local bundle adjustment's window grows by (SLAM mode, 1-255): 1
    /// takes the keyframes sharing landmarks with the new one, 2 also those sharing with them,
    /// and so on; the window also stops at 65 keyframes or when no keyframe joins. The paper's
    /// window of 50-65 keyframes in a map of over 120 takes `--map host --window-levels 255`.
    #[arg(long, default_value_t = ferroslam_core::backend::BackendParams::DEFAULT.window_levels,
          value_parser = clap::value_parser!(u8).range(1..))]
    pub window_levels: u8,
    /// Forget the keyframes that leave the map (SLAM mode): no long-term store, no
    /// relocalization in a remembered place (the behaviour before issue 47).
    #[arg(long)]
    pub no_places: bool,
}

/// The command-line parser of a `--depth-level`: 0 to the core's
/// [`MAX_DEPTH_LEVEL`](ferroslam_core::image::MAX_DEPTH_LEVEL).
pub fn depth_level_parser() -> clap::builder::RangedI64ValueParser<u8> {
    clap::value_parser!(u8).range(0..=i64::from(ferroslam_core::image::MAX_DEPTH_LEVEL))
}

/// The arguments `args` of the subcommand `name` (`ferroslam-sim NAME ARGS`), parsed as the
/// command line parses them.
///
/// # Errors
/// The usage error the command line would print.
pub(super) fn parse_args<A, I, T>(name: &'static str, args: I) -> Result<A, clap::Error>
where
    A: Args + FromArgMatches,
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let command =
        A::augment_args(clap::Command::new(name).bin_name(format!("ferroslam-sim {name}")));
    let argv = std::iter::once(OsString::from(name)).chain(args.into_iter().map(Into::into));
    A::from_arg_matches(&command.try_get_matches_from(argv)?)
}

/// The virtual objects a SLAM run places (`demo` and `replay`).
#[derive(Debug, Args)]
pub struct ArArgs {
    /// Place the paper's two objects on the two largest planes of the first tracked frame that
    /// shows two, and measure where each later frame draws them against where they belong: the
    /// room's point under each (demo), or the placing frame's depth seen from its true pose
    /// (a recording with ground truth) (report.json `ar`: pixel error and jitter). SLAM mode.
    #[arg(long)]
    pub ar: bool,
    /// Place, scale and remove virtual objects as this TOML script says instead of the paper's
    /// two (`[[step]]` tables: `frame`, `action` = "place" | "scale" | "remove", `object`,
    /// `pixel = [u, v]` in the recording's (sensor's) pixels, `scale`); measured as `--ar` is.
    /// SLAM mode.
    #[arg(long, value_name = "FILE")]
    pub anchors: Option<std::path::PathBuf>,
}

impl ArArgs {
    /// The AR plan (the script wins: it replaces the paper's objects), its pixels brought
    /// `downsample_levels` halvings down to the processing resolution.
    ///
    /// # Errors
    /// The script cannot be read or is invalid.
    pub fn plan(&self, downsample_levels: u8) -> anyhow::Result<Option<ArPlan>> {
        Ok(match &self.anchors {
            Some(path) => Some(ArPlan::Script(AnchorScript::load(path, downsample_levels)?)),
            None => self.ar.then_some(ArPlan::Paper),
        })
    }
}
