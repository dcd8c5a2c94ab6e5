//! Relative pose error (RPE) over matched pose pairs.
//!
//! Both functions take the associated poses as parallel slices: `gt[k]` and `est[k]` are the k-th
//! match (camera to world), `est_stamps_s[k]` the estimate's timestamp of that match. Neither needs
//! the ATE alignment: a relative motion `A⁻¹ B` does not change when a fixed rigid transform is
//! applied to the whole estimate, so, like `evo_rpe` without `-a`, the estimate is used as read.

use nalgebra::{Isometry3, UnitQuaternion};

/// The relative error of one pose pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RpeSample {
    /// Estimate timestamp of the pair's first pose, in seconds.
    pub from_s: f64,
    /// Estimate timestamp of the pair's second pose, in seconds.
    pub to_s: f64,
    /// Translation error in metres.
    pub trans_m: f64,
    /// Rotation error in degrees.
    pub rot_deg: f64,
}

/// Rotation angle of a unit quaternion in radians, in `[0, π]`; `2 atan2(|v|, |w|)` is accurate
/// near zero, where `acos(w)` is not.
pub fn rotation_angle_rad(q: &UnitQuaternion<f64>) -> f64 {
    2.0 * q.imag().norm().atan2(q.w.abs())
}

fn sample(from_s: f64, to_s: f64, e: &Isometry3<f64>) -> RpeSample {
    RpeSample {
        from_s,
        to_s,
        trans_m: e.translation.vector.norm(),
        rot_deg: rotation_angle_rad(&e.rotation).to_degrees(),
    }
}

/// `evo_rpe tum GT EST --delta 1 --delta_unit f` for `trans_part` and `angle_deg`: consecutive
/// matches `(k, k + 1)` (with `delta = 1` evo's `--all_pairs` gives the same pairs) and the error
/// `E = (Q_k⁻¹ Q_{k+1})⁻¹ (P_k⁻¹ P_{k+1})` (Q ground truth, P estimate); translation error `|t(E)|`
/// (m), rotation error the angle of `R(E)` (degrees).
pub fn per_frame(
    gt: &[Isometry3<f64>],
    est: &[Isometry3<f64>],
    est_stamps_s: &[f64],
) -> Vec<RpeSample> {
    let n = gt.len().min(est.len()).min(est_stamps_s.len());
    (1..n)
        .map(|j| {
            let i = j - 1;
            let q_rel = gt[i].inverse() * gt[j];
            let p_rel = est[i].inverse() * est[j];
            sample(est_stamps_s[i], est_stamps_s[j], &(q_rel.inverse() * p_rel))
        })
        .collect()
}

/// TUM's `evaluate_rpe.py --fixed_delta --delta DELTA --delta_unit s`, on the matched poses: for each
/// match `i` (in order), `j` = TUM's `find_closest_index(stamps, stamps[i] + delta_s)` over the
/// matched estimate timestamps; the pair is kept unless `j` is the last match (TUM's rule, which also
/// drops every pair near the end). The error is TUM's
/// `E = (P_j⁻¹ P_i)⁻¹ (Q_j⁻¹ Q_i)`, translation `|t(E)|` in metres per `delta_s` (not divided by
/// the pair's actual time difference, as TUM does) and rotation angle in degrees.
///
/// Unlike TUM's script, the ground-truth pose of each estimate pose is its evo association (not
/// TUM's nearest ground-truth stamp within twice the median ground-truth period).
pub fn per_delta_seconds(
    gt: &[Isometry3<f64>],
    est: &[Isometry3<f64>],
    est_stamps_s: &[f64],
    delta_s: f64,
) -> Vec<RpeSample> {
    let n = gt.len().min(est.len()).min(est_stamps_s.len());
    let stamps = &est_stamps_s[..n];
    let mut out = Vec::new();
    for i in 0..n {
        let j = find_closest_index(stamps, stamps[i] + delta_s);
        if j + 1 == n {
            continue;
        }
        let p = est[j].inverse() * est[i];
        let q = gt[j].inverse() * gt[i];
        out.push(sample(stamps[i], stamps[j], &(p.inverse() * q)));
    }
    out
}

/// TUM's `find_closest_index(L, t)` (a binary search that keeps the closest value seen on its
/// path, first one on ties; `L` sorted), ported line by line so ties resolve the same way.
pub fn find_closest_index(list: &[f64], t: f64) -> usize {
    let Some(&first) = list.first() else {
        return 0;
    };
    let mut beginning = 0;
    let mut difference = (first - t).abs();
    let mut best = 0;
    let mut end = list.len();
    while beginning < end {
        let middle = (end + beginning) / 2;
        let value = list[middle];
        if (value - t).abs() < difference {
            difference = (value - t).abs();
            best = middle;
        }
        if t == value {
            return middle;
        } else if value > t {
            end = middle;
        } else {
            beginning = middle + 1;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, Vector3};

    fn pose(x: f64, yaw_rad: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(x, 0.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_rad),
        )
    }

    #[test]
    fn closest_index_like_tum() {
        let l = [0.0, 1.0, 2.0, 3.0];
        assert_eq!(find_closest_index(&l, 1.4), 1);
        assert_eq!(find_closest_index(&l, 1.6), 2);
        assert_eq!(find_closest_index(&l, 9.0), 3);
        assert_eq!(find_closest_index(&l, -9.0), 0);
        assert_eq!(find_closest_index(&l, 2.0), 2);
        assert_eq!(find_closest_index(&[], 2.0), 0);
    }

    #[test]
    fn perfect_estimate_has_zero_error_even_if_moved() {
        let gt: Vec<_> = (0..10).map(|i| pose(i as f64 * 0.1, i as f64 * 0.05)).collect();
        let offset = pose(5.0, 1.0);
        let est: Vec<_> = gt.iter().map(|g| offset * g).collect();
        let stamps: Vec<f64> = (0..10).map(|i| i as f64 * 0.5).collect();
        for s in per_frame(&gt, &est, &stamps)
            .into_iter()
            .chain(per_delta_seconds(&gt, &est, &stamps, 1.0))
        {
            assert!(s.trans_m < 1e-12 && s.rot_deg < 1e-9, "{s:?}");
        }
    }

    #[test]
    fn per_frame_measures_the_relative_motion_error() {
        let gt = [pose(0.0, 0.0), pose(1.0, 0.0)];
        let est = [pose(0.0, 0.0), pose(1.1, 0.1)];
        let s = per_frame(&gt, &est, &[0.0, 1.0]);
        assert_eq!(s.len(), 1);
        assert!((s[0].trans_m - 0.1).abs() < 1e-12);
        assert!((s[0].rot_deg - 0.1_f64.to_degrees()).abs() < 1e-9);
    }

    #[test]
    fn per_second_drops_pairs_ending_at_the_last_match() {
        let gt: Vec<_> = (0..5).map(|i| pose(i as f64, 0.0)).collect();
        let stamps = [0.0, 0.5, 1.0, 1.5, 2.0];
        let s = per_delta_seconds(&gt, &gt, &stamps, 1.0);
        // i = 0 -> j = 2, i = 1 -> j = 3, i = 2.. -> j = 4 (last): dropped.
        assert_eq!(s.len(), 2);
        assert_eq!((s[0].from_s, s[0].to_s), (0.0, 1.0));
        assert_eq!((s[1].from_s, s[1].to_s), (0.5, 1.5));
    }
}
