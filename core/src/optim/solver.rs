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

use super::model::Model;
use super::problem::Problem;
use super::solver_state::{
    Budget, LAMBDA_MAX, LAMBDA_MIN, PassKind, Pcg, Phase, PointAcc, PointCursor, State, Sum,
    Workspace,
};
use super::{BaError, BaParams, BaStatus, BaSummary, Termination};
use crate::geometry::PinholeCamera;

/// A fixed-memory, resumable bundle adjuster; see the [module documentation](super) for the
/// model, the algorithm, the work unit and the memory.
///
/// Capacities: `RIGS` pose variables, `CAMERAS` cameras hanging from them, `POINTS` points and
/// `OBSERVATIONS` observations, each at most 65,535. Build it in place (`static`, or
/// [`Self::new`] into its final home): at the back end's capacities it is large.
///
/// # Use
///
/// Fill (rigs or keyframes, then each point followed by its observations), [`Self::start`],
/// call [`Self::step`] between frames until it reports [`BaStatus::Finished`], read the
/// results; [`Self::clear`] before the next problem.
///
/// ```
/// use ferroslam_core::geometry::{PinholeCamera, Pose};
/// use ferroslam_core::optim::{BaParams, BaStatus, BundleAdjuster, Termination};
/// use nalgebra::{Point3, Translation3, UnitQuaternion};
///
/// let camera = PinholeCamera::new(262.5, 262.5, 159.75, 119.75, 320, 240)?;
/// let at = |x: f32| Pose::from_parts(Translation3::new(x, 0.0, 0.0), UnitQuaternion::identity());
/// let truth = [at(0.0), at(-0.1)];
/// // A small adjuster fits on the stack; the back end keeps its own in a `static`.
/// let mut ba = BundleAdjuster::<4, 4, 64, 256>::new();
/// let k0 = ba.add_keyframe(&truth[0], true)?; // fixed: it holds the gauge
/// let k1 = ba.add_keyframe(&at(-0.12), false)?; // starts 2 cm off
/// for i in 0..30 {
///     let f = i as f32;
///     let p_w = Point3::new(-0.5 + 0.035 * f, 0.1 * (f % 5.0) - 0.2, 2.0 + 0.05 * (f % 7.0));
///     let p = ba.add_point(&p_w, false)?;
///     for (k, t_cw) in [k0, k1].into_iter().zip(truth) {
///         let p_c = t_cw * p_w;
///         let uv = camera.project(&p_c).ok_or("behind the camera")?;
///         ba.add_observation(p, k, uv, Some(p_c.z))?;
///     }
/// }
/// ba.start(&camera, &BaParams::DEFAULT)?;
/// let summary = loop {
///     // One call per frame, at most 5,000 work units each.
///     if let BaStatus::Finished(summary) = ba.step(5000)? {
///         break summary;
///     }
/// };
/// assert_eq!(summary.termination, Termination::Converged);
/// let t1 = ba.camera_pose(k1).ok_or("unknown camera")?;
/// assert!((t1.translation.vector - truth[1].translation.vector).norm() < 1e-3);
/// # Ok::<(), Box<dyn core::error::Error>>(())
/// ```
#[derive(Debug, Clone)]
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

