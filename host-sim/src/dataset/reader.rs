//! [`DatasetReader`]: frames decoded ahead of the pipeline on another thread.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

use ferroslam_core::frame::{FrameSource, RgbdFrame};

use super::{Dataset, DatasetError, OwnedFrame};

/// What the decoding thread sends: frame `index` decoded, or why it could not be.
type Item = Result<OwnedFrame, DatasetError>;

/// How frames are produced.
#[derive(Debug)]
enum Decoder {
    /// A thread decodes ahead into a bounded channel.
    Thread { rx: Receiver<Item>, stop: Arc<AtomicBool>, worker: JoinHandle<()> },
    /// The thread could not be spawned: frames are decoded on the caller's thread.
    Inline,
    /// Dropped or finished: nothing more will come.
    Done,
}

/// A [`FrameSource`] over a [`Dataset`] whose frames are decoded on a separate thread, up to
/// `read_ahead` frames ahead of the caller, through a bounded `std::sync::mpsc::sync_channel`. The
/// pipeline's time per frame is then not the decoder's, as long as decoding keeps up.
///
/// Frames come in dataset order. A frame that cannot be decoded is returned as that call's
/// `Err` in its place in the order; the next call goes on with the following frame. After the last
/// frame every call returns `Ok(None)`. Dropping the reader stops the thread (it finishes the frame
/// it is decoding, then sees the closed channel) and joins it.
///
/// Memory: up to `read_ahead + 2` decoded frames exist at once (the queue, the one being decoded,
/// the one lent out); at VGA one frame is 0.9 MB. A `read_ahead` of 0 still decodes the next frame
/// on the thread while the caller works, then waits for the caller to take it.
#[derive(Debug)]
pub struct DatasetReader {
    dataset: Arc<Dataset>,
    decoder: Decoder,
    /// Frames (or their errors) handed out so far.
    next_index: usize,
    /// The frame lent out by the last `next_frame`.
    current: Option<OwnedFrame>,
}

impl DatasetReader {
    /// Starts the decoding thread over `dataset`. If the operating system refuses a thread, the
    /// reader decodes on the caller's thread instead (same frames, no read-ahead).
    pub(crate) fn new(dataset: Dataset, read_ahead: usize) -> Self {
        let dataset = Arc::new(dataset);
        let (tx, rx) = sync_channel(read_ahead);
        let stop = Arc::new(AtomicBool::new(false));
        let spawned = std::thread::Builder::new().name("dataset-read-ahead".into()).spawn({
            let (dataset, stop) = (Arc::clone(&dataset), Arc::clone(&stop));
            move || decode_all(&dataset, &tx, &stop)
        });
        let decoder = match spawned {
            Ok(worker) => Decoder::Thread { rx, stop, worker },
            Err(_) => Decoder::Inline,
        };
        Self { dataset, decoder, next_index: 0, current: None }
    }

    /// The dataset being read (calibration, ground truth, frame list).
    pub fn dataset(&self) -> &Dataset {
        &self.dataset
    }

    /// Frames handed out so far (including ones returned as errors).
    pub fn position(&self) -> usize {
        self.next_index
    }

    /// The next decoded frame, owned: `Ok(None)` after the last. Same order and error behaviour as
    /// [`FrameSource::next_frame`], without the borrow.
    ///
    /// # Errors
    /// The frame's [`DatasetError`] (see [`Dataset::load_frame`]), or
    /// [`DatasetError::ReaderStopped`] when the decoding thread died early.
    pub fn next_owned(&mut self) -> Result<Option<OwnedFrame>, DatasetError> {
        let len = self.dataset.len();
        let item = match &self.decoder {
            Decoder::Done => return Ok(None),
            Decoder::Inline if self.next_index >= len => None,
            Decoder::Inline => Some(self.dataset.load_frame(self.next_index)),
            Decoder::Thread { rx, .. } => rx.recv().ok(),
        };
        let Some(item) = item else {
            self.shutdown();
            if self.next_index < len {
                return Err(DatasetError::ReaderStopped { delivered: self.next_index, len });
            }
            return Ok(None);
        };
        self.next_index += 1;
        item.map(Some)
    }

    /// Stops and joins the thread, if any; afterwards nothing more is produced.
    fn shutdown(&mut self) {
        if let Decoder::Thread { rx, stop, worker } =
            std::mem::replace(&mut self.decoder, Decoder::Done)
        {
            stop.store(true, Ordering::Relaxed);
            // Closing the channel wakes a thread blocked in `send`.
            drop(rx);
            // A panic on the thread has already been reported by the panic hook; the reader's
            // caller learns of it as `ReaderStopped`.
            let _ = worker.join();
        }
    }
}

/// The thread's loop: decodes every frame in order until done, stopped, or the reader is gone.
fn decode_all(dataset: &Dataset, tx: &SyncSender<Item>, stop: &AtomicBool) {
    for index in 0..dataset.len() {
        if stop.load(Ordering::Relaxed) {
            return;
        }
        if tx.send(dataset.load_frame(index)).is_err() {
            return;
        }
    }
}

impl FrameSource for DatasetReader {
    type Error = DatasetError;

    /// The next frame, borrowed until the next call; see [`DatasetReader`] for order and errors.
    fn next_frame(&mut self) -> Result<Option<RgbdFrame<'_>>, DatasetError> {
        self.current = None;
        let Some(frame) = self.next_owned()? else { return Ok(None) };
        let index = self.next_index - 1;
        let frame = self.current.insert(frame);
        frame.view().map(Some).map_err(|source| DatasetError::Image {
            path: self.dataset.frames().get(index).map(|f| f.rgb_path.clone()).unwrap_or_default(),
            source,
        })
    }
}

impl Drop for DatasetReader {
    fn drop(&mut self) {
        self.shutdown();
    }
}
