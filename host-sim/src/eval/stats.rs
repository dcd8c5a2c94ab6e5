//! Summary statistics of an error array, as evo's `PE.get_all_statistics` computes them.

use serde::Serialize;

/// Statistics of a list of non-negative errors, all in the unit of the errors.
///
/// Definitions (numpy, as evo uses them): `rmse = sqrt(mean(e²))`, `mean`, `median` (the mean of the
/// two middle values for an even count), `std` = population standard deviation
/// `sqrt(mean((e - mean)²))`, `min`, `max`, `sse = sum(e²)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrorStats {
    /// Root mean square.
    pub rmse: f64,
    /// Arithmetic mean.
    pub mean: f64,
    /// Median.
    pub median: f64,
    /// Population standard deviation.
    pub std: f64,
    /// Smallest error.
    pub min: f64,
    /// Largest error.
    pub max: f64,
    /// Sum of squared errors.
    pub sse: f64,
    /// Number of errors.
    pub count: usize,
}

/// The median of ascending `sorted` values as numpy computes it (the mean of the two middle values
/// for an even count); `None` when empty.
pub fn median_of_sorted(sorted: &[f64]) -> Option<f64> {
    let mid = sorted.len() / 2;
    match (sorted.len() % 2, sorted.get(mid), mid.checked_sub(1).and_then(|lo| sorted.get(lo))) {
        (1, Some(&m), _) => Some(m),
        (_, Some(&hi), Some(&lo)) => Some((lo + hi) / 2.0),
        _ => None,
    }
}

impl ErrorStats {
    /// Statistics of `errors`; `None` if it is empty.
    pub fn from_errors(errors: &[f64]) -> Option<Self> {
        if errors.is_empty() {
            return None;
        }
        let n = errors.len() as f64;
        let sse: f64 = errors.iter().map(|e| e * e).sum();
        let mean = errors.iter().sum::<f64>() / n;
        let var = errors.iter().map(|e| (e - mean) * (e - mean)).sum::<f64>() / n;
        let mut sorted = errors.to_vec();
        sorted.sort_by(f64::total_cmp);
        let median = median_of_sorted(&sorted)?;
        Some(Self {
            rmse: (sse / n).sqrt(),
            mean,
            median,
            std: var.sqrt(),
            min: sorted.first().copied().unwrap_or(f64::NAN),
            max: sorted.last().copied().unwrap_or(f64::NAN),
            sse,
            count: errors.len(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_numpy_definitions() {
        let s = ErrorStats::from_errors(&[3.0, 1.0, 4.0, 2.0]).unwrap();
        assert_eq!(s.count, 4);
        assert_eq!(s.mean, 2.5);
        assert_eq!(s.median, 2.5);
        assert_eq!(s.min, 1.0);
        assert_eq!(s.max, 4.0);
        assert_eq!(s.sse, 30.0);
        assert!((s.rmse - 7.5_f64.sqrt()).abs() < 1e-15);
        assert!((s.std - 1.25_f64.sqrt()).abs() < 1e-15);
        let odd = ErrorStats::from_errors(&[5.0, 1.0, 2.0]).unwrap();
        assert_eq!(odd.median, 2.0);
        assert!(ErrorStats::from_errors(&[]).is_none());
    }
}
