//! TUM RGB-D folders and MCAP recordings: lists, association, calibration, and image decoding on
//! a read-ahead thread.
//!
//! An MCAP file (ROS 2 bag) is read through [`mcap`]: its colour and depth topics take the place
//! of `rgb.txt` and `depth.txt` (each image's header stamp its timestamp, its number in stamp
//! order its line), and everything below applies to it as to a folder.
//!
//! A dataset folder holds `rgb.txt` and `depth.txt` (`timestamp path` lines), an optional
//! `groundtruth.txt` (`timestamp tx ty tz qx qy qz qw`, camera to world) and, unless a preset or
//! another file is chosen, `calibration.toml` (see [`Calibration`]; depth that is not registered
//! to colour is registered as it is decoded, see [`registration`]; a lens distortion is removed as
//! the frames are decoded, see [`undistort`]). A folder without `calibration.toml` whose name names
//! a TUM sensor (`rgbd_dataset_freiburg1_xyz`) takes that sensor's preset
//! ([`CalibrationOrigin::FolderName`]). Opening one ([`Dataset::open`]) parses the lists, checks
//! which listed images exist, associates colour to depth by timestamp and validates the
//! calibration; it decodes nothing. Frames are decoded one at a time with
//! [`Dataset::load_frame`], or ahead of the pipeline on another thread by a [`DatasetReader`],
//! which implements the core's [`ferroslam_core::frame::FrameSource`] port. For a sensor whose
//! depth is not registered to colour, [`calibrate_depth`] estimates the `[depth]` table from the
//! images (`ferroslam-sim calibrate-depth`).
//!
//! Policy for what real TUM sequences contain:
//! - a listed image that is not on disk is skipped, not fatal: it is left out before association
//!   (so it cannot take a partner from a present frame) and reported by [`Dataset::skipped`], which
//!   `replay` prints as a counted warning (`replay --strict` refuses to run instead); a dataset
//!   with no usable frame at all is an error;
//! - colour and depth are associated as TUM's `associate.py` does (see `associate`); images that
//!   find no partner within [`DatasetOptions::max_dt_s`] are skipped and reported the same way. A
//!   frame is a colour image: [`Dataset::skipped_frames`] are the colour images skipped, and the
//!   depth images left over are only noted (TUM's two streams run on clocks of their own, so a
//!   few depth images without a colour image are normal);
//! - each frame's time is its colour image's timestamp;
//! - ground truth is parsed (by [`crate::trajectory::Trajectory::parse_tum`]) but not associated
//!   per frame (evaluation associates whole trajectories).
//!
//! A path that is not a folder, or a folder without `rgb.txt` or `depth.txt`, is an error that
//! says so before anything else is read. Everything else that is wrong (a malformed line,
//! timestamps that do not increase, a bad calibration, an undecodable image, a depth image that is
//! not 16-bit, a size that differs from the calibration) is a [`DatasetError`] naming the file
//! and, for lists, the 1-based line.

mod associate;
pub mod calibrate_depth;
mod calibration;
mod decode;
mod error;
mod lists;
pub mod mcap;
mod reader;
pub mod registration;
pub mod selection;
mod skipped;
mod sources;
#[cfg(test)]
mod tests;
pub mod undistort;

use std::fmt;
use std::path::{Path, PathBuf};

use ferroslam_core::config::{ASSOCIATION_MAX_DT_S, QVGA, Resolution};

pub use crate::frame::OwnedFrame;
use crate::frame::halve_frame;
pub use calibration::{Calibration, DepthCamera, Distortion};
pub use decode::{depth_from_bytes, gray_from_bytes};
pub use error::DatasetError;
pub use lists::{ListEntry, parse_image_list};
pub use reader::DatasetReader;
use selection::{FrameSelection, SelectionError};
pub use skipped::{SkipReason, SkippedFrame, Stream};
use skipped::{nearest_missing, skip};
use sources::{ImageStore, Listed, open_folder, open_mcap};
use undistort::Undistorter;

use self::mcap::McapTopics;

/// Ground-truth poses are the trajectory module's type (re-exported for convenience).
pub use crate::trajectory::StampedPose;
use crate::trajectory::Trajectory;

