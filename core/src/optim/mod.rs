//! Fixed-memory least squares: a resumable bundle adjuster for RGB-D keyframes (local BA and
//! segmented global BA), by Levenberg-Marquardt on the Schur-reduced camera system solved
//! matrix-free by preconditioned conjugate gradients.
//!
//! # Variables and data
//!
//! - **Rigs** ([`RigId`]): pose variables `T_s = t_sw` (world to rig), each free or fixed.
//! - **Cameras** ([`CameraId`]): a keyframe hanging from a rig by a fixed offset `t_cs`, so its
//!   world-to-camera pose is `t_cw = t_cs T_s`. Local BA gives every keyframe its own rig at
//!   identity offset ([`BundleAdjuster::add_keyframe`]); segmented global BA gives each segment
//!   one rig and each of its keyframes the offset `t_cs = t_cw t_sw^-1` measured before the
//!   solve, so the segment's internal relative poses stay fixed and only segment poses move.
//! - **Points** ([`PointId`]): `p_w` (world, metres), free or fixed. Fixed points are the back
//!   end's reference landmarks: they anchor the poses and are never changed.
//! - **Observations** ([`ObservationId`]): point, camera, pixel `uv`, optional measured depth.
//!
//! All intrinsics are the one [`PinholeCamera`](crate::geometry::PinholeCamera) given to
//! [`BundleAdjuster::start`].
//!
//! # Cost
//!
//! The pose estimator's model ([`crate::pose`], the one [`SensorModel`](crate::config::SensorModel)
//! both take): per observation the whitened reprojection residual
//! `(project(t_cw p_w) - uv) / pixel_sigma_px` and, with depth, the whitened inverse-depth
//! residual `(1/z_pred - 1/z_meas) / depth_noise_coeff_per_m` (Kinect-class depth has a
//! constant inverse-depth sigma), each block under its own Huber loss with threshold
//! `huber_delta_px / pixel_sigma_px`.
//! Poses are updated on the left, `T_s <- exp(xi) T_s`, points additively.
//!
//! # Algorithm
//!
//! Levenberg-Marquardt with Marquardt damping `lambda (diag(H) + floor)` on every block. Each
//! solve eliminates the points (Schur complement with their damped 3x3 inverses) and solves the
//! reduced camera system `S x = -b` over the free rigs by preconditioned conjugate gradients:
//! `S` is never formed, its product runs through the observations (two visits each), and the
//! preconditioner is block Jacobi (each rig's 6x6 diagonal block of `S`, Cholesky-factored; exact
//! when a point's observations from one rig are consecutive, as in local BA, otherwise a positive
//! definite approximation). Points then get their steps by back-substitution. A trial that
//! lowers the cost without losing an observation in front of its camera is accepted (lambda
//! / 10), otherwise rejected (lambda * 10). The solve ends when a step, accepted or not, changes
//! the cost by less than [`BaParams::function_tolerance`] or moves nothing by more than the step
//! thresholds ([`Termination::Converged`]: at the minimum a trial differs from the current cost
//! by rounding only), after [`BaParams::max_iterations`] solves, or when lambda exceeds 1e6
//! ([`Termination::Stalled`]).
//!
//! Why matrix-free: a dense reduced system for 65 keyframes is 390 x 390 f32, 608 KB; its
//! packed triangle still 305 KB. PCG needs five 6-vectors and one 6x6 factor per rig instead.
//! The price is recomputing each observation's residual and Jacobian in every product: no
//! per-observation storage beyond the 8-byte observation itself.
//!
//! A point whose damped block is ill-conditioned (a pivot below 1e-5 of its diagonal: seen once
//! without depth, or along one ray only) and a rig whose preconditioner block fails to factor
//! (it sees nothing) are held fixed for that iteration; points behind a camera contribute nothing
//! until they come back in front.
//!
//! # Gauge
//!
//! The caller fixes the gauge: fixed rigs (e.g. the oldest keyframe, or keyframes outside the
//! window that see window points) or fixed points (reference landmarks; three non-collinear
//! ones fix a pose). With depth the scale is observed; without any fixed variable the six gauge
//! directions are held only by the damping (a weak prior towards the start): the solve still
//! converges, but the whole solution may drift by a small rigid motion.
//!
//! # Bounded steps and work units
//!
//! [`BundleAdjuster::step`] runs at most `work_quota` **work units** and returns; the solver is a
//! state machine (see `solver.rs`) whose cursors and partial sums live in the adjuster, so the
//! result is bit-identical however the work is split (tested with quotas 1, 1000 and
//! unbounded). A work unit is one of:
//!
//! - one observation visit in a pass (projection, residuals, Jacobian rows and their
//!   accumulation): the bulk of the work;
//! - the end of a point's sweep (its damped 3x3 inverse) or of a point;
//! - one rig or camera item (a 6-vector update, a 6x6 Cholesky, a camera pose).
//!
//! A Levenberg-Marquardt iteration with `k` PCG iterations costs about
//! `(6 + 2k) n_obs + (6 + 3k) n_points` units, plus `5 + 5k` per rig and camera.
//!
//! A unit costs about 400 host instructions on average (x86_64; the Cortex-M count is still to be
//! measured) and at most about 680 averaged over a step, so a quota of 5,000 keeps a step under
//! the back end's bar of 4 M host instructions. The cost of each kind of unit, and the benchmark's
//! figures: docs/decisions.md, "Bundle adjustment work units".
//!
//! # Memory
//!
//! Everything is in the adjuster: no heap; `step` keeps under about 1 KB on the stack (estimated
//! from the types it holds, not measured on the target). Observations take 8 bytes (pixels
//! rounded to 1/32 pixel, inverse depth to `2^-13` per metre, the camera as `u16`; the point is
//! implied by the grouping), a point 15 (position, fixed flag, end of its observations), a rig
//! 286 (pose, trial pose, its 6x6 preconditioner block, damping, five PCG 6-vectors), a camera
//! 258 (offset, two cached `t_cw`, its 6x6 block, two 6-vectors). The back end's one adjuster
//! (`backend::BoardBundleAdjuster`: the capacities of `config::BOARD_MAP`) serves local and
//! segmented BA, which never run at the same time; its size is in `memory-budget.md`.
//!
//! # Determinism
//!
//! f32 `+ - * /` in a fixed order (points, their observations, cameras and rigs in insertion
//! order; no `mul_add`), square roots through `ferroslam_fpu` (correctly rounded, as libm's),
//! SE(3) exp through `libm`; costs summed with Kahan compensation. No input (NaN, empty, all
//! fixed, degenerate geometry) panics: input is checked when added ([`BaError`]), numerical
//! trouble ends the solve with a [`Termination`].
//!
//! # Cost measurement
//!
//! `core/benches/ba_step.rs` solves a realistic window (65 keyframes, 1000 points, 5875
//! observations, Kinect-like noise at QVGA, 2 cm / 0.5 deg / 3 cm start error; or, with
//! `segmented`, the same keyframes as 13 segments of 5) in steps of a fixed quota, printing the
//! units of every step. Instructions per step, from the workspace root:
//!
//! ```text
//! cargo bench -p ferroslam-core --bench ba_step --no-run
//! BIN=$(ls -t target/release/deps/ba_step-* | grep -v '\.d$' | head -1)
//! mkdir -p target/ba-cg
//! valgrind --tool=callgrind --callgrind-out-file=target/ba-cg/cg.out.%p \
//!     --toggle-collect='ba_step::one_step*' --dump-after='*::one_step*' $BIN 5000 > target/ba-cg/steps.txt
//! grep -h '^totals:' target/ba-cg/cg.out.*.* | sort -k2 -n | tail -1
//! ```

