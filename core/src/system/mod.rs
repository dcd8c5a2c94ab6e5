//! The facade: [`Slam::process`] runs the front end on a frame, [`Slam::step_backend`] advances
//! the back end by a bounded amount of work. The caller schedules the two: on the firmware the
//! back end runs between frames, in turn with the front end. With a fixed quota per frame the
//! result is the same bits however the steps fall in time.
//!
//! The back end's solve may also run while the front end tracks the next frame:
//! [`Slam::overlap`] lends the front end with the map as a [`FrameJob`] and the back end as a
//! [`SolveJob`], the two borrowed apart, when the solve step cannot finish within the frame's
//! quota. Such a step reads no map, writes none and finishes nothing, so tracking beside it gives
//! the same bits as [`Slam::step_backend`] then [`Slam::process`]. A host runs the job on
//! another thread (the paper's parallel back end); a board could run it as a lower-priority task
//! between frame interrupts. A keyframe the frame job makes reaches the back end at the next
//! call that steps it.
//!
//! A [`Slam`] is sized by its profile ([`crate::config::Profile`]): [`QvgaSlam`] is the board's.
//!
//! ```
//! use ferroslam_core::system::{MapAccess, QvgaSlam};
//! // About 350 KB: give it a `static` on a board, a box on a host.
//! let slam: Box<QvgaSlam> = Box::default();
//! assert_eq!(slam.map().num_keyframes(), 0);
//! ```

mod planes;
mod profile;
mod telemetry;

use crate::ar::{Anchor, AnchorCommand, AnchorError, Anchors, PlacingFrame, SavedWorld, World};
use crate::backend::{BackendError, BackendParams, BackendStatus};
use crate::frame::RgbdFrame;
use crate::geometry::PinholeCamera;
use crate::map::KeyFrameId;
use crate::tracking::{FrameResult, FrontendError, FrontendParams, NoPlaces, Places};

pub use crate::backend::SolveJob;
pub use crate::config::{DEFAULT_BACKEND_QUOTA, DEFAULT_DRAIN_STEPS, HostQvga, HostVga, Qvga, Vga};
pub use planes::{OnlinePlanes, PLANE_FRAMES_AFTER_KEYFRAME};
pub use profile::{Adjuster, MapAccess, ProfileTypes, Tracker};

/// SLAM at the reference board's profile ([`Qvga`]: 320 x 240, the board's map).
pub type QvgaSlam = Slam<Qvga>;
/// SLAM at full resolution with the board's map ([`Vga`]).
pub type VgaSlam = Slam<Vga>;

/// The front end's parameters in SLAM mode: [`FrontendParams::DEFAULT`] without depth fusion
/// (bundle adjustment refines landmark positions instead).
///
/// Why: docs/decisions.md, "Depth fusion off in SLAM mode"; where SLAM still loses to odometry:
/// docs/decisions.md, "SLAM against odometry under per-frame depth noise".
pub const SLAM_FRONTEND: FrontendParams =
    FrontendParams { fuse_depth: false, ..FrontendParams::DEFAULT };

/// The front end, the map and the back end at profile `P` (see the module documentation).
#[derive(Debug)]
pub struct Slam<P: ProfileTypes> {
    frontend: P::Frontend,
    map: P::Map,
    backend: P::Backend,
    /// A keyframe a [`FrameJob`] made, with its creation number, not yet told to the back end.
    new_keyframe: Option<(KeyFrameId, u32)>,
    /// Whether a [`FrameJob`] closed a loop (moved the map) not yet told to the back end.
    map_moved: bool,
    /// The world's planes found as the frames come.
    planes: OnlinePlanes,
    /// The virtual objects placed on them ([`Self::command`]).
    anchors: Anchors,
}

impl<P: ProfileTypes> Default for Slam<P> {
    fn default() -> Self {
        Self::new()
    }
}

impl<P: ProfileTypes> Slam<P> {
    /// A system with [`SLAM_FRONTEND`] and [`BackendParams::DEFAULT`] (`const`, for a
    /// `static`).
    pub const fn new() -> Self {
        P::NEW
    }

