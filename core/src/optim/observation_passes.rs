//! The observation passes: every pass walks the points in order and, per point, its observations
//! in up to two sweeps. One observation visit is one work unit; so is the end of a sweep and the
//! end of a point.
//!
//! | pass | sweep 0 (at the linearization point) | sweep 1 |
//! | --- | --- | --- |
//! | linearize | residuals, cost, camera blocks and gradients, the point's block and gradient | free active points: Schur terms into the rig blocks and gradients |
//! | product | free points: the point's block and `J_l^T W J_c x` | camera part of the reduced product |
//! | trial | free points: the point's block, gradient and `J_l^T W J_c x`, giving its step | cost at the trial estimate |
//! | apply | free points: as trial, giving the same step | - |
//!
//! The point's 3x3 block is recomputed in every pass rather than stored (36 bytes a point saved);
//! the arithmetic is the same each time, so every pass sees the same inverse.

use super::linalg::{
    Sym3, Vec3, Vec6, cross3, dot3, sym3_inverse, sym3_mul, sym3_rank1, sym6_rank1,
    sym6_sub_congruence,
};
use super::model::pose_row;
use super::solver::BundleAdjuster;
use super::solver_state::{Budget, PassKind, PointAcc, PointCursor};

/// Relative floor added to each diagonal entry before scaling by lambda (as tracking's), so a
/// direction the data do not see still gets damped.
pub(super) const DIAG_FLOOR: f32 = 1.0e-6;
/// Smallest pivot-to-diagonal ratio of a point block that is inverted; below it the point is
/// held fixed for the iteration (a point seen once without depth, or from one direction only).
const POINT_MIN_PIVOT_RATIO: f32 = 1.0e-5;

/// `y += s x`.
fn axpy3(y: &mut Vec3, s: f32, x: &Vec3) {
    for k in 0..3 {
        y[k] += s * x[k];
    }
}

fn axpy6(y: &mut Vec6, s: f32, x: &Vec6) {
    for k in 0..6 {
        y[k] += s * x[k];
    }
}

/// The inverse of `h + lambda (diag(h) + floor)`, or `None` when ill-conditioned.
pub(super) fn damped_inverse3(h: &Sym3, lambda: f32) -> Option<Sym3> {
    let floor = h[0].max(h[3]).max(h[5]) * DIAG_FLOOR;
    let mut d = *h;
    for k in [0, 3, 5] {
        d[k] += lambda * (h[k] + floor);
    }
    sym3_inverse(&d, POINT_MIN_PIVOT_RATIO)
}

/// The camera-frame displacement `rho + phi x p_c` of the camera twist `x`.
fn displacement(x: &Vec6, p_c: &Vec3) -> Vec3 {
    let c = cross3(&[x[3], x[4], x[5]], p_c);
    [x[0] + c[0], x[1] + c[1], x[2] + c[2]]
}

impl<const R: usize, const C: usize, const P: usize, const O: usize> BundleAdjuster<R, C, P, O> {
    /// Runs pass `kind` from `cur` while the budget lasts: the cursor to resume at, or `None`
    /// when the pass is done.
    pub(super) fn run_point_pass(
        &mut self,
        kind: PassKind,
        mut cur: PointCursor,
        b: &mut Budget,
    ) -> Option<PointCursor> {
        while cur.point < self.problem.n_points {
            let l = usize::from(cur.point);
            let (start, end) = self.problem.obs_range(l);
            if cur.sweep < 2 {
                let runs = self.sweep_runs(kind, l, cur.sweep);
                if runs && usize::from(cur.obs) < end {
                    if !b.take() {
                        return Some(cur);
                    }
                    self.visit(kind, cur.sweep, l, usize::from(cur.obs));
                    cur.obs += 1;
                    continue;
                }
                if runs {
                    if !b.take() {
                        return Some(cur);
                    }
                    self.end_sweep(kind, cur.sweep, l);
                }
                cur.sweep += 1;
                cur.obs = start as u16;
                continue;
            }
            if !b.take() {
                return Some(cur);
            }
            self.end_point(kind, l);
            self.state.acc = PointAcc::EMPTY;
            cur = PointCursor { point: cur.point + 1, sweep: 0, obs: end as u16 };
        }
        None
    }

