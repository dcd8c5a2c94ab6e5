//! TUM RGB-D folders: lists, association, calibration, and image decoding on a read-ahead thread.
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
//!   the CLI prints as a counted warning; a dataset with no usable frame at all is an error;
//! - colour and depth are associated as TUM's `associate.py` does (see `associate`); frames that
//!   find no partner within [`DatasetOptions::max_dt_s`] are skipped and reported the same way;
//! - each frame's time is its colour image's timestamp;
//! - ground truth is parsed (by [`crate::trajectory::Trajectory::parse_tum`]) but not associated
//!   per frame (evaluation associates whole trajectories).
//!
//! Everything else that is wrong (a malformed line, timestamps that do not increase, a bad
//! calibration, an undecodable image, a depth image that is not 16-bit, a size that differs from
//! the calibration) is a [`DatasetError`] naming the file and, for lists, the 1-based line.

mod associate;
pub mod calibrate_depth;
mod calibration;
mod decode;
mod error;
mod lists;
mod reader;
pub mod registration;
pub mod selection;
#[cfg(test)]
mod tests;
pub mod undistort;

use std::fmt;
use std::path::{Path, PathBuf};

use ferroslam_core::config::{ASSOCIATION_MAX_DT_S, QVGA, Resolution};

pub use crate::frame::OwnedFrame;
use crate::frame::halve_frame;
pub use calibration::{Calibration, DepthCamera, Distortion};
pub use error::DatasetError;
pub use reader::DatasetReader;
use selection::{FrameSelection, SelectionError};
use undistort::Undistorter;

/// Ground-truth poses are the trajectory module's type (re-exported for convenience).
pub use crate::trajectory::StampedPose;
use crate::trajectory::Trajectory;
use lists::ListEntry;

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
        }
    }
}

/// One colour image and the depth image associated with it.
#[derive(Debug, Clone, PartialEq)]
pub struct AssociatedFrame {
    /// Colour timestamp in seconds (the frame's time).
    pub rgb_timestamp_s: f64,
    /// The colour image: its list path joined to the dataset folder.
    pub rgb_path: PathBuf,
    /// Depth timestamp in seconds.
    pub depth_timestamp_s: f64,
    /// The depth image: its list path joined to the dataset folder.
    pub depth_path: PathBuf,
}

/// Why a listed image is not replayed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SkipReason {
    /// The image file does not exist (or is not a regular file).
    Missing,
    /// No image of the other stream lies within the association limit (or the nearest ones were
    /// taken by closer frames).
    Unassociated,
}

/// A listed image that is not replayed, and why; `Display` gives a one-line warning.
#[derive(Debug, Clone, PartialEq)]
pub struct SkippedFrame {
    /// The list naming it (`.../rgb.txt` or `.../depth.txt`).
    pub list: PathBuf,
    /// 1-based line in that list.
    pub line: usize,
    /// Its timestamp, in seconds.
    pub timestamp_s: f64,
    /// The image path.
    pub path: PathBuf,
    /// Why it is skipped.
    pub reason: SkipReason,
}

impl fmt::Display for SkippedFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (list, line, path) = (self.list.display(), self.line, self.path.display());
        match self.reason {
            SkipReason::Missing => write!(f, "{list}:{line}: {path} does not exist; skipped"),
            SkipReason::Unassociated => write!(
                f,
                "{list}:{line}: {path} (t = {} s) has no partner within the association limit; \
                 skipped",
                self.timestamp_s
            ),
        }
    }
}

/// An opened TUM RGB-D folder: associated frame list, calibration and ground truth. Decodes
/// nothing until asked.
#[derive(Debug, Clone)]
pub struct Dataset {
    dir: PathBuf,
    frames: Vec<AssociatedFrame>,
    skipped: Vec<SkippedFrame>,
    groundtruth: Option<Trajectory>,
    sensor: Calibration,
    calibration: Calibration,
    profile: Resolution,
    depth_level: u8,
    calibration_origin: CalibrationOrigin,
    /// The sensor's lens distortion removed from every frame; `None` for a pinhole sensor.
    undistorter: Option<Undistorter>,
}

