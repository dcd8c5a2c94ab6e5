//! The resumable Levenberg-Marquardt state machine: what runs in which order, and how a work
//! quota cuts it into steps.
//!
//! One LM iteration runs these phases (item counts in parentheses; each item is one work unit):
//!
//! 1. `Clear` (cameras + rigs): zero the accumulators.
//! 2. `Linearize` (per point: its observations twice, plus up to 3): residuals, Huber weights,
//!    cost; camera blocks and gradients; each free point's 3x3 block, inverted with damping,
//!    and its Schur terms subtracted from the rig blocks and gradients.
//! 3. `ReduceCams`, `ReduceRigs`: camera blocks mapped to their rigs, damping added, the block-
//!    Jacobi preconditioner factored (Cholesky per rig).
//! 4. PCG on the reduced camera system: `PcgStart` (rigs), then per iteration `ProductMap`
//!    (cameras), `ProductObs` (the matrix-free Schur product: per point, observations twice),
//!    `GatherRigs`, `GatherCams`, `GatherDot`, `Update`, `Direction` (rigs or cameras).
//! 5. `TrialRigs`, `TrialCams`, `TrialObs` (per point: its observations twice, back-substituting
//!    the point step, then the cost at the trial estimate), `Decide`.
//! 6. On acceptance `Apply` (per point: its observations once) and `ApplyRigs`.
//!
//! Nothing a phase needs lives on the stack between two units: cursors and accumulators are in
//! [`State`], so cutting the sequence anywhere gives the same arithmetic in the same order.

use super::linalg::{PoseMatrix, StoredPose, Sym3, Sym6, Vec3, Vec6};
use super::model::Model;
use super::passes::{PassKind, PointCursor};
use super::problem::Problem;
use super::{BaError, BaParams, BaStatus, BaSummary, Termination};
use crate::geometry::PinholeCamera;

/// Damping bounds (as tracking's).
pub(super) const LAMBDA_MIN: f32 = 1.0e-7;
pub(super) const LAMBDA_MAX: f32 = 1.0e6;

/// Where the solver is. Item cursors count rigs or cameras; point cursors walk observations.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Phase {
    Idle,
    Prepare(u32),
    Clear(u32),
    Linearize(PointCursor),
    ReduceCams(u32),
    ReduceRigs(u32),
    PcgStart(u32),
    ProductMap(u32),
    ProductObs(PointCursor),
    GatherRigs(u32),
    GatherCams(u32),
    GatherDot(u32),
    Update(u32),
    Direction(u32),
    TrialRigs(u32),
    TrialCams(u32),
    TrialObs(PointCursor),
    Decide,
    Apply(PointCursor),
    ApplyRigs(u32),
    Finished,
}

/// A work quota being spent.
#[derive(Debug)]
pub(super) struct Budget {
    remaining: u32,
    used: u32,
}

impl Budget {
    /// Takes one unit; false when none is left.
    pub(super) fn take(&mut self) -> bool {
        if self.remaining == 0 {
            return false;
        }
        self.remaining -= 1;
        self.used += 1;
        true
    }
}

/// Compensated (Kahan) f32 sum: the cost of thousands of terms stays accurate enough to compare
/// a trial with the current estimate. Rust never reassociates float arithmetic, so the
/// compensation survives optimization.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct Sum {
    s: f32,
    c: f32,
}

impl Sum {
    pub(super) const ZERO: Self = Self { s: 0.0, c: 0.0 };

    pub(super) fn add(&mut self, x: f32) {
        let y = x - self.c;
        let t = self.s + y;
        self.c = (t - self.s) - y;
        self.s = t;
    }

    pub(super) fn value(&self) -> f32 {
        self.s
    }
}

