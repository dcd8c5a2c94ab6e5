//! A TUM RGB-D folder written as an MCAP recording (`ferroslam-sim convert DIR --mcap OUT`), so
//! that replaying the file gives the same bits as replaying the folder.
//!
//! What is written (CDR messages with `ros2msg` schemas, zstd-compressed chunks, indexed):
//! - [`RGB_TOPIC`]: every colour image on disk, `rgb8` (or `mono8` for a gray or 16-bit image:
//!   the loader's gray), stamped with its `rgb.txt` time, with a CameraInfo of the calibration
//!   on [`CAMERA_INFO_TOPIC`] beside each;
//! - [`DEPTH_TOPIC`]: every depth image on disk, stamped with its `depth.txt` time: `16UC1` when
//!   the calibration's depth scale is 1000 (millimetres, the samples as they are), `32FC1`
//!   metres otherwise (`raw / depth_scale`, which reads back as the same sample: see
//!   `docs/decisions.md`);
//! - [`GROUNDTRUTH_TOPIC`]: `groundtruth.txt`'s poses, values as written;
//! - metadata [`CALIBRATION_METADATA`]: the calibration file's text (`calibration.toml`), or the
//!   preset's name (`preset`), which a replay uses whole (depth registration, noise, scale);
//! - metadata [`EXACT_TIMES_METADATA`]: the times finer than a nanosecond (see
//!   [`super::time`]).
//!
//! Images listed but not on disk are left out (and counted); the replay of the file then
//! associates the same images as the folder's.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use mcap::records::{MessageHeader, Metadata};

use super::camera_info::camera_info;
use super::messages::{self, IMAGE, ImageMsg, PoseStampedMsg, Stamp};
use super::pixels::metres_of;
use super::time::{EXACT_TIMES_METADATA, ExactTimes};
use super::{CALIBRATION_METADATA, CAMERA_INFO_TOPIC, DEPTH_TOPIC, GROUNDTRUTH_TOPIC, RGB_TOPIC};
use crate::dataset::decode::{ColourPixels, decode_colour, decode_depth};
use crate::dataset::lists::{parse_image_list, read_text};
use crate::dataset::sources::{check_folder, open_calibration};
use crate::dataset::{Calibration, CalibrationOrigin, CalibrationSource, DatasetError, ListEntry};
use crate::trajectory::Trajectory;

/// Why a folder could not be converted.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConvertError {
    /// The folder could not be read (its lists, calibration, an image).
    #[error(transparent)]
    Dataset(#[from] DatasetError),
    /// A time a header stamp cannot hold (negative, past 2038), or two times less than a
    /// nanosecond apart.
    #[error("{}:{line}: time {timestamp_s} s {reason}", list.display())]
    Timestamp {
        /// The list or ground-truth file.
        list: PathBuf,
        /// 1-based line.
        line: usize,
        /// The time, seconds.
        timestamp_s: f64,
        /// What is wrong.
        reason: &'static str,
    },
    /// The MCAP file could not be written.
    #[error("cannot write {}: {reason}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// What the writer said.
        reason: String,
    },
}

/// What [`convert_to_mcap`] wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Converted {
    /// Colour images written.
    pub rgb_images: usize,
    /// Depth images written.
    pub depth_images: usize,
    /// Ground-truth poses written.
    pub groundtruth_poses: usize,
    /// Images listed but not on disk, left out.
    pub missing_images: usize,
    /// The depth encoding: `16UC1` or `32FC1`.
    pub depth_encoding: &'static str,
    /// Where the calibration came from, as the replay of the folder would say it.
    pub calibration: String,
}

/// One message to write, in time order.
enum Event {
    Rgb(ListEntry),
    Depth(ListEntry),
    Pose([f64; 8]),
}

