//! The pipeline the board runs, and the one step that wires a frame source, the pipeline and a
//! telemetry sink together ([`run_frame`]), shared by every binary and by the host's check.
//!
//! [`Pipeline`] is the single place that names the core's processing: the QVGA [`QvgaSlam`]
//! facade, its front end on each frame (and the anchor commands due in it), then its back end
//! for a fixed quota of work units ([`BACKEND_QUOTA`]) before the next frame: the same schedule
//! as the host's deterministic replay, so both give the same bits.

use ferroslam_core::ar::WorldError;
use ferroslam_core::frame::{FrameSource, RgbdFrame, TelemetrySink};
use ferroslam_core::geometry::PinholeCamera;
use ferroslam_core::loops::PlaceMemory;
use ferroslam_core::map::KeyframeStore;
use ferroslam_core::system::{DEFAULT_BACKEND_QUOTA, DEFAULT_DRAIN_STEPS, MapAccess, QvgaSlam};
use ferroslam_core::tracking::{FrameResult, FrontendError, Places};
use ferroslam_core::wire::{
    AnchorMessage, CostMessage, FaultCode, FaultMessage, Message, PoseMessage, StatusMessage,
    TickUnit,
};

use crate::commands::CommandSource;

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

    /// The front end on one frame (it takes the next frame index, even when rejected) with
    /// `places` as the place memory (`ferroslam_core::loops::PlaceMemory` over the board's flash
    /// store, or `NoPlaces`), then the anchor commands due in it (from `commands`, each through
    /// `QvgaSlam::command`: on the world's planes found so far); each command not applied is a
    /// fault sent to `sink`. Only [`run_frame`] calls it, then [`Self::step_backend`], so the
    /// back-end step can never be skipped or doubled (the host replay's schedule, hence its bits,
    /// depend on it).
    ///
    /// Returns the frame's pose message, or the front end's [`FrontendError`] for a frame it
    /// rejects (size, timestamp).
    ///
    /// # Errors
    /// The sink's (the link failed).
    fn track<T: TelemetrySink>(
        &mut self,
        (frame, cam): (&RgbdFrame<'_>, &PinholeCamera),
        places: &mut impl Places,
        commands: &mut impl CommandSource,
        sink: &mut T,
    ) -> Result<Result<PoseMessage, FrontendError>, T::Error> {
        let index = self.next_index;
        self.next_index = self.next_index.saturating_add(1);
        let result = match self.slam.process_with(frame, cam, places) {
            Ok(r) => r,
            Err(e) => return Ok(Err(e)),
        };
        self.apply_commands(commands, (frame, cam, &result), index, sink)?;
        Ok(Ok(PoseMessage::from_frame_result(index, frame.timestamp_s, &result)))
    }

    /// The anchor commands `commands` has due in frame `index`, which the front end just took
    /// (`result`), each through `QvgaSlam::command`; each not applied is a fault sent to `sink`.
    /// Out of line: its planes seen from the frame (1.3 KB) are stacked only while it runs, not
    /// under the front end's deepest calls.
    #[inline(never)]
    fn apply_commands<T: TelemetrySink>(
        &mut self,
        commands: &mut impl CommandSource,
        (frame, cam, result): (&RgbdFrame<'_>, &PinholeCamera, &FrameResult),
        index: u32,
        sink: &mut T,
    ) -> Result<(), T::Error> {
        while let Some(command) = commands.next_due(index) {
            let detail = match command {
                Ok(c) => match self.slam.command(&c.command, frame, cam, result) {
                    Ok(_) => continue,
                    Err(e) => e.code(),
                },
                Err(e) => e.code(),
            };
            self.note_fault();
            let fault = FaultMessage { frame_index: index, code: FaultCode::Command, detail };
            sink.send(&Message::Fault(fault))?;
        }
        Ok(())
    }

    /// After [`Self::track`]: the back end for [`BACKEND_QUOTA`] units, then the place memory's
    /// pending store write ([`Places::flush`]). A back-end error drops that back-end job and
    /// counts as a fault.
    fn step_backend(&mut self, cam: &PinholeCamera, places: &mut impl Places) {
        if self.slam.step_backend(cam, BACKEND_QUOTA).is_err() {
            self.note_fault();
        }
        places.flush();
    }

    /// Ends the back end's work as the host replay does after its last frame (the work under way,
    /// then the newest keyframes settled: `Slam::drain_backend`, [`DEFAULT_DRAIN_STEPS`] steps of
    /// [`BACKEND_QUOTA`] at most), then hands every keyframe of the active map to `places` to be
    /// remembered, oldest first (they stay in the map): a save's first half, before the place
    /// memory's commit. A back-end error counts as a fault.
    pub fn remember_map_in(&mut self, cam: &PinholeCamera, places: &mut impl Places) {
        if self.slam.drain_backend(cam, BACKEND_QUOTA, DEFAULT_DRAIN_STEPS).is_err() {
            self.note_fault();
        }
        self.slam.map().remember_all_in(places);
    }

    /// Makes the place memory's records, then the world's planes and anchors, what a boot finds
    /// (`PlaceMemory::commit`).
    ///
    /// # Errors
    /// The store's; the last commit stands then.
    pub fn commit<S: KeyframeStore>(&self, places: &mut PlaceMemory<S>) -> Result<(), S::Error> {
        places.commit(Some(&self.slam.world()))
    }

    /// Starts from the planes and anchors the store `places` was attached to held (a boot in a
    /// saved map: `PlaceMemory::held_world`), before the first frame. Returns the planes and
    /// anchors taken, `None` when the store held none. Out of line: the world read back (about
    /// 3 KB) is stacked only while it runs, at boot.
    ///
    /// # Errors
    /// What is wrong with the saved world: nothing of it is taken (the records still are).
    #[inline(never)]
    pub fn restore_world<S: KeyframeStore>(
        &mut self,
        places: &mut PlaceMemory<S>,
    ) -> Result<Option<(usize, usize)>, WorldError> {
        let Some(world) = places.held_world().transpose()? else { return Ok(None) };
        self.slam.restore_world(&world);
        Ok(Some((world.planes().len(), world.anchors().len())))
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

/// The serial link's two sides, for [`run_frame`]: telemetry out, anchor commands in.
#[derive(Debug)]
pub struct Link<'a, T, R> {
    /// The sending side.
    pub tx: &'a mut T,
    /// The receiving side.
    pub rx: &'a mut R,
}

/// One frame through the board: read it from `source`, process it (with `places` as the place
/// memory), apply the anchor commands due in it (from `link.rx`), send its [`PoseMessage`], an
/// [`AnchorMessage`] per placed anchor and its [`CostMessage`] to `link.tx` (or a
/// [`FaultMessage`] when the source fails or the pipeline rejects the frame, and one per command
/// not applied; the caller may go on with the next frame either way).
///
/// The cost message times four stages with `clock`: acquiring the frame, the front end (with the
/// commands), the back-end step after it (with the place memory's store write), and sending the
/// pose and the anchors (the cost message itself is not counted).
///
/// # Errors
/// The sending side's error (the link itself failed).
pub fn run_frame<S, T, R, C>(
    source: &mut S,
    pipeline: &mut Pipeline,
    places: &mut impl Places,
    cam: &PinholeCamera,
    link: Link<'_, T, R>,
    clock: &mut C,
    source_fault_detail: impl Fn(&S::Error) -> u32,
) -> Result<FrameOutcome, T::Error>
where
    S: FrameSource,
    T: TelemetrySink,
    R: CommandSource,
    C: TickClock,
{
    let sink = link.tx;
    let frame_index = pipeline.next_index();
    let t0 = clock.now();
    let fault = match source.next_frame() {
        Ok(None) => return Ok(FrameOutcome::End),
        Ok(Some(frame)) => {
            let t1 = clock.now();
            match pipeline.track((&frame, cam), places, link.rx, sink)? {
                Ok(pose) => {
                    let t2 = clock.now();
                    pipeline.step_backend(cam, places);
                    let t3 = clock.now();
                    sink.send(&Message::Pose(pose))?;
                    for anchor in pipeline.slam.anchors().iter() {
                        sink.send(&Message::Anchor(AnchorMessage::of(frame_index, anchor)))?;
                    }
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
    use crate::commands::NoCommands;
    use ferroslam_core::ar::AnchorError;
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
            let link = Link { tx: &mut sink, rx: &mut NoCommands };
            run_frame(&mut source, &mut pipeline, &mut places, &cam, link, &mut clock, |_| 5)
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
                Message::Command(_) | Message::Anchor(_) => "anchors",
            })
            .collect();
        assert_eq!(kinds, ["pose", "cost", "fault", "fault", "pose", "cost"]);
        let status = pipeline.status();
        assert_eq!((status.frames, status.faults), (2, 2));
        assert_eq!(status.state_bytes as usize, core::mem::size_of::<Pipeline>());
    }

    #[test]
    fn commands_not_applied_are_faults_of_their_frame() {
        use crate::commands::{Arrived, LinkCommands};
        use ferroslam_core::ar::AnchorCommand;
        use ferroslam_core::wire::CommandMessage;

        let mut source = Script {
            gray: std::vec![128; 320 * 240],
            depth: std::vec![1000; 320 * 240],
            times: std::vec![Some(1.0), Some(2.0)],
            at: 0,
        };
        let cam = PinholeCamera::new(292.5, 292.5, 160.0, 120.0, 320, 240).unwrap();
        let mut pipeline = Box::new(Pipeline::new());
        let (mut sink, mut clock) = (Recorder::default(), Counter(0));
        // Frame 1: a place (the wall is never tracked) and a scale of an object never placed.
        let commands = [
            AnchorCommand::Place { object: 0, pixel: [160.0, 120.0], scale: 1.0 },
            AnchorCommand::Scale { object: 7, scale: 2.0 },
        ]
        .map(|command| Message::Command(CommandMessage { frame_index: 1, command }));
        let bytes = crate::commands::tests::wire(&commands);
        let mut rx = LinkCommands::new(Arrived(&bytes[..]));
        for _ in 0..2 {
            let link = Link { tx: &mut sink, rx: &mut rx };
            let step =
                run_frame(&mut source, &mut pipeline, &mut NoPlaces, &cam, link, &mut clock, |_| 5);
            assert!(matches!(step, Ok(FrameOutcome::Processed { .. })), "{step:?}");
        }
        let faults: Vec<(u32, FaultCode, u32)> = sink
            .0
            .iter()
            .filter_map(|m| match m {
                Message::Fault(f) => Some((f.frame_index, f.code, f.detail)),
                _ => None,
            })
            .collect();
        let (not_tracked, unknown) =
            (AnchorError::NotTracked.code(), AnchorError::UnknownObject.code());
        assert_eq!(
            faults,
            [(1, FaultCode::Command, not_tracked), (1, FaultCode::Command, unknown)]
        );
        assert_eq!(pipeline.status().faults, 2);
        assert!(pipeline.slam().anchors().is_empty());
    }
}
