//! The pipeline the board runs, and the one step that wires a frame source, the pipeline and a
//! telemetry sink together ([`run_frame`]), shared by every binary and by the host's check.
//!
//! [`Pipeline`] is the single place that names the core's processing: the QVGA [`QvgaSlam`]
//! facade, its front end on each frame, then its back end for a fixed quota of work units
//! ([`BACKEND_QUOTA`]) before the next frame: the same schedule as the host's deterministic
//! replay, so both give the same bits.

use ferroslam_core::frame::{FrameSource, RgbdFrame, TelemetrySink};
use ferroslam_core::geometry::PinholeCamera;
use ferroslam_core::system::{DEFAULT_BACKEND_QUOTA, DEFAULT_DRAIN_STEPS, MapAccess, QvgaSlam};
use ferroslam_core::tracking::{FrontendError, Places};
use ferroslam_core::wire::{
    CostMessage, FaultCode, FaultMessage, Message, PoseMessage, StatusMessage, TickUnit,
};

/// Back-end work units run after every frame (the host replay's default quota).
pub const BACKEND_QUOTA: u32 = DEFAULT_BACKEND_QUOTA;

/// The core's processing of one frame, with the frame counter and fault count of the board.
#[derive(Debug)]
pub struct Pipeline {
    slam: QvgaSlam,
    next_index: u32,
    faults: u32,
}

impl Default for Pipeline {
    fn default() -> Self {
        Self::new()
    }
}

impl Pipeline {
    /// A pipeline at the start (`const`: it initializes a `static`, never built on the stack).
    pub const fn new() -> Self {
        Self { slam: QvgaSlam::new(), next_index: 0, faults: 0 }
    }

    /// Processes one frame (it takes the next frame index, even when rejected) with `places` as
    /// the place memory (`ferroslam_core::loops::PlaceMemory` over the board's flash store, or
    /// `NoPlaces`), then runs the back end for [`BACKEND_QUOTA`] units, and returns the frame's
    /// pose message.
    ///
    /// # Errors
    /// The front end's [`FrontendError`] for a frame it rejects (size, timestamp). A back-end
    /// error drops that back-end job and counts as a fault; the pose still goes out.
    pub fn process(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        places: &mut impl Places,
    ) -> Result<PoseMessage, FrontendError> {
        let pose = self.track(frame, cam, places)?;
        self.step_backend(cam, places);
        Ok(pose)
    }

    /// The first half of [`Pipeline::process`]: the front end on the frame. [`run_frame`] calls
    /// the halves itself to time them apart; anything else calls `process`, so the back-end step
    /// can never be skipped or doubled (the host replay's schedule, hence its bits, depend on it).
    fn track(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        places: &mut impl Places,
    ) -> Result<PoseMessage, FrontendError> {
        let index = self.next_index;
        self.next_index = self.next_index.saturating_add(1);
        let result = self.slam.process_with(frame, cam, places)?;
        Ok(PoseMessage::from_frame_result(index, frame.timestamp_s, &result))
    }

    /// The second half of [`Pipeline::process`]: the back end for [`BACKEND_QUOTA`] units, then
    /// the place memory's pending store write ([`Places::flush`]).
    fn step_backend(&mut self, cam: &PinholeCamera, places: &mut impl Places) {
        if self.slam.step_backend(cam, BACKEND_QUOTA).is_err() {
            self.note_fault();
        }
        places.flush();
    }

    /// Finishes the back end's work under way ([`DEFAULT_DRAIN_STEPS`] steps of [`BACKEND_QUOTA`] at
    /// most, as the host replay does after its last frame), then hands every keyframe of the
    /// active map to `places` to be remembered, oldest first (they stay in the map): a save's
    /// first half, before the place memory's commit. A back-end error counts as a fault.
    pub fn remember_map_in(&mut self, cam: &PinholeCamera, places: &mut impl Places) {
        if self.slam.drain_backend(cam, BACKEND_QUOTA, DEFAULT_DRAIN_STEPS).is_err() {
            self.note_fault();
        }
        self.slam.map().remember_all_in(places);
    }

    /// The core's state (map, front end, back end), read only: what a host check inspects.
    pub fn slam(&self) -> &QvgaSlam {
        &self.slam
    }

