//! Association of two timestamp streams (colour to depth), as TUM's `associate.py` does it.
//!
//! Every pair `(a, b)` with `|t_a - t_b| < max_dt_s` is a candidate. Candidates are taken greedily
//! from the smallest `|dt|` up (ties broken by the earlier `a`, then the earlier `b`, which is the
//! order `associate.py` sorts its `(diff, a, b)` tuples in); a pair is accepted when neither side
//! is used yet, so each timestamp is used at most once. The result is sorted by `a`.

/// Associates the sorted timestamps `a` and `b` (seconds, strictly increasing each): returns pairs
/// of indices `(i, j)` into `a` and `b`, sorted by `i`.
///
/// A `max_dt_s` that is not a positive number gives no pairs.
pub(crate) fn associate(a: &[f64], b: &[f64], max_dt_s: f64) -> Vec<(usize, usize)> {
    // Candidates: for each a_i, the b_j inside (a_i - max, a_i + max). Both streams are sorted, so
    // the window's start only moves forward: O(|a| + |b| + candidates).
    let mut candidates: Vec<(f64, usize, usize)> = Vec::new();
    let mut start = 0;
    for (i, &ta) in a.iter().enumerate() {
        while start < b.len() && b[start] <= ta - max_dt_s {
            start += 1;
        }
        for (j, &tb) in b.iter().enumerate().skip(start) {
            if tb >= ta + max_dt_s {
                break;
            }
            let dt = (ta - tb).abs();
            if dt < max_dt_s {
                candidates.push((dt, i, j));
            }
        }
    }
    candidates.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));

    let mut used_a = vec![false; a.len()];
    let mut used_b = vec![false; b.len()];
    let mut pairs = Vec::new();
    for (_, i, j) in candidates {
        // `i` and `j` come from enumerating `a` and `b`: always in range.
        if !used_a[i] && !used_b[j] {
            used_a[i] = true;
            used_b[j] = true;
            pairs.push((i, j));
        }
    }
    pairs.sort_unstable();
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ~30 Hz stream starting at `t0` with period `dt` and `n` frames.
    fn stream(t0: f64, dt: f64, n: usize) -> Vec<f64> {
        (0..n).map(|k| t0 + dt * k as f64).collect()
    }

    #[test]
    fn identical_clocks_pair_one_to_one() {
        let a = stream(0.0, 1.0 / 30.0, 100);
        let pairs = associate(&a, &a, 0.02);
        assert_eq!(pairs, (0..100).map(|k| (k, k)).collect::<Vec<_>>());
    }

    #[test]
    fn tum_like_offset_clocks_pair_nearest() {
        // Colour at 30 Hz from a Unix time; depth on its own clock, 13 ms later and slightly faster.
        let rgb = stream(1305031102.175304, 0.033333, 300);
        let depth = stream(1305031102.188304, 0.033320, 300);
        let pairs = associate(&rgb, &depth, 0.02);
        assert_eq!(pairs.len(), 300);
        for &(i, j) in &pairs {
            assert_eq!(i, j);
            assert!((rgb[i] - depth[j]).abs() < 0.02);
        }
    }

    #[test]
    fn each_timestamp_is_used_once_by_smallest_dt() {
        // Two colour frames compete for depth 1.005: the nearer (1.0, dt 0.005) wins, and 1.012
        // falls back to 1.020 (dt 0.008), not to the used one.
        let rgb = [1.0, 1.012];
        let depth = [1.005, 1.020];
        assert_eq!(associate(&rgb, &depth, 0.02), vec![(0, 0), (1, 1)]);
        // One depth frame for two equidistant colour frames: the earlier colour frame takes it.
        assert_eq!(associate(&[1.0, 1.5], &[1.25], 0.5), vec![(0, 0)]);
    }

    #[test]
    fn greedy_is_global_not_first_come() {
        // Colour 1.000 comes first and its nearest depth is 1.010 (dt 0.010), but colour 1.012 is
        // nearer to it (dt 0.002) and takes it; colour 1.000 has no other candidate and stays
        // unpaired, and depth 1.030 (dt 0.018 to colour 1.012) is left over.
        let rgb = [1.000, 1.012];
        let depth = [1.010, 1.030];
        assert_eq!(associate(&rgb, &depth, 0.02), vec![(1, 0)]);
    }

    #[test]
    fn gaps_and_far_timestamps_stay_unpaired() {
        // A 0.5 s gap in depth and a colour frame far from everything.
        let rgb = [0.0, 0.0333, 0.0667, 0.1, 0.5, 100.0];
        let depth = [0.001, 0.034, 0.5005, 200.0];
        assert_eq!(associate(&rgb, &depth, 0.02), vec![(0, 0), (1, 1), (4, 2)]);
    }

    #[test]
    fn the_limit_is_strict_and_empty_inputs_are_fine() {
        assert!(associate(&[1.0], &[1.5], 0.5).is_empty());
        assert_eq!(associate(&[1.0], &[1.25], 0.5), vec![(0, 0)]);
        assert!(associate(&[], &[1.0], 0.02).is_empty());
        assert!(associate(&[1.0], &[], 0.02).is_empty());
        assert!(associate(&[1.0], &[1.0], 0.0).is_empty());
        assert!(associate(&[1.0], &[1.0], f64::NAN).is_empty());
    }

    #[test]
    fn output_is_sorted_by_colour_time() {
        let rgb = stream(0.0, 0.01, 50);
        let depth = stream(0.003, 0.017, 30);
        let pairs = associate(&rgb, &depth, 0.02);
        assert!(pairs.windows(2).all(|w| w[0].0 < w[1].0));
        let mut js: Vec<_> = pairs.iter().map(|p| p.1).collect();
        js.sort_unstable();
        js.dedup();
        assert_eq!(js.len(), pairs.len(), "a depth frame was used twice");
    }
}
