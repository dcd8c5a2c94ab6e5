//! An MCAP file held in memory: its messages visited once when it is opened, and an image's bytes
//! found again when its frame is decoded.
//!
//! The whole file is read into memory (a host tool; memory = the file's size). A file with a
//! summary whose chunks all carry message indexes is read back message by message through those
//! indexes ([`MessageAt::Chunk`]: one chunk decompressed per image); any other (no summary, no
//! message indexes, messages outside chunks) is read start to end and the messages visited are
//! kept decompressed ([`MessageAt::Memory`]).

use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use mcap::read::{MessageStream, Summary};
use mcap::records::{MessageIndexEntry, Record};
use mcap::{Channel, Message};

use super::error::McapError;
use crate::dataset::DatasetError;

/// Where a message's bytes are.
#[derive(Debug, Clone)]
pub enum MessageAt {
    /// In chunk `chunk` (an index into the summary's chunk indexes), at `entry`.
    Chunk {
        /// Index of the chunk in the summary.
        chunk: usize,
        /// The message's index entry in that chunk.
        entry: MessageIndexEntry,
    },
    /// Kept in memory, decompressed.
    Memory(Arc<[u8]>),
}

/// A topic of the file: its message type, encoding and message count.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicInfo {
    /// The topic.
    pub topic: String,
    /// Its schema's name (`sensor_msgs/msg/Image`), empty without a schema.
    pub schema: String,
    /// Its message encoding (`cdr`).
    pub message_encoding: String,
    /// Messages on it.
    pub messages: usize,
}

/// A message visited by [`McapFile::scan`].
#[derive(Debug)]
pub struct Visit<'a> {
    /// Its channel.
    pub channel: &'a Channel<'a>,
    /// Its bytes.
    pub data: &'a [u8],
    /// Where to find them again.
    pub at: MessageAt,
}

/// An MCAP file read into memory.
pub struct McapFile {
    path: PathBuf,
    bytes: Vec<u8>,
    summary: Option<Summary>,
    /// Whether every message can be found through the summary's indexes (set by the scan).
    indexed: bool,
}

impl std::fmt::Debug for McapFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McapFile")
            .field("path", &self.path)
            .field("bytes", &self.bytes.len())
            .field("indexed", &self.indexed)
            .finish()
    }
}

/// The largest chunk this reader decompresses, bytes (the `mcap` crate reserves a chunk's
/// declared uncompressed size before reading it, so a damaged size would abort the process;
/// recorders write chunks of a few megabytes).
const MAX_CHUNK_BYTES: u64 = 1 << 30;

/// Opcode of a chunk record.
const CHUNK_OPCODE: u8 = 0x06;

/// Walks the records after the magic and refuses a chunk record whose declared uncompressed size
/// is over [`MAX_CHUNK_BYTES`]. Records whose lengths run past the end stop the walk (the reader
/// then says what is wrong).
fn check_chunk_sizes(bytes: &[u8]) -> Result<(), String> {
    let u64_at = |at: usize| -> Option<u64> {
        bytes
            .get(at..at.checked_add(8)?)
            .map(|b| u64::from_le_bytes(b.try_into().unwrap_or([0; 8])))
    };
    let mut at = mcap::MAGIC.len();
    while let (Some(&opcode), Some(length)) = (bytes.get(at), u64_at(at + 1)) {
        let body = at + 9;
        if opcode == CHUNK_OPCODE {
            // Message start and end times (8 bytes each), then the uncompressed size.
            if let Some(size) = u64_at(body + 16).filter(|&s| s > MAX_CHUNK_BYTES) {
                return Err(format!(
                    "a chunk at byte {at} says {size} bytes uncompressed, over the \
                     {MAX_CHUNK_BYTES} this reader takes"
                ));
            }
        }
        let Some(next) = usize::try_from(length).ok().and_then(|l| body.checked_add(l)) else {
            break;
        };
        at = next;
    }
    Ok(())
}

/// Reads the file once start to end, chunks decompressed, with the `mcap` crate's record length
/// limit at [`MAX_CHUNK_BYTES`], and refuses a record over it. The crate's message stream and
/// chunk reader set no limit and reserve a record's declared length before reading it, so a
/// damaged length inside a compressed chunk would abort the process; after this pass the file
/// holds none. Other errors are left to the reading that follows, which says them in its terms.
/// Cost: one decompression of every chunk.
fn check_record_lengths(bytes: &[u8]) -> Result<(), String> {
    check_records_from(bytes, false, false)
}