/// Where the camera calibration comes from.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum CalibrationSource {
    /// `calibration.toml` in the dataset folder; when it has none, the TUM preset its name
    /// implies ([`Calibration::preset_for_folder`]: `rgbd_dataset_freiburg1_xyz` is `tum1`).
    #[default]
    File,
    /// A named preset: `tum1`, `tum2` or `tum3` (see [`Calibration::preset`]).
    Preset(String),
    /// A calibration file of the same format elsewhere (for a dataset whose own file is wrong or
    /// incomplete, e.g. nominal intrinsics for depth that is not registered to colour).
    Path(PathBuf),
}

/// How to open a dataset.
#[derive(Debug, Clone, PartialEq)]
pub struct DatasetOptions {
    /// Where the calibration comes from (default: the folder's `calibration.toml`).
    pub calibration: CalibrationSource,
    /// The processing resolution: frames are halved `profile.downsample_levels` times after
    /// decoding (default: the core's default profile, QVGA).
    pub profile: Resolution,
    /// Drop this many associated frames from the start (default: 0), before `max_frames`.
    pub skip_frames: usize,
    /// Keep at most this many associated frames, the earliest (default: all).
    pub max_frames: Option<usize>,
    /// Play these ranges of the associated frames, in this order, instead of all of them in
    /// order (`--frames`; see [`selection`]): timestamps are renumbered to keep increasing and
    /// the ground truth follows its frames. `skip_frames` and `max_frames` then apply to the
    /// frames played. Default `None`.
    pub frames: Option<FrameSelection>,
    /// Halve the depth this many more times than the gray image (see
    /// [`OwnedFrame::coarsen_depth`]); default `None`: the profile's `depth_level`, as the
    /// firmware's frame store keeps it (1 at QVGA).
    pub depth_level: Option<u8>,
    /// Association limit between colour and depth timestamps, in seconds, exclusive (default: the
    /// core's `config::ASSOCIATION_MAX_DT_S`, 0.02 s).
    pub max_dt_s: f64,
    /// The image topics of an MCAP file (`--rgb-topic`, `--depth-topic`; default: found by
    /// their encodings, see [`mcap`]); naming one for a folder is an error.
    pub topics: McapTopics,
}

impl Default for DatasetOptions {
    fn default() -> Self {
        Self {
            calibration: CalibrationSource::File,
            profile: QVGA,
            skip_frames: 0,
            max_frames: None,
            frames: None,
            depth_level: None,
            max_dt_s: ASSOCIATION_MAX_DT_S,
            topics: McapTopics::default(),
        }
    }
}

/// One colour image and the depth image associated with it.
#[derive(Debug, Clone, PartialEq)]
pub struct AssociatedFrame {
    /// Colour timestamp in seconds (the frame's time).
    pub rgb_timestamp_s: f64,
    /// The colour image: its list path joined to the dataset folder (for an MCAP file,
    /// `FILE:TOPIC#N`, as messages name it).
    pub rgb_path: PathBuf,
    /// Its 1-based line in `rgb.txt` (for an MCAP file, its number on the colour topic in stamp
    /// order).
    pub rgb_line: usize,
    /// Depth timestamp in seconds.
    pub depth_timestamp_s: f64,
    /// The depth image: its list path joined to the dataset folder (or `FILE:TOPIC#N`).
    pub depth_path: PathBuf,
    /// Its 1-based line in `depth.txt` (or number on the depth topic).
    pub depth_line: usize,
}

/// An opened TUM RGB-D folder: associated frame list, calibration and ground truth. Decodes
/// nothing until asked.
#[derive(Debug, Clone)]
pub struct Dataset {
    dir: PathBuf,
    frames: Vec<AssociatedFrame>,
    /// Data lines of `rgb.txt`: the frames the folder lists.
    listed_frames: usize,
    skipped: Vec<SkippedFrame>,
    groundtruth: Option<Trajectory>,
    sensor: Calibration,
    calibration: Calibration,
    profile: Resolution,
    depth_level: u8,
    calibration_origin: CalibrationOrigin,
    /// The sensor's lens distortion removed from every frame; `None` for a pinhole sensor.
    undistorter: Option<Undistorter>,
    /// Where the images are.
    images: ImageStore,
}