/// The phase `here(i)` to resume an item phase at cursor `i`, or `then` once it is done.
fn resume(cursor: Option<u32>, here: fn(u32) -> Phase, then: Phase) -> Phase {
    match cursor {
        Some(i) => here(i),
        None => then,
    }
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
        Self { problem: Problem::new(), work: Workspace::new(), state: State::new() }
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

    /// At least how many work units the solve must still do before it can finish: a
    /// [`Self::step`] with a smaller quota returns [`BaStatus::Running`]. An iteration can end the
    /// solve at four points only (after the linearization, the reduction, the trial's decision and
    /// the applied step); this counts the units to the nearest one ahead. 0 before
    /// [`Self::start`] and once finished. Cost: one pass over the points.
    pub fn units_before_finish(&self) -> u64 {
        let (nc, nr) = (u64::from(self.problem.n_cams), u64::from(self.problem.n_rigs));
        let left = |i: u32, n: u64| n.saturating_sub(u64::from(i));
        let pass = |kind| self.point_pass_units_at_least(kind, PointCursor::START);
        // The trial pass, then its decision (one unit).
        let trial = |rigs: u64, cams: u64| rigs + cams + pass(PassKind::Trial) + 1;
        match self.state.phase {
            Phase::Idle | Phase::Finished => 0,
            Phase::Prepare(i) => left(i, nc) + nc + nr + pass(PassKind::Linearize),
            Phase::Clear(i) => left(i, nc + nr) + pass(PassKind::Linearize),
            Phase::Linearize(cur) => self.point_pass_units_at_least(PassKind::Linearize, cur),
            Phase::ReduceCams(i) => left(i, nc) + nr,
            Phase::ReduceRigs(i) => left(i, nr),
            // The conjugate gradients may stop after any of their iterations: the trial follows.
            Phase::PcgStart(_)
            | Phase::ProductMap(_)
            | Phase::ProductObs(_)
            | Phase::GatherRigs(_)
            | Phase::GatherCams(_)
            | Phase::GatherDot(_)
            | Phase::Update(_)
            | Phase::Direction(_) => trial(nr, nc),
            Phase::TrialRigs(i) => trial(left(i, nr), nc),
            Phase::TrialCams(i) => trial(0, left(i, nc)),
            Phase::TrialObs(cur) => self.point_pass_units_at_least(PassKind::Trial, cur) + 1,
            Phase::Decide => 1,
            Phase::Apply(cur) => self.point_pass_units_at_least(PassKind::Apply, cur) + nr,
            Phase::ApplyRigs(i) => left(i, nr),
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
        n: u32,
        b: &mut Budget,
        f: fn(&mut Self, usize),
    ) -> Option<u32> {
        while i < n {
            if !b.take() {
                return Some(i);
            }
            f(self, i as usize);
            i += 1;
        }
        None
    }

    /// One stretch of the state machine: runs `phase` while the budget lasts and returns the
    /// phase to continue with (see the module documentation for the order of the phases).
    fn advance(&mut self, phase: Phase, b: &mut Budget) -> Phase {
        let (nc, nr) = (u32::from(self.problem.n_cams), u32::from(self.problem.n_rigs));
        match phase {
            Phase::Idle | Phase::Finished => phase,
            Phase::Prepare(i) => {
                let c = self.items(i, nc, b, Self::prepare_camera);
                resume(c, Phase::Prepare, Phase::Clear(0))
            }
            Phase::Clear(i) => match self.items(i, nc + nr, b, Self::clear_item) {
                Some(i) => Phase::Clear(i),
                None => self.begin_pass(PassKind::Linearize),
            },
            Phase::Linearize(cur) => self.point_phase(PassKind::Linearize, cur, b),
            Phase::ReduceCams(i) => {
                let c = self.items(i, nc, b, Self::reduce_camera);
                resume(c, Phase::ReduceCams, Phase::ReduceRigs(0))
            }
            Phase::ReduceRigs(i) => match self.items(i, nr, b, Self::reduce_rig) {
                Some(i) => Phase::ReduceRigs(i),
                None => self.after_reduce(),
            },
            Phase::PcgStart(_)
            | Phase::ProductMap(_)
            | Phase::ProductObs(_)
            | Phase::GatherRigs(_)
            | Phase::GatherCams(_)
            | Phase::GatherDot(_)
            | Phase::Update(_)
            | Phase::Direction(_) => self.advance_pcg(phase, b),
            Phase::TrialRigs(i) => {
                let c = self.items(i, nr, b, Self::trial_rig);
                resume(c, Phase::TrialRigs, Phase::TrialCams(0))
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

    /// [`Self::advance`] for the phases of the conjugate-gradient solve.
    fn advance_pcg(&mut self, phase: Phase, b: &mut Budget) -> Phase {
        let (nc, nr) = (u32::from(self.problem.n_cams), u32::from(self.problem.n_rigs));
        match phase {
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
                resume(c, Phase::GatherRigs, Phase::GatherCams(0))
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
            _ => phase,
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
        self.state.pcg_last_ratio = ferroslam_fpu::sqrtf(pcg.rz_new / pcg.rz0);
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
