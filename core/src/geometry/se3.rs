//! SE(3): rigid-body motions on [`Isometry3`], the exponential and logarithm maps, the adjoint and
//! the left Jacobian.
//!
//! A tangent vector (twist) is a `Vector6` ordered `[rho; phi]`: `rho` (entries 0..3) is the
//! translational part in metres, `phi` (entries 3..6) the rotation vector in radians. The exp is
//! the true SE(3) exponential: `exp([rho; phi]) = (exp(phi), J_l(phi) rho)`, so a constant twist
//! moves along a screw, not along a straight line with an independent rotation.

use nalgebra::{Isometry3, Matrix3, Matrix6, RealField, Translation3, Vector3, Vector6};

use super::so3::{hat, lit, so3_exp, so3_left_jacobian, so3_left_jacobian_inv, so3_log};

/// A rigid-body motion (an element of SE(3)) in f32: rotation and translation in metres.
///
/// Names say which frames it maps: `t_ab` takes coordinates in frame `b` to frame `a`
/// (`p_a = t_ab * p_b`). `t_wc` is camera-to-world (the camera's pose in the world, what
/// trajectories report), `t_cw = t_wc.inverse()` world-to-camera (what projection uses).
pub type Pose = Isometry3<f32>;

/// How far apart two poses of one camera are: the distance between their camera centres (metres)
/// and the angle of the rotation from one orientation to the other (radians), both independent
/// of where the world origin is. Takes camera-to-world poses (`t_wc`), whose translations are the
/// centres.
pub fn camera_gap(a_wc: &Pose, b_wc: &Pose) -> (f32, f32) {
    let moved = (a_wc.translation.vector - b_wc.translation.vector).norm();
    let turned = (a_wc.rotation * b_wc.rotation.inverse()).angle();
    (moved, turned)
}

/// The `(rho, phi)` parts of a twist `[rho; phi]`.
fn split<T: RealField + Copy>(xi: &Vector6<T>) -> (Vector3<T>, Vector3<T>) {
    // nalgebra names the six entries x, y, z, w, a, b.
    (Vector3::new(xi.x, xi.y, xi.z), Vector3::new(xi.w, xi.a, xi.b))
}

/// The twist `[rho; phi]`.
fn join<T: RealField + Copy>(rho: &Vector3<T>, phi: &Vector3<T>) -> Vector6<T> {
    Vector6::new(rho.x, rho.y, rho.z, phi.x, phi.y, phi.z)
}

/// The 6x6 matrix `[[a, b], [c, d]]` of four 3x3 blocks.
fn blocks<T: RealField + Copy>(
    a: &Matrix3<T>,
    b: &Matrix3<T>,
    c: &Matrix3<T>,
    d: &Matrix3<T>,
) -> Matrix6<T> {
    let mut m = Matrix6::zeros();
    // Constant offsets inside the 6x6 bounds: nalgebra's bounds checks cannot fire.
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(a);
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(b);
    m.fixed_view_mut::<3, 3>(3, 0).copy_from(c);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(d);
    m
}

/// The motion `exp(xi)` of the twist `xi = [rho; phi]` (metres; radians):
/// rotation `so3_exp(phi)`, translation `J_l(phi) rho` (the `V` matrix of the SE(3) exp).
pub fn se3_exp<T: RealField + Copy>(xi: &Vector6<T>) -> Isometry3<T> {
    let (rho, phi) = split(xi);
    let t = so3_left_jacobian(&phi) * rho;
    Isometry3::from_parts(Translation3::from(t), so3_exp(&phi))
}

/// The twist `[rho; phi]` of `pose`, with rotation angle `|phi|` in `[0, pi]`:
/// `phi = so3_log(R)`, `rho = J_l(phi)^-1 t`. Inverse of [`se3_exp`] for angles below pi.
pub fn se3_log<T: RealField + Copy>(pose: &Isometry3<T>) -> Vector6<T> {
    let phi = so3_log(&pose.rotation);
    let rho = so3_left_jacobian_inv(&phi) * pose.translation.vector;
    join(&rho, &phi)
}

/// The adjoint `Ad(T)` of `pose` on twists `[rho; phi]`: `T exp(xi) T^-1 = exp(Ad(T) xi)`.
///
/// `Ad(T) = [[R, [t]x R], [0, R]]`. It moves a perturbation from one side to the other:
/// `T exp(xi) = exp(Ad(T) xi) T`.
pub fn se3_adjoint<T: RealField + Copy>(pose: &Isometry3<T>) -> Matrix6<T> {
    let r = pose.rotation.to_rotation_matrix().into_inner();
    let tr = hat(&pose.translation.vector) * r;
    blocks(&r, &tr, &Matrix3::zeros(), &r)
}

/// `theta^2` below which [`q_coefficients`] uses its series: `128 epsilon^(1/4)` (f32: about
/// 2.4, angles up to 1.5 rad; f64: 0.016). Above it the closed forms lose no more than a few
/// epsilon; below it the series truncation error is below epsilon.
fn q_series_limit<T: RealField + Copy>() -> T {
    T::default_epsilon().sqrt().sqrt() * lit(128.0)
}

