//! Rigid alignment of two point sets (Horn 1987 / Umeyama 1991), without scale.
//!
//! Generic over the scalar so the core runs it in f32 (map merging, relocalization) and the host
//! in f64 (trajectory evaluation, which must agree with evo's `umeyama_alignment` with
//! `with_scale=False`).

use core::fmt;

use nalgebra::{
    Isometry3, Matrix3, Point3, RealField, Rotation3, SVD, Translation3, UnitQuaternion,
};

/// Why [`align_rigid`] found no transform.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum AlignError {
    /// The two point sets have different lengths.
    LengthMismatch {
        /// Number of source points.
        src_len: usize,
        /// Number of destination points.
        dst_len: usize,
    },
    /// Fewer than three point pairs.
    TooFewPoints {
        /// Number of pairs given.
        len: usize,
    },
    /// A coordinate is NaN or infinite.
    NonFinite {
        /// Index of the first pair holding one.
        index: usize,
    },
    /// The rotation is not determined: all points coincide or lie on one line (the
    /// cross-covariance has rank below 2), or the SVD did not converge.
    Degenerate,
}

impl fmt::Display for AlignError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::LengthMismatch { src_len, dst_len } => {
                write!(f, "point sets differ in length: {src_len} source, {dst_len} destination")
            }
            Self::TooFewPoints { len } => write!(f, "need at least 3 point pairs, got {len}"),
            Self::NonFinite { index } => write!(f, "point pair {index} is not finite"),
            Self::Degenerate => {
                write!(f, "points are coincident or collinear: the rotation is not determined")
            }
        }
    }
}

impl core::error::Error for AlignError {}

/// Iteration cap of the 3x3 SVD (its symmetric eigensolver); it converges in a handful.
const SVD_MAX_ITERATIONS: usize = 1000;