impl Dataset {
    /// Opens the folder `dir`: reads the calibration and the lists, drops listed images that are
    /// not on disk, associates colour to depth and applies `skip_frames`, then `max_frames`. A
    /// path that is an MCAP file (named `*.mcap` or starting with its magic) is opened as one
    /// instead (see [`mcap`]), and the same follows.
    ///
    /// # Errors
    /// [`DatasetError::NoFolder`] or [`DatasetError::NotAFolder`] when `dir` is not a folder,
    /// [`DatasetError::NoList`] when it has no `rgb.txt` or `depth.txt`, [`DatasetError::Io`] for
    /// an unreadable list or a missing or unreadable calibration file (an absent `groundtruth.txt`
    /// is fine), the list and calibration errors of the module doc,
    /// [`DatasetError::ProfileSize`] when the calibrated size cannot be halved as the profile asks,
    /// and [`DatasetError::EmptyDataset`] when no frame is left; [`DatasetError::Mcap`] for what
    /// is wrong with an MCAP file, or topics named for a folder.
    pub fn open(dir: &Path, opts: &DatasetOptions) -> Result<Self, DatasetError> {
        let listed =
            if mcap::is_mcap_file(dir) { open_mcap(dir, opts)? } else { open_folder(dir, opts)? };
        Self::from_listed(dir, listed, opts)
    }

    /// Associates what `open_folder` or `open_mcap` listed, and keeps the frames `opts` asks for.
    fn from_listed(
        dir: &Path,
        listed: Listed,
        opts: &DatasetOptions,
    ) -> Result<Self, DatasetError> {
        let Listed { rgb_list, rgb, depth_list, depth, mut skipped, .. } = listed;
        let max_dt_s = opts.max_dt_s;
        let (mut frames, unpaired) = pair(&rgb, &depth, max_dt_s);
        let unpaired: Vec<SkippedFrame> = unpaired
            .into_iter()
            .map(|(stream, entry)| {
                let list = if stream == Stream::Rgb { &rgb_list } else { &depth_list };
                let missing_partner =
                    nearest_missing(&skipped, stream.other(), entry.timestamp_s, max_dt_s);
                let skipped = skip((list, stream), entry, SkipReason::Unassociated, max_dt_s);
                SkippedFrame { missing_partner, ..skipped }
            })
            .collect();
        skipped.extend(unpaired);
        skipped.sort_by(|a, b| a.list.cmp(&b.list).then(a.line.cmp(&b.line)));
        let associated = frames.len();
        let mut groundtruth = listed.groundtruth;
        if let Some(selection) = &opts.frames {
            let played = select(&frames, groundtruth.as_ref(), selection, opts.max_dt_s)
                .map_err(|e| DatasetError::Selection { dir: dir.to_owned(), source: e })?;
            (frames, groundtruth) = played;
        }
        frames.drain(..opts.skip_frames.min(frames.len()));
        if let Some(max) = opts.max_frames {
            frames.truncate(max);
        }
        if frames.is_empty() {
            let missing = skipped.iter().filter(|s| s.reason == SkipReason::Missing).count();
            let reason = format!(
                "{} colour and {} depth images on disk ({missing} listed but missing), {} \
                 associated within {} s, {} skipped at the start (--skip-frames), {} kept \
                 (--max-frames)",
                rgb.len(),
                depth.len(),
                associated,
                opts.max_dt_s,
                opts.skip_frames,
                opts.max_frames.map_or("all".to_owned(), |n| format!("at most {n}")),
            );
            return Err(DatasetError::EmptyDataset { dir: dir.to_owned(), reason });
        }
        let sensor = listed.sensor;
        let levels = opts.profile.downsample_levels;
        // The frames `load_frame` gives are registered and undistorted, so their calibration has
        // no depth camera and no distortion.
        let calibration =
            Calibration { depth: None, distortion: Distortion::NONE, ..sensor.downsampled(levels) };
        let undistorter = Undistorter::new(&sensor);
        let profile = opts.profile;
        let depth_level = opts.depth_level.unwrap_or(profile.depth_level);
        Ok(Self {
            dir: dir.to_owned(),
            frames,
            listed_frames: listed.listed_frames,
            skipped,
            groundtruth,
            sensor,
            calibration,
            profile,
            depth_level,
            calibration_origin: listed.calibration_origin,
            undistorter,
            images: listed.images,
        })
    }

    /// Where the calibration came from.
    pub fn calibration_origin(&self) -> &CalibrationOrigin {
        &self.calibration_origin
    }

    /// The dataset folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Number of associated frames (after `skip_frames` and `max_frames`).
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether there are no frames (never true for an opened dataset).
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// The associated frames, sorted by colour timestamp.
    pub fn frames(&self) -> &[AssociatedFrame] {
        &self.frames
    }

    /// The ground-truth trajectory (camera to world), or `None` when the folder has no
    /// `groundtruth.txt` or it holds no pose line.
    pub fn groundtruth(&self) -> Option<&[StampedPose]> {
        self.groundtruth.as_ref().map(|t| t.poses.as_slice())
    }

