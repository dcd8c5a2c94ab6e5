//! Small fixed-size linear algebra on plain arrays: 3- and 6-vectors, packed symmetric 3x3 and 6x6
//! matrices (inverse, Cholesky), and rigid transforms held as a rotation matrix and a translation
//! with their SE(3) adjoint.
//!
//! Plain `[f32; N]` arrays keep the solver's storage `const`-constructible and its arithmetic
//! explicit: every sum below runs in a fixed order with `+ - * /` only (no `mul_add`), square roots
//! through `ferroslam_fpu::sqrtf` (correctly rounded, like libm's), so the same inputs give the
//! same bits on every target.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

use crate::geometry::Pose;

/// A 3-vector.
pub(super) type Vec3 = [f32; 3];
/// A 6-vector; as a twist, `[rho; phi]` (metres; radians) like [`crate::geometry::se3_exp`].
pub(super) type Vec6 = [f32; 6];
/// A symmetric 3x3 matrix, packed `[a00, a01, a02, a11, a12, a22]`.
pub(super) type Sym3 = [f32; 6];
/// A symmetric 6x6 matrix, packed lower triangle row by row: entry `(i, j)`, `j <= i`, at
/// [`sym6_index`]`(i, j)`.
pub(super) type Sym6 = [f32; 21];

/// Index of entry `(i, j)` (`j <= i < 6`) of a packed [`Sym6`].
pub(super) const fn sym6_index(i: usize, j: usize) -> usize {
    i * (i + 1) / 2 + j
}

pub(super) fn dot3(a: &Vec3, b: &Vec3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(super) fn cross3(a: &Vec3, b: &Vec3) -> Vec3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

pub(super) fn dot6(a: &Vec6, b: &Vec6) -> f32 {
    let mut s = 0.0;
    for k in 0..6 {
        s += a[k] * b[k];
    }
    s
}

/// `h v` for a packed symmetric `h`.
pub(super) fn sym3_mul(h: &Sym3, v: &Vec3) -> Vec3 {
    [
        h[0] * v[0] + h[1] * v[1] + h[2] * v[2],
        h[1] * v[0] + h[3] * v[1] + h[4] * v[2],
        h[2] * v[0] + h[4] * v[1] + h[5] * v[2],
    ]
}

/// `h += w a a^T`.
pub(super) fn sym3_rank1(h: &mut Sym3, w: f32, a: &Vec3) {
    let (wa0, wa1, wa2) = (w * a[0], w * a[1], w * a[2]);
    h[0] += wa0 * a[0];
    h[1] += wa0 * a[1];
    h[2] += wa0 * a[2];
    h[3] += wa1 * a[1];
    h[4] += wa1 * a[2];
    h[5] += wa2 * a[2];
}

/// The inverse of the symmetric `h`, or `None` unless it is positive definite with every pivot of
/// its `L D L^T` factorization above `min_pivot_ratio` times its diagonal entry (a cheap
/// conditioning test: a pivot far below its diagonal means a direction the data hardly fix).
pub(super) fn sym3_inverse(h: &Sym3, min_pivot_ratio: f32) -> Option<Sym3> {
    let [a00, a01, a02, a11, a12, a22] = *h;
    // Cofactors (the adjugate is symmetric).
    let c00 = a11 * a22 - a12 * a12;
    let c01 = a02 * a12 - a01 * a22;
    let c02 = a01 * a12 - a02 * a11;
    let c11 = a00 * a22 - a02 * a02;
    let c12 = a01 * a02 - a00 * a12;
    let c22 = a00 * a11 - a01 * a01;
    let det = a00 * c00 + a01 * c01 + a02 * c02;
    // Pivots: d0 = a00, d1 = c22 / a00, d2 = det / c22. Written without division; NaN fails.
    let ok = a00 > 0.0
        && c22 > min_pivot_ratio * a11 * a00
        && det > min_pivot_ratio * a22 * c22
        && det.is_finite();
    if !ok {
        return None;
    }
    let inv_det = 1.0 / det;
    let inv = [c00, c01, c02, c11, c12, c22].map(|c| c * inv_det);
    inv.iter().all(|x| x.is_finite()).then_some(inv)
}

/// `h += w a a^T` for a 6-vector `a`.
pub(super) fn sym6_rank1(h: &mut Sym6, w: f32, a: &Vec6) {
    let mut k = 0;
    for i in 0..6 {
        let wa = w * a[i];
        for aj in a.iter().take(i + 1) {
            h[k] += wa * aj;
            k += 1;
        }
    }
}

/// `h += d` on the diagonal.
pub(super) fn sym6_add_diagonal(h: &mut Sym6, d: &Vec6) {
    for (i, di) in d.iter().enumerate() {
        h[sym6_index(i, i)] += di;
    }
}

/// The diagonal of `h`.
pub(super) fn sym6_diagonal(h: &Sym6) -> Vec6 {
    core::array::from_fn(|i| h[sym6_index(i, i)])
}

/// `h -= f g f^T` with `f` a 6x3 matrix given by its rows and `g` symmetric 3x3: the Schur
/// complement update of one eliminated point.
pub(super) fn sym6_sub_congruence(h: &mut Sym6, f: &[Vec3; 6], g: &Sym3) {
    let fg: [Vec3; 6] = core::array::from_fn(|i| sym3_mul(g, &f[i]));
    let mut k = 0;
    for (i, fgi) in fg.iter().enumerate() {
        for fj in f.iter().take(i + 1) {
            h[k] -= dot3(fgi, fj);
            k += 1;
        }
    }
}

/// In-place Cholesky `h = L L^T` (the packed lower triangle becomes `L`). False, leaving `h`
/// partly overwritten, unless every pivot exceeds `min_pivot_ratio` times its diagonal entry.
pub(super) fn sym6_cholesky(h: &mut Sym6, min_pivot_ratio: f32) -> bool {
    for j in 0..6 {
        let jj = sym6_index(j, j);
        let mut d = h[jj];
        for k in 0..j {
            let l = h[sym6_index(j, k)];
            d -= l * l;
        }
        // NaN fails the comparison.
        let pivot_ok = d > min_pivot_ratio * h[jj] && d.is_finite();
        if !pivot_ok {
            return false;
        }
        let l_jj = ferroslam_fpu::sqrtf(d);
        h[jj] = l_jj;
        let inv = 1.0 / l_jj;
        for i in j + 1..6 {
            let mut s = h[sym6_index(i, j)];
            for k in 0..j {
                s -= h[sym6_index(i, k)] * h[sym6_index(j, k)];
            }
            h[sym6_index(i, j)] = s * inv;
        }
    }
    true
}

/// `x` with `L L^T x = r`, for the factor `l` of [`sym6_cholesky`].
pub(super) fn sym6_solve(l: &Sym6, r: &Vec6) -> Vec6 {
    let mut y = [0.0f32; 6];
    for i in 0..6 {
        let mut s = r[i];
        for (k, yk) in y.iter().enumerate().take(i) {
            s -= l[sym6_index(i, k)] * yk;
        }
        y[i] = s / l[sym6_index(i, i)];
    }
    let mut x = [0.0f32; 6];
    for i in (0..6).rev() {
        let mut s = y[i];
        for (k, xk) in x.iter().enumerate().skip(i + 1) {
            s -= l[sym6_index(k, i)] * xk;
        }
        x[i] = s / l[sym6_index(i, i)];
    }
    x
}

/// A pose stored compactly and `const`-constructibly: unit quaternion `[i, j, k, w]` and
/// translation, in the frames of the field that holds it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct StoredPose {
    q: [f32; 4],
    t: [f32; 3],
}