/// Per-point scratch of the observation passes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct PointAcc {
    /// The point's 3x3 block `sum w l l^T` (undamped).
    pub(super) h: Sym3,
    /// Its gradient `sum w e l`.
    pub(super) g: Vec3,
    /// `sum w l (j . x_c)`: the point row of the reduced product or back-substitution.
    pub(super) v: Vec3,
    /// The damped inverse of `h`, when the point is active.
    pub(super) hi: Sym3,
    /// `hi g` (linearization), `hi v` (product), or the point step (trial, apply).
    pub(super) u: Vec3,
    pub(super) active: bool,
    /// Schur run: the rig whose observations are being summed, and their `F = J_s^T W J_l`.
    pub(super) run_rig: u16,
    pub(super) run_open: bool,
    pub(super) run_f: [Vec3; 6],
    /// Cost and projecting observations of this point.
    pub(super) cost: f32,
    pub(super) valid: u32,
}

impl PointAcc {
    pub(super) const EMPTY: Self = Self {
        h: [0.0; 6],
        g: [0.0; 3],
        v: [0.0; 3],
        hi: [0.0; 6],
        u: [0.0; 3],
        active: false,
        run_rig: 0,
        run_open: false,
        run_f: [[0.0; 3]; 6],
        cost: 0.0,
        valid: 0,
    };
}

/// Scalars of the conjugate-gradient iteration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Pcg {
    pub(super) rz: f32,
    pub(super) rz0: f32,
    pub(super) rz_new: f32,
    pub(super) pq: f32,
    pub(super) alpha: f32,
    pub(super) beta: f32,
    pub(super) iteration: u32,
}

impl Pcg {
    const ZERO: Self =
        Self { rz: 0.0, rz0: 0.0, rz_new: 0.0, pq: 0.0, alpha: 0.0, beta: 0.0, iteration: 0 };
}

/// Everything but the problem and the per-variable workspace.
#[derive(Debug)]
pub(super) struct State {
    pub(super) phase: Phase,
    pub(super) model: Model,
    pub(super) params: BaParams,
    pub(super) lambda: f32,
    /// Cost and projecting observations at the current estimate.
    pub(super) cost: f32,
    pub(super) valid: u32,
    pub(super) initial_cost: f32,
    /// Cost and projecting observations at the trial estimate (kept while the trial is applied).
    pub(super) trial_cost: f32,
    pub(super) trial_valid: u32,
    pub(super) acc: PointAcc,
    /// Running sums of the current observation pass.
    pub(super) pass_cost: Sum,
    pub(super) pass_valid: u32,
    pub(super) active_points: u32,
    pub(super) active_rigs: u32,
    pub(super) pcg: Pcg,
    /// Largest rig step (translation m, rotation rad) and point step (m) of the trial.
    pub(super) step_max: [f32; 3],
    /// Which of the two camera-pose slots holds the linearization point (the other: the trial).
    pub(super) lin_slot: usize,
    pub(super) iterations: u32,
    pub(super) accepted: u32,
    pub(super) pcg_iterations: u32,
    /// `sqrt(rz / rz0)` where the last PCG solve stopped.
    pub(super) pcg_last_ratio: f32,
    pub(super) work_units: u64,
    pub(super) termination: Termination,
}

impl State {
    /// Whether the trial moved every pose and point by less than the step thresholds.
    fn small_step(&self) -> bool {
        let p = &self.params;
        self.step_max[0] < p.min_step_translation_m
            && self.step_max[1] < p.min_step_rotation_rad
            && self.step_max[2] < p.min_step_point_m
    }
}

/// Per-rig and per-camera workspace.
#[derive(Debug)]
pub(super) struct Workspace<const R: usize, const C: usize> {
    pub(super) rig_trial: [StoredPose; R],
    /// Free and well-conditioned in this linearization.
    pub(super) rig_active: [bool; R],
    /// Diagonal of the rig's own block while linearizing; `lambda D` once reduced.
    pub(super) rig_damp: [Vec6; R],
    /// The Schur diagonal block, then its Cholesky factor: the preconditioner.
    pub(super) rig_precond: [Sym6; R],
    /// PCG vectors; `rig_r` holds the reduced gradient before PCG starts.
    pub(super) rig_x: [Vec6; R],
    pub(super) rig_r: [Vec6; R],
    pub(super) rig_z: [Vec6; R],
    pub(super) rig_p: [Vec6; R],
    pub(super) rig_q: [Vec6; R],
    /// `t_cw` of every camera in two slots: linearization point and trial.
    pub(super) cam_pose: [[PoseMatrix; C]; 2],
    /// The camera's own 6x6 block (camera frame), while linearizing.
    pub(super) cam_h: [Sym6; C],
    /// Gradient (linearizing), then the camera part of the Schur product (PCG).
    pub(super) cam_acc: [Vec6; C],
    /// The rig direction (PCG) or step (trial) mapped to the camera: `Ad(t_cs) x_s`.
    pub(super) cam_x: [Vec6; C],
}

