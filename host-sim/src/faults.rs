//! [`FaultySource`]: a fault injector wrapping any [`FrameSource`], in the style of smoltcp's
//! fault-injecting devices: it drops, duplicates, reorders or re-stamps frames, corrupts rows,
//! blacks out or saturates images, or swaps in a frame of another scene, at a given rate over a
//! given span of frames. Seeded and deterministic: the same plan over the same frames injects the
//! same faults, so a fault run is as reproducible as a clean one.
//!
//! What the core does with each fault is its documented behaviour (see `docs/reliability.md`):
//! a frame whose timestamp does not increase is rejected with nothing changed, a frame of another
//! size is rejected, an image with nothing to track gives a lost frame whose pose is the
//! prediction.

use std::collections::VecDeque;
use std::ops::Range;

use ferroslam_core::frame::{FrameSource, RgbdFrame};
use ferroslam_core::image::ImageError;
use ferroslam_core::pose::TrackingRng;

use crate::frame::{OwnedFrame, halve_frame};

/// One kind of frame fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum FrameFault {
    /// The frame never arrives (a lost DMA buffer).
    Drop,
    /// The frame arrives twice, the copy stamped halfway to the next frame (a driver that
    /// re-sends its buffer).
    Duplicate,
    /// The frame arrives after the next one (out of order: its timestamp then goes backwards).
    Reorder,
    /// The frame carries the previous frame's timestamp (a clock glitch).
    RepeatTimestamp,
    /// A band of an eighth of the rows is noise in gray and depth (a torn transfer).
    CorruptRows,
    /// The gray image is all 0 (lights off, a covered lens); depth unchanged.
    Black,
    /// The gray image is all 255 and the depth has no reading (sensor saturated by sunlight).
    Saturated,
    /// The images are those of another scene, the timestamp this frame's (a wrong buffer).
    OtherScene,
}

impl FrameFault {
    /// Every fault, in declaration order.
    pub const ALL: [Self; 8] = [
        Self::Drop,
        Self::Duplicate,
        Self::Reorder,
        Self::RepeatTimestamp,
        Self::CorruptRows,
        Self::Black,
        Self::Saturated,
        Self::OtherScene,
    ];

    /// The fault's name in reports and on the command line (`drop`, `corrupt-rows`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Self::Drop => "drop",
            Self::Duplicate => "duplicate",
            Self::Reorder => "reorder",
            Self::RepeatTimestamp => "repeat-timestamp",
            Self::CorruptRows => "corrupt-rows",
            Self::Black => "black",
            Self::Saturated => "saturated",
            Self::OtherScene => "other-scene",
        }
    }
}

/// Which frames a [`FaultySource`] hits: each input frame whose index is in `span` is hit with
/// probability `rate`, drawn from a generator seeded by `seed`.
#[derive(Debug, Clone, PartialEq)]
pub struct FaultPlan {
    /// The fault injected.
    pub fault: FrameFault,
    /// Probability that a frame in `span` is hit, in `[0, 1]`.
    pub rate: f64,
    /// Input frame indices (0-based, in the wrapped source's order) that may be hit; frames after
    /// it are passed through clean, so a run shows whether tracking recovers.
    pub span: Range<usize>,
    /// The generator's seed.
    pub seed: u64,
}

/// A fault the source injected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Injected {
    /// Index of the hit frame in the wrapped source's order.
    pub input_index: usize,
    /// The fault.
    pub fault: FrameFault,
}

/// Why a [`FaultySource`] could not give a frame.
#[derive(Debug, thiserror::Error)]
pub enum FaultySourceError<E: std::error::Error + 'static> {
    /// The wrapped source failed.
    #[error(transparent)]
    Source(E),
    /// A frame could not be copied or lent (never for a well-formed source).
    #[error("copying the frame failed: {0}")]
    Image(#[from] ImageError),
}

/// Any [`FrameSource`] with the faults of a [`FaultPlan`] injected (see the module
/// documentation). Frames are copied, so the wrapper costs one frame copy per frame.
#[derive(Debug)]
pub struct FaultySource<S> {
    inner: S,
    plan: FaultPlan,
    rng: TrackingRng,
    /// Frames taken from `inner` so far.
    taken: usize,
    /// Frames ready to go out, in order.
    queue: VecDeque<OwnedFrame>,
    /// The frame lent out by the last `next_frame`.
    current: Option<OwnedFrame>,
    /// Timestamps of the last two frames taken from `inner` (the one before the latest, the
    /// latest), seconds.
    previous_s: Option<f64>,
    latest_s: Option<f64>,
    /// The frames [`FrameFault::OtherScene`] swaps in, in turn.
    foreign: Vec<OwnedFrame>,
    next_foreign: usize,
    injected: Vec<Injected>,
}

impl<S> FaultySource<S> {
    /// Wraps `inner` with the faults of `plan`; `foreign` holds the frames that
    /// [`FrameFault::OtherScene`] swaps in (used in turn; with none, that fault leaves frames
    /// clean and injects nothing).
    pub fn new(inner: S, plan: FaultPlan, foreign: Vec<OwnedFrame>) -> Self {
        Self {
            inner,
            rng: TrackingRng::new(plan.seed),
            plan,
            taken: 0,
            queue: VecDeque::new(),
            current: None,
            previous_s: None,
            latest_s: None,
            foreign,
            next_foreign: 0,
            injected: Vec::new(),
        }
    }