/// The rigid motion `(R, t)` minimizing `sum_i |dst_i - (R src_i + t)|^2`, without scale.
///
/// Exactly Umeyama 1991 (as evo's `umeyama_alignment(x=src, y=dst, with_scale=False)`): the
/// means `mu_src`, `mu_dst`; the cross-covariance
/// `C = (1/n) sum_i (dst_i - mu_dst)(src_i - mu_src)^T`; its SVD `C = U D V^T`;
/// `S = diag(1, 1, sign(det U det V))` so `R` is a rotation, never a reflection;
/// `R = U S V^T`, `t = mu_dst - R mu_src`. The result maps source coordinates to destination
/// coordinates: aligning an estimated trajectory (`src`) to ground truth (`dst`) gives `t_gt_est`.
///
/// The rank test is relative: the second singular value must exceed `sqrt(epsilon)` times the
/// first (f32: 3.5e-4), below which the rotation about the points' line is not determined to any
/// useful precision.
///
/// # Errors
/// [`AlignError::LengthMismatch`], [`AlignError::TooFewPoints`] (fewer than 3),
/// [`AlignError::NonFinite`], and [`AlignError::Degenerate`] for coincident or collinear points
/// or a failed SVD.
pub fn align_rigid<T: RealField + Copy>(
    src: &[Point3<T>],
    dst: &[Point3<T>],
) -> Result<Isometry3<T>, AlignError> {
    if src.len() != dst.len() {
        return Err(AlignError::LengthMismatch { src_len: src.len(), dst_len: dst.len() });
    }
    if src.len() < 3 {
        return Err(AlignError::TooFewPoints { len: src.len() });
    }
    let finite = |p: &Point3<T>| p.x.is_finite() && p.y.is_finite() && p.z.is_finite();
    if let Some(index) = src.iter().zip(dst).position(|(s, d)| !finite(s) || !finite(d)) {
        return Err(AlignError::NonFinite { index });
    }

    let inv_n = T::one() / nalgebra::convert::<f64, T>(src.len() as f64);
    let mean =
        |pts: &[Point3<T>]| pts.iter().fold(Point3::origin(), |acc, p| acc + p.coords) * inv_n;
    let (mu_src, mu_dst) = (mean(src), mean(dst));
    let cov = src
        .iter()
        .zip(dst)
        .fold(Matrix3::zeros(), |acc, (s, d)| acc + (d - mu_dst) * (s - mu_src).transpose())
        * inv_n;

    let svd = SVD::try_new(cov, true, true, T::default_epsilon(), SVD_MAX_ITERATIONS)
        .ok_or(AlignError::Degenerate)?;
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(AlignError::Degenerate);
    };
    // Singular values come sorted in decreasing order.
    let d = svd.singular_values;
    let rank_ok = d.x > T::zero() && d.y > d.x * T::default_epsilon().sqrt();
    if !rank_ok || !d.x.is_finite() {
        return Err(AlignError::Degenerate);
    }

    let mut s = Matrix3::identity();
    if u.determinant() * v_t.determinant() < T::zero() {
        s.m33 = -T::one();
    }
    let r = u * s * v_t;
    let rotation = UnitQuaternion::from_quaternion(
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r)).into_inner(),
    );
    // t from the rotation actually returned, so (rotation, t) is exactly optimal for each other.
    let t = mu_dst - rotation * mu_src;
    if !t.x.is_finite() || !t.y.is_finite() || !t.z.is_finite() {
        return Err(AlignError::Degenerate);
    }
    Ok(Isometry3::from_parts(Translation3::from(t), rotation))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::se3::se3_exp;
    use crate::geometry::test_support::{random_point3, random_twist, random_vector3};
    use crate::test_rng::TestRng;
    use nalgebra::{Vector3, Vector6};

    fn cost(pose: &Isometry3<f64>, src: &[Point3<f64>], dst: &[Point3<f64>]) -> f64 {
        src.iter().zip(dst).map(|(s, d)| (d - pose * s).norm_squared()).sum()
    }

    fn pose_distance(a: &Isometry3<f64>, b: &Isometry3<f64>) -> f64 {
        (a.translation.vector - b.translation.vector).norm() + a.rotation.angle_to(&b.rotation)
    }

    #[test]
    fn recovers_a_known_transform_from_noiseless_points() {
        let mut rng = TestRng::new(30);
        for i in 0..200 {
            let truth = se3_exp(&random_twist(&mut rng, i));
            let n = 3 + i % 40;
            let mut src = [Point3::origin(); 48];
            let mut dst = [Point3::origin(); 48];
            for k in 0..n {
                src[k] = random_point3(&mut rng, -3.0, 3.0);
                dst[k] = truth * src[k];
            }
            let got = align_rigid(&src[..n], &dst[..n]).unwrap();
            assert!(pose_distance(&got, &truth) < 1e-12, "case {i}");
            // f32: the same data rounded.
            let src32 = src.map(|p| p.cast::<f32>());
            let dst32 = dst.map(|p| p.cast::<f32>());
            let got32 = align_rigid(&src32[..n], &dst32[..n]).unwrap().cast::<f64>();
            assert!(pose_distance(&got32, &truth) < 1e-5, "case {i}: {got32:?} vs {truth:?}");
        }
    }

    #[test]
    fn coplanar_points_give_a_rotation_not_a_reflection() {
        // With planar data U or V may come out with det -1; the S sign fix must keep R proper.
        let mut rng = TestRng::new(31);
        for i in 0..200 {
            let truth = se3_exp(&random_twist(&mut rng, i));
            let src: [Point3<f64>; 6] = core::array::from_fn(|_| {
                Point3::new(rng.uniform(-2.0, 2.0), rng.uniform(-2.0, 2.0), 0.0)
            });
            let dst = src.map(|p| truth * p);
            let got = align_rigid(&src, &dst).unwrap();
            assert!(pose_distance(&got, &truth) < 1e-12, "case {i}");
        }
    }

    #[test]
    fn mirrored_points_give_the_best_proper_rotation() {
        // dst is a mirror image of src: no rotation fits exactly. The result must still be a
        // rotation, and a local minimum of the cost over all rigid motions.
        let mut rng = TestRng::new(32);
        for _ in 0..50 {
            let src: [Point3<f64>; 10] =
                core::array::from_fn(|_| random_point3(&mut rng, -1.0, 1.0));
            let dst = src.map(|p| Point3::new(p.x, p.y, -p.z) + Vector3::new(0.3, -0.1, 2.0));
            let got = align_rigid(&src, &dst).unwrap();
            let r = got.rotation.to_rotation_matrix().into_inner();
            assert!((r.determinant() - 1.0).abs() < 1e-12);
            let c0 = cost(&got, &src, &dst);
            for k in 0..6 {
                for sign in [-1.0, 1.0] {
                    let mut xi = Vector6::zeros();
                    xi[k] = sign * 1e-3;
                    assert!(cost(&(se3_exp(&xi) * got), &src, &dst) >= c0);
                }
            }
        }
    }

    #[test]
    fn noisy_points_give_a_stationary_cost() {
        let mut rng = TestRng::new(33);
        for i in 0..50 {
            let truth = se3_exp(&random_twist(&mut rng, i));
            let src: [Point3<f64>; 30] =
                core::array::from_fn(|_| random_point3(&mut rng, -3.0, 3.0));
            let dst = src.map(|p| truth * p + random_vector3(&mut rng, -0.05, 0.05));
            let got = align_rigid(&src, &dst).unwrap();
            // Zero gradient of the cost under left perturbations, by central differences.
            for k in 0..6 {
                let mut xi = Vector6::zeros();
                xi[k] = 1e-6;
                let g = (cost(&(se3_exp(&xi) * got), &src, &dst)
                    - cost(&(se3_exp(&-xi) * got), &src, &dst))
                    / 2e-6;
                assert!(g.abs() < 1e-6, "case {i}, direction {k}: gradient {g}");
            }
        }
    }

    #[test]
    fn matches_evo_umeyama_on_fixed_data() {
        // Noisy data; the reference is evo's umeyama_alignment(with_scale=False) run with numpy.
        #[rustfmt::skip]
        let src = [
            [0.751, 2.383, 1.654], [-1.649, -1.199, 2.241], [-2.968, 1.927, 1.782],
            [-0.192, -1.182, -1.329], [-1.471, -0.33, 0.027], [0.321, 2.973, 1.756],
            [0.733, 2.934, -1.708], [-2.039, 0.675, -2.736], [-2.786, 0.089, -0.203],
            [2.503, 0.775, 0.085], [-0.019, -1.515, -2.929], [-1.846, 1.152, -1.796],
        ];
        #[rustfmt::skip]
        let dst = [
            [0.281, 1.146, 4.287], [0.241, -3.146, 3.513], [-2.381, -1.129, 2.895],
            [2.431, -1.458, 0.832], [0.526, -1.725, 1.729], [-0.334, 1.336, 4.234],
            [0.93, 2.563, 1.237], [0.25, -0.301, -0.955], [-0.72, -1.907, 0.932],
            [3.021, 1.068, 3.285], [3.103, -1.061, -0.59], [-0.178, -0.161, -0.01],
        ];
        #[rustfmt::skip]
        let r_evo = Matrix3::new(
            0.787076426460132, -0.55508413532506, -0.2690581751613957,
            0.4811894456731971, 0.8254041248043729, -0.2952367662210281,
            0.3859629726845195, 0.10290594475713785, 0.9167567563155289,
        );
        let t_evo = Vector3::new(1.4964790723400392, -0.7254052389436578, 2.227672181661971);
        let src = src.map(|[x, y, z]| Point3::new(x, y, z));
        let dst = dst.map(|[x, y, z]| Point3::new(x, y, z));
        let got = align_rigid(&src, &dst).unwrap();
        let r = got.rotation.to_rotation_matrix().into_inner();
        assert!((r - r_evo).norm() < 1e-12 && (got.translation.vector - t_evo).norm() < 1e-12);
        let got32 = align_rigid(&src.map(|p| p.cast::<f32>()), &dst.map(|p| p.cast::<f32>()))
            .unwrap()
            .cast::<f64>();
        let r32 = got32.rotation.to_rotation_matrix().into_inner();
        assert!((r32 - r_evo).norm() < 1e-5 && (got32.translation.vector - t_evo).norm() < 1e-5);
    }

    #[test]
    fn rejects_bad_input() {
        let p =
            [Point3::new(0.0f32, 0.0, 0.0), Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0)];
        assert_eq!(
            align_rigid(&p, &p[..2]),
            Err(AlignError::LengthMismatch { src_len: 3, dst_len: 2 })
        );
        assert_eq!(align_rigid(&p[..2], &p[..2]), Err(AlignError::TooFewPoints { len: 2 }));
        assert_eq!(align_rigid::<f32>(&[], &[]), Err(AlignError::TooFewPoints { len: 0 }));
        let mut nan = p;
        nan[1].y = f32::NAN;
        assert_eq!(align_rigid(&p, &nan), Err(AlignError::NonFinite { index: 1 }));
        let mut inf = p;
        inf[2].z = f32::INFINITY;
        assert_eq!(align_rigid(&inf, &p), Err(AlignError::NonFinite { index: 2 }));
        let same = [Point3::new(1.0f32, 2.0, 3.0); 5];
        assert_eq!(align_rigid(&same, &same), Err(AlignError::Degenerate));
        let line: [Point3<f64>; 5] =
            core::array::from_fn(|i| Point3::new(i as f64, 2.0 * i as f64, 1.0));
        assert_eq!(align_rigid(&line, &line), Err(AlignError::Degenerate));
        assert_eq!(align_rigid(&p, &p).map(|t| t.translation.vector.norm() < 1e-6), Ok(true));
    }
}
