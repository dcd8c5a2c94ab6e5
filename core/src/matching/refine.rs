//! Sub-pixel refinement by inverse-compositional affine Lucas-Kanade (Baker and Matthews 2004),
//! with the warped patch normalized to the template's mean and spread at every step so that a
//! gain or offset change between the frames does not bias the result (as ZNCC ignores it).
//!
//! Warp of a grid offset `u`: `W(u) = t + M u` (target pixels). The increment is parameterized as
//! `D(u) = (I + [[p1, p3], [p2, p4]]) u + (p5, p6)`, estimated on the template side and composed
//! inversely: `W <- W o D^-1`, so the 6x6 normal matrix is built and factored once.

use nalgebra::{Matrix6, Vector6};

use super::affine::{Mat2, mat_apply, mat_inverse, mat_mul};
use super::patch::{MAX_GRID, Template, grid, sample_bilinear};
use crate::image::GrayView;

/// The steepest-descent row `grad T * dW/dp` at grid offset `u`.
fn steepest_descent(t: &Template, u: (f32, f32)) -> Vector6<f32> {
    let (gx, gy) = t.gradient(u);
    Vector6::new(gx * u.0, gy * u.0, gx * u.1, gy * u.1, gx, gy)
}

/// What removes the photometric directions (a constant offset and a gain on the template) from
/// the steepest-descent images, so that Gauss-Newton on the normalized residual sees only geometry
/// (variable projection of the model `I(W(u)) = g T(u) + b`).
struct PhotometricBasis {
    /// Mean of the steepest-descent rows over the grid.
    mean_sd: Vector6<f32>,
    /// `sum_u (SD(u) - mean) (T(u) - mean_T) / sum_u (T(u) - mean_T)^2`.
    gain_coeff: Vector6<f32>,
}

impl PhotometricBasis {
    fn new(t: &Template) -> Self {
        let n = t.len() as f32;
        let mut mean_sd = Vector6::<f32>::zeros();
        for u in grid(t.half()) {
            mean_sd += steepest_descent(t, u);
        }
        mean_sd /= n;
        let mut gain_coeff = Vector6::<f32>::zeros();
        for u in grid(t.half()) {
            gain_coeff += (steepest_descent(t, u) - mean_sd) * (t.at(u) - t.mean);
        }
        // `t.norm > 0` is checked by the caller (flat templates never reach the refinement).
        gain_coeff /= t.norm * t.norm;
        Self { mean_sd, gain_coeff }
    }

    /// The steepest-descent row at `u`, orthogonal (over the grid) to 1 and to `T - mean_T`.
    fn project(&self, t: &Template, u: (f32, f32)) -> Vector6<f32> {
        steepest_descent(t, u) - self.mean_sd - self.gain_coeff * (t.at(u) - t.mean)
    }
}

/// Samples `target` at `centre + m u` over the template grid into `buf`; returns the number of
/// samples, their mean and zero-mean norm, or `None` when a sample leaves the target.
fn warp_patch(
    target: &GrayView<'_>,
    half: usize,
    centre: (f32, f32),
    m: &Mat2,
    buf: &mut [f32; MAX_GRID],
) -> Option<(f32, f32)> {
    let mut n = 0usize;
    let mut sum = 0.0f32;
    for (slot, u) in buf.iter_mut().zip(grid(half)) {
        let (dx, dy) = mat_apply(m, u);
        *slot = sample_bilinear(target, centre.0 + dx, centre.1 + dy)?;
        sum += *slot;
        n += 1;
    }
    let mean = sum / n as f32;
    let ss: f32 = buf.iter().take(n).map(|v| (v - mean) * (v - mean)).sum();
    Some((mean, ferroslam_fpu::sqrtf(ss)))
}

/// Refines the warp `(centre, m)` of template `t` into `target`. Returns the refined
/// `(centre, m)`, or `None` when a sample leaves the target, the normal matrix is singular or an
/// increment is not invertible. Stops after `max_iters` steps or once the translation increment is
/// below `eps_px`.
///
/// Cost: `(2h + 1)^2` samples plus ~30 flops each per iteration, and one 6x6 Cholesky.
pub(crate) fn refine_affine(
    t: &Template,
    target: &GrayView<'_>,
    centre: (f32, f32),
    m: Mat2,
    max_iters: usize,
    eps_px: f32,
) -> Option<((f32, f32), Mat2)> {
    let basis = PhotometricBasis::new(t);
    let mut hessian = Matrix6::<f32>::zeros();
    for u in grid(t.half()) {
        let sd = basis.project(t, u);
        hessian += sd * sd.transpose();
    }
    let chol = hessian.cholesky()?;
    let (mut c, mut m) = (centre, m);
    let mut buf = [0.0f32; MAX_GRID];
    for _ in 0..max_iters {
        let (mean_i, norm_i) = warp_patch(target, t.half(), c, &m, &mut buf)?;
        if norm_i.is_nan() || norm_i <= 0.0 {
            return None;
        }
        // Map the warped patch onto the template's photometry: (I - mean_I) * gain + mean_T.
        let gain = t.norm / norm_i;
        let mut b = Vector6::<f32>::zeros();
        for (&i_val, u) in buf.iter().zip(grid(t.half())) {
            let err = (i_val - mean_i) * gain + t.mean - t.at(u);
            b += basis.project(t, u) * err;
        }
        let dp = chol.solve(&b);
        // Components x, y, z, w, a, b of the 6-vector are p1..p6.
        let d: Mat2 = [[1.0 + dp.x, dp.z], [dp.y, 1.0 + dp.w]];
        let d_inv = mat_inverse(&d)?;
        // W o D^-1 (u) = c + M D^-1 (u - dt): new M = M D^-1, new c = c - (M D^-1) dt.
        m = mat_mul(&m, &d_inv);
        let (sx, sy) = mat_apply(&m, (dp.a, dp.b));
        c = (c.0 - sx, c.1 - sy);
        if !(c.0.is_finite() && c.1.is_finite()) {
            return None;
        }
        if dp.a * dp.a + dp.b * dp.b < eps_px * eps_px {
            break;
        }
    }
    Some((c, m))
}