/// [`check_record_lengths`] of `bytes`, a whole file or (`records_only`) records without the
/// file's magic, as a chunk index addresses them; `strict`: any error of the reading is one.
fn check_records_from(bytes: &[u8], records_only: bool, strict: bool) -> Result<(), String> {
    use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
    let limit = usize::try_from(MAX_CHUNK_BYTES).unwrap_or(usize::MAX);
    let options = LinearReaderOptions::default()
        .with_record_length_limit(limit)
        .with_skip_start_magic(records_only)
        .with_skip_end_magic(records_only);
    let mut reader = LinearReader::new_with_options(options);
    let mut rest = bytes;
    while let Some(event) = reader.next_event() {
        match event {
            Ok(LinearReadEvent::ReadRequest(need)) => {
                let n = need.min(rest.len());
                reader.insert(n).copy_from_slice(&rest[..n]);
                reader.notify_read(n);
                rest = &rest[n..];
            }
            Ok(LinearReadEvent::Record { .. }) => {}
            Err(
                e @ (mcap::McapError::RecordTooLarge { .. } | mcap::McapError::ChunkTooLarge(_)),
            ) => {
                return Err(e.to_string());
            }
            Err(e) if strict => return Err(e.to_string()),
            Err(_) => break,
        }
    }
    Ok(())
}

/// The MCAP reader's error, said about `path`.
fn malformed(path: &Path, e: impl std::fmt::Display) -> McapError {
    McapError::Malformed { path: path.to_owned(), reason: e.to_string() }
}