    /// A system with the given parameters.
    pub fn with_params(frontend: FrontendParams, backend: BackendParams) -> Self {
        let (frontend, map, backend) = P::start(frontend, backend);
        Self::from_parts(frontend, map, backend)
    }

    /// A system of these parts, with no keyframe waiting for the back end.
    const fn from_parts(frontend: P::Frontend, map: P::Map, backend: P::Backend) -> Self {
        Self {
            frontend,
            map,
            backend,
            new_keyframe: None,
            map_moved: false,
            planes: OnlinePlanes::new(),
            anchors: Anchors::new(),
        }
    }

    /// Tracks one frame and hands a new keyframe to the back end (see
    /// [`Frontend::process`](crate::tracking::Frontend::process)), with no place memory: a
    /// keyframe leaving the map is forgotten and a lost frame does not relocalize.
    ///
    /// # Errors
    /// As `Frontend::process`; nothing changes then.
    pub fn process(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
    ) -> Result<FrameResult, FrontendError> {
        self.process_with(frame, cam, &mut NoPlaces)
    }

    /// As [`Self::process`], with `places` (a [`crate::loops::PlaceMemory`] over a store) as the
    /// place memory: keyframes leaving the map are remembered there, and a frame that cannot be
    /// tracked is relocalized in a verified remembered place.
    ///
    /// # Errors
    /// As `Frontend::process`; nothing changes then.
    pub fn process_with(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        places: &mut impl Places,
    ) -> Result<FrameResult, FrontendError> {
        self.tell_backend();
        let result = self.frame_job().process_with(frame, cam, places);
        self.tell_backend();
        result
    }

    /// Advances the back end by at most about `work_quota` units (see
    /// [`Backend::step`](crate::backend::Backend::step)).
    ///
    /// # Errors
    /// As `Backend::step`.
    // Not inlined: the frame's step and the drain share one copy of the back end's code (two
    // were 20 KB more flash on the board).
    #[inline(never)]
    pub fn step_backend(
        &mut self,
        cam: &PinholeCamera,
        work_quota: u32,
    ) -> Result<BackendStatus, BackendError> {
        self.tell_backend();
        let cam = self.frontend.tracking_camera(cam);
        self.backend.step(&mut self.map, &cam, work_quota)
    }

    /// What ends a run before its map is read or saved, in steps of `work_quota` units, at
    /// most `max_steps` in all: a busy back end works until it finds nothing to do (the solve
    /// under way applied, then a keyframe waiting), then each of the newest
    /// [`BackendParams::settle_keyframes`] keyframes gets a local BA around it, oldest first. A
    /// segmented global BA that is due runs once no keyframe waits, as in a run that goes on.
    /// Returns the steps run.
    ///
    /// # Errors
    /// As `Backend::step`; the steps stop at the first.
    pub fn drain_backend(
        &mut self,
        cam: &PinholeCamera,
        work_quota: u32,
        max_steps: u32,
    ) -> Result<u32, BackendError> {
        // The keyframe the last frame made is the back end's before the settling replaces it.
        self.tell_backend();
        let mut steps = 0;
        if self.backend.is_busy() {
            steps = self.run_backend_until_idle(cam, work_quota, max_steps)?;
        }
        let mut next = self.oldest_to_settle();
        // Once the steps are spent, the keyframes left are not handed over: none would be settled.
        while let Some((kf, seq)) = next
            && steps < max_steps
        {
            self.backend.keyframe_added(kf, seq);
            steps += self.run_backend_until_idle(cam, work_quota, max_steps - steps)?;
            next = self.next_keyframe_after(seq);
        }
        Ok(steps)
    }

    /// Back-end steps until one finds nothing to do, at most `max_steps`; returns the steps run.
    fn run_backend_until_idle(
        &mut self,
        cam: &PinholeCamera,
        work_quota: u32,
        max_steps: u32,
    ) -> Result<u32, BackendError> {
        for step in 0..max_steps {
            if let BackendStatus::Idle = self.step_backend(cam, work_quota)? {
                return Ok(step + 1);
            }
        }
        Ok(max_steps)
    }

