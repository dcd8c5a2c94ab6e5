//! The solver's state besides the problem: the phase and its cursors, the work budget, the
//! per-point scratch, the PCG scalars and the per-rig and per-camera workspace.

use super::BaParams;
use super::Termination;
use super::linalg::{PoseMatrix, StoredPose, Sym3, Sym6, Vec3, Vec6};
use super::model::Model;

/// Damping bounds (as tracking's).
pub(super) const LAMBDA_MIN: f32 = 1.0e-7;
pub(super) const LAMBDA_MAX: f32 = 1.0e6;

/// Which observation pass.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum PassKind {
    Linearize,
    Product,
    Trial,
    Apply,
}

/// Position in a point pass: the point, the sweep (0, 1; 2 = point end) and the observation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct PointCursor {
    pub(super) point: u16,
    pub(super) sweep: u8,
    pub(super) obs: u16,
}

impl PointCursor {
    pub(super) const START: Self = Self { point: 0, sweep: 0, obs: 0 };
}

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
    pub(super) remaining: u32,
    pub(super) used: u32,
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
    pub(super) const ZERO: Self =
        Self { rz: 0.0, rz0: 0.0, rz_new: 0.0, pq: 0.0, alpha: 0.0, beta: 0.0, iteration: 0 };
}

/// Everything but the problem and the per-variable workspace.
#[derive(Debug, Clone)]
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
    pub(super) const fn new() -> Self {
        State {
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
        }
    }

    /// Whether the trial moved every pose and point by less than the step thresholds.
    pub(super) fn small_step(&self) -> bool {
        let p = &self.params;
        self.step_max[0] < p.min_step_translation_m
            && self.step_max[1] < p.min_step_rotation_rad
            && self.step_max[2] < p.min_step_point_m
    }
}

/// Per-rig and per-camera workspace.
#[derive(Debug, Clone)]
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

impl<const R: usize, const C: usize> Workspace<R, C> {
    pub(super) const fn new() -> Self {
        Workspace {
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
        }
    }
}
