//! SO(3): the hat operator, exp and log on unit quaternions, the left Jacobian and its inverse.
//!
//! Rotations are [`UnitQuaternion`]s (what [`nalgebra::Isometry3`] stores); a rotation vector
//! `phi` (radians, axis times angle) is the tangent. Functions are generic over
//! `T: RealField + Copy` so the core runs them in f32 and the host may run them in f64; with
//! nalgebra's `libm-force` every transcendental call goes through `libm` on every target.

use nalgebra::{Matrix3, Quaternion, RealField, UnitQuaternion, Vector3};

/// `x` rounded to `T` (to nearest for f32): how the generic code writes its constants.
pub(crate) fn lit<T: RealField + Copy>(x: f64) -> T {
    nalgebra::convert(x)
}

/// The skew-symmetric matrix `[v]x` with `[v]x w = v x w` (cross product).
pub fn hat<T: RealField + Copy>(v: &Vector3<T>) -> Matrix3<T> {
    let z = T::zero();
    #[rustfmt::skip]
    let m = Matrix3::new(
        z, -v.z, v.y,
        v.z, z, -v.x,
        -v.y, v.x, z,
    );
    m
}

/// The inverse of [`hat`]: the vector of the skew-symmetric part `(m - m^T) / 2` of `m`.
///
/// Taking the skew part first makes `vee` the least-squares inverse of `hat` for a matrix that is
/// only nearly skew-symmetric.
pub fn vee<T: RealField + Copy>(m: &Matrix3<T>) -> Vector3<T> {
    let half: T = lit(0.5);
    Vector3::new((m.m32 - m.m23) * half, (m.m13 - m.m31) * half, (m.m21 - m.m12) * half)
}

/// The rotation `exp([phi]x)` of the rotation vector `phi` (radians; axis times angle).
///
/// Any `phi` is accepted (angles beyond pi wrap); a non-finite `phi` gives a non-finite
/// quaternion. Near `phi = 0` a Taylor expansion replaces `sin(theta/2)/theta`.
pub fn so3_exp<T: RealField + Copy>(phi: &Vector3<T>) -> UnitQuaternion<T> {
    let theta_sq = phi.norm_squared();
    let (w, k) = if theta_sq < T::default_epsilon() {
        // cos(t/2) = 1 - t^2/8 + ..., sin(t/2)/t = 1/2 - t^2/48 + ...; the next terms are below
        // epsilon^2 here.
        (T::one() - theta_sq * lit(1.0 / 8.0), lit::<T>(0.5) - theta_sq * lit(1.0 / 48.0))
    } else {
        let theta = theta_sq.sqrt();
        let half = theta * lit(0.5);
        (half.cos(), half.sin() / theta)
    };
    UnitQuaternion::new_normalize(Quaternion::from_parts(w, phi * k))
}

/// The rotation vector `phi` (radians) of `q`, with angle `|phi|` in `[0, pi]`.
///
/// Inverse of [`so3_exp`] for angles below pi. Accurate everywhere: the angle comes from
/// `2 atan2(|v|, w)` (no `acos` precision loss near 0 or pi), `q` and `-q` give the same result,
/// and a series replaces `theta / |v|` near the identity. At exactly pi either of the two opposite
/// vectors is returned. A quaternion that is not exactly unit is handled as its normalization.
pub fn so3_log<T: RealField + Copy>(q: &UnitQuaternion<T>) -> Vector3<T> {
    // q and -q are the same rotation; w >= 0 selects the angle in [0, pi].
    let (w, v) =
        if q.scalar() < T::zero() { (-q.scalar(), -q.imag()) } else { (q.scalar(), q.imag()) };
    let n_sq = v.norm_squared();
    let scale = if n_sq < T::default_epsilon() {
        // theta / n = 2 atan(n/w) / n = (2/w) (1 - n^2/(3 w^2) + ...), with w close to 1 here.
        let inv_w = T::one() / w;
        lit::<T>(2.0) * inv_w * (T::one() - n_sq * inv_w * inv_w * lit(1.0 / 3.0))
    } else {
        let n = n_sq.sqrt();
        lit::<T>(2.0) * n.atan2(w) / n
    };
    v * scale
}

/// The coefficients `a = (1 - cos t)/t^2` and `b = (t - sin t)/t^3` of the left Jacobian.
fn left_jacobian_coefficients<T: RealField + Copy>(theta_sq: T) -> (T, T) {
    if theta_sq < T::default_epsilon().sqrt() {
        // Series; the first omitted terms are below epsilon^1.5.
        let a = lit::<T>(0.5) - theta_sq * (lit::<T>(1.0 / 24.0) - theta_sq * lit(1.0 / 720.0));
        let b =
            lit::<T>(1.0 / 6.0) - theta_sq * (lit::<T>(1.0 / 120.0) - theta_sq * lit(1.0 / 5040.0));
        (a, b)
    } else {
        let theta = theta_sq.sqrt();
        let half = theta * lit(0.5);
        // 1 - cos t = 2 sin^2(t/2): no cancellation. (t - sin t) cancels for small t, but its error
        // (about epsilon/t^2 relative) multiplies [phi]x^2, of size t^2, so the matrix keeps an
        // absolute error near epsilon.
        let sinc_half = half.sin() / half;
        (lit::<T>(0.5) * sinc_half * sinc_half, (theta - theta.sin()) / (theta_sq * theta))
    }
}

