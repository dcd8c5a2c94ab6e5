//! An MCAP file opened as a recording: its colour and depth topics chosen, their images listed by
//! stamp, its calibration and ground truth read; and its images decoded on request.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::error::McapError;
use super::file::{McapFile, MessageAt, TopicInfo, Visit};
use super::messages::{CAMERA_INFO, CameraInfoMsg, IMAGE, ImageMsg, POSE_STAMPED, PoseStampedMsg};
use super::pixels::{self, COLOUR_ENCODINGS, DEPTH_ENCODINGS, Encoding, PixelError};
use super::time::{EXACT_TIMES_METADATA, ExactTimes, stamp_text};
use super::{CALIBRATION_METADATA, GROUNDTRUTH_TOPIC, McapTopics, camera_info};
use crate::dataset::{
    Calibration, CalibrationOrigin, CalibrationSource, DatasetError, ListEntry, StampedPose,
};
use crate::trajectory::Trajectory;

/// An image message as listed when the file is opened.
#[derive(Debug, Clone)]
struct ImageRecord {
    stamp: super::messages::Stamp,
    width: u32,
    height: u32,
    encoding: String,
    at: MessageAt,
}

/// What the scan of a file keeps: image messages and CameraInfo by topic, ground-truth poses.
#[derive(Debug, Default)]
struct Scanned {
    images: BTreeMap<String, Vec<ImageRecord>>,
    camera_infos: BTreeMap<String, CameraInfoMsg>,
    poses: Vec<PoseStampedMsg>,
}

/// One image stream of a recording: its topic and its messages in stamp order.
#[derive(Debug)]
struct ImageStream {
    topic: String,
    messages: Vec<MessageAt>,
}

/// The images of an opened MCAP recording, decoded on request (see [`McapImages::gray`]).
#[derive(Debug)]
pub struct McapImages {
    file: McapFile,
    rgb: ImageStream,
    depth: ImageStream,
}

/// An MCAP file opened as a recording: what `Dataset::open` makes a dataset of.
#[derive(Debug)]
pub struct McapRecording {
    /// The colour images, in stamp order; `line` is the 1-based number in that order.
    pub rgb: Vec<ListEntry>,
    /// The depth images, likewise.
    pub depth: Vec<ListEntry>,
    /// How the colour stream is named in messages: `FILE:TOPIC`.
    pub rgb_list: PathBuf,
    /// How the depth stream is named in messages.
    pub depth_list: PathBuf,
    /// The ground truth (camera to world) of [`GROUNDTRUTH_TOPIC`], if any.
    pub groundtruth: Option<Trajectory>,
    /// The calibration at the sensor's resolution.
    pub sensor: Calibration,
    /// Where it came from.
    pub origin: CalibrationOrigin,
    /// The images, to decode.
    pub images: McapImages,
}

/// Whether the reader uses messages of `channel`: CDR messages of the three types it reads.
fn wanted(channel: &mcap::Channel<'_>) -> bool {
    let schema = channel.schema.as_ref().map_or("", |s| s.name.as_str());
    channel.message_encoding == "cdr" && [IMAGE, CAMERA_INFO, POSE_STAMPED].contains(&schema)
}

/// Decodes one visited message into `scanned`; `path` names the file in errors.
fn keep(path: &Path, scanned: &mut Scanned, v: Visit<'_>) -> Result<(), McapError> {
    let topic = &v.channel.topic;
    let schema = v.channel.schema.as_ref().map_or("", |s| s.name.as_str());
    let cdr = |schema, message, source| McapError::Cdr {
        path: path.to_owned(),
        topic: topic.clone(),
        message,
        schema,
        source,
    };
    if schema == IMAGE {
        let records = scanned.images.entry(topic.clone()).or_default();
        let msg = ImageMsg::decode(v.data).map_err(|e| cdr(IMAGE, records.len() + 1, e))?;
        let (stamp, width, height) = (msg.stamp, msg.width, msg.height);
        let encoding = msg.encoding.to_owned();
        records.push(ImageRecord { stamp, width, height, encoding, at: v.at });
    } else if schema == CAMERA_INFO {
        if !scanned.camera_infos.contains_key(topic) {
            let info = CameraInfoMsg::decode(v.data).map_err(|e| cdr(CAMERA_INFO, 1, e))?;
            scanned.camera_infos.insert(topic.clone(), info);
        }
    } else if topic == GROUNDTRUTH_TOPIC {
        let message = scanned.poses.len() + 1;
        let pose = PoseStampedMsg::decode(v.data).map_err(|e| cdr(POSE_STAMPED, message, e))?;
        scanned.poses.push(pose);
    }
    Ok(())
}

