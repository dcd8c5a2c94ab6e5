//! Grid bucketing: every cell keeps its strongest candidates while they stream in, then features
//! are taken in rank-major rounds so that they spread over the frame (the rule is documented on
//! [`super::HessianParams::per_cell_cap`]). The grid, the per-cell lists and the order are
//! `crate::grid_spread`'s; the cap, the streaming and the last round's rule are the detector's.

use super::{Feature, FeatureError, FeatureVec, HessianParams};
use crate::grid_spread::{Grid, insert_best_first};
use core::cmp::Ordering;

/// Most grid cells the bucketing supports (e.g. 8x8).
pub const MAX_GRID_CELLS: usize = 64;
/// Most candidates one cell can keep (the upper bound of `per_cell_cap`).
pub const MAX_PER_CELL: usize = 12;

/// A candidate in 16 bytes: the Laplacian sign rides on the sign of the (always positive) response.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    x: f32,
    y: f32,
    scale: f32,
    signed_response: f32,
}

impl Candidate {
    const ZERO: Self = Self { x: 0.0, y: 0.0, scale: 0.0, signed_response: 0.0 };

    fn from_feature(f: &Feature) -> Self {
        let r = f.response;
        let signed_response = if f.laplacian_positive { r } else { -r };
        Self { x: f.x, y: f.y, scale: f.scale, signed_response }
    }

    fn to_feature(self) -> Feature {
        Feature {
            x: self.x,
            y: self.y,
            scale: self.scale,
            response: self.signed_response.abs(),
            laplacian_positive: self.signed_response >= 0.0,
        }
    }
}

/// The deterministic ranking: stronger response first, then smaller row, column and scale.
pub(super) fn rank(a: &Feature, b: &Feature) -> Ordering {
    b.response
        .total_cmp(&a.response)
        .then(a.y.total_cmp(&b.y))
        .then(a.x.total_cmp(&b.x))
        .then(a.scale.total_cmp(&b.scale))
        .then(a.laplacian_positive.cmp(&b.laplacian_positive))
}

/// Per-cell top-k storage: 16 bytes x `MAX_GRID_CELLS * MAX_PER_CELL` = 12,288 bytes.
#[derive(Debug, Clone)]
pub(super) struct GridBuckets {
    cells: [[Candidate; MAX_PER_CELL]; MAX_GRID_CELLS],
    counts: [u8; MAX_GRID_CELLS],
    cols: usize,
    rows: usize,
    cap: usize,
    width: usize,
    height: usize,
}

impl GridBuckets {
    pub(super) const fn new() -> Self {
        Self {
            cells: [[Candidate::ZERO; MAX_PER_CELL]; MAX_GRID_CELLS],
            counts: [0; MAX_GRID_CELLS],
            cols: 1,
            rows: 1,
            cap: 1,
            width: 1,
            height: 1,
        }
    }

    /// Empties every cell and sets the grid for a `width` x `height` image.
    pub(super) fn reset(&mut self, params: &HessianParams, width: usize, height: usize) {
        self.counts.fill(0);
        self.cols = usize::from(params.grid_cols).max(1);
        self.rows = usize::from(params.grid_rows).max(1);
        self.cap = usize::from(params.per_cell_cap).clamp(1, MAX_PER_CELL);
        self.width = width.max(1);
        self.height = height.max(1);
    }

    fn grid(&self) -> Grid {
        Grid::with_cells((self.width, self.height), (self.cols, self.rows))
    }

    /// The cell of the pixel nearest `f` (saturating float-to-int casts; positions are inside the
    /// image).
    fn cell_of(&self, f: &Feature) -> usize {
        self.grid().cell_of_pixel(((f.x + 0.5) as usize, (f.y + 0.5) as usize))
    }

    /// Offers a candidate to its cell, which keeps its `cap` best in [`rank`] order (ties: the
    /// earlier one).
    pub(super) fn insert(&mut self, f: &Feature) {
        let cell = self.cell_of(f);
        let (Some(slots), Some(count)) = (self.cells.get_mut(cell), self.counts.get_mut(cell))
        else {
            return;
        };
        let Some(slots) = slots.get_mut(..self.cap) else { return };
        let item = Candidate::from_feature(f);
        let n = insert_best_first(slots, usize::from(*count), item, |c| {
            rank(f, &c.to_feature()) == Ordering::Less
        });
        // At most `cap <= MAX_PER_CELL` items.
        *count = n as u8;
    }

    /// The selection rounds into `out` (cleared first), at most `max` features: round `k` takes
    /// the `k`-th strongest of every cell that has one, cells in raster order (rank-major order);
    /// the last round, when it does not fit, its strongest first.
    pub(super) fn select(&self, max: usize, out: &mut FeatureVec) -> Result<(), FeatureError> {
        out.clear();
        let cells = self.grid().cells();
        let max = max.min(out.capacity());
        for k in 0..self.cap {
            let in_round = (0..cells).filter(|&c| self.kth(c, k).is_some()).count();
            if in_round == 0 {
                break;
            }
            let left = max.saturating_sub(out.len());
            if in_round <= left {
                for f in (0..cells).filter_map(|c| self.kth(c, k)) {
                    out.push(f)
                        .map_err(|_| FeatureError::InvalidParams { field: "max_features" })?;
                }
            } else {
                self.take_strongest_of_round(k, cells, left, out)?;
            }
            if out.len() >= max {
                break;
            }
        }
        Ok(())
    }

    fn kth(&self, cell: usize, k: usize) -> Option<Feature> {
        let n = usize::from(*self.counts.get(cell)?);
        if k >= n {
            return None;
        }
        Some(self.cells.get(cell)?.get(k)?.to_feature())
    }

    /// Takes the `left` strongest of round `k`, strongest first (ties: the earlier cell).
    fn take_strongest_of_round(
        &self,
        k: usize,
        cells: usize,
        left: usize,
        out: &mut FeatureVec,
    ) -> Result<(), FeatureError> {
        // The round's cells, strongest first: one item per cell, so at most MAX_GRID_CELLS (< 256).
        let mut strongest = [0u8; MAX_GRID_CELLS];
        let list = strongest.get_mut(..left.min(MAX_GRID_CELLS)).unwrap_or_default();
        let mut n = 0;
        for c in 0..cells.min(MAX_GRID_CELLS) {
            let Some(f) = self.kth(c, k) else { continue };
            n = insert_best_first(list, n, c as u8, |&other| {
                self.kth(usize::from(other), k).is_some_and(|o| rank(&f, &o) == Ordering::Less)
            });
        }
        for &c in list.get(..n).unwrap_or_default() {
            if let Some(f) = self.kth(usize::from(c), k) {
                out.push(f).map_err(|_| FeatureError::InvalidParams { field: "max_features" })?;
            }
        }
        Ok(())
    }
}