    /// The ground truth as a [`Trajectory`] (what evaluation takes), or `None` as for
    /// [`Dataset::groundtruth`].
    pub fn groundtruth_trajectory(&self) -> Option<&Trajectory> {
        self.groundtruth.as_ref()
    }

    /// The calibration at the processing profile's resolution (what the core must use; its
    /// `depth` is `None` and its distortion none, as the frames are registered and undistorted).
    pub fn calibration(&self) -> &Calibration {
        &self.calibration
    }

    /// The calibration at the sensor's resolution, as read.
    pub fn sensor_calibration(&self) -> &Calibration {
        &self.sensor
    }

    /// The processing profile.
    pub fn profile(&self) -> Resolution {
        self.profile
    }

    /// How many times more than the gray image the frames' depth is halved (the options', or
    /// else the profile's).
    pub fn depth_level(&self) -> u8 {
        self.depth_level
    }

    /// Listed images that are not replayed (missing on disk or unassociated), colour and depth,
    /// sorted by list and line. `Display` of each is a one-line warning.
    pub fn skipped(&self) -> &[SkippedFrame] {
        &self.skipped
    }

    /// The frames `rgb.txt` lists (its data lines), played or not.
    pub fn listed_frames(&self) -> usize {
        self.listed_frames
    }

    /// The frames skipped: the colour images of [`Dataset::skipped`], by line. With the frames
    /// associated they make up [`Dataset::listed_frames`]; frames left out by
    /// [`DatasetOptions::skip_frames`], `max_frames` or `frames` are not skipped ones.
    pub fn skipped_frames(&self) -> impl Iterator<Item = &SkippedFrame> {
        self.skipped.iter().filter(|s| s.stream == Stream::Rgb)
    }

    /// Decodes frame `index`: colour to 8-bit gray, depth as raw 16-bit, both checked against the
    /// calibrated size; registers the depth to the colour camera when the calibration has a
    /// depth camera ([`registration::register_depth`]); removes the lens distortion when it has
    /// one (see [`undistort`]: from the gray image, and from the depth unless it was registered
    /// here, which already gives it in the undistorted geometry); then halves both
    /// `profile.downsample_levels` times by the core's 2x2 downsamplers, and the depth
    /// `depth_level` more times ([`OwnedFrame::coarsen_depth`]).
    ///
    /// # Errors
    /// [`DatasetError::FrameIndex`] past the end; [`DatasetError::Io`], [`DatasetError::Decode`],
    /// [`DatasetError::ColorFormat`], [`DatasetError::DepthFormat`] or [`DatasetError::ImageSize`]
    /// naming the image file.
    pub fn load_frame(&self, index: usize) -> Result<OwnedFrame, DatasetError> {
        let frame = self
            .frames
            .get(index)
            .ok_or(DatasetError::FrameIndex { index, len: self.frames.len() })?;
        let size = (self.sensor.width, self.sensor.height);
        let (mut gray, mut depth) = match &self.images {
            ImageStore::Files => (
                decode::decode_gray(&frame.rgb_path, size)?,
                decode::decode_depth(&frame.depth_path, size)?,
            ),
            ImageStore::Mcap(images) => (
                images.gray(frame.rgb_line)?,
                images.depth(frame.depth_line, self.sensor.depth_scale)?,
            ),
        };
        if let Some(u) = &self.undistorter {
            gray = u.gray(&gray);
        }
        // Registered here, the depth comes out in the pinhole geometry; registered by the sensor,
        // it shares the raw colour image's lens.
        depth = match (&self.sensor.depth, &self.undistorter) {
            (Some(camera), _) => registration::register_depth(&depth, &self.sensor, camera),
            (None, Some(u)) => u.depth(&depth),
            (None, None) => depth,
        };
        let full = OwnedFrame {
            timestamp_s: frame.rgb_timestamp_s,
            width: size.0 as usize,
            height: size.1 as usize,
            gray,
            depth,
            depth_level: 0,
            depth_scale: self.sensor.depth_scale,
        };
        let levels = self.profile.downsample_levels;
        let err = |source| DatasetError::Image { path: frame.rgb_path.clone(), source };
        let mut out = if levels == 0 {
            full
        } else {
            halve_frame(&full.view().map_err(err)?, levels).map_err(err)?
        };
        out.coarsen_depth(self.depth_level).map_err(err)?;
        Ok(out)
    }

