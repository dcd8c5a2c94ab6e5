//! Test helpers: a deterministic xorshift generator and samplers of rotations and twists.
//!
//! Test code only: this file is compiled under #[cfg(test)] (see the `mod` line that includes it).

use nalgebra::{Point3, Vector3, Vector6};

/// xorshift64* (Vigna): tiny, deterministic, good enough to spread test points.
pub struct XorShift(u64);

impl XorShift {
    /// A generator from a non-zero seed (zero is mapped to a fixed constant).
    pub fn new(seed: u64) -> Self {
        Self(if seed == 0 { 0x9E37_79B9_7F4A_7C15 } else { seed })
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in `[0, 1)`.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[lo, hi)`.
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// A vector with components uniform in `[lo, hi)`.
    pub fn vector3(&mut self, lo: f64, hi: f64) -> Vector3<f64> {
        Vector3::new(self.uniform(lo, hi), self.uniform(lo, hi), self.uniform(lo, hi))
    }

    /// A point with components uniform in `[lo, hi)`.
    pub fn point3(&mut self, lo: f64, hi: f64) -> Point3<f64> {
        Point3::from(self.vector3(lo, hi))
    }

    /// A direction uniform on the unit sphere.
    pub fn unit_vector3(&mut self) -> Vector3<f64> {
        loop {
            let v = self.vector3(-1.0, 1.0);
            let n = v.norm();
            if n > 0.1 && n <= 1.0 {
                return v / n;
            }
        }
    }
}

/// A rotation vector whose angle regime cycles with `i`: zero, tiny (1e-9..1e-6 rad), small
/// (1e-4..1e-2), moderate (0.05..1), large (1..3) and near pi (pi-1e-3..pi-1e-5).
pub fn random_rotation_vector(rng: &mut XorShift, i: usize) -> Vector3<f64> {
    let axis = rng.unit_vector3();
    let log_uniform = |rng: &mut XorShift, lo: f64, hi: f64| (rng.uniform(lo.ln(), hi.ln())).exp();
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
pub fn random_twist(rng: &mut XorShift, i: usize) -> Vector6<f64> {
    let rho = rng.vector3(-2.0, 2.0);
    let phi = random_rotation_vector(rng, i);
    Vector6::new(rho.x, rho.y, rho.z, phi.x, phi.y, phi.z)
}