/// The left Jacobian `J_l(phi)` of SO(3): `exp(phi + d) = exp(J_l(phi) d) exp(phi)` to first
/// order in `d`. It is also the `V` matrix of [`se3_exp`](super::se3_exp): `t = J_l(phi) rho`.
///
/// `J_l = I + (1 - cos t)/t^2 [phi]x + (t - sin t)/t^3 [phi]x^2` with `t = |phi|`, by series near 0.
pub fn so3_left_jacobian<T: RealField + Copy>(phi: &Vector3<T>) -> Matrix3<T> {
    let (a, b) = left_jacobian_coefficients(phi.norm_squared());
    let h = hat(phi);
    Matrix3::identity() + h * a + h * h * b
}

/// The inverse `J_l(phi)^-1` of [`so3_left_jacobian`]: `log(exp(d) exp(phi)) = phi +
/// J_l(phi)^-1 d` to first order in `d`.
///
/// `J_l^-1 = I - [phi]x / 2 + (1 - (t/2) cot(t/2))/t^2 [phi]x^2`, by series near 0. Valid for
/// angles `|phi| < 2 pi` (it is singular at 2 pi); [`so3_log`] returns angles up to pi.
pub fn so3_left_jacobian_inv<T: RealField + Copy>(phi: &Vector3<T>) -> Matrix3<T> {
    let theta_sq = phi.norm_squared();
    let c = if theta_sq < T::default_epsilon().sqrt() {
        lit::<T>(1.0 / 12.0) + theta_sq * (lit::<T>(1.0 / 720.0) + theta_sq * lit(1.0 / 30240.0))
    } else {
        let half = theta_sq.sqrt() * lit(0.5);
        (T::one() - half * half.cos() / half.sin()) / theta_sq
    };
    let h = hat(phi);
    Matrix3::identity() - h * lit::<T>(0.5) + h * h * c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::test_support::{random_rotation_vector, random_vector3};
    use crate::test_rng::TestRng;

    #[test]
    fn hat_is_cross_product_and_vee_inverts_it() {
        let mut rng = TestRng::new(1);
        for _ in 0..100 {
            let a = random_vector3(&mut rng, -3.0, 3.0);
            let b = random_vector3(&mut rng, -3.0, 3.0);
            assert!((hat(&a) * b - a.cross(&b)).norm() < 1e-12);
            assert_eq!(vee(&hat(&a)), a);
        }
    }

    #[test]
    fn exp_matches_rodrigues_and_log_inverts_exp() {
        let mut rng = TestRng::new(2);
        for i in 0..2000 {
            let phi = random_rotation_vector(&mut rng, i);
            let q = so3_exp(&phi);
            // Rodrigues' formula in f64 as the reference.
            let t = phi.norm();
            let r_ref = if t > 0.0 {
                let k = hat(&(phi / t));
                Matrix3::identity() + k * t.sin() + k * k * (1.0 - t.cos())
            } else {
                Matrix3::identity()
            };
            assert!((q.to_rotation_matrix().matrix() - r_ref).norm() < 1e-14, "phi {phi:?}");
            let back = so3_log(&q);
            let tol = 1e-14 * (1.0 + t) + if t > 3.1 { 1e-12 } else { 0.0 };
            assert!((back - phi).norm() <= tol, "phi {phi:?} back {back:?}");
            // The same in f32, against the f64 result.
            let phi32: Vector3<f32> = phi.cast();
            let back32 = so3_log(&so3_exp(&phi32));
            let tol32 = 1e-6 * (1.0 + t) + if t > 3.1 { 2e-6 } else { 0.0 };
            assert!((back32.cast::<f64>() - phi).norm() <= tol32, "phi {phi:?} f32 {back32:?}");
        }
    }

    #[test]
    fn log_handles_both_quaternion_signs_and_exact_pi() {
        let q = so3_exp(&Vector3::new(0.3, -0.2, 0.9));
        let neg = UnitQuaternion::new_unchecked(-q.into_inner());
        assert!((so3_log(&q) - so3_log(&neg)).norm() < 1e-15);
        // 180 degrees about an axis: w = 0.
        let axis = Vector3::new(1.0f32, 2.0, -2.0) / 3.0;
        let pi_rot = UnitQuaternion::new_unchecked(Quaternion::from_parts(0.0, axis));
        let phi = so3_log(&pi_rot);
        assert!((phi.norm() - core::f32::consts::PI).abs() < 1e-6);
        assert!((phi.normalize() - axis).norm() < 1e-6 || (phi.normalize() + axis).norm() < 1e-6);
        assert_eq!(so3_log(&UnitQuaternion::<f32>::identity()), Vector3::zeros());
    }

    #[test]
    fn jacobian_and_its_inverse_are_inverse_in_both_precisions() {
        let mut rng = TestRng::new(3);
        for i in 0..1000 {
            let phi = random_rotation_vector(&mut rng, i);
            let j = so3_left_jacobian(&phi);
            let prod = j * so3_left_jacobian_inv(&phi);
            assert!((prod - Matrix3::identity()).norm() < 1e-12, "phi {phi:?}");
            let phi32: Vector3<f32> = phi.cast();
            let j32 = so3_left_jacobian(&phi32).cast::<f64>();
            let jinv32 = so3_left_jacobian_inv(&phi32).cast::<f64>();
            assert!((j32 - j).norm() < 2e-6, "phi {phi:?}");
            assert!((jinv32 - so3_left_jacobian_inv(&phi)).norm() < 2e-6, "phi {phi:?}");
        }
    }
}