/// Opens the MCAP file `path` as a recording: the topics `topics` names (or those found by
/// their images' encodings), the calibration `source` says (the file's own: a carried
/// calibration, else its CameraInfo), the ground truth of [`GROUNDTRUTH_TOPIC`].
///
/// # Errors
/// [`DatasetError::Io`] for an unreadable file, the calibration errors of a calibration file, and
/// [`McapError`]s for everything else (see its variants).
pub fn open(
    path: &Path,
    topics: &McapTopics,
    source: &CalibrationSource,
) -> Result<McapRecording, DatasetError> {
    let mut file = McapFile::read(path)?;
    let mut scanned = Scanned::default();
    let all_topics = file.scan(wanted, |v| keep(path, &mut scanned, v))?;
    let exact =
        ExactTimes::from_metadata(&file.metadata(EXACT_TIMES_METADATA)?.unwrap_or_default());
    let listing = list_topics(&all_topics, &scanned.images);
    let chosen = |given: &Option<String>, depth: bool| {
        choose_topic(path, given.as_deref(), depth, &scanned.images, &all_topics, &listing)
    };
    let rgb_topic = chosen(&topics.rgb, false)?;
    let depth_topic = chosen(&topics.depth, true)?;
    let (sensor, origin) = calibration(&file, source, &scanned.camera_infos, &rgb_topic)?;
    let mut stream = |topic: &str| {
        let records = scanned.images.remove(topic).unwrap_or_default();
        image_stream(path, topic, records, &exact, &sensor)
    };
    let (rgb, rgb_stream) = stream(&rgb_topic)?;
    let (depth, depth_stream) = stream(&depth_topic)?;
    let groundtruth = groundtruth(path, &scanned.poses, &exact)?;
    let name = |topic: &str| PathBuf::from(format!("{}:{topic}", path.display()));
    Ok(McapRecording {
        rgb,
        depth,
        rgb_list: name(&rgb_topic),
        depth_list: name(&depth_topic),
        groundtruth,
        sensor,
        origin,
        images: McapImages { file, rgb: rgb_stream, depth: depth_stream },
    })
}

/// Every topic, `TOPIC (TYPE[ ENCODING], N messages)`, joined by commas.
fn list_topics(topics: &[TopicInfo], images: &BTreeMap<String, Vec<ImageRecord>>) -> String {
    let text: Vec<String> = topics
        .iter()
        .map(|t| {
            let schema = if t.schema.is_empty() { "no schema" } else { t.schema.as_str() };
            let encoding = images
                .get(&t.topic)
                .and_then(|r| r.first())
                .map_or(String::new(), |r| format!(" {}", r.encoding));
            format!("{} ({schema}{encoding}, {} messages)", t.topic, t.messages)
        })
        .collect();
    if text.is_empty() { "none".to_owned() } else { text.join(", ") }
}

