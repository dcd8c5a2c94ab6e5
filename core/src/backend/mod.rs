//! The back end: bundle adjustment of the map in bounded steps (paper Sec. II.B).
//!
//! # What it does
//!
//! - **Local BA** after each new keyframe: a window of keyframes chosen by covisibility with it
//!   (see `local.rs`: the keyframes sharing the most landmarks with it, then with those, up to
//!   [`capacity::LOCAL_WINDOW_MAX`] = 65), every landmark they observe (at least twice), and as
//!   fixed poses the other keyframes observing those landmarks.
//! - **Reference landmarks**: a landmark counts the bundle adjustments that optimized its
//!   position; at [`BackendParams::reference_after`] (10) it becomes a reference landmark, fixed in
//!   every later adjustment, where it anchors the poses and costs no variables.
//! - **Segmented global BA** each time a new segment of [`BackendParams::segment_keyframes`]
//!   keyframes (by creation number) is complete (see `global.rs`): inside a segment the relative
//!   poses stay fixed; only one pose per segment and the landmarks seen from two or more
//!   segments (the joints) are optimized; the other landmarks move with their segment. Memory is
//!   bounded whatever the map size: the map itself is bounded, and the problem's capacities are
//!   those of one [`BoardBundleAdjuster`].
//!
//! # Scheduling
//!
//! [`Backend::step`] does a bounded amount of work and returns: building a problem (one step,
//! charged by the observations it scans), then solver steps of at most `work_quota` units (see
//! [`crate::optim`]), then writing the result back to the map (one step). New keyframes only
//! set the next local BA's target ([`Backend::keyframe_added`]), so the back end never queues
//! unbounded work: when it is busy, it adjusts around the newest keyframe next. Given the same
//! frames and the same quota per step, the results are the same bits however the caller
//! schedules the steps in time (deterministic replay gives a fixed quota per frame). When a run
//! ends, its newest keyframes, which the skipped targets leave least adjusted, each get a local
//! BA ([`BackendParams::settle_keyframes`], run by `system::Slam::drain_backend`).
//!
//! A solver step reads no map and writes none: [`Backend::solve_job`] hands it out as a
//! [`SolveJob`] that borrows only the back end, which can run while the front end tracks the
//! next frame (`system::Slam::overlap` pairs the two); a solve it finishes is written to the map
//! by the next [`Backend::step`].
//!
//! While a solve runs, the front end keeps tracking and the map keeps growing: the solve works on
//! a copy of the window's poses and positions, and only keyframes and landmarks still in the map
//! when it finishes get its results (ids are generation-checked). A global BA also moves the
//! keyframes made during its solve, and the landmarks they host, with their segment (or the
//! newest segment of the problem), so the part of the map the front end tracks stays rigid.
//!
//! A local BA goes first: a global BA starts only when no keyframe waits for one. When the
//! front end makes keyframes faster than local BAs finish, a global BA therefore never starts (the
//! case on 7-Scenes with the board's 32-keyframe map). Why: docs/decisions.md, "Global BA after
//! the local BAs".
//!
//! # Capacities: the board's and the host-scale
//!
//! [`Backend`] is sized by its parameters, for a map of the same sizes. The board's
//! ([`BoardBackend`], the defaults, with [`crate::map::BoardMap`]: 32 keyframes, 1,024
//! landmarks, an adjuster of 32 rigs) is what the firmware runs; it caps a local BA at 32
//! keyframes in all, so the window's type cap of 65 is never reached there. The host-scale one
//! ([`HostBackend`] with [`crate::map::HostMap`]: 256 keyframes, 16,384 landmarks, 96 rigs) has
//! room for a full window and is the host simulator's `--map host`. While the board's map has
//! room (fewer than 32 keyframes, nothing retired) the two give the same bits.
//!
//! The default window grows by 2 covisibility levels ([`BackendParams::window_levels`]) on the
//! board's map. The paper's window of 50-65 keyframes in a map of over 120 is an option: the
//! host-scale map with `window_levels` 255 and a larger quota (`--map host --window-levels 255
//! --backend-quota 10000` of `ferroslam-sim replay` and `demo`); such a window takes hundreds of
//! frames to solve at the board's quota. Why it is not the default: docs/decisions.md, "Local
//! window: the board's map, two covisibility levels".