/// A fixed-memory, resumable bundle adjuster; see the [module documentation](super) for the
/// model, the algorithm, the work unit and the memory.
///
/// Capacities: `RIGS` pose variables, `CAMERAS` cameras hanging from them, `POINTS` points and
/// `OBSERVATIONS` observations, each at most 65,535. Build it in place (`static`, or
/// [`Self::new`] into its final home): it is large.
#[derive(Debug)]
pub struct BundleAdjuster<
    const RIGS: usize,
    const CAMERAS: usize,
    const POINTS: usize,
    const OBSERVATIONS: usize,
> {
    pub(super) problem: Problem<RIGS, CAMERAS, POINTS, OBSERVATIONS>,
    pub(super) work: Workspace<RIGS, CAMERAS>,
    pub(super) state: State,
}

impl<const R: usize, const C: usize, const P: usize, const O: usize> Default
    for BundleAdjuster<R, C, P, O>
{
    fn default() -> Self {
        Self::new()
    }
}

impl<const R: usize, const C: usize, const P: usize, const O: usize> BundleAdjuster<R, C, P, O> {
    /// Indices are stored as `u16`.
    const CAPACITIES_FIT_U16: () = assert!(
        R <= 65535 && C <= 65535 && P <= 65535 && O <= 65535,
        "bundle adjuster capacities must be at most 65535"
    );

    /// An empty adjuster, in `const` context (for a `static`).
    pub const fn new() -> Self {
        let () = Self::CAPACITIES_FIT_U16;
        Self {
            problem: Problem::new(),
            work: Workspace {
                rig_trial: [StoredPose::IDENTITY; R],
                rig_active: [false; R],
                rig_damp: [[0.0; 6]; R],
                rig_precond: [[0.0; 21]; R],
                rig_x: [[0.0; 6]; R],
                rig_r: [[0.0; 6]; R],
                rig_z: [[0.0; 6]; R],
                rig_p: [[0.0; 6]; R],
                rig_q: [[0.0; 6]; R],
                cam_pose: [[PoseMatrix::IDENTITY; C]; 2],
                cam_h: [[0.0; 21]; C],
                cam_acc: [[0.0; 6]; C],
                cam_x: [[0.0; 6]; C],
            },
            state: State {
                phase: Phase::Idle,
                model: Model::EMPTY,
                params: BaParams::DEFAULT,
                lambda: BaParams::DEFAULT.lambda_init,
                cost: 0.0,
                valid: 0,
                initial_cost: 0.0,
                trial_cost: 0.0,
                trial_valid: 0,
                acc: PointAcc::EMPTY,
                pass_cost: Sum::ZERO,
                pass_valid: 0,
                active_points: 0,
                active_rigs: 0,
                pcg: Pcg::ZERO,
                step_max: [0.0; 3],
                lin_slot: 0,
                iterations: 0,
                accepted: 0,
                pcg_iterations: 0,
                pcg_last_ratio: 0.0,
                work_units: 0,
                termination: Termination::NotFinished,
            },
        }
    }

    /// Empties the problem (capacity and storage are kept) and stops any solve.
    pub fn clear(&mut self) {
        let p = &mut self.problem;
        (p.n_rigs, p.n_cams, p.n_points, p.n_obs) = (0, 0, 0, 0);
        self.state.phase = Phase::Idle;
        self.state.termination = Termination::NotFinished;
    }