impl StoredPose {
    pub(super) const IDENTITY: Self = Self { q: [0.0, 0.0, 0.0, 1.0], t: [0.0; 3] };

    pub(super) fn from_pose(pose: &Pose) -> Self {
        let c = pose.rotation.coords;
        let t = pose.translation.vector;
        Self { q: [c.x, c.y, c.z, c.w], t: [t.x, t.y, t.z] }
    }

    /// The stored bits as a [`Pose`] (the quaternion is taken as unit, as it was stored).
    pub(super) fn to_pose(self) -> Pose {
        let [i, j, k, w] = self.q;
        let q = UnitQuaternion::new_unchecked(Quaternion::new(w, i, j, k));
        Isometry3::from_parts(Translation3::new(self.t[0], self.t[1], self.t[2]), q)
    }

    pub(super) fn is_identity(&self) -> bool {
        *self == Self::IDENTITY
    }

    /// Whether every entry is finite.
    pub(super) fn is_finite(&self) -> bool {
        self.q.iter().chain(self.t.iter()).all(|x| x.is_finite())
    }
}

/// A rigid transform `p -> R p + t` as a row-major rotation matrix and a translation: what the
/// per-observation arithmetic uses (cheaper than rotating by a quaternion).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct PoseMatrix {
    /// Row-major rotation.
    pub(super) r: [f32; 9],
    pub(super) t: Vec3,
}