    /// The index the next frame gets.
    pub fn next_index(&self) -> u32 {
        self.next_index
    }

    /// Gives up the next frame index: a frame the source lost still takes its place in the
    /// stream, so indices stay the frames' positions.
    pub fn skip_frame(&mut self) {
        self.next_index = self.next_index.saturating_add(1);
    }

    /// Counts a fault (reported in [`Pipeline::status`]).
    pub fn note_fault(&mut self) {
        self.faults = self.faults.saturating_add(1);
    }

    /// The running totals; `stack_peak_bytes` is the board's to fill in.
    pub fn status(&self) -> StatusMessage {
        let bytes = u32::try_from(core::mem::size_of::<Self>()).unwrap_or(u32::MAX);
        StatusMessage::from_stats(&self.slam.frontend().stats(), self.faults, bytes)
    }
}

/// What [`run_frame`] did with one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FrameOutcome {
    /// The frame was processed; its pose and cost messages were sent.
    Processed {
        /// The pose sent.
        pose: PoseMessage,
        /// The cost sent.
        cost: CostMessage,
    },
    /// The frame could not be read or was rejected; the fault message was sent.
    Fault(FaultMessage),
    /// The source has no more frames.
    End,
}

/// The board's clock for cost figures: a free-running tick count and what a tick is.
pub trait TickClock {
    /// What one tick is.
    const UNIT: TickUnit;

    /// Ticks since some fixed start (wrapping is the caller's concern over spans above 2^32).
    fn now(&mut self) -> u32;
}

/// One frame through the board: read it from `source`, process it (with `places` as the place
/// memory), send its [`PoseMessage`] and
/// [`CostMessage`] to `sink` (or a [`FaultMessage`] when the source fails or the pipeline rejects
/// the frame; the caller may go on with the next frame either way).
///
/// The cost message times four stages with `clock`: acquiring the frame, the front end, the
/// back-end step after it (with the place memory's store write), and sending the pose (its own
/// cost message is not counted).
///
/// # Errors
/// The sink's error (the link itself failed).
pub fn run_frame<S, T, C>(
    source: &mut S,
    pipeline: &mut Pipeline,
    places: &mut impl Places,
    cam: &PinholeCamera,
    sink: &mut T,
    clock: &mut C,
    source_fault_detail: impl Fn(&S::Error) -> u32,
) -> Result<FrameOutcome, T::Error>
where
    S: FrameSource,
    T: TelemetrySink,
    C: TickClock,
{
    let frame_index = pipeline.next_index();
    let t0 = clock.now();
    let fault = match source.next_frame() {
        Ok(None) => return Ok(FrameOutcome::End),
        Ok(Some(frame)) => {
            let t1 = clock.now();
            match pipeline.track(&frame, cam, places) {
                Ok(pose) => {
                    let t2 = clock.now();
                    pipeline.step_backend(cam, places);
                    let t3 = clock.now();
                    sink.send(&Message::Pose(pose))?;
                    let t4 = clock.now();
                    let cost = CostMessage {
                        frame_index,
                        unit: C::UNIT,
                        acquire_ticks: t1.wrapping_sub(t0),
                        frontend_ticks: t2.wrapping_sub(t1),
                        backend_ticks: t3.wrapping_sub(t2),
                        report_ticks: t4.wrapping_sub(t3),
                    };
                    sink.send(&Message::Cost(cost))?;
                    return Ok(FrameOutcome::Processed { pose, cost });
                }
                Err(e) => FaultMessage {
                    frame_index,
                    code: FaultCode::FrameRejected,
                    detail: frontend_error_code(&e),
                },
            }
        }
        Err(e) => {
            pipeline.skip_frame();
            let detail = source_fault_detail(&e);
            FaultMessage { frame_index, code: FaultCode::FrameSource, detail }
        }
    };
    pipeline.note_fault();
    sink.send(&Message::Fault(fault))?;
    Ok(FrameOutcome::Fault(fault))
}