impl Dataset {
    /// Opens the folder `dir`: reads the calibration and the lists, drops listed images that are
    /// not on disk, associates colour to depth and applies `skip_frames`, then `max_frames`.
    ///
    /// # Errors
    /// [`DatasetError::Io`] for a missing or unreadable `rgb.txt`, `depth.txt` or calibration file
    /// (an absent `groundtruth.txt` is fine), the list and calibration errors of the module doc,
    /// [`DatasetError::ProfileSize`] when the calibrated size cannot be halved as the profile asks,
    /// and [`DatasetError::EmptyDataset`] when no frame is left.
    pub fn open(dir: &Path, opts: &DatasetOptions) -> Result<Self, DatasetError> {
        let (sensor, calibration_origin) = open_calibration(dir, &opts.calibration)?;
        let levels = opts.profile.downsample_levels;
        let divisor = 1u32.checked_shl(u32::from(levels)).unwrap_or(0);
        if divisor == 0 || sensor.width % divisor != 0 || sensor.height % divisor != 0 {
            return Err(DatasetError::ProfileSize {
                width: sensor.width,
                height: sensor.height,
                profile: opts.profile.name,
                levels,
            });
        }

        let rgb_list = dir.join("rgb.txt");
        let depth_list = dir.join("depth.txt");
        let rgb = lists::parse_image_list(&rgb_list, &lists::read_text(&rgb_list)?, dir)?;
        let depth = lists::parse_image_list(&depth_list, &lists::read_text(&depth_list)?, dir)?;
        let mut groundtruth = read_groundtruth(&dir.join("groundtruth.txt"))?;

        let mut skipped = Vec::new();
        let rgb_present = keep_present(&rgb_list, rgb, &mut skipped);
        let depth_present = keep_present(&depth_list, depth, &mut skipped);
        let (mut frames, unpaired) = pair(&rgb_present, &depth_present, opts.max_dt_s);
        for (list, entry) in unpaired {
            let list = if list == Stream::Rgb { &rgb_list } else { &depth_list };
            skipped.push(skip(list, entry, SkipReason::Unassociated));
        }
        skipped.sort_by(|a, b| a.list.cmp(&b.list).then(a.line.cmp(&b.line)));
        let associated = frames.len();
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
                rgb_present.len(),
                depth_present.len(),
                associated,
                opts.max_dt_s,
                opts.skip_frames,
                opts.max_frames.map_or("all".to_owned(), |n| format!("at most {n}")),
            );
            return Err(DatasetError::EmptyDataset { dir: dir.to_owned(), reason });
        }
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
            skipped,
            groundtruth,
            sensor,
            calibration,
            profile,
            depth_level,
            calibration_origin,
            undistorter,
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

    /// Listed images that are not replayed (missing on disk or unassociated), sorted by list and
    /// line. `Display` of each is a one-line warning.
    pub fn skipped(&self) -> &[SkippedFrame] {
        &self.skipped
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
        let mut gray = decode::decode_gray(&frame.rgb_path, size)?;
        let mut depth = decode::decode_depth(&frame.depth_path, size)?;
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
        }
    }
}

/// The sensor's calibration from `source`, and where it came from. A folder without
/// `calibration.toml` whose name names a TUM sensor gets that sensor's preset; otherwise the
/// missing file is an error that says how to give a calibration.
fn open_calibration(
    dir: &Path,
    source: &CalibrationSource,
) -> Result<(Calibration, CalibrationOrigin), DatasetError> {
    Ok(match source {
        CalibrationSource::File => {
            let path = dir.join("calibration.toml");
            // A folder that is not there is an I/O error of the file read first, as before.
            if dir.is_dir() && !path.exists() {
                let Some(name) = Calibration::preset_for_folder(dir) else {
                    return Err(DatasetError::NoCalibration { dir: dir.to_owned() });
                };
                return Ok((Calibration::preset(name)?, CalibrationOrigin::FolderName(name)));
            }
            (Calibration::load(&path)?, CalibrationOrigin::File(path))
        }
        CalibrationSource::Preset(name) => {
            (Calibration::preset(name)?, CalibrationOrigin::Preset(name.clone()))
        }
        CalibrationSource::Path(path) => {
            (Calibration::load(path)?, CalibrationOrigin::File(path.clone()))
        }
    })
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

/// Reads `groundtruth.txt` if it exists, with the trajectory module's TUM reader.
fn read_groundtruth(path: &Path) -> Result<Option<Trajectory>, DatasetError> {
    match std::fs::read_to_string(path) {
        Ok(text) => {
            let trajectory = Trajectory::parse_tum(&text, path)?;
            Ok(if trajectory.is_empty() { None } else { Some(trajectory) })
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(source) => Err(DatasetError::Io { path: path.to_owned(), source }),
    }
}

/// Which list an entry came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stream {
    Rgb,
    Depth,
}

fn skip(list: &Path, entry: &ListEntry, reason: SkipReason) -> SkippedFrame {
    SkippedFrame {
        list: list.to_owned(),
        line: entry.line,
        timestamp_s: entry.timestamp_s,
        path: entry.path.clone(),
        reason,
    }
}

/// The entries whose image is a file; the others go to `skipped`.
fn keep_present(
    list: &Path,
    entries: Vec<ListEntry>,
    skipped: &mut Vec<SkippedFrame>,
) -> Vec<ListEntry> {
    let (present, missing): (Vec<_>, Vec<_>) = entries.into_iter().partition(|e| e.path.is_file());
    skipped.extend(missing.iter().map(|e| skip(list, e, SkipReason::Missing)));
    present
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
            depth_timestamp_s: d.timestamp_s,
            depth_path: d.path.clone(),
        });
    }
    let unpaired_rgb = rgb.iter().zip(used_rgb).filter(|(_, u)| !u).map(|(e, _)| (Stream::Rgb, e));
    let unpaired_depth =
        depth.iter().zip(used_depth).filter(|(_, u)| !u).map(|(e, _)| (Stream::Depth, e));
    (frames, unpaired_rgb.chain(unpaired_depth).collect())
}