mod linalg;
mod model;
mod observation_passes;
mod params;
mod pose_items;
mod problem;
mod solver;
mod solver_state;
mod variables;

#[cfg(test)]
mod tests;

use core::fmt;

pub use model::{MAX_OBSERVATION_PX, MIN_OBSERVATION_DEPTH_M, MIN_OBSERVATION_PX};
pub use params::BaParams;
pub use solver::BundleAdjuster;
pub use variables::ObservationResidual;

/// A rig (pose variable) of the problem held; valid until [`BundleAdjuster::clear`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RigId(u16);

/// A camera (keyframe) of the problem held.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CameraId(u16);

/// A point of the problem held.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PointId(u16);

/// An observation of the problem held.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ObservationId(u16);

macro_rules! id_index {
    ($($t:ty),*) => {$(
        impl $t {
            /// Insertion index, from 0.
            pub const fn index(self) -> usize {
                self.0 as usize
            }
        }
    )*};
}
id_index!(RigId, CameraId, PointId, ObservationId);

/// Which capacity is exhausted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum VariableKind {
    /// Rigs (pose variables).
    Rig,
    /// Cameras.
    Camera,
    /// Points.
    Point,
    /// Observations.
    Observation,
}

/// Input refused by a [`BundleAdjuster`], or a call out of order.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum BaError {
    /// A capacity of the adjuster is exhausted.
    Full {
        /// What is full.
        kind: VariableKind,
        /// Its capacity.
        capacity: usize,
    },
    /// A pose is not finite or its rotation not unit (to 1e-3).
    InvalidPose,
    /// A point is not finite.
    InvalidPoint,
    /// A pixel is not finite or outside `[MIN_OBSERVATION_PX, MAX_OBSERVATION_PX]`.
    InvalidPixel {
        /// Horizontal coordinate given, pixels.
        u: f32,
        /// Vertical coordinate given, pixels.
        v: f32,
    },
    /// A measured depth is not finite, not positive or nearer than `MIN_OBSERVATION_DEPTH_M`.
    InvalidDepth {
        /// Depth given, metres.
        depth_m: f32,
    },
    /// No rig with this index.
    UnknownRig {
        /// Index given.
        index: usize,
    },
    /// No camera with this index.
    UnknownCamera {
        /// Index given.
        index: usize,
    },
    /// An observation names a point other than the last one added.
    ObservationNotGrouped {
        /// Index of the point named.
        point: usize,
    },
    /// A [`BaParams`] value is out of range (see [`BaParams::is_valid`]).
    InvalidParams,
    /// Input added while a solve is under way; [`BundleAdjuster::clear`] first.
    Busy,
    /// [`BundleAdjuster::step`] before [`BundleAdjuster::start`].
    NotStarted,
}

