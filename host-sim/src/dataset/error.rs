//! What can go wrong reading a TUM RGB-D folder.
//!
//! Every message is self-contained, because the CLI prints it as the only explanation of a failed
//! run: it names the file (as the path the user gave, joined with the list's name), the 1-based line
//! and the line's text where one is involved, and the value that was wrong.

use std::path::PathBuf;

use ferroslam_core::image::ImageError;

use crate::trajectory::TrajectoryError;

/// Why a dataset, a calibration or a frame could not be read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DatasetError {
    /// A file could not be opened or read (missing, unreadable, a folder).
    #[error("cannot read {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },

    /// The dataset folder does not exist.
    #[error("dataset folder {} does not exist", dir.display())]
    NoFolder {
        /// The path given.
        dir: PathBuf,
    },

    /// The dataset path is a file, not a folder.
    #[error(
        "{} is not a folder: a dataset is a TUM RGB-D folder (rgb.txt, depth.txt, \
         calibration.toml)",
        dir.display()
    )]
    NotAFolder {
        /// The path given.
        dir: PathBuf,
    },

    /// The dataset folder has no `rgb.txt` or no `depth.txt`.
    #[error(
        "{} has no {list}: not a TUM RGB-D folder (rgb.txt and depth.txt list the colour and \
         depth images, one `timestamp path` per line)",
        dir.display()
    )]
    NoList {
        /// The folder.
        dir: PathBuf,
        /// The list it lacks: `rgb.txt` or `depth.txt`.
        list: &'static str,
    },

    /// A dataset folder has no `calibration.toml`, none was given, and its name names no TUM
    /// sensor.
    #[error(
        "{} has no calibration.toml: give one with --calibration FILE, or a TUM sensor's with \
         --preset tum1|tum2|tum3",
        dir.display()
    )]
    NoCalibration {
        /// The dataset folder.
        dir: PathBuf,
    },

    /// A list line has the wrong number of fields.
    #[error("{}:{line}: expected '{expected}', got {text:?}", path.display())]
    FieldCount {
        /// The list file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// The layout the line should have, e.g. `timestamp path`.
        expected: &'static str,
        /// The line as read (without its line break).
        text: String,
    },

    /// A numeric field of a list line is not a finite number.
    #[error("{}:{line}: {field} {value:?} is not a finite number, in {text:?}", path.display())]
    BadNumber {
        /// The list file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// The field's name (`timestamp`).
        field: &'static str,
        /// The field as written.
        value: String,
        /// The line as read.
        text: String,
    },

    /// A timestamp is not later than the one on the previous data line of the same list.
    #[error(
        "{}:{line}: timestamp {timestamp_s} s is not after {previous_s} s on line {previous_line} \
         (timestamps must increase), in {text:?}",
        path.display()
    )]
    TimestampNotIncreasing {
        /// The list file.
        path: PathBuf,
        /// 1-based line number of the offending line.
        line: usize,
        /// Its timestamp, in seconds.
        timestamp_s: f64,
        /// 1-based line number of the previous data line.
        previous_line: usize,
        /// The previous timestamp, in seconds.
        previous_s: f64,
        /// The offending line as read.
        text: String,
    },

    /// `groundtruth.txt` is unreadable or has a bad line (the message names the file and line).
    #[error(transparent)]
    Groundtruth {
        /// The trajectory reader's error.
        #[from]
        source: TrajectoryError,
    },

    /// The calibration file is not valid TOML.
    #[error("{}: not valid TOML: {message}", path.display())]
    CalibrationSyntax {
        /// The calibration file.
        path: PathBuf,
        /// The TOML parser's message (it names the line and column).
        message: String,
    },

    /// A calibration file holds a key it does not define (a misspelt key would otherwise turn
    /// off what it sets without a word).
    #[error(
        "{}:{line}: unknown key `{key}`{}; {hint}",
        path.display(),
        table.map_or(String::new(), |t| format!(" in the [{t}] table"))
    )]
    CalibrationUnknownKey {
        /// The calibration file.
        path: PathBuf,
        /// 1-based line of the key.
        line: usize,
        /// The key as written.
        key: String,
        /// The table it is in (`depth`), `None` at the top level.
        table: Option<&'static str>,
        /// What to write instead: the nearest valid key, or the valid keys.
        hint: String,
    },

    /// A calibration key is missing.
    #[error("{}: missing key '{key}'", path.display())]
    CalibrationMissingKey {
        /// The calibration file.
        path: PathBuf,
        /// The missing key.
        key: &'static str,
    },

    /// A calibration value has the wrong type or is not finite and positive.
    #[error("{}: key '{key}' = {value} is invalid: {reason}", path.display())]
    CalibrationValue {
        /// The calibration file (the origin given to [`super::Calibration::validate`]).
        path: PathBuf,
        /// The key.
        key: &'static str,
        /// The value as TOML writes it.
        value: String,
        /// What is wrong with it.
        reason: &'static str,
    },

    /// The calibration preset name is none of `tum1`, `tum2`, `tum3`.
    #[error("unknown calibration preset {name:?}; expected one of tum1, tum2, tum3")]
    UnknownPreset {
        /// The name given.
        name: String,
    },

    /// The calibrated size cannot be halved as often as the processing profile asks.
    #[error(
        "calibrated size {width}x{height} cannot be halved {levels} time(s) for profile '{profile}' \
         (width and height must be divisible by {divisor})",
        divisor = 1u32 << levels
    )]
    ProfileSize {
        /// Sensor width in pixels.
        width: u32,
        /// Sensor height in pixels.
        height: u32,
        /// The profile's name.
        profile: &'static str,
        /// The profile's downsampling levels.
        levels: u8,
    },

    /// The frame ranges to play (`--frames`) do not fit the recording.
    #[error("{}: {source}", dir.display())]
    Selection {
        /// The dataset folder.
        dir: PathBuf,
        /// What is wrong with the ranges.
        source: super::selection::SelectionError,
    },

    /// No frame of the folder can be replayed.
    #[error("no usable frames in {}: {reason}", dir.display())]
    EmptyDataset {
        /// The dataset folder.
        dir: PathBuf,
        /// Why (what was listed, found and associated).
        reason: String,
    },

    /// An image file could not be decoded.
    #[error("cannot decode image {}: {source}", path.display())]
    Decode {
        /// The image file.
        path: PathBuf,
        /// The decoder's error.
        #[source]
        source: image::ImageError,
    },

    /// A depth image is not a 16-bit single-channel PNG.
    #[error("depth image {} is {found}; expected a 16-bit gray PNG", path.display())]
    DepthFormat {
        /// The image file.
        path: PathBuf,
        /// What it is, e.g. `8-bit gray PNG`.
        found: String,
    },

    /// A colour image has a pixel format the loader does not convert (e.g. floating point).
    #[error("colour image {} is {found}; expected 8- or 16-bit gray or RGB(A)", path.display())]
    ColorFormat {
        /// The image file.
        path: PathBuf,
        /// What it is.
        found: String,
    },

    /// An image's size differs from the calibration's.
    #[error(
        "image {} is {width}x{height}, but the calibration says {expected_width}x{expected_height}",
        path.display()
    )]
    ImageSize {
        /// The image file.
        path: PathBuf,
        /// Its width in pixels.
        width: u32,
        /// Its height in pixels.
        height: u32,
        /// The calibrated width in pixels.
        expected_width: u32,
        /// The calibrated height in pixels.
        expected_height: u32,
    },

    /// A frame index past the end of the dataset.
    #[error("frame index {index} is out of range: the dataset has {len} frames")]
    FrameIndex {
        /// The index asked for.
        index: usize,
        /// The number of associated frames.
        len: usize,
    },

    /// A core image operation (view, downsampling) refused the decoded buffers.
    #[error("frame {}: {source}", path.display())]
    Image {
        /// The colour or depth image involved.
        path: PathBuf,
        /// The core's error.
        #[source]
        source: ImageError,
    },

    /// An MCAP file could not be read as a recording (the message names the file and topic).
    #[error(transparent)]
    Mcap {
        /// What is wrong.
        #[from]
        source: super::mcap::McapError,
    },

    /// The read-ahead thread ended without delivering every frame (it panicked).
    #[error("the dataset read-ahead thread stopped after {delivered} of {len} frames")]
    ReaderStopped {
        /// Frames delivered before it stopped.
        delivered: usize,
        /// Frames the dataset has.
        len: usize,
    },
}