    fn point_free(&self, l: usize) -> bool {
        !self.problem.point_fixed.get(l).copied().unwrap_or(true)
    }

    fn sweep_runs(&self, kind: PassKind, l: usize, sweep: u8) -> bool {
        match (kind, sweep) {
            (PassKind::Linearize, 0) => true,
            (PassKind::Linearize, _) => self.state.acc.active,
            (_, 0) => self.point_free(l),
            (PassKind::Apply, _) => false,
            (_, _) => true,
        }
    }

    fn visit(&mut self, kind: PassKind, sweep: u8, l: usize, j: usize) {
        match (kind, sweep) {
            (PassKind::Linearize, 0) => self.visit_linearize(l, j),
            (PassKind::Linearize, _) => self.visit_schur(l, j),
            (PassKind::Product, 0) => self.visit_point_block(l, j, false),
            (PassKind::Product, _) => self.visit_product(l, j),
            (_, 0) => self.visit_point_block(l, j, true),
            (_, _) => self.visit_trial_cost(l, j),
        }
    }

    fn end_sweep(&mut self, kind: PassKind, sweep: u8, l: usize) {
        let lambda = self.state.lambda;
        let free = self.point_free(l);
        let acc = &mut self.state.acc;
        match (kind, sweep) {
            (PassKind::Linearize, 0) => {
                if let (true, Some(hi)) = (free, damped_inverse3(&acc.h, lambda)) {
                    (acc.hi, acc.u, acc.active) = (hi, sym3_mul(&hi, &acc.g), true);
                    self.state.active_points += 1;
                }
            }
            (PassKind::Linearize, _) => self.flush_run(),
            (PassKind::Product, 0) => {
                acc.u =
                    damped_inverse3(&acc.h, lambda).map_or([0.0; 3], |hi| sym3_mul(&hi, &acc.v));
            }
            (PassKind::Product, _) => {}
            (_, 0) => {
                // The point step of the reduced system: dx = -H^-1 (g + J_l^T W J_c x).
                if let Some(hi) = damped_inverse3(&acc.h, lambda) {
                    let rhs = [acc.g[0] + acc.v[0], acc.g[1] + acc.v[1], acc.g[2] + acc.v[2]];
                    acc.u = sym3_mul(&hi, &rhs).map(|x| -x);
                    acc.active = true;
                }
                let len = ferroslam_fpu::sqrtf(dot3(&acc.u, &acc.u));
                let max = &mut self.state.step_max[2];
                *max = max.max(len);
            }
            (_, _) => {}
        }
    }

    fn end_point(&mut self, kind: PassKind, l: usize) {
        let s = &mut self.state;
        match kind {
            PassKind::Linearize | PassKind::Trial => {
                s.pass_cost.add(s.acc.cost);
                s.pass_valid += s.acc.valid;
            }
            PassKind::Product => {}
            PassKind::Apply => {
                if let (true, Some(p)) = (s.acc.active, self.problem.point.get_mut(l)) {
                    for (pk, uk) in p.iter_mut().zip(s.acc.u) {
                        *pk += uk;
                    }
                }
            }
        }
    }

    /// Linearize, sweep 0: residuals and cost; the camera's block and gradient (free rigs); the
    /// point's block and gradient (free points).
    fn visit_linearize(&mut self, l: usize, j: usize) {
        let Self { problem: p, work: w, state: s } = self;
        let Some(&obs) = p.obs.get(j) else { return };
        let c = usize::from(obs.camera);
        let cam_free = !p.rig_fixed.get(p.rig_of(c)).copied().unwrap_or(true);
        let point_free = !p.point_fixed.get(l).copied().unwrap_or(true);
        let (Some(cam), Some(p_w)) = (w.cam_pose[s.lin_slot & 1].get(c), p.point.get(l)) else {
            return;
        };
        let Some(t) = s.model.terms(cam, p_w, &obs) else { return };
        s.acc.cost += t.cost;
        s.acc.valid += 1;
        for row in t.rows() {
            if cam_free {
                let jr = pose_row(&t.p_c, &row.a);
                if let (Some(h), Some(g)) = (w.cam_h.get_mut(c), w.cam_acc.get_mut(c)) {
                    sym6_rank1(h, row.w, &jr);
                    axpy6(g, row.w * row.e, &jr);
                }
            }
            if point_free {
                let lr = cam.rotate_back(&row.a);
                sym3_rank1(&mut s.acc.h, row.w, &lr);
                axpy3(&mut s.acc.g, row.w * row.e, &lr);
            }
        }
    }