impl fmt::Display for BaError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Full { kind, capacity } => write!(f, "{kind:?} capacity {capacity} exhausted"),
            Self::InvalidPose => write!(f, "pose is not finite or its rotation is not unit"),
            Self::InvalidPoint => write!(f, "point is not finite"),
            Self::InvalidPixel { u, v } => {
                write!(f, "pixel ({u}, {v}) is not finite or not storable")
            }
            Self::InvalidDepth { depth_m } => write!(f, "depth {depth_m} m is not storable"),
            Self::UnknownRig { index } => write!(f, "no rig {index}"),
            Self::UnknownCamera { index } => write!(f, "no camera {index}"),
            Self::ObservationNotGrouped { point } => {
                write!(f, "observation of point {point}, which is not the last point added")
            }
            Self::InvalidParams => write!(f, "bundle adjustment parameters out of range"),
            Self::Busy => write!(f, "a solve is under way: clear the adjuster first"),
            Self::NotStarted => write!(f, "step before start"),
        }
    }
}

impl core::error::Error for BaError {}

/// Why a solve ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Termination {
    /// Not finished yet.
    NotFinished,
    /// A step (accepted or not) changed the cost or the variables by less than the tolerances.
    Converged,
    /// [`BaParams::max_iterations`] solves done.
    MaxIterations,
    /// The damping exceeded its ceiling: no step lowers the cost (at f32 precision, usually the
    /// minimum).
    Stalled,
    /// No free rig or point can move (all fixed, or none observed well enough).
    NothingToOptimize,
    /// The cost at the start is not finite (extreme input); nothing was changed.
    NonFinite,
}

/// Figures of a solve.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BaSummary {
    /// Why it ended.
    pub termination: Termination,
    /// Robust cost (sum of Huber losses of whitened residuals) at the start.
    pub initial_cost: f32,
    /// Robust cost at the current estimate.
    pub final_cost: f32,
    /// Levenberg-Marquardt solves, accepted or not.
    pub iterations: u32,
    /// Accepted solves.
    pub accepted_iterations: u32,
    /// Conjugate-gradient iterations, over all solves.
    pub pcg_iterations: u32,
    /// Where the last conjugate-gradient solve stopped: `sqrt(r^T M^-1 r / r0^T M^-1 r0)`, the
    /// preconditioned residual relative to its start (0 when there was nothing to solve).
    pub pcg_last_relative_residual: f32,
    /// Work units spent so far.
    pub work_units: u64,
    /// Observations in front of their camera at the current estimate.
    pub valid_observations: u32,
    /// Rigs optimized in the last linearization (free and observed).
    pub active_rigs: u32,
    /// Points optimized in the last linearization (free and well-conditioned).
    pub active_points: u32,
    /// The damping reached.
    pub lambda: f32,
}

/// What [`BundleAdjuster::step`] reports.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BaStatus {
    /// More steps needed.
    Running,
    /// Done; the estimate is final.
    Finished(BaSummary),
}