    /// Moves the dataset into a reader that decodes up to `read_ahead` frames ahead of the caller
    /// on its own thread (see [`DatasetReader`]).
    pub fn into_reader(self, read_ahead: usize) -> DatasetReader {
        DatasetReader::new(self, read_ahead)
    }
}

/// Where a dataset's calibration came from; `Display` says it in words.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CalibrationOrigin {
    /// A calibration file (the folder's `calibration.toml` or another).
    File(PathBuf),
    /// A preset the caller named.
    Preset(String),
    /// The TUM preset the folder's name implies, the folder having no `calibration.toml`.
    FolderName(&'static str),
    /// A calibration an MCAP file carries (what `convert` wrote): `what` is
    /// `calibration.toml` or `preset NAME`.
    Carried {
        /// The MCAP file.
        file: PathBuf,
        /// What it carries.
        what: String,
    },
    /// An MCAP file's CameraInfo.
    CameraInfo {
        /// The MCAP file.
        file: PathBuf,
        /// The CameraInfo's topic.
        topic: String,
    },
}

impl fmt::Display for CalibrationOrigin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::File(path) => write!(f, "{}", path.display()),
            Self::Preset(name) => write!(f, "preset {name}"),
            Self::FolderName(name) => {
                write!(
                    f,
                    "preset {name} (the folder has no calibration.toml; its name says {name})"
                )
            }
            Self::Carried { file, what } => write!(f, "{what} carried in {}", file.display()),
            Self::CameraInfo { file, topic } => {
                write!(f, "{}'s CameraInfo on {topic}", file.display())
            }
        }
    }
}

/// The frames `selection` plays, renumbered, and the ground truth that follows them (see
/// [`selection`]).
fn select(
    frames: &[AssociatedFrame],
    groundtruth: Option<&Trajectory>,
    selection: &FrameSelection,
    max_dt_s: f64,
) -> Result<(Vec<AssociatedFrame>, Option<Trajectory>), SelectionError> {
    let order = selection.indices(frames.len())?;
    let times: Vec<f64> = frames.iter().map(|f| f.rgb_timestamp_s).collect();
    let played_s = selection::renumbered_times(&times, &order);
    let original_s: Vec<f64> = order.iter().filter_map(|&i| times.get(i).copied()).collect();
    let played: Vec<AssociatedFrame> = order
        .iter()
        .zip(&played_s)
        .filter_map(|(&i, &t)| frames.get(i).map(|f| (f, t)))
        .map(|(f, t)| AssociatedFrame {
            rgb_timestamp_s: t,
            // The depth keeps its offset from the colour image.
            depth_timestamp_s: f.depth_timestamp_s - f.rgb_timestamp_s + t,
            ..f.clone()
        })
        .collect();
    let followed = groundtruth
        .map(|gt| selection::following_groundtruth(gt, &original_s, &played_s, max_dt_s));
    Ok((played, followed))
}

/// Associates the two streams; returns the frames and the entries left without a partner.
fn pair<'a>(
    rgb: &'a [ListEntry],
    depth: &'a [ListEntry],
    max_dt_s: f64,
) -> (Vec<AssociatedFrame>, Vec<(Stream, &'a ListEntry)>) {
    let ta: Vec<f64> = rgb.iter().map(|e| e.timestamp_s).collect();
    let tb: Vec<f64> = depth.iter().map(|e| e.timestamp_s).collect();
    let pairs = associate::associate(&ta, &tb, max_dt_s);
    let mut used_rgb = vec![false; rgb.len()];
    let mut used_depth = vec![false; depth.len()];
    let mut frames = Vec::with_capacity(pairs.len());
    for (i, j) in pairs {
        let (Some(c), Some(d)) = (rgb.get(i), depth.get(j)) else { continue };
        used_rgb[i] = true;
        used_depth[j] = true;
        frames.push(AssociatedFrame {
            rgb_timestamp_s: c.timestamp_s,
            rgb_path: c.path.clone(),
            rgb_line: c.line,
            depth_timestamp_s: d.timestamp_s,
            depth_path: d.path.clone(),
            depth_line: d.line,
        });
    }
    let unpaired_rgb = rgb.iter().zip(used_rgb).filter(|(_, u)| !u).map(|(e, _)| (Stream::Rgb, e));
    let unpaired_depth =
        depth.iter().zip(used_depth).filter(|(_, u)| !u).map(|(e, _)| (Stream::Depth, e));
    (frames, unpaired_rgb.chain(unpaired_depth).collect())
}
