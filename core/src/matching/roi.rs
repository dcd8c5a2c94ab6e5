//! ROI selection: square templates centred where the image variation `v_m` (paper Eq. 3) is high,
//! one per grid cell, so that ROIs never overlap and spread over the image.

use heapless::Vec;

use crate::grid_spread::{Grid, insert_best_first};
use crate::image::GrayView;

/// A region of interest: a square template of `2 half_size + 1` pixels centred at `centre`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Roi {
    /// Centre pixel `(x, y)`, integer-valued, pixels.
    pub centre: (f32, f32),
    /// Half-size, pixels.
    pub half_size: usize,
    /// Score: sum of `v_m` over the ROI's pixels, gray levels.
    pub score: u32,
}

/// Largest ROI half-size [`select_rois`] accepts, pixels; above it no ROI is returned.
pub const MAX_ROI_HALF_SIZE: usize = 64;

/// Tunables of [`select_rois`]; distances in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoiParams {
    /// ROI half-size, pixels (at most [`MAX_ROI_HALF_SIZE`]); default 7 (15 x 15 at QVGA). Use
    /// the half-size of the matcher.
    pub half_size: usize,
    /// Side of the square grid cells, pixels (at least `2 half_size + 1`); one ROI per cell at
    /// most, lying wholly inside its cell. Default 40 (8 x 6 cells at QVGA).
    pub cell_px: usize,
    /// Step between the candidate centres tried inside a cell, pixels (>= 1); default 4.
    pub candidate_step: usize,
    /// Distance kept between an ROI and the image border, pixels; default 2 (the matcher needs 1
    /// for its gradient margin).
    pub border_px: usize,
    /// ROIs whose mean `v_m` is below this are dropped as flat, gray levels; default 8.
    pub min_mean_variation: u32,
}

impl Roi {
    /// A placeholder for the slots of a list not yet filled.
    const UNSET: Self = Self { centre: (0.0, 0.0), half_size: 0, score: 0 };
}

impl Default for RoiParams {
    fn default() -> Self {
        Self { half_size: 7, cell_px: 40, candidate_step: 4, border_px: 2, min_mean_variation: 8 }
    }
}

/// Sum of `variation` over the square of half-size `half` centred at `(cx, cy)` (which lies inside
/// the map); pixels outside the map count 0.
fn patch_score(variation: &GrayView<'_>, cx: usize, cy: usize, half: usize) -> u32 {
    let x0 = cx.saturating_sub(half);
    let x1 = cx.saturating_add(half + 1).min(variation.width());
    (cy.saturating_sub(half)..cy.saturating_add(half + 1))
        .filter_map(|y| variation.row(y))
        .filter_map(|row| row.get(x0..x1))
        .map(|px| px.iter().map(|&v| u32::from(v)).sum::<u32>())
        .sum()
}

/// The best-scoring ROI lying inside the cell `[x0, x1) x [y0, y1)` and the allowed centre range,
/// or `None` when none fits. Ties keep the first in scan order.
fn best_in_cell(
    variation: &GrayView<'_>,
    p: &RoiParams,
    (x0, x1): (usize, usize),
    (y0, y1): (usize, usize),
) -> Option<(usize, usize, u32)> {
    let h = p.half_size;
    let (w, ht) = variation.size();
    // `h <= MAX_ROI_HALF_SIZE` and cells lie inside the image, so only `border_px` can be huge.
    let margin = h.saturating_add(p.border_px);
    let lo_x = (x0 + h).max(margin);
    let hi_x = (x1.checked_sub(h + 1)?).min(w.checked_sub(margin.saturating_add(1))?);
    let lo_y = (y0 + h).max(margin);
    let hi_y = (y1.checked_sub(h + 1)?).min(ht.checked_sub(margin.saturating_add(1))?);
    let step = p.candidate_step.max(1);
    let mut best: Option<(usize, usize, u32)> = None;
    for cy in (lo_y..=hi_y).step_by(step) {
        for cx in (lo_x..=hi_x).step_by(step) {
            let s = patch_score(variation, cx, cy, h);
            if best.is_none_or(|b| s > b.2) {
                best = Some((cx, cy, s));
            }
        }
    }
    best
}

/// Chooses up to `N` ROIs from a variation map (`v_m` per pixel, as written by
/// [`crate::image::variation_map`]): the image is cut into square cells of
/// [`RoiParams::cell_px`], each cell proposes its best-scoring ROI lying wholly inside it (so ROIs
/// never overlap) and at least [`RoiParams::border_px`] from the image border, ROIs with a mean
/// `v_m` below [`RoiParams::min_mean_variation`] are dropped, and the `N` best are returned best
/// first (ties: earlier cell, row-major, first).
///
/// Cost: about `(cell_px / candidate_step)^2` candidates per cell, each `(2h + 1)^2` byte adds:
/// ~190 k adds at QVGA with the defaults. No allocation: the best `N` are kept in an array of `N`
/// ROIs on the stack, and the result is returned by value.
pub fn select_rois<const N: usize>(variation: &GrayView<'_>, params: &RoiParams) -> Vec<Roi, N> {
    if params.half_size > MAX_ROI_HALF_SIZE {
        return Vec::new();
    }
    let cell = params.cell_px.max(2 * params.half_size + 1);
    let side = (2 * params.half_size + 1) as u32;
    let min_score = params.min_mean_variation.saturating_mul(side * side);
    let grid = Grid::with_cell_side(variation.size(), cell);
    // The `N` best ROIs so far, best first; ties keep the earlier cell.
    let mut best = [Roi::UNSET; N];
    let mut len = 0;
    for c in 0..grid.cells() {
        let (x_range, y_range) = grid.cell_bounds(c);
        let Some((cx, cy, score)) = best_in_cell(variation, params, x_range, y_range) else {
            continue;
        };
        if score < min_score || score == 0 {
            continue;
        }
        let roi = Roi { centre: (cx as f32, cy as f32), half_size: params.half_size, score };
        len = insert_best_first(&mut best, len, roi, |r| roi.score > r.score);
    }
    Vec::from_slice(best.get(..len).unwrap_or_default()).unwrap_or_default()
}
