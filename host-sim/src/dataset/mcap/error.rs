//! What can go wrong reading an MCAP recording. Every message names the file, and the topic and
//! message where one is involved.

use std::path::PathBuf;

use super::cdr::CdrError;
use super::pixels::PixelError;

/// Why an MCAP recording could not be read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum McapError {
    /// The file is not a readable MCAP file (bad magic, a damaged record, cut short).
    #[error("{} is not a readable MCAP file: {reason}", path.display())]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What the MCAP reader said.
        reason: String,
    },

    /// A message's CDR bytes could not be decoded.
    #[error("{}: {topic} message {message}: cannot decode {schema}: {source}", path.display())]
    Cdr {
        /// The file.
        path: PathBuf,
        /// The message's topic.
        topic: String,
        /// 1-based number of the message in its topic.
        message: usize,
        /// The message type.
        schema: &'static str,
        /// What is wrong with the bytes.
        source: CdrError,
    },

    /// An image message's pixels could not be read (an encoding not supported, a short buffer).
    #[error("{}: {topic} message {message}: {source}", path.display())]
    Pixels {
        /// The file.
        path: PathBuf,
        /// The message's topic.
        topic: String,
        /// 1-based number of the message in its topic.
        message: usize,
        /// What is wrong.
        source: PixelError,
    },

    /// A topic named by `--rgb-topic` or `--depth-topic` is not in the file, or not an image
    /// topic.
    #[error(
        "{}: {flag} {topic}: {problem}; the file's topics: {topics}",
        path.display()
    )]
    Topic {
        /// The file.
        path: PathBuf,
        /// `--rgb-topic` or `--depth-topic`.
        flag: &'static str,
        /// The topic given.
        topic: String,
        /// `no such topic`, or what kind of topic it is.
        problem: String,
        /// Every topic of the file, with its message type and count.
        topics: String,
    },

    /// No topic, or more than one, holds images of the stream asked for, and none was named.
    #[error(
        "{}: {found} {kind} image topic ({encodings}); name one with {flag}; the file's topics: \
         {topics}",
        path.display()
    )]
    NoDefaultTopic {
        /// The file.
        path: PathBuf,
        /// `no` or `more than one`.
        found: &'static str,
        /// `colour` or `depth`.
        kind: &'static str,
        /// The encodings that make a topic of that kind.
        encodings: &'static str,
        /// `--rgb-topic` or `--depth-topic`.
        flag: &'static str,
        /// Every topic of the file, with its message type and count.
        topics: String,
    },

    /// Two images of one topic have the same stamp.
    #[error("{}: {topic} has two images stamped {stamp} s", path.display())]
    DuplicateStamp {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// The stamp, `sec.nnnnnnnnn`.
        stamp: String,
    },

    /// An image's size differs from the calibration's.
    #[error(
        "{}: {topic} message {message} is {width}x{height}, but the calibration says \
         {expected_width}x{expected_height}",
        path.display()
    )]
    ImageSize {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// 1-based number of the message in its topic.
        message: usize,
        /// Its width, pixels.
        width: u32,
        /// Its height, pixels.
        height: u32,
        /// The calibrated width, pixels.
        expected_width: u32,
        /// The calibrated height, pixels.
        expected_height: u32,
    },

    /// The file has no calibration: no CameraInfo, none carried, none given.
    #[error(
        "{} has no sensor_msgs/msg/CameraInfo topic and carries no calibration: give one with \
         --calibration FILE, or a TUM sensor's with --preset tum1|tum2|tum3",
        path.display()
    )]
    NoCalibration {
        /// The file.
        path: PathBuf,
    },

    /// More than one CameraInfo topic, none beside the colour topic.
    #[error(
        "{}: CameraInfo topics {topics}, none beside {rgb_topic}: give --calibration FILE",
        path.display()
    )]
    AmbiguousCameraInfo {
        /// The file.
        path: PathBuf,
        /// The CameraInfo topics.
        topics: String,
        /// The colour topic.
        rgb_topic: String,
    },

    /// A CameraInfo this reader cannot use.
    #[error("{}: {topic}: {reason}", path.display())]
    CameraInfo {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// What is wrong.
        reason: String,
    },

    /// A ground-truth pose that cannot be used (a zero quaternion, stamps not increasing).
    #[error("{}: {topic} message {message}: {reason}", path.display())]
    Groundtruth {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// 1-based number of the message in its topic.
        message: usize,
        /// What is wrong.
        reason: &'static str,
    },

    /// `--rgb-topic` or `--depth-topic` given with a dataset folder.
    #[error("{}: --rgb-topic and --depth-topic apply to MCAP files, not to folders", dir.display())]
    TopicsOnFolder {
        /// The folder.
        dir: PathBuf,
    },
}