    /// Starts (or restarts, from the current estimate) a solve of the problem held, with the
    /// intrinsics `camera` shared by every camera. Then call [`Self::step`] until it reports
    /// [`BaStatus::Finished`]. No variable may be added until [`Self::clear`].
    ///
    /// # Errors
    /// [`BaError::InvalidParams`] when `params` is not [`BaParams::is_valid`].
    pub fn start(&mut self, camera: &PinholeCamera, params: &BaParams) -> Result<(), BaError> {
        if !params.is_valid() {
            return Err(BaError::InvalidParams);
        }
        let s = &mut self.state;
        s.model = Model::new(camera, params);
        s.params = *params;
        s.lambda = params.lambda_init.clamp(LAMBDA_MIN, LAMBDA_MAX);
        (s.cost, s.valid, s.initial_cost) = (0.0, 0, 0.0);
        (s.iterations, s.accepted, s.pcg_iterations, s.work_units) = (0, 0, 0, 0);
        s.lin_slot = 0;
        s.termination = Termination::NotFinished;
        s.phase = Phase::Prepare(0);
        Ok(())
    }

    /// Advances the solve by at most `work_quota` work units (see the module documentation for
    /// what a unit costs); `u32::MAX` runs it to the end. The result depends only on the
    /// problem and parameters, never on how the work was split into steps.
    ///
    /// # Errors
    /// [`BaError::NotStarted`] before [`Self::start`].
    pub fn step(&mut self, work_quota: u32) -> Result<BaStatus, BaError> {
        if self.state.phase == Phase::Idle {
            return Err(BaError::NotStarted);
        }
        let mut budget = Budget { remaining: work_quota, used: 0 };
        while self.state.phase != Phase::Finished && budget.remaining > 0 {
            self.state.phase = self.advance(self.state.phase, &mut budget);
        }
        self.state.work_units += u64::from(budget.used);
        Ok(self.status())
    }

    /// Where the solve stands.
    pub fn status(&self) -> BaStatus {
        match self.state.phase {
            Phase::Finished => BaStatus::Finished(self.summary()),
            _ => BaStatus::Running,
        }
    }

    /// Figures of the solve so far (final once finished).
    pub fn summary(&self) -> BaSummary {
        let s = &self.state;
        BaSummary {
            termination: s.termination,
            initial_cost: s.initial_cost,
            final_cost: s.cost,
            iterations: s.iterations,
            accepted_iterations: s.accepted,
            pcg_iterations: s.pcg_iterations,
            pcg_last_relative_residual: s.pcg_last_ratio,
            work_units: s.work_units,
            valid_observations: s.valid,
            active_rigs: s.active_rigs,
            active_points: s.active_points,
            lambda: s.lambda,
        }
    }

    /// Runs `f` on items `i..n` while the budget lasts: the cursor to resume at, or `None` when
    /// done.
    fn items(
        &mut self,
        mut i: u32,
        n: u16,
        b: &mut Budget,
        f: fn(&mut Self, usize),
    ) -> Option<u32> {
        while i < u32::from(n) {
            if !b.take() {
                return Some(i);
            }
            f(self, i as usize);
            i += 1;
        }
        None
    }