mod global;
mod local;

use core::fmt;

use heapless::Vec;

use crate::config::{BA_DEPTH_NOISE_COEFF_PER_M, BOARD_MAP, HOST_MAP, SensorModel, capacity};
use crate::geometry::PinholeCamera;
use crate::map::{KeyFrameId, LandmarkId, Map};
use crate::optim::{
    BaError, BaParams, BaStatus, BaSummary, BundleAdjuster, CameraId, PointId, Termination,
};

/// The adjuster the back end uses for local and global BA (they never run at once), sized by
/// `map`: rigs, a camera for every keyframe of the map, points and observations.
macro_rules! adjuster_for {
    ($map:expr) => {
        BundleAdjuster<
            { $map.ba_rigs },
            { $map.keyframes },
            { $map.ba_points },
            { $map.ba_observations },
        >
    };
}

/// A back end sized for `map` (a [`MapCapacity`](crate::config::MapCapacity)).
macro_rules! backend_for {
    ($map:expr) => {
        Backend<
            { $map.keyframes },
            { $map.landmarks },
            { $map.landmark_words },
            { $map.ba_rigs },
            { $map.ba_points },
            { $map.ba_observations },
        >
    };
}

/// The adjuster of the board's back end.
pub type BoardBundleAdjuster = adjuster_for!(BOARD_MAP);

/// The back end sized for the board's map ([`crate::map::BoardMap`], [`BOARD_MAP`]): what the
/// firmware runs.
pub type BoardBackend = backend_for!(BOARD_MAP);

/// The back end sized for the host-scale map ([`crate::map::HostMap`], [`HOST_MAP`]).
pub type HostBackend = backend_for!(HOST_MAP);

/// Tunables of the back end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BackendParams {
    /// Solver settings of local BA. Default: [`BaParams::DEFAULT`] with 5 iterations.
    pub local: BaParams,
    /// Solver settings of segmented global BA. Default: [`BaParams::DEFAULT`] with 5 iterations.
    pub global: BaParams,
    /// Keyframes in a local window at most (free poses), 1..=[`capacity::LOCAL_WINDOW_MAX`].
    /// Default 65.
    pub window_max: usize,
    /// A keyframe joins the window when it shares at least this many landmarks with it.
    /// Default 10.
    pub min_shared_landmarks: u16,
    /// Covisibility levels the window grows by (1: keyframes sharing landmarks with the new one;
    /// 2: also those sharing with them). The window stops growing earlier when a level adds no
    /// keyframe, so `u8::MAX` means until it holds `window_max` keyframes or no keyframe joins.
    /// Default 2 (why: docs/decisions.md, "Local window: the board's map, two covisibility
    /// levels").
    pub window_levels: u8,
    /// Bundle adjustments after which a landmark becomes a reference landmark. Default 10.
    pub reference_after: u8,
    /// Keyframes per segment of global BA (by creation number). Default
    /// [`capacity::SEGMENT_MAX_KEYFRAMES`].
    pub segment_keyframes: u32,
    /// Run segmented global BA when a segment completes. Default `true`.
    pub global_enabled: bool,
    /// When a run ends (`Slam::drain_backend`, before its map is read or saved), the newest
    /// this many keyframes each get a local BA around them, oldest first: in a run that went on
    /// they would sit in the windows of the keyframes after them, so at its end they have had
    /// the fewest adjustments. 0: none. Default 8, about a board window (9 keyframes on
    /// average); why: docs/decisions.md, "A run ends with its newest keyframes settled".
    pub settle_keyframes: u8,
}

