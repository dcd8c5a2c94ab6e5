//! A run's results as an MCAP file of Foxglove messages (`replay ... --mcap OUT.mcap`, `demo
//! --mcap OUT.mcap`), so that Foxglove and other MCAP tools open a run.
//!
//! Every message uses a Foxglove well-known schema, named as Foxglove names it
//! (`foxglove.PoseInFrame`, ...), JSON-encoded (message encoding `json`, schema encoding
//! `jsonschema`: [`schemas`]); JSON is the route Foxglove documents for its schemas without
//! generated code, at a size zstd keeps small (why and the figures: `docs/decisions.md`).
//!
//! Frames: everything is in `world`, the run's world frame (its first keyframe's camera: x
//! right, y down, z forward), metres; `camera` is the camera, placed in `world` by `/tf`.
//! Topics ([`Topic`]):
//! - per posed frame, at its timestamp: `/camera/pose` (PoseInFrame, the final pose of
//!   CameraTrajectory.txt), `/tf` (FrameTransform `world` -> `camera`, the same pose),
//!   `/camera/online_pose` (PoseInFrame, the pose the front end output at that frame), and with
//!   ground truth `/groundtruth/pose` (PoseInFrame, moved into `world` by the evaluation's
//!   alignment, as report.html draws it);
//! - once, stamped with the first pose's time so that a player shows them from the start:
//!   `/trajectory` and `/groundtruth/trajectory` (PosesInFrame), `/map/points` and
//!   `/map/points_newest` (PointCloud: x, y, z as f32; the map's points over the run, and those
//!   new in the last keyframe), `/map/planes` (SceneUpdate: a 0.4 m square, 5 mm thick, about
//!   each plane's centroid, across its normal);
//! - `/map/keyframes` (SceneUpdate): at each keyframe's frame, an arrow from its final camera
//!   centre along its optical axis;
//! - `/ar/anchors` (SceneUpdate): at each placement's frame, a cube standing on its plane where
//!   it was placed (0.15 m x its scale, the object's colour of `ar/`), replacing the object's
//!   earlier one; removed at a script's remove;
//! - `/events` (Log): relocalizations, loops closed, anchor script steps (a refused one is a
//!   warning).
//!
//! The file is written after the run, from its [`TrackingRun`]: the final poses are known only
//! then. It is reproducible: the same run gives the same bytes (no wall-clock time anywhere,
//! messages in time order then topic order, zstd on the writing thread), in chunks of 1 MiB
//! (the `mcap` crate's default), zstd-compressed, with the crate's default indexes and summary.

pub mod content;
pub mod foxglove;
pub mod schemas;

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use mcap::records::MessageHeader;

pub use content::Topic;
use content::{Message, messages};

use crate::eval::EvalReport;
use crate::run::TrackingRun;

/// Why a run's MCAP file could not be written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum McapOutError {
    /// The file could not be created or written.
    #[error("cannot write the MCAP file {}: {reason}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// What the system or the writer said.
        reason: String,
    },
}

/// What [`write_run_mcap`] wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct McapWritten {
    /// Messages written, by topic (topics without one are not declared).
    pub messages: BTreeMap<&'static str, usize>,
    /// The file's size, bytes.
    pub bytes: u64,
}

/// The `mcap` writer's options: zstd chunks of the crate's default size, compressed on this
/// thread (the crate's default starts a worker per physical core: nothing in the output is left
/// to the machine), and this program as the library (not the crate's version).
fn write_options() -> mcap::WriteOptions {
    mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .chunk_size(Some(mcap::WriteOptions::DEFAULT_CHUNK_SIZE))
        .compression_threads(0)
        .library("ferroslam-sim")
}

/// Writes `run` (with the ground truth of `evaluation`, when there is one) to the MCAP file
/// `path` (see the module doc), replacing any file there.
///
/// # Errors
/// [`McapOutError::Write`] naming `path`, when it cannot be created or written (a missing
/// folder among them).
pub fn write_run_mcap(
    path: &Path,
    run: &TrackingRun,
    evaluation: Option<&EvalReport>,
) -> Result<McapWritten, McapOutError> {
    let err = |e: &dyn std::fmt::Display| McapOutError::Write {
        path: path.to_owned(),
        reason: e.to_string(),
    };
    let mut all = messages(run, evaluation);
    // Stable: a topic's messages of one time stay in the order made.
    all.sort_by_key(|m| (m.time, m.topic));
    let file = File::create(path).map_err(|e| err(&e))?;
    let mut writer = write_options().create(BufWriter::new(file)).map_err(|e| err(&e))?;
    let channels = declare_channels(&mut writer, &all).map_err(|e| err(&e))?;
    let mut sequence: BTreeMap<Topic, u32> = BTreeMap::new();
    for Message { topic, time, body } in &all {
        let Some(&channel_id) = channels.get(topic) else { continue };
        let number = sequence.entry(*topic).or_default();
        let header = MessageHeader {
            channel_id,
            sequence: *number,
            log_time: time.nanos(),
            publish_time: time.nanos(),
        };
        *number += 1;
        let data = serde_json::to_vec(body).map_err(|e| err(&e))?;
        writer.write_to_known_channel(&header, &data).map_err(|e| err(&e))?;
    }
    writer.finish().map_err(|e| err(&e))?;
    // The buffer's last bytes: a failed flush is an error, not a silently short file.
    let file = writer.into_inner().into_inner().map_err(|e| err(&e.error()))?;
    let bytes = file.metadata().map_err(|e| err(&e))?.len();
    let mut counts = BTreeMap::new();
    for m in &all {
        *counts.entry(m.topic.name()).or_insert(0) += 1;
    }
    Ok(McapWritten { messages: counts, bytes })
}

/// Declares a channel for every topic with a message, in [`Topic::ALL`]'s order, each schema
/// once; returns the channel ids.
fn declare_channels<W: std::io::Write + std::io::Seek>(
    writer: &mut mcap::Writer<W>,
    all: &[Message],
) -> Result<BTreeMap<Topic, u16>, mcap::McapError> {
    let no_metadata = BTreeMap::new();
    let mut schema_ids = BTreeMap::new();
    let mut channels = BTreeMap::new();
    for topic in Topic::ALL.into_iter().filter(|t| all.iter().any(|m| m.topic == *t)) {
        let schema = topic.schema();
        let schema_id = match schema_ids.get(&schema) {
            Some(&id) => id,
            None => {
                let id =
                    writer.add_schema(schema.name(), "jsonschema", schema.text().as_bytes())?;
                schema_ids.insert(schema, id);
                id
            }
        };
        channels.insert(topic, writer.add_channel(schema_id, topic.name(), "json", &no_metadata)?);
    }
    Ok(channels)
}