    /// One stretch of the state machine: runs `phase` while the budget lasts and returns the
    /// phase to continue with.
    fn advance(&mut self, phase: Phase, b: &mut Budget) -> Phase {
        let (nc, nr) = (self.problem.n_cams, self.problem.n_rigs);
        let next = |cursor: Option<u32>, here: fn(u32) -> Phase, then: Phase| match cursor {
            Some(i) => here(i),
            None => then,
        };
        match phase {
            Phase::Idle | Phase::Finished => phase,
            Phase::Prepare(i) => {
                let c = self.items(i, nc, b, Self::prepare_camera);
                next(c, Phase::Prepare, Phase::Clear(0))
            }
            Phase::Clear(i) => match self.items(i, nc.saturating_add(nr), b, Self::clear_item) {
                Some(i) => Phase::Clear(i),
                None => self.begin_pass(PassKind::Linearize),
            },
            Phase::Linearize(cur) => self.point_phase(PassKind::Linearize, cur, b),
            Phase::ReduceCams(i) => {
                let c = self.items(i, nc, b, Self::reduce_camera);
                next(c, Phase::ReduceCams, Phase::ReduceRigs(0))
            }
            Phase::ReduceRigs(i) => match self.items(i, nr, b, Self::reduce_rig) {
                Some(i) => Phase::ReduceRigs(i),
                None => self.after_reduce(),
            },
            Phase::PcgStart(i) => match self.items(i, nr, b, Self::pcg_start) {
                Some(i) => Phase::PcgStart(i),
                None => self.after_pcg_start(),
            },
            Phase::ProductMap(i) => match self.items(i, nc, b, Self::product_map) {
                Some(i) => Phase::ProductMap(i),
                None => self.begin_pass(PassKind::Product),
            },
            Phase::ProductObs(cur) => self.point_phase(PassKind::Product, cur, b),
            Phase::GatherRigs(i) => {
                let c = self.items(i, nr, b, Self::gather_rig);
                next(c, Phase::GatherRigs, Phase::GatherCams(0))
            }
            Phase::GatherCams(i) => match self.items(i, nc, b, Self::gather_camera) {
                Some(i) => Phase::GatherCams(i),
                None => {
                    self.state.pcg.pq = 0.0;
                    Phase::GatherDot(0)
                }
            },
            Phase::GatherDot(i) => match self.items(i, nr, b, Self::gather_dot) {
                Some(i) => Phase::GatherDot(i),
                None => self.after_gather(),
            },
            Phase::Update(i) => match self.items(i, nr, b, Self::pcg_update) {
                Some(i) => Phase::Update(i),
                None => self.after_update(),
            },
            Phase::Direction(i) => match self.items(i, nr, b, Self::pcg_direction) {
                Some(i) => Phase::Direction(i),
                None => {
                    self.state.pcg.rz = self.state.pcg.rz_new;
                    Phase::ProductMap(0)
                }
            },
            Phase::TrialRigs(i) => {
                let c = self.items(i, nr, b, Self::trial_rig);
                next(c, Phase::TrialRigs, Phase::TrialCams(0))
            }
            Phase::TrialCams(i) => match self.items(i, nc, b, Self::trial_camera) {
                Some(i) => Phase::TrialCams(i),
                None => self.begin_pass(PassKind::Trial),
            },
            Phase::TrialObs(cur) => self.point_phase(PassKind::Trial, cur, b),
            Phase::Decide => {
                if b.take() {
                    self.decide()
                } else {
                    Phase::Decide
                }
            }
            Phase::Apply(cur) => self.point_phase(PassKind::Apply, cur, b),
            Phase::ApplyRigs(i) => match self.items(i, nr, b, Self::apply_rig) {
                Some(i) => Phase::ApplyRigs(i),
                None => self.after_apply(),
            },
        }
    }

    /// Resets the per-point scratch and the pass sums, and enters the point pass `kind`.
    fn begin_pass(&mut self, kind: PassKind) -> Phase {
        let s = &mut self.state;
        s.acc = PointAcc::EMPTY;
        s.pass_cost = Sum::ZERO;
        s.pass_valid = 0;
        match kind {
            PassKind::Linearize => {
                (s.active_points, s.active_rigs) = (0, 0);
                Phase::Linearize(PointCursor::START)
            }
            PassKind::Product => Phase::ProductObs(PointCursor::START),
            PassKind::Trial => {
                s.step_max[2] = 0.0;
                Phase::TrialObs(PointCursor::START)
            }
            PassKind::Apply => Phase::Apply(PointCursor::START),
        }
    }

    /// Runs the point pass `kind` from `cur`, and what follows it once done.
    fn point_phase(&mut self, kind: PassKind, cur: PointCursor, b: &mut Budget) -> Phase {
        match (self.run_point_pass(kind, cur, b), kind) {
            (Some(cur), PassKind::Linearize) => Phase::Linearize(cur),
            (Some(cur), PassKind::Product) => Phase::ProductObs(cur),
            (Some(cur), PassKind::Trial) => Phase::TrialObs(cur),
            (Some(cur), PassKind::Apply) => Phase::Apply(cur),
            (None, PassKind::Linearize) => self.after_linearize(),
            (None, PassKind::Product) => Phase::GatherRigs(0),
            (None, PassKind::Trial) => Phase::Decide,
            (None, PassKind::Apply) => Phase::ApplyRigs(0),
        }
    }

