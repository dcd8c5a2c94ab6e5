//! MCAP (ROS 2 bag) recordings: read as a dataset beside TUM folders, and written from one.
//!
//! [`crate::dataset::Dataset::open`] opens a file (a path that is not a folder and starts with the
//! MCAP magic) through [`recording`]: `sensor_msgs/msg/Image` messages in CDR on a colour topic
//! (`rgb8`, `bgr8`, `mono8`) and a depth topic (`16UC1` millimetres, `32FC1` metres), chosen by
//! [`McapTopics`] (`--rgb-topic`, `--depth-topic`) or, by default, as the only image topic whose
//! images have an encoding of that kind. Each topic's images, in header-stamp order, are a stream
//! as a TUM list is (the message's 1-based number in that order is its "line"), and are associated
//! by stamp as the folder's lists are; everything after (`--frames`, registration, undistortion,
//! evaluation) is the folder's code.
//!
//! The calibration, the first of:
//! 1. `--calibration FILE` or `--preset` (as for a folder);
//! 2. the calibration the file carries in its [`CALIBRATION_METADATA`] metadata record (what
//!    `convert` writes: the folder's `calibration.toml` text, or a preset's name), used whole:
//!    depth registration, noise and scale included; it wins over CameraInfo, which cannot say
//!    them;
//! 3. the `sensor_msgs/msg/CameraInfo` beside the colour topic (`.../camera_info` in its
//!    namespace), or the file's only one: `K`, size and a `plumb_bob` distortion, depth in
//!    millimetres ([`camera_info::CAMERA_INFO_DEPTH_SCALE`]).
//!
//! Without any of them opening fails, saying so. Depth samples follow their encoding, brought to
//! the calibration's depth scale (see [`pixels`]). The ground truth is the
//! `geometry_msgs/msg/PoseStamped` topic [`GROUNDTRUTH_TOPIC`] (camera to world); a file without
//! it replays without evaluation, as a folder without `groundtruth.txt` does.
//!
//! The file is read whole into memory ([`mod@file`]); images are decoded from it frame by frame.
//! [`convert`] writes a TUM folder as such a file.

pub mod camera_info;
pub mod cdr;
pub mod convert;
mod error;
pub mod file;
pub mod messages;
pub mod pixels;
pub mod recording;
pub mod time;

use std::io::Read;
use std::path::Path;

pub use convert::{ConvertError, Converted, convert_to_mcap};
pub use error::McapError;
pub use recording::{McapImages, McapRecording};

/// Name of the metadata record carrying a calibration: key `calibration.toml` (a calibration
/// file's text) or `preset` (`tum1`, `tum2`, `tum3`).
pub const CALIBRATION_METADATA: &str = "ferroslam.calibration";
/// The topic of the ground truth (`geometry_msgs/msg/PoseStamped`, camera to world).
pub const GROUNDTRUTH_TOPIC: &str = "/groundtruth";
/// The colour topic `convert` writes.
pub const RGB_TOPIC: &str = "/camera/rgb/image_raw";
/// The CameraInfo topic `convert` writes (beside [`RGB_TOPIC`]).
pub const CAMERA_INFO_TOPIC: &str = "/camera/rgb/camera_info";
/// The depth topic `convert` writes.
pub const DEPTH_TOPIC: &str = "/camera/depth/image_raw";

/// The image topics to read; `None`: found by their images' encodings.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct McapTopics {
    /// The colour topic (`--rgb-topic`).
    pub rgb: Option<String>,
    /// The depth topic (`--depth-topic`).
    pub depth: Option<String>,
}

impl McapTopics {
    /// Whether a topic is named.
    pub fn any(&self) -> bool {
        self.rgb.is_some() || self.depth.is_some()
    }
}

/// Whether `path` is to be read as an MCAP file: a path named `*.mcap` that is not a folder
/// (a missing one is then said to be a missing file), or any file that starts with the MCAP
/// magic.
pub fn is_mcap_file(path: &Path) -> bool {
    if path.is_dir() {
        return false;
    }
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("mcap")) {
        return true;
    }
    let mut magic = [0u8; 8];
    std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut magic)).is_ok()
        && magic[..] == *mcap::MAGIC
}