impl BackendParams {
    /// The solver parameters both BAs start from: at most 5 iterations, a keyframe's depth
    /// weighed with [`BA_DEPTH_NOISE_COEFF_PER_M`].
    const SOLVER: BaParams = BaParams {
        max_iterations: 5,
        sensor: SensorModel {
            depth_noise_coeff_per_m: BA_DEPTH_NOISE_COEFF_PER_M,
            ..SensorModel::DEFAULT
        },
        ..BaParams::DEFAULT
    };

    /// The defaults, documented per field; both solvers run at most 5 iterations and weigh a
    /// keyframe's depth with [`BA_DEPTH_NOISE_COEFF_PER_M`].
    pub const DEFAULT: Self = Self {
        local: Self::SOLVER,
        global: Self::SOLVER,
        window_max: capacity::LOCAL_WINDOW_MAX,
        min_shared_landmarks: 10,
        window_levels: 2,
        reference_after: 10,
        segment_keyframes: capacity::SEGMENT_MAX_KEYFRAMES as u32,
        global_enabled: true,
        settle_keyframes: 8,
    };

    /// These parameters with the sensor's measurement model in both solvers, each keeping its
    /// own depth noise (bundle adjustment's, [`BA_DEPTH_NOISE_COEFF_PER_M`] by default).
    pub const fn with_sensor(self, sensor: SensorModel) -> Self {
        const fn with(ba: BaParams, sensor: SensorModel) -> BaParams {
            let depth_noise_coeff_per_m = ba.sensor.depth_noise_coeff_per_m;
            BaParams { sensor: SensorModel { depth_noise_coeff_per_m, ..sensor }, ..ba }
        }
        Self { local: with(self.local, sensor), global: with(self.global, sensor), ..self }
    }

    /// Whether every value is in range.
    pub fn is_valid(&self) -> bool {
        self.local.is_valid()
            && self.global.is_valid()
            && (1..=capacity::LOCAL_WINDOW_MAX).contains(&self.window_max)
            && self.window_levels >= 1
            && self.reference_after >= 1
            && self.segment_keyframes >= 1
    }
}

impl Default for BackendParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Which adjustment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BaKind {
    /// Local BA around a keyframe.
    Local,
    /// Segmented global BA.
    Global,
}

/// What one [`Backend::step`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BackendStatus {
    /// Nothing to do.
    Idle,
    /// Built a problem (the solve starts next step).
    Built(BaKind),
    /// Solving; more steps needed.
    Solving(BaKind),
    /// A solve finished and its result was written to the map.
    Finished(BaKind, BaSummary),
}

/// Why a step failed (bad parameters; the back end is idle again after it).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum BackendError {
    /// A [`BackendParams`] value is out of range.
    InvalidParams,
    /// The solver refused its input (a bug or a corrupted map; the job was dropped).
    Solver(BaError),
}

impl fmt::Display for BackendError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::InvalidParams => write!(f, "back-end parameters out of range"),
            Self::Solver(e) => write!(f, "bundle adjuster: {e}"),
        }
    }
}

impl core::error::Error for BackendError {}

/// Running totals since [`Backend::new`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BackendStats {
    /// Local adjustments finished and written back.
    pub local_runs: u32,
    /// Global adjustments finished and written back.
    pub global_runs: u32,
    /// Local windows by size: `window_sizes[n]` counts windows of `n` free keyframes.
    pub window_sizes: [u32; capacity::LOCAL_WINDOW_MAX + 1],
    /// Over all local adjustments: points added free and fixed (reference landmarks).
    pub free_points: u64,
    /// See `free_points`.
    pub fixed_points: u64,
    /// Landmarks made reference landmarks.
    pub reference_landmarks_made: u32,
    /// Steps taken.
    pub steps: u64,
    /// Work units charged (solver units and problem building).
    pub work_units: u64,
    /// Solves dropped because a loop closure moved the map under them.
    pub solves_dropped: u32,
}

/// The job in progress.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Job {
    Idle,
    /// A problem is built; the solve runs.
    Solving(BaKind),
    /// The solve finished in [`Backend::advance_solve`]; its result waits for
    /// [`Backend::finish_solve`] to write it to the map.
    Finished(BaKind, BaSummary),
}