/// The three angle coefficients of `Q(rho, phi)` (Barfoot, State Estimation for Robotics,
/// eq. 7.86): `(t - sin t)/t^3`, `(t^2 + 2 cos t - 2)/(2 t^4)`, `(2t - 3 sin t + t cos t)/(2 t^5)`.
///
/// All three cancel badly for small `t`, and unlike in `J_l` their matrices are only of first
/// order in `t`, so in f32 the series is used up to about 1.5 rad.
fn q_coefficients<T: RealField + Copy>(theta_sq: T) -> (T, T, T) {
    if theta_sq < q_series_limit() {
        // Horner form of the alternating series.
        let s = theta_sq;
        let series = |[k0, k1, k2, k3, k4]: [f64; 5]| {
            lit::<T>(k0)
                - s * (lit::<T>(k1) - s * (lit::<T>(k2) - s * (lit::<T>(k3) - s * lit(k4))))
        };
        let c1 =
            series([1.0 / 6.0, 1.0 / 120.0, 1.0 / 5040.0, 1.0 / 362_880.0, 1.0 / 39_916_800.0]);
        let c2 = series([
            1.0 / 24.0,
            1.0 / 720.0,
            1.0 / 40_320.0,
            1.0 / 3_628_800.0,
            1.0 / 479_001_600.0,
        ]);
        let c3 = series([
            1.0 / 120.0,
            1.0 / 2520.0,
            1.0 / 120_960.0,
            1.0 / 9_979_200.0,
            5.0 / 6_227_020_800.0,
        ]);
        (c1, c2, c3)
    } else {
        let t = theta_sq.sqrt();
        let (s, c) = (t.sin(), t.cos());
        let t4 = theta_sq * theta_sq;
        let two: T = lit(2.0);
        let c1 = (t - s) / (theta_sq * t);
        let c2 = (theta_sq + two * c - two) / (two * t4);
        let c3 = (two * t - lit::<T>(3.0) * s + t * c) / (two * t4 * t);
        (c1, c2, c3)
    }
}

/// The upper-right block `Q(rho, phi)` of the SE(3) left Jacobian.
fn q_block<T: RealField + Copy>(rho: &Vector3<T>, phi: &Vector3<T>) -> Matrix3<T> {
    let (c1, c2, c3) = q_coefficients(phi.norm_squared());
    let p = hat(phi);
    let r = hat(rho);
    let pr = p * r;
    let rp = r * p;
    let prp = pr * p;
    let ppr = p * pr;
    let rpp = rp * p;
    r * lit::<T>(0.5)
        + (pr + rp + prp) * c1
        + (ppr + rpp - prp * lit::<T>(3.0)) * c2
        + (prp * p + p * prp) * c3
}

/// The left Jacobian `J_l(xi)` of SE(3) for `xi = [rho; phi]`:
/// `exp(xi + d) = exp(J_l(xi) d) exp(xi)` to first order in `d`.
///
/// `J_l = [[J_l(phi), Q(rho, phi)], [0, J_l(phi)]]` with the SO(3) [`so3_left_jacobian`] and
/// Barfoot's `Q`. The right Jacobian is `J_l(-xi)`.
pub fn se3_left_jacobian<T: RealField + Copy>(xi: &Vector6<T>) -> Matrix6<T> {
    let (rho, phi) = split(xi);
    let j = so3_left_jacobian(&phi);
    blocks(&j, &q_block(&rho, &phi), &Matrix3::zeros(), &j)
}