    fn finish(&mut self, termination: Termination) -> Phase {
        self.state.termination = termination;
        Phase::Finished
    }

    fn after_linearize(&mut self) -> Phase {
        let s = &mut self.state;
        s.cost = s.pass_cost.value();
        s.valid = s.pass_valid;
        if s.iterations == 0 {
            s.initial_cost = s.cost;
        }
        if !s.cost.is_finite() {
            return self.finish(Termination::NonFinite);
        }
        Phase::ReduceCams(0)
    }

    fn after_reduce(&mut self) -> Phase {
        if self.state.active_rigs == 0 && self.state.active_points == 0 {
            return self.finish(Termination::NothingToOptimize);
        }
        self.state.pcg = Pcg::ZERO;
        Phase::PcgStart(0)
    }

    fn after_pcg_start(&mut self) -> Phase {
        let pcg = &mut self.state.pcg;
        pcg.rz0 = pcg.rz;
        self.state.step_max = [0.0; 3];
        // Nothing to solve (no active rig, or a zero gradient): the pose step is zero.
        if pcg.rz > 0.0 && pcg.rz.is_finite() { Phase::ProductMap(0) } else { Phase::TrialRigs(0) }
    }

    fn after_gather(&mut self) -> Phase {
        let pcg = &mut self.state.pcg;
        // A non-positive curvature can only come from rounding: keep the step so far.
        if !(pcg.pq > 0.0 && pcg.pq.is_finite()) {
            return Phase::TrialRigs(0);
        }
        pcg.alpha = pcg.rz / pcg.pq;
        pcg.rz_new = 0.0;
        Phase::Update(0)
    }

    fn after_update(&mut self) -> Phase {
        let tol = self.state.params.pcg_relative_tolerance;
        let max = self.state.params.pcg_max_iterations;
        let pcg = &mut self.state.pcg;
        pcg.iteration += 1;
        self.state.pcg_iterations += 1;
        let converged = pcg.rz_new <= tol * tol * pcg.rz0;
        self.state.pcg_last_ratio = libm::sqrtf(pcg.rz_new / pcg.rz0);
        let usable = pcg.rz_new.is_finite() && pcg.rz > 0.0;
        if converged || pcg.iteration >= max || !usable {
            return Phase::TrialRigs(0);
        }
        pcg.beta = pcg.rz_new / pcg.rz;
        Phase::Direction(0)
    }

    /// Accepts the trial when it lowers the cost without losing observations.
    fn decide(&mut self) -> Phase {
        let s = &mut self.state;
        s.iterations += 1;
        (s.trial_cost, s.trial_valid) = (s.pass_cost.value(), s.pass_valid);
        if s.trial_cost.is_finite() && s.trial_cost <= s.cost && s.trial_valid >= s.valid {
            return self.begin_pass(PassKind::Apply);
        }
        // A step that changes nothing by more than the tolerances: at the minimum, where the
        // cost of a trial differs from the current one by rounding only.
        let p = &s.params;
        let small_change = (s.trial_cost - s.cost).abs() <= p.function_tolerance * s.cost;
        if small_change || s.small_step() {
            return self.finish(Termination::Converged);
        }
        s.lambda *= 10.0;
        if s.lambda > LAMBDA_MAX {
            return self.finish(Termination::Stalled);
        }
        if s.iterations >= s.params.max_iterations {
            return self.finish(Termination::MaxIterations);
        }
        Phase::Clear(0)
    }

    fn after_apply(&mut self) -> Phase {
        let s = &mut self.state;
        s.lin_slot = 1 - s.lin_slot;
        s.accepted += 1;
        let (old, new) = (s.cost, s.trial_cost);
        s.cost = new;
        s.valid = s.trial_valid;
        s.lambda = (s.lambda * 0.1).max(LAMBDA_MIN);
        let small_decrease = old - new <= s.params.function_tolerance * old;
        if small_decrease || s.small_step() {
            return self.finish(Termination::Converged);
        }
        if s.iterations >= s.params.max_iterations {
            return self.finish(Termination::MaxIterations);
        }
        Phase::Clear(0)
    }
}