    /// The oldest of the newest [`BackendParams::settle_keyframes`] keyframes (its id and
    /// creation number), if any. Cost: one pass over the keyframes per keyframe settled.
    fn oldest_to_settle(&self) -> Option<(KeyFrameId, u32)> {
        let mut oldest = None;
        let mut below = u32::MAX;
        for _ in 0..self.backend.params().settle_keyframes {
            let seqs = self.map.keyframes().map(|(_, k)| k.seq);
            let Some(seq) = seqs.filter(|&s| s < below).max() else { break };
            below = seq;
            oldest = Some(seq);
        }
        let seq = oldest?;
        self.map.keyframes().find(|(_, k)| k.seq == seq).map(|(id, _)| (id, seq))
    }

    /// The keyframe created next after creation number `seq`, if any.
    fn next_keyframe_after(&self, seq: u32) -> Option<(KeyFrameId, u32)> {
        let next = self.map.keyframes().filter(|(_, k)| k.seq > seq).min_by_key(|(_, k)| k.seq);
        next.map(|(id, k)| (id, k.seq))
    }

    /// The front end with the map, and the back end's solve, borrowed apart for one frame: `Some`
    /// when the back end's next step is a solve step that cannot finish the solve within
    /// `work_quota` units. Then [`SolveJob::advance`]`(work_quota)` beside
    /// [`FrameJob::process_with`] gives the same bits as [`Self::step_backend`]`(cam, work_quota)`
    /// followed by [`Self::process_with`] with the same place memory. `None`: run those two in
    /// turn. Cost: one pass over the solve's points.
    pub fn overlap(&mut self, work_quota: u32) -> Option<(FrameJob<'_, P>, SolveJob<'_>)> {
        self.tell_backend();
        let solve = self.backend.solve_job()?;
        if solve.units_before_finish() <= u64::from(work_quota) {
            return None;
        }
        let frame = FrameJob {
            frontend: &mut self.frontend,
            map: &mut self.map,
            new_keyframe: &mut self.new_keyframe,
            map_moved: &mut self.map_moved,
            planes: &mut self.planes,
            anchors: &mut self.anchors,
        };
        Some((frame, solve))
    }

    /// As [`Self::overlap`], whenever a solve is under way and whatever work it has left: for a
    /// caller that solves for as long as the front end tracks (not deterministic). A solve the
    /// job finishes is written to the map by the next [`Self::step_backend`].
    pub fn overlap_any(&mut self) -> Option<(FrameJob<'_, P>, SolveJob<'_>)> {
        self.tell_backend();
        let solve = self.backend.solve_job()?;
        let frame = FrameJob {
            frontend: &mut self.frontend,
            map: &mut self.map,
            new_keyframe: &mut self.new_keyframe,
            map_moved: &mut self.map_moved,
            planes: &mut self.planes,
            anchors: &mut self.anchors,
        };
        Some((frame, solve))
    }

    /// The map.
    pub fn map(&self) -> &P::Map {
        &self.map
    }

    /// The front end.
    pub fn frontend(&self) -> &P::Frontend {
        &self.frontend
    }

    /// The back end.
    pub fn backend(&self) -> &P::Backend {
        &self.backend
    }

    /// The world's planes found so far (see [`OnlinePlanes`]).
    pub fn planes(&self) -> &OnlinePlanes {
        &self.planes
    }

    /// The virtual objects placed ([`Self::command`]), in the world frame.
    pub fn anchors(&self) -> &Anchors {
        &self.anchors
    }

