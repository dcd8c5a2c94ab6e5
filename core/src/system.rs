//! The facade: [`Slam::process`] runs the front end on a frame, [`Slam::step_backend`] advances
//! the back end by a bounded amount of work. The caller schedules the two: on the firmware the
//! back end runs between frames; on the host it runs on its own thread beside the front end
//! ([`Slam::parts_mut`]), with a fixed quota per frame so the result is the same bits as running
//! the two in turn (or with as much work as it gets done while the front end tracks a frame,
//! trading determinism for throughput).
//!
//! ```
//! use ferroslam_core::system::QvgaSlam;
//! // About 350 KB: give it a `static` on a board, a box on a host.
//! let slam: Box<QvgaSlam> = Box::default();
//! assert_eq!(slam.map().num_keyframes(), 0);
//! ```

use crate::backend::{
    BA_OBSERVATIONS, BA_POINTS, BA_RIGS, Backend, BackendError, BackendParams, BackendStatus,
    HOST_BA_OBSERVATIONS, HOST_BA_POINTS, HOST_BA_RIGS, HOST_MAX_KEYFRAMES, HOST_MAX_LANDMARKS,
};
use crate::config::capacity;
use crate::frame::RgbdFrame;
use crate::geometry::PinholeCamera;
use crate::map::Map;
use crate::tracking::{FrameResult, Frontend, FrontendError, FrontendParams};

/// Back-end work units per frame in deterministic replay and on the board, the same after every
/// frame. At about 400 host instructions a unit (see [`crate::optim`]) a step stays under 2 M
/// Cortex-M4 instructions (`memory-budget.md` has today's figures); a local BA then takes tens of
/// frames to solve.
///
/// Why this value: docs/decisions.md, "Back-end work quota per frame".
pub const DEFAULT_BACKEND_QUOTA: u32 = 2_500;

/// SLAM at the reference board's QVGA profile (320 x 240).
pub type QvgaSlam = Slam<320, 240>;
/// SLAM at the VGA profile (640 x 480).
pub type VgaSlam = Slam<640, 480>;
/// SLAM with the host-scale map and back end ([`crate::map::HostMap`],
/// [`crate::backend::HostBackend`]) at a `W` x `H` profile: for the host simulator (about 1.6 MB
/// at QVGA).
pub type HostScaleSlam<const W: usize, const H: usize> = Slam<
    W,
    H,
    HOST_MAX_KEYFRAMES,
    HOST_MAX_LANDMARKS,
    { HOST_MAX_LANDMARKS / 32 },
    HOST_BA_RIGS,
    HOST_BA_POINTS,
    HOST_BA_OBSERVATIONS,
>;

/// The front end's parameters in SLAM mode: [`FrontendParams::DEFAULT`] without depth fusion
/// (bundle adjustment refines landmark positions instead).
///
/// Why: docs/decisions.md, "Depth fusion off in SLAM mode"; where SLAM still loses to odometry:
/// docs/decisions.md, "SLAM against odometry under per-frame depth noise".
pub const SLAM_FRONTEND: FrontendParams =
    FrontendParams { fuse_depth: false, ..FrontendParams::DEFAULT };

/// The front end at `W` x `H`, the map and the back end (see the module documentation). The
/// other parameters size the map and the back end as [`Backend`] says; their defaults are the
/// board's.
#[derive(Debug)]
pub struct Slam<
    const W: usize,
    const H: usize,
    const K: usize = { capacity::MAX_KEYFRAMES },
    const L: usize = { capacity::MAX_LANDMARKS },
    const LW: usize = { capacity::MAX_LANDMARKS / 32 },
    const R: usize = BA_RIGS,
    const P: usize = BA_POINTS,
    const O: usize = BA_OBSERVATIONS,
> {
    frontend: Frontend<W, H>,
    map: Map<K, L>,
    backend: Backend<K, L, LW, R, P, O>,
}

impl<
    const W: usize,
    const H: usize,
    const K: usize,
    const L: usize,
    const LW: usize,
    const R: usize,
    const P: usize,
    const O: usize,
> Default for Slam<W, H, K, L, LW, R, P, O>
{
    fn default() -> Self {
        Self::new()
    }
}

impl<
    const W: usize,
    const H: usize,
    const K: usize,
    const L: usize,
    const LW: usize,
    const R: usize,
    const P: usize,
    const O: usize,
> Slam<W, H, K, L, LW, R, P, O>
{
    /// A system with [`SLAM_FRONTEND`] and [`BackendParams::DEFAULT`] (`const`, for a
    /// `static`).
    pub const fn new() -> Self {
        Self::with_params(SLAM_FRONTEND, BackendParams::DEFAULT)
    }

    /// A system with the given parameters.
    pub const fn with_params(frontend: FrontendParams, backend: BackendParams) -> Self {
        Self {
            frontend: Frontend::with_params(frontend),
            map: Map::new(),
            backend: Backend::with_params(backend),
        }
    }

    /// Tracks one frame and hands a new keyframe to the back end (see
    /// [`Frontend::process`]).
    ///
    /// # Errors
    /// As [`Frontend::process`].
    pub fn process(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
    ) -> Result<FrameResult, FrontendError> {
        let result = self.frontend.process(frame, cam, &mut self.map)?;
        self.hand_over(&result);
        Ok(result)
    }

    /// Hands the keyframe `result` made, if any, to the back end: the second half of
    /// [`Self::process`], for a caller that ran [`Frontend::process`] itself through
    /// [`Self::parts_mut`].
    pub fn hand_over(&mut self, result: &FrameResult) {
        if let Some((kf, k)) = result.keyframe.and_then(|kf| self.map.keyframe(kf).map(|k| (kf, k)))
        {
            self.backend.keyframe_added(kf, k.seq);
        }
    }

    /// The front end, the map and the back end, borrowed apart: a host runs
    /// [`Backend::advance_solve`] (which reads no map) on another thread while
    /// [`Frontend::process`] tracks the next frame into the map, then calls [`Self::hand_over`]
    /// and, when the solve finished, [`Backend::finish_solve`] (see `ferroslam-sim`'s SLAM
    /// replay for a schedule that keeps the sequential result bit for bit).
    #[allow(clippy::type_complexity)]
    pub fn parts_mut(
        &mut self,
    ) -> (&mut Frontend<W, H>, &mut Map<K, L>, &mut Backend<K, L, LW, R, P, O>) {
        (&mut self.frontend, &mut self.map, &mut self.backend)
    }

    /// Advances the back end by at most about `work_quota` units (see [`Backend::step`]).
    ///
    /// # Errors
    /// As [`Backend::step`].
    pub fn step_backend(
        &mut self,
        cam: &PinholeCamera,
        work_quota: u32,
    ) -> Result<BackendStatus, BackendError> {
        self.backend.step(&mut self.map, cam, work_quota)
    }

    /// The map.
    pub fn map(&self) -> &Map<K, L> {
        &self.map
    }

    /// The front end.
    pub fn frontend(&self) -> &Frontend<W, H> {
        &self.frontend
    }

    /// The back end.
    pub fn backend(&self) -> &Backend<K, L, LW, R, P, O> {
        &self.backend
    }
}