/// The colour (`depth` false) or depth topic: `given`, checked, or the only image topic whose
/// first image has an encoding of that kind. Every image of the topic must have one.
fn choose_topic(
    path: &Path,
    given: Option<&str>,
    depth: bool,
    images: &BTreeMap<String, Vec<ImageRecord>>,
    topics: &[TopicInfo],
    listing: &str,
) -> Result<String, McapError> {
    let (flag, kind, encodings) = if depth {
        ("--depth-topic", "depth", DEPTH_ENCODINGS)
    } else {
        ("--rgb-topic", "colour", COLOUR_ENCODINGS)
    };
    let of_kind =
        |r: &ImageRecord| Encoding::parse(&r.encoding).is_some_and(|e| e.is_depth() == depth);
    let topic = match given {
        Some(topic) if images.contains_key(topic) => topic.to_owned(),
        Some(topic) => {
            let problem = match topics.iter().find(|t| t.topic == topic) {
                Some(t) => {
                    format!("a {} topic ({}), not {IMAGE} in CDR", t.schema, t.message_encoding)
                }
                None => "no such topic".to_owned(),
            };
            let (path, topic, topics) = (path.to_owned(), topic.to_owned(), listing.to_owned());
            return Err(McapError::Topic { path, flag, topic, problem, topics });
        }
        None => {
            let candidates: Vec<&String> = images
                .iter()
                .filter(|(_, records)| records.first().is_some_and(of_kind))
                .map(|(topic, _)| topic)
                .collect();
            match candidates.as_slice() {
                [one] => (*one).clone(),
                none_or_many => {
                    let found = if none_or_many.is_empty() { "no" } else { "more than one" };
                    let (path, topics) = (path.to_owned(), listing.to_owned());
                    return Err(McapError::NoDefaultTopic {
                        path,
                        found,
                        kind,
                        encodings,
                        flag,
                        topics,
                    });
                }
            }
        }
    };
    let records = images.get(&topic).map_or(&[][..], Vec::as_slice);
    if let Some((i, bad)) = records.iter().enumerate().find(|(_, r)| !of_kind(r)) {
        let source = PixelError::Encoding { encoding: bad.encoding.clone() };
        return Err(McapError::Pixels { path: path.to_owned(), topic, message: i + 1, source });
    }
    Ok(topic)
}

/// The calibration `source` says, and its origin: a file or preset named; else the one the
/// file carries; else its CameraInfo (the one beside the colour topic, or the only one).
fn calibration(
    file: &McapFile,
    source: &CalibrationSource,
    camera_infos: &BTreeMap<String, CameraInfoMsg>,
    rgb_topic: &str,
) -> Result<(Calibration, CalibrationOrigin), DatasetError> {
    let path = file.path();
    match source {
        CalibrationSource::Path(p) => {
            return Ok((Calibration::load(p)?, CalibrationOrigin::File(p.clone())));
        }
        CalibrationSource::Preset(name) => {
            return Ok((Calibration::preset(name)?, CalibrationOrigin::Preset(name.clone())));
        }
        CalibrationSource::File => {}
    }
    if let Some(carried) = file.metadata(CALIBRATION_METADATA)? {
        let file_path = path.to_owned();
        if let Some(text) = carried.get("calibration.toml") {
            let named = PathBuf::from(format!("{}:calibration.toml", path.display()));
            let what = "calibration.toml".to_owned();
            let origin = CalibrationOrigin::Carried { file: file_path, what };
            return Ok((Calibration::from_toml_str(text, &named)?, origin));
        }
        if let Some(name) = carried.get("preset") {
            let what = format!("preset {name}");
            let origin = CalibrationOrigin::Carried { file: file_path, what };
            return Ok((Calibration::preset(name)?, origin));
        }
    }
    let beside = rgb_topic.rsplit_once('/').map(|(ns, _)| format!("{ns}/camera_info"));
    let info = match beside.as_ref().and_then(|t| camera_infos.get_key_value(t)) {
        Some(found) => found,
        None if camera_infos.len() == 1 => camera_infos
            .iter()
            .next()
            .ok_or_else(|| McapError::NoCalibration { path: path.to_owned() })?,
        None if camera_infos.is_empty() => {
            return Err(McapError::NoCalibration { path: path.to_owned() }.into());
        }
        None => {
            let topics = camera_infos.keys().cloned().collect::<Vec<_>>().join(", ");
            let rgb_topic = rgb_topic.to_owned();
            return Err(McapError::AmbiguousCameraInfo {
                path: path.to_owned(),
                topics,
                rgb_topic,
            }
            .into());
        }
    };
    let (topic, info) = info;
    let calibration = camera_info::calibration(path, topic, info)?;
    let origin = CalibrationOrigin::CameraInfo { file: path.to_owned(), topic: topic.clone() };
    Ok((calibration, origin))
}