impl McapFile {
    /// Reads `path` whole and its summary, if it has one.
    ///
    /// # Errors
    /// [`DatasetError::Io`] when it cannot be read, [`McapError::Malformed`] for a damaged
    /// summary or a file that is not MCAP.
    pub fn read(path: &Path) -> Result<Self, DatasetError> {
        let bytes = std::fs::read(path)
            .map_err(|source| DatasetError::Io { path: path.to_owned(), source })?;
        if !bytes.starts_with(mcap::MAGIC) {
            return Err(malformed(path, "it does not start with the MCAP magic").into());
        }
        check_chunk_sizes(&bytes).map_err(|e| malformed(path, e))?;
        let summary = Summary::read(&bytes).map_err(|e| malformed(path, e))?;
        let oversized = summary
            .as_ref()
            .and_then(|s| s.chunk_indexes.iter().find(|c| c.uncompressed_size > MAX_CHUNK_BYTES));
        if let Some(c) = oversized {
            let size = c.uncompressed_size;
            return Err(malformed(path, format!("a chunk index says {size} bytes uncompressed, over the {MAX_CHUNK_BYTES} this reader takes")).into());
        }
        Ok(Self { path: path.to_owned(), bytes, summary, indexed: false })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Visits every message whose channel `wanted` accepts, in file order within each topic, and
    /// returns every topic of the file with its message count.
    ///
    /// # Errors
    /// [`McapError::Malformed`] for a damaged file; the first error `visit` returns.
    pub fn scan(
        &mut self,
        wanted: impl Fn(&Channel<'_>) -> bool,
        mut visit: impl FnMut(Visit<'_>) -> Result<(), McapError>,
    ) -> Result<Vec<TopicInfo>, McapError> {
        let mut counts: BTreeMap<String, TopicInfo> = BTreeMap::new();
        let mut count = |channel: &Channel<'_>| {
            let info = counts.entry(channel.topic.clone()).or_insert_with(|| TopicInfo {
                topic: channel.topic.clone(),
                schema: channel.schema.as_ref().map_or(String::new(), |s| s.name.clone()),
                message_encoding: channel.message_encoding.clone(),
                messages: 0,
            });
            info.messages += 1;
        };
        if let Some(summary) = self.summary.as_ref().filter(|s| fully_indexed(&self.bytes, s)) {
            // A chunk without message indexes holds no message here (the counts matched): a
            // writer's schemas and channels before its first message.
            let chunks = summary.chunk_indexes.iter().enumerate();
            for (chunk, index) in chunks.filter(|(_, c)| !c.message_index_offsets.is_empty()) {
                let entries = summary.read_message_indexes(&self.bytes, index);
                let mut entries: HashMap<u16, Vec<MessageIndexEntry>> = entries
                    .map_err(|e| malformed(&self.path, e))?
                    .into_iter()
                    .map(|(c, mut e)| {
                        e.sort_by_key(|e| std::cmp::Reverse(e.offset));
                        (c.id, e)
                    })
                    .collect();
                let stream = summary.stream_chunk(&self.bytes, index);
                for message in stream.map_err(|e| malformed(&self.path, e))? {
                    let message = message.map_err(|e| malformed(&self.path, e))?;
                    count(&message.channel);
                    let entry = entries.get_mut(&message.channel.id).and_then(Vec::pop);
                    let Some(entry) = entry else {
                        return Err(malformed(&self.path, "a chunk's message index is short"));
                    };
                    if wanted(&message.channel) {
                        let at = MessageAt::Chunk { chunk, entry };
                        visit(Visit { channel: &message.channel, data: &message.data, at })?;
                    }
                }
            }
            self.indexed = true;
        } else {
            // Read with the crate's record length limit first (the indexed path checks its
            // chunks in `fully_indexed`).
            check_record_lengths(&self.bytes).map_err(|e| malformed(&self.path, e))?;
            let stream = MessageStream::new(&self.bytes).map_err(|e| malformed(&self.path, e))?;
            for message in stream {
                let Message { channel, data, .. } =
                    message.map_err(|e| malformed(&self.path, e))?;
                count(&channel);
                if wanted(&channel) {
                    let data: Arc<[u8]> = Arc::from(data.into_owned());
                    let at = MessageAt::Memory(Arc::clone(&data));
                    visit(Visit { channel: &channel, data: &data, at })?;
                }
            }
        }
        Ok(counts.into_values().collect())
    }

    /// The bytes of the message at `at`.
    ///
    /// # Errors
    /// [`McapError::Malformed`] when the chunk cannot be read again.
    pub fn message<'a>(&'a self, at: &'a MessageAt) -> Result<Cow<'a, [u8]>, McapError> {
        match at {
            MessageAt::Memory(data) => Ok(Cow::Borrowed(data)),
            MessageAt::Chunk { chunk, entry } => {
                let summary = self.summary.as_ref().filter(|_| self.indexed);
                let index = summary.and_then(|s| s.chunk_indexes.get(*chunk).map(|i| (s, i)));
                let Some((summary, index)) = index else {
                    return Err(malformed(&self.path, "a message's chunk is not indexed"));
                };
                let message = summary.seek_message(&self.bytes, index, entry);
                Ok(Cow::Owned(message.map_err(|e| malformed(&self.path, e))?.data.into_owned()))
            }
        }
    }

    /// The map of the metadata record named `name`, if the file has one (the first).
    ///
    /// # Errors
    /// [`McapError::Malformed`] for a damaged record.
    pub fn metadata(&self, name: &str) -> Result<Option<BTreeMap<String, String>>, McapError> {
        if let Some(summary) = self.summary.as_ref().filter(|s| !s.metadata_indexes.is_empty()) {
            let Some(index) = summary.metadata_indexes.iter().find(|i| i.name == name) else {
                return Ok(None);
            };
            let end = index.offset.checked_add(index.length);
            if end.is_none_or(|end| end > self.bytes.len() as u64) {
                return Err(malformed(&self.path, "a metadata index points past the end"));
            }
            let record = mcap::read::metadata(&self.bytes, index);
            return Ok(Some(record.map_err(|e| malformed(&self.path, e))?.metadata));
        }
        // No metadata index: look through the top-level records.
        let reader =
            mcap::read::LinearReader::new(&self.bytes).map_err(|e| malformed(&self.path, e))?;
        for record in reader {
            if let Record::Metadata(m) = record.map_err(|e| malformed(&self.path, e))?
                && m.name == name
            {
                return Ok(Some(m.metadata));
            }
        }
        Ok(None)
    }
}

/// Bytes of a record's opcode and length.
const RECORD_HEADER_LEN: u64 = 9;
/// Bytes of the shortest message index record (no entry).
const MIN_MESSAGE_INDEX_LEN: u64 = RECORD_HEADER_LEN + 2 + 4;

/// Whether every message of the file is in a chunk whose message indexes list it: the summary's
/// statistics count as many messages as the chunks' message indexes hold.
fn fully_indexed(bytes: &[u8], summary: &Summary) -> bool {
    let Some(stats) = &summary.stats else { return false };
    // The mcap crate slices the file at these offsets; a damaged index is not followed.
    let len = bytes.len() as u64;
    let within = |start: u64, length: u64| start.checked_add(length).is_some_and(|end| end <= len);
    let sane = summary.chunk_indexes.iter().all(|c| {
        c.chunk_length >= RECORD_HEADER_LEN
            && within(c.chunk_start_offset, c.chunk_length)
            && c.message_index_offsets.values().all(|&o| within(o, MIN_MESSAGE_INDEX_LEN))
    });
    if !sane {
        return false;
    }
    // The crate's chunk reader sets no record length limit: each indexed chunk is read once with
    // one first (the index may address other bytes than a start-to-end reading visits), and a
    // chunk that does not read cleanly so sends the file to the start-to-end reading.
    let chunks_ok = summary.chunk_indexes.iter().all(|c| {
        let (start, end) =
            (c.chunk_start_offset as usize, (c.chunk_start_offset + c.chunk_length) as usize);
        // Read as the crate's chunk reader reads it: a chunk record of the index's length,
        // whatever opcode the file has there.
        bytes.get(start.saturating_add(9)..end).is_some_and(|body| {
            let mut record = Vec::with_capacity(body.len() + 9);
            record.push(CHUNK_OPCODE);
            record.extend_from_slice(&(body.len() as u64).to_le_bytes());
            record.extend_from_slice(body);
            check_records_from(&record, true, true).is_ok()
        })
    });
    if !chunks_ok {
        return false;
    }
    let mut indexed = 0u64;
    for index in summary.chunk_indexes.iter().filter(|c| !c.message_index_offsets.is_empty()) {
        match summary.read_message_indexes(bytes, index) {
            Ok(entries) => indexed += entries.values().map(|e| e.len() as u64).sum::<u64>(),
            Err(_) => return false,
        }
    }
    indexed == stats.message_count
}