/// The back end (see the module documentation), sized for a map of `K` keyframes and `L`
/// landmarks ([`Map<K, L>`]; `LW` = `L / 32` rounded up, the words of a bitset over its landmark
/// slots, a parameter of its own because stable Rust cannot compute it in a type) with an adjuster
/// of `R` rigs, `K` cameras, `P` points and `O` observations. The defaults are the board's
/// ([`BoardBackend`]); [`HostBackend`] is the host-scale one.
#[derive(Debug)]
pub struct Backend<
    const K: usize,
    const L: usize,
    const LW: usize,
    const R: usize,
    const P: usize,
    const O: usize,
> {
    params: BackendParams,
    ba: BundleAdjuster<R, K, P, O>,
    job: Job,
    /// The newest keyframe not yet adjusted around.
    pending: Option<KeyFrameId>,
    /// Segment of the newest keyframe at the last global BA.
    last_global_segment: Option<u32>,
    /// Newest keyframe creation number seen.
    newest_seq: u32,
    /// The keyframe of every camera of the problem, its id there, and whether its pose is free.
    cameras: Vec<(KeyFrameId, CameraId, bool), K>,
    /// The landmark of every point of the problem, its id there once added, and whether it is
    /// free.
    points: Vec<(LandmarkId, Option<PointId>, bool), P>,
    /// Global BA: each rig's segment number and pose before the solve (`t_sw`).
    rig_before: Vec<(u32, crate::geometry::Pose), K>,
    /// Global BA: the newest keyframe creation number when the problem was built (keyframes
    /// and landmarks made after it are not in the problem, and move with their segment).
    built_seq: u32,
    scratch: local::Scratch<K, L, LW, P>,
    stats: BackendStats,
}

impl<
    const K: usize,
    const L: usize,
    const LW: usize,
    const R: usize,
    const P: usize,
    const O: usize,
> Default for Backend<K, L, LW, R, P, O>
{
    fn default() -> Self {
        Self::new()
    }
}

impl<
    const K: usize,
    const L: usize,
    const LW: usize,
    const R: usize,
    const P: usize,
    const O: usize,