impl PoseMatrix {
    pub(super) const IDENTITY: Self =
        Self { r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], t: [0.0; 3] };

    pub(super) fn from_pose(pose: &Pose) -> Self {
        let m = pose.rotation.to_rotation_matrix().into_inner();
        let t = pose.translation.vector;
        Self {
            r: [m.m11, m.m12, m.m13, m.m21, m.m22, m.m23, m.m31, m.m32, m.m33],
            t: [t.x, t.y, t.z],
        }
    }

    /// `R p + t`.
    pub(super) fn transform(&self, p: &Vec3) -> Vec3 {
        let r = &self.r;
        [
            r[0] * p[0] + r[1] * p[1] + r[2] * p[2] + self.t[0],
            r[3] * p[0] + r[4] * p[1] + r[5] * p[2] + self.t[1],
            r[6] * p[0] + r[7] * p[1] + r[8] * p[2] + self.t[2],
        ]
    }

    /// `R v`.
    pub(super) fn rotate(&self, v: &Vec3) -> Vec3 {
        let r = &self.r;
        [
            r[0] * v[0] + r[1] * v[1] + r[2] * v[2],
            r[3] * v[0] + r[4] * v[1] + r[5] * v[2],
            r[6] * v[0] + r[7] * v[1] + r[8] * v[2],
        ]
    }

    /// Column `k` of `R` (0, 1 or 2).
    pub(super) fn column(&self, k: usize) -> Vec3 {
        let r = &self.r;
        match k {
            0 => [r[0], r[3], r[6]],
            1 => [r[1], r[4], r[7]],
            _ => [r[2], r[5], r[8]],
        }
    }

    /// `R^T v`.
    pub(super) fn rotate_back(&self, v: &Vec3) -> Vec3 {
        let r = &self.r;
        [
            r[0] * v[0] + r[3] * v[1] + r[6] * v[2],
            r[1] * v[0] + r[4] * v[1] + r[7] * v[2],
            r[2] * v[0] + r[5] * v[1] + r[8] * v[2],
        ]
    }

    /// `Ad(T) xi = [R rho + t x (R phi); R phi]`: a left perturbation `exp(xi)` of the right
    /// factor `S` in `T S` is the left perturbation `exp(Ad(T) xi)` of the product.
    pub(super) fn adjoint(&self, xi: &Vec6) -> Vec6 {
        let r_rho = self.rotate(&[xi[0], xi[1], xi[2]]);
        let r_phi = self.rotate(&[xi[3], xi[4], xi[5]]);
        let t_x = cross3(&self.t, &r_phi);
        [r_rho[0] + t_x[0], r_rho[1] + t_x[1], r_rho[2] + t_x[2], r_phi[0], r_phi[1], r_phi[2]]
    }

    /// `Ad(T)^T y = [R^T y_rho; R^T (y_phi - t x y_rho)]`: maps a gradient or a row of a
    /// Jacobian back through [`Self::adjoint`].
    pub(super) fn adjoint_transpose(&self, y: &Vec6) -> Vec6 {
        let y_rho = [y[0], y[1], y[2]];
        let t_x = cross3(&self.t, &y_rho);
        let top = self.rotate_back(&y_rho);
        let bottom = self.rotate_back(&[y[3] - t_x[0], y[4] - t_x[1], y[5] - t_x[2]]);
        [top[0], top[1], top[2], bottom[0], bottom[1], bottom[2]]
    }

    /// `Ad(T)^T h Ad(T)` for a symmetric `h`.
    pub(super) fn adjoint_congruence(&self, h: &Sym6) -> Sym6 {
        // Columns of Ad: Ad e_k.
        let cols: [Vec6; 6] = core::array::from_fn(|k| {
            let mut e = [0.0; 6];
            e[k] = 1.0;
            self.adjoint(&e)
        });
        // h Ad, column by column, then Ad^T (h Ad).
        let h_cols: [Vec6; 6] = core::array::from_fn(|k| sym6_mul(h, &cols[k]));
        let mut out = [0.0; 21];
        for i in 0..6 {
            for j in 0..=i {
                out[sym6_index(i, j)] = dot6(&cols[i], &h_cols[j]);
            }
        }
        out
    }
}

