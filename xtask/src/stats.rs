//! Order statistics of per-frame counts and how the xtasks print numbers, shared by
//! `bench-frontend` and `budgets`.
//!
//! Percentiles are by nearest rank: the p-th percentile of n sorted values is the value of rank
//! `ceil(p * n / 100)`, counting from 1, so the median of an even count is the lower middle value.

use serde_json::{Value, json};

/// Order statistics of a count per frame (instructions, bytes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stats {
    /// Nearest-rank 50th percentile.
    pub median: u64,
    /// Nearest-rank 90th percentile.
    pub p90: u64,
    /// Nearest-rank 99th percentile.
    pub p99: u64,
    /// The largest value.
    pub max: u64,
    /// The arithmetic mean.
    pub mean: f64,
}

impl Stats {
    /// Of a non-empty set of values (0 everywhere when empty).
    pub fn of(values: &[u64]) -> Self {
        let mut sorted = values.to_vec();
        sorted.sort_unstable();
        let mean = values.iter().map(|&v| v as f64).sum::<f64>() / values.len().max(1) as f64;
        Self {
            median: nearest_rank(&sorted, 50),
            p90: nearest_rank(&sorted, 90),
            p99: nearest_rank(&sorted, 99),
            max: sorted.last().copied().unwrap_or(0),
            mean,
        }
    }

    /// As a JSON object with the five fields.
    pub fn to_json(self) -> Value {
        json!({"median": self.median, "p90": self.p90, "p99": self.p99, "max": self.max,
               "mean": self.mean})
    }
}

/// The `p`-th percentile of ascending `sorted` by nearest rank: the value of rank
/// `ceil(p * n / 100)` (from 1, at least 1); 0 when empty.
pub fn nearest_rank(sorted: &[u64], p: usize) -> u64 {
    let rank = (p * sorted.len()).div_ceil(100).max(1);
    sorted.get(rank - 1).copied().unwrap_or(0)
}

pub use ferroslam_sim::report::thousands;

/// `14_391_120` as `14.39 M`: instruction counts in millions, two decimals.
pub fn millions(value: u64) -> String {
    format!("{:.2} M", value as f64 / 1e6)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let v: Vec<u64> = (1..=10).collect();
        assert_eq!(nearest_rank(&v, 50), 5);
        assert_eq!(nearest_rank(&v, 90), 9);
        assert_eq!(nearest_rank(&v, 99), 10);
        assert_eq!(nearest_rank(&[7], 50), 7);
        assert_eq!(nearest_rank(&[], 50), 0);
        let s = Stats::of(&[3, 1, 2]);
        assert_eq!((s.median, s.p90, s.max), (2, 3, 3));
        assert!((s.mean - 2.0).abs() < 1e-12);
    }

    #[test]
    fn number_formats() {
        assert_eq!(thousands(0), "0");
        assert_eq!(thousands(999), "999");
        assert_eq!(thousands(1000), "1,000");
        assert_eq!(thousands(1_185_000_000), "1,185,000,000");
        assert_eq!(millions(14_391_120), "14.39 M");
        assert_eq!(millions(0), "0.00 M");
    }
}