> Backend<K, L, LW, R, P, O>
{
    /// The capacities agree: the landmark bitset covers every landmark slot, the adjuster has a
    /// camera for every keyframe of the map (a global BA adds them all) and at least as many as
    /// its rigs (every rig of a local BA is a keyframe), and point and camera numbers fit the
    /// `u16` scratch. Evaluated by [`Self::with_params`], so a wrong size fails to compile.
    const CAPACITIES_AGREE: () = assert!(
        LW * 32 >= L && K >= R && R >= 1 && P < u16::MAX as usize && K < u16::MAX as usize - 1
    );

    /// An idle back end with [`BackendParams::DEFAULT`] (`const`, for a `static`).
    pub const fn new() -> Self {
        Self::with_params(BackendParams::DEFAULT)
    }

    /// An idle back end with `params` (checked on every step).
    pub const fn with_params(params: BackendParams) -> Self {
        let () = Self::CAPACITIES_AGREE;
        Self {
            params,
            ba: BundleAdjuster::new(),
            job: Job::Idle,
            pending: None,
            last_global_segment: None,
            newest_seq: 0,
            cameras: Vec::new(),
            points: Vec::new(),
            rig_before: Vec::new(),
            built_seq: 0,
            scratch: local::Scratch::new(),
            stats: BackendStats {
                local_runs: 0,
                global_runs: 0,
                window_sizes: [0; capacity::LOCAL_WINDOW_MAX + 1],
                free_points: 0,
                fixed_points: 0,
                reference_landmarks_made: 0,
                steps: 0,
                work_units: 0,
                solves_dropped: 0,
            },
        }
    }

    /// The parameters in use.
    pub fn params(&self) -> &BackendParams {
        &self.params
    }

    /// Running totals.
    pub fn stats(&self) -> &BackendStats {
        &self.stats
    }

    /// Whether a solve is in progress.
    pub fn is_busy(&self) -> bool {
        !matches!(self.job, Job::Idle)
    }

    /// Tells the back end that the front end made keyframe `kf` with creation number `seq`: the
    /// next local BA adjusts around it (replacing an older keyframe still waiting).
    pub fn keyframe_added(&mut self, kf: KeyFrameId, seq: u32) {
        self.pending = Some(kf);
        self.newest_seq = self.newest_seq.max(seq);
    }

    /// Tells the back end that a loop closure moved the whole map: a solve under way (built from
    /// the map before the move) is dropped, since writing it back would undo the move; the
    /// keyframe waiting for a local BA still gets one.
    pub fn map_moved(&mut self) {
        if self.is_busy() {
            self.ba.clear();
            self.job = Job::Idle;
            self.stats.solves_dropped = self.stats.solves_dropped.saturating_add(1);
        }
    }

    /// Does at most about `work_quota` units of work on `map` (see the module documentation).
    /// `cam` is the camera the map's observations were made with.
    ///
    /// # Errors
    /// [`BackendError::InvalidParams`]; [`BackendError::Solver`] when the solver refuses a
    /// problem (the job is dropped, the map unchanged).
    pub fn step(
        &mut self,
        map: &mut Map<K, L>,
        cam: &PinholeCamera,
        work_quota: u32,
    ) -> Result<BackendStatus, BackendError> {
        if !self.params.is_valid() {
            return Err(BackendError::InvalidParams);
        }
        match self.job {
            Job::Idle => {
                self.stats.steps += 1;
                self.start_job(map, cam)
            }
            Job::Solving(kind) => {
                if self.advance_solve(work_quota)? {
                    Ok(self.finish_solve(map).unwrap_or(BackendStatus::Idle))
                } else {
                    Ok(BackendStatus::Solving(kind))
                }
            }
            // Left by an `advance_solve` whose caller did not finish it: finish it now.
            Job::Finished(..) => Ok(self.finish_solve(map).unwrap_or(BackendStatus::Idle)),
        }
    }

    /// The solve under way as a [`SolveJob`], which borrows only this back end and never the
    /// map; `None` when no solve is under way (the next [`Self::step`] builds a problem or writes
    /// a result, and reads the map).
    pub fn solve_job(&mut self) -> Option<SolveJob<'_>> {
        matches!(self.job, Job::Solving(_)).then_some(SolveJob { solve: self })
    }

    /// The part of [`Self::step`] that reads no map and writes none: advances the solve under way
    /// by at most about `work_quota` units and returns whether it finished; its result then waits
    /// for [`Self::finish_solve`], which the next `step` does. When solving, `step(map, cam, q)` is
    /// exactly `advance_solve(q)` followed, if it returned `true`, by `finish_solve(map)`.
    fn advance_solve(&mut self, work_quota: u32) -> Result<bool, BackendError> {
        if !self.params.is_valid() {
            return Err(BackendError::InvalidParams);
        }
        let Job::Solving(kind) = self.job else {
            return Ok(false);
        };
        self.stats.steps += 1;
        let status = self.ba.step(work_quota.max(1)).map_err(|e| self.abort(e))?;
        let BaStatus::Finished(summary) = status else {
            return Ok(false);
        };
        self.job = Job::Finished(kind, summary);
        Ok(true)
    }

    /// Writes the result of a solve that [`Self::advance_solve`] finished to `map` (unless the
    /// solve diverged) and makes the back end idle; `None` when no finished solve waits.
    fn finish_solve(&mut self, map: &mut Map<K, L>) -> Option<BackendStatus> {
        let Job::Finished(kind, summary) = self.job else {
            return None;
        };
        self.stats.work_units += summary.work_units;
        if summary.termination != Termination::NonFinite {
            match kind {
                BaKind::Local => self.write_back_local(map),
                BaKind::Global => self.write_back_global(map),
            }
        }
        self.ba.clear();
        self.job = Job::Idle;
        Some(BackendStatus::Finished(kind, summary))
    }

    /// Builds the next problem, if any, and starts its solve.
    fn start_job(
        &mut self,
        map: &Map<K, L>,
        cam: &PinholeCamera,
    ) -> Result<BackendStatus, BackendError> {
        let segment = self.newest_seq / self.params.segment_keyframes.max(1);
        let global_due = self.params.global_enabled
            && segment > 0
            && self.last_global_segment.is_none_or(|s| segment > s);
        let (kind, built) = match self.pending.take() {
            Some(kf) => (BaKind::Local, self.build_local(map, kf)),
            None if global_due => {
                self.last_global_segment = Some(segment);
                (BaKind::Global, self.build_global(map))
            }
            None => return Ok(BackendStatus::Idle),
        };
        match built {
            Ok(scanned) => self.stats.work_units += scanned,
            Err(e) => return Err(self.abort(e)),
        }
        let params = match kind {
            BaKind::Local => self.params.local,
            BaKind::Global => self.params.global,
        };
        self.ba.start(cam, &params).map_err(|e| self.abort(e))?;
        self.job = Job::Solving(kind);
        Ok(BackendStatus::Built(kind))
    }

    /// Drops the job after a solver error.
    fn abort(&mut self, e: BaError) -> BackendError {
        self.ba.clear();
        self.job = Job::Idle;
        BackendError::Solver(e)
    }

    /// Counts one optimization of a free landmark, making it a reference landmark at the
    /// threshold.
    fn count_optimization(&mut self, map: &mut Map<K, L>, id: LandmarkId) {
        let threshold = self.params.reference_after;
        let Some(lm) = map.landmark_mut(id) else { return };
        lm.times_optimized = lm.times_optimized.saturating_add(1);
        if !lm.reference && lm.times_optimized >= threshold {
            lm.reference = true;
            self.stats.reference_landmarks_made =
                self.stats.reference_landmarks_made.saturating_add(1);
        }
    }
}