/// Writes the TUM folder `dir`, calibrated as `source` says, as the MCAP file `out` (see the
/// module doc).
///
/// # Errors
/// [`ConvertError::Dataset`] for a folder that cannot be read (as `replay` would say it),
/// [`ConvertError::Timestamp`] for a time no header stamp holds, [`ConvertError::Write`].
pub fn convert_to_mcap(
    dir: &Path,
    out: &Path,
    source: &CalibrationSource,
) -> Result<Converted, ConvertError> {
    check_folder(dir)?;
    let (sensor, origin) = open_calibration(dir, source)?;
    let carried = carried_calibration(&origin)?;
    let list = |name: &str| -> Result<(PathBuf, Vec<ListEntry>), DatasetError> {
        let path = dir.join(name);
        let entries = parse_image_list(&path, &read_text(&path)?, dir)?;
        Ok((path, entries))
    };
    let (rgb_list, rgb) = list("rgb.txt")?;
    let (depth_list, depth) = list("depth.txt")?;
    let gt_path = dir.join("groundtruth.txt");
    let poses = match std::fs::read_to_string(&gt_path) {
        Ok(text) => Trajectory::parse_tum_values(&text, &gt_path).map_err(DatasetError::from)?,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
        Err(source) => return Err(DatasetError::Io { path: gt_path, source }.into()),
    };
    let listed = rgb.len() + depth.len();
    let rgb: Vec<ListEntry> = rgb.into_iter().filter(|e| e.path.is_file()).collect();
    let depth: Vec<ListEntry> = depth.into_iter().filter(|e| e.path.is_file()).collect();
    let missing_images = listed - rgb.len() - depth.len();

    // Stamps first: the exact times are known before anything is written.
    let mut exact = ExactTimes::default();
    let mut events: Vec<(Stamp, Event)> = Vec::with_capacity(listed + poses.len());
    let mut stamp = |list: &Path, line: usize, t: f64| {
        exact.stamp(t).ok_or_else(|| ConvertError::Timestamp {
            list: list.to_owned(),
            line,
            timestamp_s: t,
            reason: "has no header stamp: negative, past 2038, or within a nanosecond of another",
        })
    };
    for e in rgb {
        events.push((stamp(&rgb_list, e.line, e.timestamp_s)?, Event::Rgb(e)));
    }
    for e in depth {
        events.push((stamp(&depth_list, e.line, e.timestamp_s)?, Event::Depth(e)));
    }
    for (i, values) in poses.iter().enumerate() {
        events.push((stamp(&gt_path, i + 1, values[0])?, Event::Pose(*values)));
    }
    events.sort_by_key(|(stamp, _)| *stamp);

    let mut writer = Writer::create(out)?;
    let depth_encoding = if sensor.depth_scale == 1000.0 { "16UC1" } else { "32FC1" };
    let mut counts = [0usize; 3];
    for (stamp, event) in events {
        let kind = match event {
            Event::Rgb(e) => writer.rgb(&e, stamp, &sensor).map(|()| 0)?,
            Event::Depth(e) => writer.depth(&e, stamp, &sensor, depth_encoding).map(|()| 1)?,
            Event::Pose(v) => writer.pose(stamp, v).map(|()| 2)?,
        };
        counts[kind] += 1;
    }
    // After the messages, so that no chunk holds only the schemas and channels.
    writer.metadata(CALIBRATION_METADATA, carried)?;
    if !exact.is_empty() {
        writer.metadata(EXACT_TIMES_METADATA, exact.to_metadata())?;
    }
    writer.finish()?;
    let [rgb_images, depth_images, groundtruth_poses] = counts;
    let calibration = origin.to_string();
    Ok(Converted {
        rgb_images,
        depth_images,
        groundtruth_poses,
        missing_images,
        depth_encoding,
        calibration,
    })
}

/// The metadata that carries the calibration: the file's text, or the preset's name.
fn carried_calibration(
    origin: &CalibrationOrigin,
) -> Result<BTreeMap<String, String>, DatasetError> {
    let (key, value) = match origin {
        CalibrationOrigin::File(path) => ("calibration.toml", read_text(path)?),
        CalibrationOrigin::Preset(name) => ("preset", name.clone()),
        CalibrationOrigin::FolderName(name) => ("preset", (*name).to_owned()),
        // A folder's calibration comes from a file or a preset.
        other => ("preset", other.to_string()),
    };
    Ok(BTreeMap::from([(key.to_owned(), value)]))
}

/// The MCAP writer and its channels.
struct Writer {
    path: PathBuf,
    inner: mcap::Writer<BufWriter<File>>,
    /// Channel ids: colour, depth, CameraInfo, ground truth.
    channels: [u16; 4],
    /// Messages written per channel (each message's sequence number).
    sequence: [u32; 4],
}

