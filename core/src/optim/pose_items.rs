//! The per-camera and per-rig work items: camera poses, the reduction of camera blocks to rigs,
//! the block-Jacobi preconditioner, the preconditioned conjugate-gradient vector updates, and
//! the trial and accepted rig poses. Each item is one work unit.

use nalgebra::{UnitQuaternion, Vector6};

use super::linalg::{
    StoredPose, Vec6, dot6, sym6_add_diagonal, sym6_cholesky, sym6_diagonal, sym6_solve,
};
use super::observation_passes::DIAG_FLOOR;
use super::solver::BundleAdjuster;
use crate::geometry::se3_exp;

/// Smallest pivot-to-diagonal ratio of a rig block of the preconditioner; below it the rig is
/// held fixed for the iteration (a rig that sees too little).
const RIG_MIN_PIVOT_RATIO: f32 = 1.0e-6;

/// `exp(xi) t`, with the rotation re-normalized so repeated updates do not drift (as tracking's
/// update).
fn compose_left(xi: &Vec6, t: &StoredPose) -> StoredPose {
    let mut pose = se3_exp(&Vector6::from(*xi)) * t.to_pose();
    pose.rotation = UnitQuaternion::new_normalize(pose.rotation.into_inner());
    StoredPose::from_pose(&pose)
}

impl<const R: usize, const C: usize, const P: usize, const O: usize> BundleAdjuster<R, C, P, O> {
    fn rig_active(&self, s: usize) -> bool {
        self.work.rig_active.get(s).copied().unwrap_or(false)
    }

    fn rig_fixed(&self, s: usize) -> bool {
        self.problem.rig_fixed.get(s).copied().unwrap_or(true)
    }

    /// The camera's pose at the linearization point, from its rig's current pose.
    pub(super) fn prepare_camera(&mut self, c: usize) {
        let p = &self.problem;
        let Some(t_s) = p.rig_pose.get(p.rig_of(c)) else { return };
        let m = p.camera_matrix(c, t_s);
        if let Some(slot) = self.work.cam_pose[self.state.lin_slot & 1].get_mut(c) {
            *slot = m;
        }
    }

    /// Item `i`: camera `i` for `i < n_cams`, else rig `i - n_cams`: zero its accumulators.
    pub(super) fn clear_item(&mut self, i: usize) {
        let w = &mut self.work;
        let n_cams = usize::from(self.problem.n_cams);
        if i < n_cams {
            if let (Some(h), Some(g)) = (w.cam_h.get_mut(i), w.cam_acc.get_mut(i)) {
                (*h, *g) = ([0.0; 21], [0.0; 6]);
            }
            return;
        }
        let s = i - n_cams;
        if let (Some(b), Some(d), Some(r), Some(a)) = (
            w.rig_precond.get_mut(s),
            w.rig_damp.get_mut(s),
            w.rig_r.get_mut(s),
            w.rig_active.get_mut(s),
        ) {
            (*b, *d, *r, *a) = ([0.0; 21], [0.0; 6], [0.0; 6], false);
        }
    }

    /// Adds the camera's own block and gradient to its rig's, through `Ad(t_cs)`.
    pub(super) fn reduce_camera(&mut self, c: usize) {
        let s = self.problem.rig_of(c);
        if self.rig_fixed(s) {
            return;
        }
        let w = &mut self.work;
        let (Some(&h), Some(&g)) = (w.cam_h.get(c), w.cam_acc.get(c)) else { return };
        let (h, g) = match self.problem.offset_matrix(c) {
            Some(m) => (m.adjoint_congruence(&h), m.adjoint_transpose(&g)),
            None => (h, g),
        };
        if let (Some(d), Some(b), Some(r)) =
            (w.rig_damp.get_mut(s), w.rig_precond.get_mut(s), w.rig_r.get_mut(s))
        {
            let diag = sym6_diagonal(&h);
            for k in 0..6 {
                d[k] += diag[k];
                r[k] += g[k];
            }
            for (bk, hk) in b.iter_mut().zip(h.iter()) {
                *bk += hk;
            }
        }
    }

    /// Damps the rig's block (`lambda (diag + floor)`, kept for the product) and factors it.
    pub(super) fn reduce_rig(&mut self, s: usize) {
        if self.rig_fixed(s) {
            return;
        }
        let lambda = self.state.lambda;
        let w = &mut self.work;
        let (Some(d), Some(b), Some(r), Some(a)) = (
            w.rig_damp.get_mut(s),
            w.rig_precond.get_mut(s),
            w.rig_r.get_mut(s),
            w.rig_active.get_mut(s),
        ) else {
            return;
        };
        let floor = d.iter().fold(0.0f32, |m, &x| m.max(x)) * DIAG_FLOOR;
        *d = d.map(|x| lambda * (x + floor));
        sym6_add_diagonal(b, d);
        *a = sym6_cholesky(b, RIG_MIN_PIVOT_RATIO);
        if *a {
            self.state.active_rigs += 1;
        } else {
            *r = [0.0; 6];
        }
    }

    /// PCG start: `x = 0`, `r = -g`, `z = M^-1 r`, `p = z`.
    pub(super) fn pcg_start(&mut self, s: usize) {
        let active = self.rig_active(s);
        let w = &mut self.work;
        let (Some(x), Some(r), Some(z), Some(p), Some(l)) = (
            w.rig_x.get_mut(s),
            w.rig_r.get_mut(s),
            w.rig_z.get_mut(s),
            w.rig_p.get_mut(s),
            w.rig_precond.get(s),
        ) else {
            return;
        };
        *x = [0.0; 6];
        if !active {
            (*r, *z, *p) = ([0.0; 6], [0.0; 6], [0.0; 6]);
            return;
        }
        *r = r.map(|v| -v);
        *z = sym6_solve(l, r);
        *p = *z;
        self.state.pcg.rz += dot6(r, z);
    }