/// The inverse of [`se3_left_jacobian`]: `log(exp(d) exp(xi)) = xi + J_l(xi)^-1 d` to first
/// order in `d`. Valid for rotation angles `|phi| < 2 pi`.
///
/// `J_l^-1 = [[J^-1, -J^-1 Q J^-1], [0, J^-1]]` with `J = J_l(phi)`.
pub fn se3_left_jacobian_inv<T: RealField + Copy>(xi: &Vector6<T>) -> Matrix6<T> {
    let (rho, phi) = split(xi);
    let ji = so3_left_jacobian_inv(&phi);
    let upper = -(ji * q_block(&rho, &phi) * ji);
    blocks(&ji, &upper, &Matrix3::zeros(), &ji)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::test_support::{random_twist, random_vector3};
    use crate::test_rng::TestRng;
    use nalgebra::{Point3, UnitQuaternion};

    fn pose_distance(a: &Isometry3<f64>, b: &Isometry3<f64>) -> f64 {
        (a.translation.vector - b.translation.vector).norm() + a.rotation.angle_to(&b.rotation)
    }

    /// The gap between two poses of a camera is the same wherever the world's origin is, and is
    /// the offset and turn of one camera seen from the other (`a_cw * b_cw^-1`).
    #[test]
    fn camera_gap_does_not_depend_on_the_world_origin() {
        let mut rng = TestRng::new(11);
        for i in 0..200 {
            let a: Pose = se3_exp(&random_twist(&mut rng, i)).cast();
            let nudge: Pose = se3_exp(&(random_twist(&mut rng, i) * 0.01)).cast();
            let b = nudge * a;
            let world: Pose = se3_exp(&(random_twist(&mut rng, i) * 5.0)).cast();
            let (moved, turned) = camera_gap(&a, &b);
            let (moved_w, turned_w) = camera_gap(&(world * a), &(world * b));
            let seen = a.inverse() * b;
            let expected = (seen.translation.vector.norm(), seen.rotation.angle());
            for (got, want) in [(moved, expected.0), (moved_w, expected.0)] {
                assert!((got - want).abs() <= 1e-4 * (1.0 + want), "{i}: {got} vs {want}");
            }
            for (got, want) in [(turned, expected.1), (turned_w, expected.1)] {
                assert!((got - want).abs() <= 1e-3, "{i}: {got} vs {want}");
            }
        }
    }

    #[test]
    fn exp_is_the_matrix_exponential() {
        // exp of the 4x4 twist matrix by its (converging) power series, as the reference.
        let mut rng = TestRng::new(10);
        for i in 0..300 {
            let xi = random_twist(&mut rng, i);
            let (rho, phi) = split(&xi);
            let mut x = nalgebra::Matrix4::zeros();
            x.fixed_view_mut::<3, 3>(0, 0).copy_from(&hat(&phi));
            x.fixed_view_mut::<3, 1>(0, 3).copy_from(&rho);
            let mut term = nalgebra::Matrix4::identity();
            let mut sum = term;
            for k in 1..60 {
                term = term * x / f64::from(k);
                sum += term;
            }
            assert!((se3_exp(&xi).to_homogeneous() - sum).norm() < 1e-12, "xi {xi:?}");
        }
    }

    #[test]
    fn log_inverts_exp_and_exp_inverts_log() {
        let mut rng = TestRng::new(11);
        for i in 0..3000 {
            let xi = random_twist(&mut rng, i);
            let pose = se3_exp(&xi);
            let back = se3_log(&pose);
            // Near pi, rho = J^-1 t is sensitive to the angle: allow for it.
            let tol = if xi.fixed_rows::<3>(3).norm() > 3.1 { 1e-12 } else { 1e-14 };
            assert!((back - xi).norm() <= tol * (1.0 + xi.norm()), "xi {xi:?} back {back:?}");
            assert!(pose_distance(&se3_exp(&back), &pose) < 1e-13);
            // f32 against f64.
            let xi32: Vector6<f32> = xi.cast();
            let pose32 = se3_exp(&xi32);
            assert!(pose_distance(&pose32.cast(), &pose) < 2e-6 * (1.0 + xi.norm()));
            let back32 = se3_log(&pose32).cast::<f64>();
            let tol32 = if xi.fixed_rows::<3>(3).norm() > 3.1 { 1e-5 } else { 1e-6 };
            assert!((back32 - xi).norm() <= tol32 * (1.0 + xi.norm()), "xi {xi:?} {back32:?}");
        }
    }

    #[test]
    fn log_exp_of_arbitrary_poses() {
        let mut rng = TestRng::new(12);
        for _ in 0..1000 {
            let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
            ));
            let pose =
                Isometry3::from_parts(Translation3::from(random_vector3(&mut rng, -5.0, 5.0)), q);
            assert!(pose_distance(&se3_exp(&se3_log(&pose)), &pose) < 1e-12);
            let pose32: Pose = pose.cast();
            assert!(pose_distance(&se3_exp(&se3_log(&pose32)).cast(), &pose) < 1e-5);
        }
    }

    #[test]
    fn adjoint_moves_perturbations_across() {
        let mut rng = TestRng::new(13);
        for i in 0..500 {
            let pose = se3_exp(&random_twist(&mut rng, i));
            let xi = random_twist(&mut rng, i + 3) * 0.3;
            let lhs = pose * se3_exp(&xi);
            let rhs = se3_exp(&(se3_adjoint(&pose) * xi)) * pose;
            assert!(pose_distance(&lhs, &rhs) < 1e-12);
            let p = Point3::new(0.1, 0.2, 0.3);
            assert!((lhs * p - rhs * p).norm() < 1e-12);
        }
    }

    #[test]
    fn left_jacobian_inverse_and_f32_precision() {
        let mut rng = TestRng::new(14);
        for i in 0..2000 {
            let xi = random_twist(&mut rng, i);
            let j = se3_left_jacobian(&xi);
            let ji = se3_left_jacobian_inv(&xi);
            assert!((j * ji - Matrix6::identity()).norm() < 1e-12, "xi {xi:?}");
            // The f32 versions lose no more than a few epsilon (the Q series matters here).
            let xi32: Vector6<f32> = xi.cast();
            let scale = 1.0 + xi.norm();
            let e = (se3_left_jacobian(&xi32).cast::<f64>() - j).norm() / scale;
            assert!(e < 2e-6, "xi {xi:?}: f32 error {e}");
            let e = (se3_left_jacobian_inv(&xi32).cast::<f64>() - ji).norm() / scale;
            assert!(e < 2e-6, "xi {xi:?}: f32 error {e}");
        }
    }
}
