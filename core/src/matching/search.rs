//! Stages 1-3 of region matching: the coarse identity-map scan, the affine bank at the best coarse
//! offsets, and the integer refinement of the offset; plus the coarse score grid that exposes a
//! second, competing peak (repeated patterns).

use heapless::Vec;

use super::MatchParams;
use super::affine::{Mat2, mat_mul};
use super::patch::Template;
use crate::image::GrayView;

/// Most coarse offsets carried into the bank stage.
const MAX_COARSE: usize = 4;

/// Most coarse positions on each side of the prediction: `search_radius / coarse_step <= 8`.
pub(crate) const MAX_COARSE_STEPS: usize = 8;

/// Side of the largest coarse grid.
const GRID_SIDE: usize = 2 * MAX_COARSE_STEPS + 1;

/// The coarse stage's ZNCC per grid position (NaN: candidate invalid). 289 f32 = 1156 bytes.
struct CoarseGrid {
    steps: i32,
    zncc: [f32; GRID_SIDE * GRID_SIDE],
}

impl CoarseGrid {
    fn new(steps: i32) -> Self {
        Self { steps, zncc: [f32::NAN; GRID_SIDE * GRID_SIDE] }
    }

    fn index(&self, i: i32, j: i32) -> Option<usize> {
        if i.abs() > self.steps || j.abs() > self.steps {
            return None;
        }
        usize::try_from((j + self.steps) * GRID_SIDE as i32 + i + self.steps).ok()
    }

    fn get(&self, i: i32, j: i32) -> f32 {
        self.index(i, j).and_then(|k| self.zncc.get(k)).copied().unwrap_or(f32::NAN)
    }

    fn set(&mut self, i: i32, j: i32, v: f32) {
        if let Some(slot) = self.index(i, j).and_then(|k| self.zncc.get_mut(k)) {
            *slot = v;
        }
    }

    /// The highest local maximum (not below any valid 8-neighbour) more than one grid step from
    /// the peak at `(pi, pj)` (grid units), or `None` when there is none.
    fn second_peak(&self, pi: i32, pj: i32) -> Option<f32> {
        let mut second: Option<f32> = None;
        for j in -self.steps..=self.steps {
            for i in -self.steps..=self.steps {
                let v = self.get(i, j);
                if v.is_nan() || ((i - pi).abs() <= 1 && (j - pj).abs() <= 1) {
                    continue;
                }
                let is_max =
                    (-1..=1).flat_map(|dj| (-1..=1).map(move |di| (di, dj))).all(|(di, dj)| {
                        // Invalid (NaN) neighbours do not compete.
                        let n = self.get(i + di, j + dj);
                        n.is_nan() || n <= v
                    });
                if is_max && second.is_none_or(|s| v > s) {
                    second = Some(v);
                }
            }
        }
        second
    }
}

/// A scored search candidate: ZNCC, integer offset from the predicted centre, linear map.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Candidate {
    /// ZNCC in [-1, 1].
    pub zncc: f32,
    /// Offset from the predicted centre, whole pixels.
    pub offset: (i32, i32),
    /// The linear map tried.
    pub affine: Mat2,
}

/// Scores `affine` at integer `offset` from `predicted`; `None` outside the target or flat.
fn score(
    t: &Template,
    target: &GrayView<'_>,
    predicted: (f32, f32),
    offset: (i32, i32),
    affine: &Mat2,
) -> Option<Candidate> {
    let c = (predicted.0 + offset.0 as f32, predicted.1 + offset.1 as f32);
    let zncc = t.zncc(target, c, affine)?;
    Some(Candidate { zncc, offset, affine: *affine })
}

/// Keeps `best` as the `cap` highest-scoring candidates, best first; ties keep the earlier one.
fn keep_best(best: &mut Vec<Candidate, MAX_COARSE>, cand: Candidate, cap: usize) {
    let pos = best.iter().position(|b| cand.zncc > b.zncc).unwrap_or(best.len());
    if pos >= cap {
        return;
    }
    if best.len() >= cap {
        best.pop();
    }
    // Cannot fail: there is room after the pop, and `pos <= len`.
    let _ = best.insert(pos, cand);
}

/// The outcome of the search: the best candidate, and the coarse stage's peak for the ambiguity
/// test.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SearchResult {
    /// The best candidate of stages 1-3.
    pub best: Candidate,
    /// The highest ZNCC of the coarse stage.
    pub coarse_peak: f32,
    /// The highest other local maximum of the coarse stage (see [`CoarseGrid::second_peak`]).
    pub second_peak: Option<f32>,
}

/// Stages 1-3 of the module's pipeline: the best candidate of the search window, or `None`.
pub(crate) fn search(
    t: &Template,
    target: &GrayView<'_>,
    predicted: (f32, f32),
    p: &MatchParams,
    bank: &[Mat2],
) -> Option<SearchResult> {
    let (r, s) = (p.search_radius as i32, p.coarse_step as i32);
    let cap = p.coarse_candidates.clamp(1, MAX_COARSE);
    let steps = r / s;
    let mut coarse: Vec<Candidate, MAX_COARSE> = Vec::new();
    let mut grid = CoarseGrid::new(steps);
    for j in -steps..=steps {
        for i in -steps..=steps {
            if let Some(c) = score(t, target, predicted, (i * s, j * s), &p.initial_affine) {
                grid.set(i, j, c.zncc);
                keep_best(&mut coarse, c, cap);
            }
        }
    }
    let mut best = *coarse.first()?;
    let coarse_peak = best.zncc;
    let second_peak = grid.second_peak(best.offset.0 / s, best.offset.1 / s);
    for c in coarse.iter() {
        for b in bank {
            let a = mat_mul(b, &p.initial_affine);
            if let Some(cand) = score(t, target, predicted, c.offset, &a)
                && cand.zncc > best.zncc
            {
                best = cand;
            }
        }
    }
    let centre = best.offset;
    for j in (centre.1 - s + 1)..=(centre.1 + s - 1) {
        for i in (centre.0 - s + 1)..=(centre.0 + s - 1) {
            if (i, j) == centre || i.abs() > r || j.abs() > r {
                continue;
            }
            if let Some(cand) = score(t, target, predicted, (i, j), &best.affine)
                && cand.zncc > best.zncc
            {
                best = cand;
            }
        }
    }
    Some(SearchResult { best, coarse_peak, second_peak })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn second_peak_skips_the_peak_and_its_slopes() {
        let mut g = CoarseGrid::new(2);
        for j in -2..=2 {
            for i in -2..=2 {
                // A ridge falling away from (0, 0), with a bump at (2, -2).
                g.set(i, j, 1.0 - 0.1 * (i.abs() + j.abs()) as f32);
            }
        }
        assert_eq!(g.second_peak(0, 0), None);
        g.set(2, -2, 0.95);
        assert_eq!(g.second_peak(0, 0), Some(0.95));
        g.set(2, -2, f32::NAN);
        assert_eq!(g.second_peak(0, 0), None);
        // Out-of-grid writes are ignored.
        g.set(3, 0, 9.0);
        assert!(g.get(3, 0).is_nan());
    }
}