    /// Product start: the rig direction mapped to the camera, the camera accumulator zeroed.
    pub(super) fn product_map(&mut self, c: usize) {
        let s = self.problem.rig_of(c);
        let p = match (self.rig_active(s), self.work.rig_p.get(s)) {
            (true, Some(p)) => match self.problem.offset_matrix(c) {
                Some(m) => m.adjoint(p),
                None => *p,
            },
            _ => [0.0; 6],
        };
        if let (Some(x), Some(y)) = (self.work.cam_x.get_mut(c), self.work.cam_acc.get_mut(c)) {
            (*x, *y) = (p, [0.0; 6]);
        }
    }

    /// Product end, per rig: `q = lambda D p` (the damping term).
    pub(super) fn gather_rig(&mut self, s: usize) {
        let w = &mut self.work;
        if let (Some(q), Some(d), Some(p)) = (w.rig_q.get_mut(s), w.rig_damp.get(s), w.rig_p.get(s))
        {
            *q = core::array::from_fn(|k| d[k] * p[k]);
        }
    }

    /// Product end, per camera: `q_s += Ad(t_cs)^T y_c`.
    pub(super) fn gather_camera(&mut self, c: usize) {
        let s = self.problem.rig_of(c);
        if !self.rig_active(s) {
            return;
        }
        let Some(&y) = self.work.cam_acc.get(c) else { return };
        let y = match self.problem.offset_matrix(c) {
            Some(m) => m.adjoint_transpose(&y),
            None => y,
        };
        if let Some(q) = self.work.rig_q.get_mut(s) {
            for k in 0..6 {
                q[k] += y[k];
            }
        }
    }

    /// Product end, per rig: mask inactive rigs, accumulate `p . q`.
    pub(super) fn gather_dot(&mut self, s: usize) {
        let active = self.rig_active(s);
        let w = &mut self.work;
        if let (Some(q), Some(p)) = (w.rig_q.get_mut(s), w.rig_p.get(s)) {
            if !active {
                *q = [0.0; 6];
            }
            self.state.pcg.pq += dot6(p, q);
        }
    }

    /// `x += alpha p`, `r -= alpha q`, `z = M^-1 r`, accumulate `r . z`.
    pub(super) fn pcg_update(&mut self, s: usize) {
        if !self.rig_active(s) {
            return;
        }
        let alpha = self.state.pcg.alpha;
        let w = &mut self.work;
        let (Some(x), Some(r), Some(z), Some(p), Some(q), Some(l)) = (
            w.rig_x.get_mut(s),
            w.rig_r.get_mut(s),
            w.rig_z.get_mut(s),
            w.rig_p.get(s),
            w.rig_q.get(s),
            w.rig_precond.get(s),
        ) else {
            return;
        };
        for k in 0..6 {
            x[k] += alpha * p[k];
            r[k] -= alpha * q[k];
        }
        *z = sym6_solve(l, r);
        self.state.pcg.rz_new += dot6(r, z);
    }

    /// `p = z + beta p`.
    pub(super) fn pcg_direction(&mut self, s: usize) {
        if !self.rig_active(s) {
            return;
        }
        let beta = self.state.pcg.beta;
        let w = &mut self.work;
        if let (Some(p), Some(z)) = (w.rig_p.get_mut(s), w.rig_z.get(s)) {
            for k in 0..6 {
                p[k] = z[k] + beta * p[k];
            }
        }
    }

    /// The trial pose `exp(x) T_s` of an active rig (else its pose); the largest step so far.
    pub(super) fn trial_rig(&mut self, s: usize) {
        let active = self.rig_active(s);
        let (Some(&t), Some(&x)) = (self.problem.rig_pose.get(s), self.work.rig_x.get(s)) else {
            return;
        };
        let trial = if active { compose_left(&x, &t) } else { t };
        if active {
            let norm3 = |a: f32, b: f32, c: f32| ferroslam_fpu::sqrtf(a * a + b * b + c * c);
            let m = &mut self.state.step_max;
            m[0] = m[0].max(norm3(x[0], x[1], x[2]));
            m[1] = m[1].max(norm3(x[3], x[4], x[5]));
        }
        if let Some(slot) = self.work.rig_trial.get_mut(s) {
            *slot = trial;
        }
    }

    /// The camera's trial pose (second slot) and its step `Ad(t_cs) x_s`.
    pub(super) fn trial_camera(&mut self, c: usize) {
        let s = self.problem.rig_of(c);
        let Some(t_s) = self.work.rig_trial.get(s) else { return };
        let m = self.problem.camera_matrix(c, t_s);
        let x = match (self.rig_active(s), self.work.rig_x.get(s)) {
            (true, Some(x)) => match self.problem.offset_matrix(c) {
                Some(o) => o.adjoint(x),
                None => *x,
            },
            _ => [0.0; 6],
        };
        let slot = (self.state.lin_slot + 1) & 1;
        if let (Some(pose), Some(cx)) =
            (self.work.cam_pose[slot].get_mut(c), self.work.cam_x.get_mut(c))
        {
            (*pose, *cx) = (m, x);
        }
    }

    /// Accepts the trial pose of an active rig.
    pub(super) fn apply_rig(&mut self, s: usize) {
        if !self.rig_active(s) {
            return;
        }
        if let (Some(pose), Some(&trial)) =
            (self.problem.rig_pose.get_mut(s), self.work.rig_trial.get(s))
        {
            *pose = trial;
        }
    }
}
