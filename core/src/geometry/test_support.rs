//! Test helpers: samplers of vectors, rotations and twists from the tests' generator
//! ([`crate::test_rng::TestRng`]).
//!
//! Test code only: this file is compiled under #[cfg(test)] (see the `mod` line that includes it).

use nalgebra::{Point3, Vector3, Vector6};

use crate::test_rng::TestRng;

/// A vector with components uniform in `[lo, hi)`.
pub fn random_vector3(rng: &mut TestRng, lo: f64, hi: f64) -> Vector3<f64> {
    Vector3::new(rng.uniform(lo, hi), rng.uniform(lo, hi), rng.uniform(lo, hi))
}

/// A point with components uniform in `[lo, hi)`.
pub fn random_point3(rng: &mut TestRng, lo: f64, hi: f64) -> Point3<f64> {
    Point3::from(random_vector3(rng, lo, hi))
}

/// A direction uniform on the unit sphere.
pub fn random_unit_vector3(rng: &mut TestRng) -> Vector3<f64> {
    loop {
        let v = random_vector3(rng, -1.0, 1.0);
        let n = v.norm();
        if n > 0.1 && n <= 1.0 {
            return v / n;
        }
    }
}

/// A rotation vector whose angle regime cycles with `i`: zero, tiny (1e-9..1e-6 rad), small
/// (1e-4..1e-2), moderate (0.05..1), large (1..3) and near pi (pi-1e-3..pi-1e-5).
pub fn random_rotation_vector(rng: &mut TestRng, i: usize) -> Vector3<f64> {
    let axis = random_unit_vector3(rng);
    let log_uniform = |rng: &mut TestRng, lo: f64, hi: f64| (rng.uniform(lo.ln(), hi.ln())).exp();
    let pi = core::f64::consts::PI;
    let angle = match i % 6 {
        0 if i.is_multiple_of(12) => 0.0,
        0 | 1 => log_uniform(rng, 1e-9, 1e-6),
        2 => log_uniform(rng, 1e-4, 1e-2),
        3 => rng.uniform(0.05, 1.0),
        4 => rng.uniform(1.0, 3.0),
        _ => pi - log_uniform(rng, 1e-5, 1e-3),
    };
    axis * angle
}

/// A twist `[rho; phi]`: translation part uniform in +-2 m, rotation part from
/// [`random_rotation_vector`].
pub fn random_twist(rng: &mut TestRng, i: usize) -> Vector6<f64> {
    let rho = random_vector3(rng, -2.0, 2.0);
    let phi = random_rotation_vector(rng, i);
    Vector6::new(rho.x, rho.y, rho.z, phi.x, phi.y, phi.z)
}