/// The list entries of one topic's images and where each is, in stamp order, each checked to
/// be the calibrated size.
fn image_stream(
    path: &Path,
    topic: &str,
    mut records: Vec<ImageRecord>,
    exact: &ExactTimes,
    sensor: &Calibration,
) -> Result<(Vec<ListEntry>, ImageStream), McapError> {
    records.sort_by_key(|r| r.stamp);
    if let Some(w) = records.windows(2).find(|w| w[0].stamp == w[1].stamp) {
        let (path, topic, stamp) = (path.to_owned(), topic.to_owned(), stamp_text(w[0].stamp));
        return Err(McapError::DuplicateStamp { path, topic, stamp });
    }
    let expected = (sensor.width, sensor.height);
    if let Some((i, r)) = records.iter().enumerate().find(|(_, r)| (r.width, r.height) != expected)
    {
        return Err(McapError::ImageSize {
            path: path.to_owned(),
            topic: topic.to_owned(),
            message: i + 1,
            width: r.width,
            height: r.height,
            expected_width: expected.0,
            expected_height: expected.1,
        });
    }
    let entries = records
        .iter()
        .enumerate()
        .map(|(i, r)| ListEntry {
            timestamp_s: exact.seconds(r.stamp),
            path: PathBuf::from(format!("{}:{topic}#{}", path.display(), i + 1)),
            line: i + 1,
        })
        .collect();
    let messages = records.into_iter().map(|r| r.at).collect();
    Ok((entries, ImageStream { topic: topic.to_owned(), messages }))
}

/// The ground truth from [`GROUNDTRUTH_TOPIC`]'s poses (in file order, stamps increasing), or
/// `None` without any.
fn groundtruth(
    path: &Path,
    poses: &[PoseStampedMsg],
    exact: &ExactTimes,
) -> Result<Option<Trajectory>, McapError> {
    let mut out: Vec<StampedPose> = Vec::with_capacity(poses.len());
    for (i, p) in poses.iter().enumerate() {
        let bad = |reason| McapError::Groundtruth {
            path: path.to_owned(),
            topic: GROUNDTRUTH_TOPIC.to_owned(),
            message: i + 1,
            reason,
        };
        let t_s = exact.seconds(p.stamp);
        let pose = StampedPose::from_tum_values(t_s, p.position_m, p.orientation_xyzw)
            .ok_or_else(|| bad("its orientation is not a rotation (zero or not finite)"))?;
        if out.last().is_some_and(|last| last.timestamp_s >= t_s) {
            return Err(bad("its stamp is not after the previous pose's"));
        }
        out.push(pose);
    }
    Ok(if out.is_empty() { None } else { Some(Trajectory::new(out)) })
}

impl McapImages {
    /// The colour image with 1-based number `line` (in stamp order) as 8-bit gray.
    ///
    /// # Errors
    /// [`McapError`]s naming the topic and message.
    pub fn gray(&self, line: usize) -> Result<Vec<u8>, DatasetError> {
        self.decode(&self.rgb, line, pixels::gray)
    }

    /// The depth image with 1-based number `line` as raw samples of `depth_scale` units per metre.
    ///
    /// # Errors
    /// [`McapError`]s naming the topic and message.
    pub fn depth(&self, line: usize, depth_scale: f32) -> Result<Vec<u16>, DatasetError> {
        self.decode(&self.depth, line, |m| pixels::depth(m, depth_scale))
    }

    /// Message `line` of `stream` decoded, its pixels converted by `convert`.
    fn decode<T>(
        &self,
        stream: &ImageStream,
        line: usize,
        convert: impl Fn(&ImageMsg<'_>) -> Result<T, PixelError>,
    ) -> Result<T, DatasetError> {
        let path = self.file.path();
        let topic = || stream.topic.clone();
        let at = line.checked_sub(1).and_then(|i| stream.messages.get(i));
        let len = stream.messages.len();
        let at = at.ok_or(DatasetError::FrameIndex { index: line, len })?;
        let bytes = self.file.message(at)?;
        let msg = ImageMsg::decode(&bytes).map_err(|source| McapError::Cdr {
            path: path.to_owned(),
            topic: topic(),
            message: line,
            schema: IMAGE,
            source,
        })?;
        let message = line;
        let pixels = convert(&msg).map_err(|source| McapError::Pixels {
            path: path.to_owned(),
            topic: topic(),
            message,
            source,
        })?;
        Ok(pixels)
    }
}