    /// The planes and anchors as a map saves them (`PlaceMemory::save`, `PlaceMemory::commit`).
    pub fn world(&self) -> World<'_> {
        World { planes: self.planes.map(), anchors: &self.anchors }
    }

    /// Takes the planes and anchors a saved map held (`PlaceMemory::load`,
    /// `PlaceMemory::held_world`) in place of its own: the remembered world, which this run's
    /// loops move its own planes and anchors onto. For a system switched on in a loaded map,
    /// before its first frame.
    pub fn restore_world(&mut self, saved: &SavedWorld) {
        let (planes, anchors) = saved.restored();
        self.planes.restore(planes);
        self.anchors = anchors;
    }

    /// Applies an anchor `command` in `frame`, the frame the last [`Self::process_with`] took
    /// (`result` its result; `cam` as given to it). A place stands the object where the pixel's
    /// ray meets the plane under it among the world's planes found so far ([`OnlinePlanes`]),
    /// seen from the frame's output pose: no detection on this frame, so a command costs a pass
    /// over the planes, not a detection. The anchor then follows loop corrections with the
    /// keyframe the frame was tracked against ([`Anchors::correct`]). A frame not tracked
    /// places nothing ([`AnchorError::NotTracked`]).
    ///
    /// # Errors
    /// [`AnchorError`]: nothing changed.
    // Not inlined: the planes seen from the frame (1.3 KB) are stacked only while it runs.
    #[inline(never)]
    pub fn command(
        &mut self,
        command: &AnchorCommand,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        result: &FrameResult,
    ) -> Result<Anchor, AnchorError> {
        let planes = self.planes.seen_from(&result.t_wc);
        let placing = PlacingFrame {
            depth: &frame.depth,
            cam,
            t_wc: &result.t_wc,
            planes: &planes,
            reference: result.reference_keyframe,
        };
        self.anchors.apply(command, result.tracked.then_some(&placing))
    }

    /// The front end with the map, as a job.
    fn frame_job(&mut self) -> FrameJob<'_, P> {
        FrameJob {
            frontend: &mut self.frontend,
            map: &mut self.map,
            new_keyframe: &mut self.new_keyframe,
            map_moved: &mut self.map_moved,
            planes: &mut self.planes,
            anchors: &mut self.anchors,
        }
    }

    /// Tells the back end of the loop the last frame job closed and of the keyframe it made, if
    /// any.
    fn tell_backend(&mut self) {
        if core::mem::take(&mut self.map_moved) {
            self.backend.map_moved();
        }
        if let Some((kf, seq)) = self.new_keyframe.take() {
            self.backend.keyframe_added(kf, seq);
        }
    }
}

/// The front end with the map, borrowed for one frame ([`Slam::overlap`]): what
/// [`Slam::process`] does, apart from the back end.
#[derive(Debug)]
pub struct FrameJob<'a, P: ProfileTypes> {
    frontend: &'a mut P::Frontend,
    map: &'a mut P::Map,
    new_keyframe: &'a mut Option<(KeyFrameId, u32)>,
    map_moved: &'a mut bool,
    planes: &'a mut OnlinePlanes,
    anchors: &'a mut Anchors,
}

impl<P: ProfileTypes> FrameJob<'_, P> {
    /// Tracks one frame into the map with `places` as the place memory (see
    /// [`Slam::process_with`]; [`NoPlaces`] for none); a keyframe it makes is told to the back
    /// end by the next [`Slam`] call that steps it.
    ///
    /// # Errors
    /// As `Frontend::process`; nothing changes then.
    pub fn process_with(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        places: &mut impl Places,
    ) -> Result<FrameResult, FrontendError> {
        let result = track::<P>(self.frontend, frame, cam, self.map, places)?;
        let made = result.keyframe.and_then(|kf| self.map.keyframe(kf).map(|k| (kf, k.seq)));
        if made.is_some() {
            *self.new_keyframe = made;
        }
        *self.map_moved |= result.loop_closure.is_some();
        if let Some(closure) = &result.loop_closure {
            let map = &*self.map;
            self.anchors.correct(&closure.correction, |k| map.keyframe(k).is_some());
        }
        let sensor = *self.frontend.params().sensor();
        self.planes.after_frame(frame, cam, &sensor, &result);
        Ok(result)
    }
}

/// The front end on one frame, out of line: the planes found after it (on some frames) stack
/// their detector where the front end's own frame was, not on top of it (the board's peak
/// stack).
#[inline(never)]
fn track<P: ProfileTypes>(
    frontend: &mut P::Frontend,
    frame: &RgbdFrame<'_>,
    cam: &PinholeCamera,
    map: &mut P::Map,
    places: &mut impl Places,
) -> Result<FrameResult, FrontendError> {
    frontend.process(frame, cam, map, places)
}
