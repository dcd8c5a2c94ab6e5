//! SE(3) poses on `Isometry3<f32>`, exp/log, the pinhole camera of the paper's Eq. 1-2 with
//! Jacobians, depth back-projection, Horn/Umeyama alignment.
//!
//! # Conventions
//!
//! - **Frames.** `t_ab` maps coordinates in frame `b` to frame `a`: `p_a = t_ab * p_b`. `t_wc` is
//!   camera-to-world (the camera's pose; what trajectories and outputs report), `t_cw` is
//!   world-to-camera (what projection uses). Camera axes: x right, y down, z forward. Metres.
//! - **Paper.** Eq. 1, `X_c = R_n X_w - p_n`, is `t_cw` with rotation `R_n` and translation
//!   `-p_n` (so `t_wc` has rotation `R_n^T` and translation `R_n^T p_n`, the camera centre).
//! - **Tangent vectors.** A twist is a `Vector6` ordered `[rho; phi]`: `rho` (entries 0..3) the
//!   translational part in metres, `phi` (entries 3..6) the rotation vector in radians. [`se3_exp`]
//!   is the true SE(3) exponential (`t = J_l(phi) rho`, the `V` matrix), not the decoupled one.
//! - **Perturbations** are on the left: `T <- exp(xi) T`. [`se3_adjoint`] moves them to the right.
//! - **Pixels.** Integer coordinates at pixel centres; the image spans
//!   `[-0.5, width - 0.5) x [-0.5, height - 0.5)`.
//! - **Precision.** The core works in f32. The Lie-group functions and [`align_rigid`] are generic
//!   over `T: RealField + Copy` so the host can use f64; every transcendental call goes through
//!   `libm` (nalgebra's `libm-force`), and no FMA is used, so host and Cortex-M give the same bits.

mod align;
mod camera;
mod se3;
mod so3;

#[cfg(test)]
mod jacobian_tests;
#[cfg(test)]
pub(crate) mod test_support;

pub use align::{AlignError, align_rigid};
pub use camera::{
    CameraError, MIN_PROJECTION_DEPTH_M, PinholeCamera, PoseProjection, WorldProjection,
};
pub use se3::{
    Pose, camera_gap, se3_adjoint, se3_exp, se3_left_jacobian, se3_left_jacobian_inv, se3_log,
};
pub use so3::{hat, so3_exp, so3_left_jacobian, so3_left_jacobian_inv, so3_log, vee};