    /// Linearize, sweep 1 (active free points): `F = J_c^T W J_l` of the observation; the
    /// gradient's Schur term `-F H^-1 g`; `F` in rig coordinates added to the current run.
    fn visit_schur(&mut self, l: usize, j: usize) {
        let Self { problem: p, work: w, state: s } = self;
        let Some(&obs) = p.obs.get(j) else { return };
        let c = usize::from(obs.camera);
        let rig = p.rig_of(c);
        if p.rig_fixed.get(rig).copied().unwrap_or(true) {
            return;
        }
        let (Some(cam), Some(p_w)) = (w.cam_pose[s.lin_slot & 1].get(c), p.point.get(l)) else {
            return;
        };
        let Some(t) = s.model.terms(cam, p_w, &obs) else { return };
        // F = J_c^T W J_l = [I; [p_c]x] M R with M = sum_k w_k a_k a_k^T (camera frame).
        let mut m: Sym3 = [0.0; 6];
        for row in t.rows() {
            sym3_rank1(&mut m, row.w, &row.a);
        }
        // Gradient Schur term: F u = [M R u; p_c x (M R u)].
        let m_ru = sym3_mul(&m, &cam.rotate(&s.acc.u));
        if let Some(g) = w.cam_acc.get_mut(c) {
            let lower = cross3(&t.p_c, &m_ru);
            for k in 0..3 {
                g[k] -= m_ru[k];
                g[k + 3] -= lower[k];
            }
        }
        // Columns of M R, then of F.
        let cols: [Vec3; 3] = core::array::from_fn(|k| sym3_mul(&m, &cam.column(k)));
        let lower: [Vec3; 3] = core::array::from_fn(|k| cross3(&t.p_c, &cols[k]));
        let mut f: [Vec3; 6] = core::array::from_fn(|i| {
            let src = if i < 3 { &cols } else { &lower };
            [src[0][i % 3], src[1][i % 3], src[2][i % 3]]
        });
        if let Some(offset) = p.offset_matrix(c) {
            // Column by column: each column of F is a 6-vector in camera coordinates.
            let cols: [Vec6; 3] = core::array::from_fn(|k| {
                offset.adjoint_transpose(&core::array::from_fn(|i| f[i][k]))
            });
            f = core::array::from_fn(|i| [cols[0][i], cols[1][i], cols[2][i]]);
        }
        if s.acc.run_open && usize::from(s.acc.run_rig) != rig {
            self.flush_run();
        }
        let acc = &mut self.state.acc;
        (acc.run_rig, acc.run_open) = (rig as u16, true);
        for (run, fi) in acc.run_f.iter_mut().zip(&f) {
            for (r, x) in run.iter_mut().zip(fi) {
                *r += x;
            }
        }
    }

    /// Subtracts the open run's `F H^-1 F^T` from its rig's block.
    fn flush_run(&mut self) {
        let acc = &mut self.state.acc;
        if !acc.run_open {
            return;
        }
        if let Some(block) = self.work.rig_precond.get_mut(usize::from(acc.run_rig)) {
            sym6_sub_congruence(block, &acc.run_f, &acc.hi);
        }
        acc.run_f = [[0.0; 3]; 6];
        acc.run_open = false;
    }