    /// The faults injected so far, in order.
    pub fn injected(&self) -> &[Injected] {
        &self.injected
    }

    /// Whether input frame `index` is hit (one draw per frame in the span, hit or not).
    fn hits(&mut self, index: usize) -> bool {
        if !self.plan.span.contains(&index) {
            return false;
        }
        // 32 random bits as a uniform value in [0, 1).
        f64::from(self.rng.next_u32()) / 4_294_967_296.0 < self.plan.rate
    }

    /// Applies `fault` to `frame`, the latest frame taken (`next`, taken after it for
    /// [`FrameFault::Duplicate`] and [`FrameFault::Reorder`]), queueing what goes out.
    fn inject(&mut self, fault: FrameFault, mut frame: OwnedFrame, mut next: Option<OwnedFrame>) {
        match fault {
            FrameFault::Drop => {}
            FrameFault::Duplicate => {
                let mut copy = frame.clone();
                copy.timestamp_s = next.as_ref().map_or(frame.timestamp_s + 1e-3, |n| {
                    frame.timestamp_s + 0.5 * (n.timestamp_s - frame.timestamp_s)
                });
                self.queue.push_back(frame);
                self.queue.push_back(copy);
            }
            FrameFault::Reorder => {
                self.queue.extend(next.take());
                self.queue.push_back(frame);
            }
            FrameFault::RepeatTimestamp => {
                frame.timestamp_s = self.previous_s.unwrap_or(frame.timestamp_s);
                self.queue.push_back(frame);
            }
            FrameFault::CorruptRows => {
                let band = (frame.height / 8).max(1);
                let top = self.rng.below(frame.height);
                let rows = top..(top + band).min(frame.height);
                let (dw, _) = frame.depth_size();
                let shift = frame.depth_level;
                for y in rows.clone() {
                    for x in 0..frame.width {
                        if let Some(p) = frame.gray.get_mut(y * frame.width + x) {
                            *p = self.rng.next_u32() as u8;
                        }
                    }
                }
                for y in (rows.start >> shift)..(rows.end >> shift) {
                    for x in 0..dw {
                        if let Some(d) = frame.depth.get_mut(y * dw + x) {
                            *d = self.rng.next_u32() as u16;
                        }
                    }
                }
                self.queue.push_back(frame);
            }
            FrameFault::Black => {
                frame.gray.fill(0);
                self.queue.push_back(frame);
            }
            FrameFault::Saturated => {
                frame.gray.fill(u8::MAX);
                frame.depth.fill(0);
                self.queue.push_back(frame);
            }
            FrameFault::OtherScene => {
                if let Some(f) = self.foreign.get(self.next_foreign % self.foreign.len().max(1)) {
                    self.next_foreign += 1;
                    frame = OwnedFrame { timestamp_s: frame.timestamp_s, ..f.clone() };
                }
                self.queue.push_back(frame);
            }
        }
        self.queue.extend(next);
    }
}

impl<S> FaultySource<S>
where
    S: FrameSource,
    S::Error: std::error::Error + 'static,
{
    /// The next frame of `inner`, copied, its index taken; `None` at the end.
    fn take(&mut self) -> Result<Option<(usize, OwnedFrame)>, FaultySourceError<S::Error>> {
        let frame = self.inner.next_frame().map_err(FaultySourceError::Source)?;
        let Some(frame) = frame else { return Ok(None) };
        let owned = halve_frame(&frame, 0)?;
        (self.previous_s, self.latest_s) = (self.latest_s, Some(owned.timestamp_s));
        let index = self.taken;
        self.taken += 1;
        Ok(Some((index, owned)))
    }
}

impl<S> FrameSource for FaultySource<S>
where
    S: FrameSource,
    S::Error: std::error::Error + 'static,
{
    type Error = FaultySourceError<S::Error>;

    fn next_frame(&mut self) -> Result<Option<RgbdFrame<'_>>, Self::Error> {
        loop {
            if let Some(frame) = self.queue.pop_front() {
                return Ok(Some(self.current.insert(frame).view()?));
            }
            let Some((index, frame)) = self.take()? else { return Ok(None) };
            let fault = self.plan.fault;
            let foreign_missing = fault == FrameFault::OtherScene && self.foreign.is_empty();
            if !self.hits(index) || foreign_missing {
                self.queue.push_back(frame);
                continue;
            }
            self.injected.push(Injected { input_index: index, fault });
            // Duplicate and Reorder need the next frame (its timestamp, or to go first); it is
            // never hit itself (one fault at a time).
            let next = if matches!(fault, FrameFault::Duplicate | FrameFault::Reorder) {
                self.take()?.map(|(_, n)| n)
            } else {
                None
            };
            self.inject(fault, frame, next);
        }
    }
}

#[cfg(test)]
mod tests;