/// A number naming a front-end error variant, for [`FaultMessage::detail`].
fn frontend_error_code(e: &FrontendError) -> u32 {
    match e {
        FrontendError::SizeMismatch { .. } => 1,
        FrontendError::TimestampNotIncreasing { .. } => 2,
        FrontendError::InvalidParams => 3,
        _ => 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferroslam_core::image::{DepthView, GrayView, ImageView};
    use ferroslam_core::tracking::NoPlaces;
    use ferroslam_core::wire::TrackingState;
    use std::boxed::Box;
    use std::vec::Vec;

    /// Frames of a flat gray wall at 1 m, with timestamps from a list; `None` entries fail.
    struct Script {
        gray: Vec<u8>,
        depth: Vec<u16>,
        times: Vec<Option<f64>>,
        at: usize,
    }

    impl FrameSource for Script {
        type Error = &'static str;

        fn next_frame(&mut self) -> Result<Option<RgbdFrame<'_>>, Self::Error> {
            let Some(&t) = self.times.get(self.at) else { return Ok(None) };
            self.at += 1;
            let timestamp_s = t.ok_or("sensor unplugged")?;
            let gray = GrayView::packed(&self.gray, 320, 240).map_err(|_| "gray")?;
            let raw = ImageView::packed(&self.depth, 320, 240).map_err(|_| "depth")?;
            let depth = DepthView::new(raw, 1000.0).map_err(|_| "scale")?;
            Ok(Some(RgbdFrame { timestamp_s, gray, depth }))
        }
    }

    #[derive(Default)]
    struct Recorder(Vec<Message>);

    impl TelemetrySink for Recorder {
        type Error = core::convert::Infallible;

        fn send(&mut self, message: &Message) -> Result<(), Self::Error> {
            self.0.push(*message);
            Ok(())
        }
    }

    /// Ten ticks per call, one instruction each.
    struct Counter(u32);

    impl TickClock for Counter {
        const UNIT: TickUnit = TickUnit::Instructions { per_tick: 1 };

        fn now(&mut self) -> u32 {
            self.0 += 10;
            self.0
        }
    }

    #[test]
    fn frames_faults_and_the_end_of_the_source() {
        let mut source = Script {
            gray: std::vec![128; 320 * 240],
            depth: std::vec![1000; 320 * 240],
            times: std::vec![Some(1.0), None, Some(0.5), Some(2.0)],
            at: 0,
        };
        let cam = PinholeCamera::new(292.5, 292.5, 160.0, 120.0, 320, 240).unwrap();
        let mut pipeline = Box::new(Pipeline::new());
        let (mut sink, mut clock) = (Recorder::default(), Counter(0));
        let mut places = NoPlaces;
        let mut step = || {
            run_frame(&mut source, &mut pipeline, &mut places, &cam, &mut sink, &mut clock, |_| 5)
        };

        // A featureless wall: processed, no keyframe possible, still initializing.
        let Ok(FrameOutcome::Processed { pose, cost }) = step() else { panic!("frame 0") };
        assert_eq!(
            (pose.frame_index, pose.timestamp_s, pose.state),
            (0, 1.0, TrackingState::Initializing)
        );
        let ticks =
            (cost.acquire_ticks, cost.frontend_ticks, cost.backend_ticks, cost.report_ticks);
        assert_eq!(ticks, (10, 10, 10, 10));
        // The source fails: a fault, and the frame keeps its index.
        let fault = FaultMessage { frame_index: 1, code: FaultCode::FrameSource, detail: 5 };
        assert_eq!(step(), Ok(FrameOutcome::Fault(fault)));
        // A timestamp going backwards is rejected by the front end.
        let Ok(FrameOutcome::Fault(f)) = step() else { panic!("frame 2") };
        assert_eq!((f.frame_index, f.code, f.detail), (2, FaultCode::FrameRejected, 2));
        let Ok(FrameOutcome::Processed { pose, .. }) = step() else { panic!("frame 3") };
        assert_eq!(pose.frame_index, 3);
        assert_eq!(step(), Ok(FrameOutcome::End));

        let kinds: Vec<&str> = sink
            .0
            .iter()
            .map(|m| match m {
                Message::Pose(_) => "pose",
                Message::Cost(_) => "cost",
                Message::Fault(_) => "fault",
                Message::Status(_) => "status",
            })
            .collect();
        assert_eq!(kinds, ["pose", "cost", "fault", "fault", "pose", "cost"]);
        let status = pipeline.status();
        assert_eq!((status.frames, status.faults), (2, 2));
        assert_eq!(status.state_bytes as usize, core::mem::size_of::<Pipeline>());
    }
}