    /// Product, trial and apply, sweep 0 (free points): the point's block, with its gradient when
    /// `gradient`, and `v += J_l^T W J_c x_c`.
    fn visit_point_block(&mut self, l: usize, j: usize, gradient: bool) {
        let Self { problem: p, work: w, state: s } = self;
        let Some(&obs) = p.obs.get(j) else { return };
        let c = usize::from(obs.camera);
        let rig_active = w.rig_active.get(p.rig_of(c)).copied().unwrap_or(false);
        let (Some(cam), Some(p_w), Some(x)) =
            (w.cam_pose[s.lin_slot & 1].get(c), p.point.get(l), w.cam_x.get(c))
        else {
            return;
        };
        let Some(t) = s.model.terms(cam, p_w, &obs) else { return };
        let d = displacement(x, &t.p_c);
        for row in t.rows() {
            let lr = cam.rotate_back(&row.a);
            sym3_rank1(&mut s.acc.h, row.w, &lr);
            if gradient {
                axpy3(&mut s.acc.g, row.w * row.e, &lr);
            }
            if rig_active {
                axpy3(&mut s.acc.v, row.w * dot3(&row.a, &d), &lr);
            }
        }
    }

    /// Product, sweep 1: `y_c += J_c^T W (J_c x_c - J_l u)` for cameras of active rigs.
    fn visit_product(&mut self, l: usize, j: usize) {
        let Self { problem: p, work: w, state: s } = self;
        let Some(&obs) = p.obs.get(j) else { return };
        let c = usize::from(obs.camera);
        if !w.rig_active.get(p.rig_of(c)).copied().unwrap_or(false) {
            return;
        }
        let point_free = !p.point_fixed.get(l).copied().unwrap_or(true);
        let (Some(cam), Some(p_w), Some(&x)) =
            (w.cam_pose[s.lin_slot & 1].get(c), p.point.get(l), w.cam_x.get(c))
        else {
            return;
        };
        let Some(t) = s.model.terms(cam, p_w, &obs) else { return };
        // Per row, J_c x - J_l u = a . (d - R u): the point's camera-frame displacement.
        let mut e = displacement(&x, &t.p_c);
        if point_free {
            let r_u = cam.rotate(&s.acc.u);
            for (ek, rk) in e.iter_mut().zip(r_u) {
                *ek -= rk;
            }
        }
        // sum_k w_k e_k [a_k; p_c x a_k] = [m; p_c x m] with m = sum_k w_k e_k a_k.
        let mut m = [0.0f32; 3];
        for row in t.rows() {
            axpy3(&mut m, row.w * dot3(&row.a, &e), &row.a);
        }
        if let Some(y) = w.cam_acc.get_mut(c) {
            for (yk, jk) in y.iter_mut().zip(pose_row(&t.p_c, &m)) {
                *yk += jk;
            }
        }
    }

    /// Trial, sweep 1: the cost at the trial poses and `p_w + dx`.
    fn visit_trial_cost(&mut self, l: usize, j: usize) {
        let Self { problem: p, work: w, state: s } = self;
        let Some(&obs) = p.obs.get(j) else { return };
        let c = usize::from(obs.camera);
        let (Some(cam), Some(&p_w)) = (w.cam_pose[(s.lin_slot + 1) & 1].get(c), p.point.get(l))
        else {
            return;
        };
        let p_trial = if s.acc.active {
            [p_w[0] + s.acc.u[0], p_w[1] + s.acc.u[1], p_w[2] + s.acc.u[2]]
        } else {
            p_w
        };
        if let Some(t) = s.model.terms(cam, &p_trial, &obs) {
            s.acc.cost += t.cost;
            s.acc.valid += 1;
        }
    }

    /// At least how many units pass `kind` still takes from `cur` before it is done: every unit
    /// [`Self::run_point_pass`] charges from there, except the Schur sweeps of the linearization
    /// whose points are not reached yet (whether one runs is known only after its first sweep).
    pub(super) fn point_pass_units_at_least(&self, kind: PassKind, cur: PointCursor) -> u64 {
        let mut units = 0u64;
        for point in cur.point..self.problem.n_points {
            let l = usize::from(point);
            let (start, end) = self.problem.obs_range(l);
            let here = point == cur.point;
            let first_sweep = if here { cur.sweep } else { 0 };
            for sweep in first_sweep..2 {
                let runs = match (kind, sweep) {
                    (PassKind::Linearize, 1) => here && cur.sweep == 1 && self.state.acc.active,
                    _ => self.sweep_runs(kind, l, sweep),
                };
                if runs {
                    let from =
                        if here && sweep == cur.sweep { usize::from(cur.obs) } else { start };
                    units += end.saturating_sub(from) as u64 + 1;
                }
            }
            units += 1;
        }
        units
    }
}