impl Writer {
    /// Creates `path` and declares the four channels.
    fn create(path: &Path) -> Result<Self, ConvertError> {
        let err = |e: mcap::McapError| write_error(path, e);
        let file = File::create(path).map_err(|e| write_error(path, e))?;
        let options = mcap::WriteOptions::new().profile("ros2");
        let mut inner = options.create(BufWriter::new(file)).map_err(err)?;
        let no_metadata = BTreeMap::new();
        let mut channel = |topic: &str, schema: &str| -> Result<u16, mcap::McapError> {
            let text = messages::schema_text(schema);
            let schema_id = inner.add_schema(schema, "ros2msg", text.as_bytes())?;
            inner.add_channel(schema_id, topic, "cdr", &no_metadata)
        };
        let channels = [
            channel(RGB_TOPIC, IMAGE).map_err(err)?,
            channel(DEPTH_TOPIC, IMAGE).map_err(err)?,
            channel(CAMERA_INFO_TOPIC, messages::CAMERA_INFO).map_err(err)?,
            channel(GROUNDTRUTH_TOPIC, messages::POSE_STAMPED).map_err(err)?,
        ];
        Ok(Self { path: path.to_owned(), inner, channels, sequence: [0; 4] })
    }

    /// Writes `data` on channel `k` (an index into `channels`) at `stamp`.
    fn write(&mut self, k: usize, stamp: Stamp, data: &[u8]) -> Result<(), ConvertError> {
        let header = MessageHeader {
            channel_id: self.channels[k],
            sequence: self.sequence[k],
            log_time: stamp.as_nanos(),
            publish_time: stamp.as_nanos(),
        };
        self.sequence[k] += 1;
        self.inner.write_to_known_channel(&header, data).map_err(|e| write_error(&self.path, e))
    }

    /// A metadata record.
    fn metadata(
        &mut self,
        name: &str,
        metadata: BTreeMap<String, String>,
    ) -> Result<(), ConvertError> {
        let record = Metadata { name: name.to_owned(), metadata };
        self.inner.write_metadata(&record).map_err(|e| write_error(&self.path, e))
    }

    /// The colour image of `entry`, and a CameraInfo beside it.
    fn rgb(
        &mut self,
        entry: &ListEntry,
        stamp: Stamp,
        sensor: &Calibration,
    ) -> Result<(), ConvertError> {
        let (width, height) = (sensor.width, sensor.height);
        let (encoding, data, channels) = match decode_colour(&entry.path, (width, height))? {
            ColourPixels::Rgb8(data) => ("rgb8", data, 3),
            ColourPixels::Mono8(data) => ("mono8", data, 1),
        };
        let step = width * channels;
        let msg =
            ImageMsg { stamp, height, width, encoding, is_bigendian: false, step, data: &data };
        self.write(0, stamp, &msg.encode("camera_rgb_optical_frame"))?;
        self.write(2, stamp, &camera_info(sensor, stamp).encode("camera_rgb_optical_frame"))?;
        Ok(())
    }

    /// The depth image of `entry`, in `encoding` (`16UC1` or `32FC1`).
    fn depth(
        &mut self,
        entry: &ListEntry,
        stamp: Stamp,
        sensor: &Calibration,
        encoding: &str,
    ) -> Result<(), ConvertError> {
        let (width, height) = (sensor.width, sensor.height);
        let raw = decode_depth(&entry.path, (width, height))?;
        let (data, bytes): (Vec<u8>, u32) = if encoding == "16UC1" {
            (raw.iter().flat_map(|v| v.to_le_bytes()).collect(), 2)
        } else {
            let scale = sensor.depth_scale;
            (raw.iter().flat_map(|&v| metres_of(v, scale).to_le_bytes()).collect(), 4)
        };
        let step = width * bytes;
        let msg =
            ImageMsg { stamp, height, width, encoding, is_bigendian: false, step, data: &data };
        self.write(1, stamp, &msg.encode("camera_depth_optical_frame"))?;
        Ok(())
    }

    /// A ground-truth pose from its TUM values `[t, tx, ty, tz, qx, qy, qz, qw]`.
    fn pose(&mut self, stamp: Stamp, v: [f64; 8]) -> Result<(), ConvertError> {
        let [_, tx, ty, tz, qx, qy, qz, qw] = v;
        let msg =
            PoseStampedMsg { stamp, position_m: [tx, ty, tz], orientation_xyzw: [qx, qy, qz, qw] };
        self.write(3, stamp, &msg.encode("world"))?;
        Ok(())
    }

    /// Writes the summary and closes the file.
    fn finish(mut self) -> Result<(), ConvertError> {
        self.inner.finish().map_err(|e| write_error(&self.path, e))?;
        // The buffer's last bytes: a failed flush is an error, not a silently short file.
        let buffered = self.inner.into_inner();
        buffered.into_inner().map_err(|e| write_error(&self.path, e.error()))?;
        Ok(())
    }
}

/// A writer's error, said about `path`.
fn write_error(path: &Path, e: impl std::fmt::Display) -> ConvertError {
    ConvertError::Write { path: path.to_owned(), reason: e.to_string() }
}