/// `h v` for a packed symmetric 6x6 `h`.
pub(super) fn sym6_mul(h: &Sym6, v: &Vec6) -> Vec6 {
    core::array::from_fn(|i| {
        let mut s = 0.0;
        for (j, vj) in v.iter().enumerate() {
            let k = if j <= i { sym6_index(i, j) } else { sym6_index(j, i) };
            s += h[k] * vj;
        }
        s
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

    fn sym6_full(h: &Sym6) -> Matrix6<f32> {
        Matrix6::from_fn(|i, j| if j <= i { h[sym6_index(i, j)] } else { h[sym6_index(j, i)] })
    }

    fn spd6() -> Sym6 {
        let mut h = [0.0; 21];
        for k in 0..9 {
            let a: Vec6 = core::array::from_fn(|i| ((i * 7 + k * 3) % 11) as f32 - 5.0);
            sym6_rank1(&mut h, 0.5 + k as f32, &a);
        }
        h
    }

    #[test]
    fn sym3_inverse_inverts_and_rejects_singular() {
        let h: Sym3 = [4.0, 1.0, 0.5, 3.0, -0.25, 2.0];
        let inv = sym3_inverse(&h, 1e-6).unwrap();
        let full = |s: &Sym3| Matrix3::new(s[0], s[1], s[2], s[1], s[3], s[4], s[2], s[4], s[5]);
        assert!((full(&h) * full(&inv) - Matrix3::identity()).norm() < 1e-6);
        // Rank 2 (a point seen once without depth) and NaN are refused.
        let mut rank2 = [0.0; 6];
        sym3_rank1(&mut rank2, 1.0, &[1.0, 0.0, 0.2]);
        sym3_rank1(&mut rank2, 1.0, &[0.0, 1.0, -0.3]);
        assert_eq!(sym3_inverse(&rank2, 1e-6), None);
        assert_eq!(sym3_inverse(&[f32::NAN, 0.0, 0.0, 1.0, 0.0, 1.0], 1e-6), None);
        // Nearly collinear rows: a pivot far below its diagonal. A badly scaled but
        // uncorrelated matrix is fine (the test is relative to each diagonal entry).
        assert_eq!(sym3_inverse(&[1.0, 0.999_999_9, 0.0, 1.0, 0.0, 1.0], 1e-6), None);
        assert!(sym3_inverse(&[1.0, 0.0, 0.0, 1.0, 0.0, 1e-7], 1e-6).is_some());
    }

    #[test]
    fn sym6_cholesky_solves() {
        let h = spd6();
        let mut l = h;
        assert!(sym6_cholesky(&mut l, 1e-7));
        let r: Vec6 = [1.0, -2.0, 0.5, 3.0, 0.0, -1.0];
        let x = sym6_solve(&l, &r);
        let back = sym6_full(&h) * Vector6::from(x);
        assert!((back - Vector6::from(r)).norm() < 1e-4 * Vector6::from(r).norm());
        assert_eq!(sym6_mul(&h, &x).map(|v| (v * 1e3).round()), r.map(|v| (v * 1e3).round()));
        let mut singular = [0.0; 21];
        sym6_rank1(&mut singular, 1.0, &[1.0; 6]);
        assert!(!sym6_cholesky(&mut singular, 1e-7));
    }

    #[test]
    fn schur_update_matches_dense() {
        let mut h = spd6();
        let before = sym6_full(&h);
        let f: [Vec3; 6] = core::array::from_fn(|i| [i as f32, 1.0 - i as f32, 0.5]);
        let g: Sym3 = [2.0, 0.1, -0.2, 1.5, 0.3, 1.0];
        sym6_sub_congruence(&mut h, &f, &g);
        let fm = nalgebra::Matrix6x3::from_fn(|i, j| f[i][j]);
        let gm = Matrix3::new(g[0], g[1], g[2], g[1], g[3], g[4], g[2], g[4], g[5]);
        let expect = before - fm * gm * fm.transpose();
        assert!((sym6_full(&h) - expect).norm() < 1e-4 * expect.norm());
    }

    #[test]
    fn adjoint_matches_geometry() {
        let pose = Pose::from_parts(
            Translation3::new(0.3, -0.2, 1.1),
            UnitQuaternion::from_scaled_axis(Vector3::new(0.2, -0.4, 0.1)),
        );
        let m = PoseMatrix::from_pose(&pose);
        let ad = crate::geometry::se3_adjoint(&pose);
        let xi: Vec6 = [0.1, -0.3, 0.2, 0.05, 0.4, -0.2];
        let got = Vector6::from(m.adjoint(&xi));
        assert!((got - ad * Vector6::from(xi)).norm() < 1e-6);
        let got_t = Vector6::from(m.adjoint_transpose(&xi));
        assert!((got_t - ad.transpose() * Vector6::from(xi)).norm() < 1e-6);
        let h = spd6();
        let c = sym6_full(&m.adjoint_congruence(&h));
        let expect = ad.transpose() * sym6_full(&h) * ad;
        assert!((c - expect).norm() < 1e-5 * expect.norm());
        let p = [0.5, 0.25, 2.0];
        let q = pose * nalgebra::Point3::from(p);
        assert!((Vector3::from(m.transform(&p)) - q.coords).norm() < 1e-6);
        assert_eq!(StoredPose::from_pose(&pose).to_pose(), pose);
    }
}
