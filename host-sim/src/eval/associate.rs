//! Timestamp association, exactly as evo 1.38.1 (`evo.core.sync`, `nearest_time` method).
//!
//! evo's `associate_trajectories(ref, est, max_diff)` starts from the trajectory with **fewer** poses
//! (the estimate when both have the same count), so that none of its poses is lost, and for each of
//! its timestamps `t` (in order) looks up the nearest timestamp of the longer trajectory:
//!
//! 1. skip `t` if `t < long[0] - max_diff` or `t > long[last] + max_diff`;
//! 2. `k` = `searchsorted(long, t, side="right")` (first index with `long[k] > t`), clamped to
//!    `len - 1`;
//! 3. `diff_ub = long[k] - t`, `diff_lb = t - long[k - 1]` (infinite when `k == 0`);
//! 4. take `k` if `diff_ub <= max_diff && diff_ub < diff_lb`, else `k - 1` if
//!    `diff_lb <= max_diff && diff_lb <= diff_ub`, else no match (a tie goes to the earlier pose).
//!
//! A pose of the longer trajectory may be matched by several poses of the shorter one (evo keeps the
//! repeats, and so do we). Timestamps are assumed strictly increasing (our reader enforces it), so
//! evo's fallback linear search for unsorted input is never needed.

/// One association: indices into the ground truth and into the estimate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MatchIndices {
    /// Index into the ground-truth poses.
    pub gt: usize,
    /// Index into the estimated poses.
    pub est: usize,
}

/// evo's `matching_time_indices(stamps_1, stamps_2, max_diff)` with zero offset: for each stamp of
/// `short_s` (seconds, increasing), the index of the nearest stamp of `long_s` (seconds, increasing)
/// within `max_dt_s`, as `(short index, long index)` pairs in order of the short stamps.
pub fn matching_time_indices(
    short_s: &[f64],
    long_s: &[f64],
    max_dt_s: f64,
) -> Vec<(usize, usize)> {
    let (Some(&first), Some(&last)) = (long_s.first(), long_s.last()) else {
        return Vec::new();
    };
    let mut matches = Vec::new();
    for (i_short, &t) in short_s.iter().enumerate() {
        if t < first - max_dt_s || t > last + max_dt_s {
            continue;
        }
        let k = long_s.partition_point(|&s| s <= t).min(long_s.len() - 1);
        let diff_ub = long_s[k] - t;
        let diff_lb = if k > 0 { t - long_s[k - 1] } else { f64::INFINITY };
        if diff_ub <= max_dt_s && diff_ub < diff_lb {
            matches.push((i_short, k));
        } else if diff_lb <= max_dt_s && diff_lb <= diff_ub {
            matches.push((i_short, k - 1));
        }
    }
    matches
}

/// evo's `associate_trajectories(gt, est, max_diff)`: the shorter trajectory (the estimate on a tie)
/// drives the matching; the result is in the order of the shorter trajectory's poses.
pub fn associate(gt_s: &[f64], est_s: &[f64], max_dt_s: f64) -> Vec<MatchIndices> {
    let est_longer = est_s.len() > gt_s.len();
    if est_longer {
        matching_time_indices(gt_s, est_s, max_dt_s)
            .into_iter()
            .map(|(gt, est)| MatchIndices { gt, est })
            .collect()
    } else {
        matching_time_indices(est_s, gt_s, max_dt_s)
            .into_iter()
            .map(|(est, gt)| MatchIndices { gt, est })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_within_window_and_ties_go_to_the_earlier_pose() {
        let long = [0.0, 1.0, 2.0, 3.0];
        let short = [-0.05, 0.4, 0.5, 1.01, 2.99, 3.04, 3.2];
        let m = matching_time_indices(&short, &long, 0.5);
        // -0.05 -> 0; 0.4 -> 0; 0.5 is a tie -> 0; 1.01 -> 1; 2.99 -> 3; 3.04 -> 3; 3.2 -> 3.
        assert_eq!(m, vec![(0, 0), (1, 0), (2, 0), (3, 1), (4, 3), (5, 3), (6, 3)]);
        let m = matching_time_indices(&short, &long, 0.02);
        assert_eq!(m, vec![(3, 1), (4, 3)]);
    }

    #[test]
    fn outside_the_long_range_is_skipped() {
        let m = matching_time_indices(&[-1.0, 5.0], &[0.0, 1.0], 0.5);
        assert!(m.is_empty());
        assert!(matching_time_indices(&[0.0], &[], 0.5).is_empty());
    }

    #[test]
    fn single_long_stamp() {
        assert_eq!(
            matching_time_indices(&[0.9, 1.0, 1.1], &[1.0], 0.1),
            vec![(0, 0), (1, 0), (2, 0)]
        );
    }

    #[test]
    fn shorter_side_drives_and_long_side_may_repeat() {
        // Estimate longer than ground truth: ground truth drives; both gt poses match est index 1.
        let gt = [0.99, 1.01];
        let est = [0.0, 1.0, 5.0];
        let m = associate(&gt, &est, 0.02);
        assert_eq!(m, vec![MatchIndices { gt: 0, est: 1 }, MatchIndices { gt: 1, est: 1 }]);
        // Same length: the estimate drives.
        let m = associate(&[0.0, 1.0], &[0.01, 0.99], 0.02);
        assert_eq!(m, vec![MatchIndices { gt: 0, est: 0 }, MatchIndices { gt: 1, est: 1 }]);
    }
}