/// The solving half of a back end, which a [`SolveJob`] drives without naming its capacities.
trait Solve {
    fn advance(&mut self, work_units: u32) -> Result<bool, BackendError>;
    fn units_before_finish(&self) -> u64;
}

impl<
    const K: usize,
    const L: usize,
    const LW: usize,
    const R: usize,
    const P: usize,
    const O: usize,
> Solve for Backend<K, L, LW, R, P, O>
{
    fn advance(&mut self, work_units: u32) -> Result<bool, BackendError> {
        self.advance_solve(work_units)
    }

    fn units_before_finish(&self) -> u64 {
        self.ba.units_before_finish()
    }
}

/// The solve under way, as a job that borrows only the back end ([`Backend::solve_job`]): a
/// solve step reads no map and writes none, so the job can run while the front end tracks the
/// next frame, on another thread on a host or as a lower-priority task between frame interrupts
/// on a board. A solve the job finishes waits for the back end's next [`Backend::step`] to be
/// written to the map; a job advanced by fewer units than [`Self::units_before_finish`] cannot
/// finish, and then gives the same bits as that many units of `step` run in turn.
pub struct SolveJob<'a> {
    solve: &'a mut (dyn Solve + Send),
}

impl SolveJob<'_> {
    /// Advances the solve by at most about `work_units` (at least 1) and returns whether it
    /// finished.
    ///
    /// # Errors
    /// As [`Backend::step`]; the job is dropped then.
    pub fn advance(&mut self, work_units: u32) -> Result<bool, BackendError> {
        self.solve.advance(work_units)
    }

    /// At least how many work units the solve still takes before it can finish (see
    /// [`BundleAdjuster::units_before_finish`]). Cost: one pass over the problem's points.
    pub fn units_before_finish(&self) -> u64 {
        self.solve.units_before_finish()
    }
}

impl fmt::Debug for SolveJob<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SolveJob").finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests;
