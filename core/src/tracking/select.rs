//! Choosing which tracked landmarks to match in a frame so that they spread over the image.

use heapless::Vec;
use nalgebra::Point2;

/// A landmark predicted inside the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Candidate {
    /// Index into the local map.
    pub index: u16,
    /// Predicted pixel.
    pub uv: Point2<f32>,
    /// Preference within a cell, higher first (e.g. how often it was found).
    pub score: u16,
    cell: u16,
    rank: u16,
}

impl Candidate {
    /// A candidate for local-map entry `index` predicted at `uv`.
    pub fn new(index: u16, uv: Point2<f32>, score: u16) -> Self {
        Self { index, uv, score, cell: 0, rank: 0 }
    }
}

/// Orders `cands` so that every prefix spreads over a `cols` x `rows` grid of the `width` x
/// `height` image: the best candidate of every cell first (cells in raster order), then the second
/// best of every cell, and so on; then keeps the first `max`. Within a cell, higher `score` first,
/// then lower `index`: the order is a pure function of the input.
pub(crate) fn spread<const N: usize>(
    cands: &mut Vec<Candidate, N>,
    (width, height): (usize, usize),
    (cols, rows): (usize, usize),
    max: usize,
) {
    let (cols, rows) = (cols.max(1), rows.max(1));
    let cell_w = (width.max(1) as f32) / cols as f32;
    let cell_h = (height.max(1) as f32) / rows as f32;
    for c in cands.iter_mut() {
        // Clamped to the grid; `as` saturates NaN and negatives to 0.
        let cx = ((c.uv.x / cell_w) as usize).min(cols - 1);
        let cy = ((c.uv.y / cell_h) as usize).min(rows - 1);
        c.cell = u16::try_from(cy * cols + cx).unwrap_or(u16::MAX);
    }
    cands.sort_unstable_by(|a, b| {
        (a.cell, core::cmp::Reverse(a.score), a.index).cmp(&(
            b.cell,
            core::cmp::Reverse(b.score),
            b.index,
        ))
    });
    let mut prev_cell = u16::MAX;
    let mut rank = 0u16;
    for c in cands.iter_mut() {
        rank = if c.cell == prev_cell { rank.saturating_add(1) } else { 0 };
        prev_cell = c.cell;
        c.rank = rank;
    }
    cands.sort_unstable_by_key(|c| (c.rank, c.cell, c.index));
    cands.truncate(max);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prefixes_cover_every_occupied_cell_first() {
        let mut v: Vec<Candidate, 16> = Vec::new();
        // Cell 0 (top-left) has four candidates, cells 1 and 3 one each.
        for (i, (x, y, s)) in [
            (1.0, 1.0, 5),
            (2.0, 2.0, 9),
            (3.0, 3.0, 1),
            (4.0, 4.0, 9),
            (15.0, 1.0, 0),
            (15.0, 15.0, 2),
        ]
        .into_iter()
        .enumerate()
        {
            v.push(Candidate::new(i as u16, Point2::new(x, y), s)).unwrap();
        }
        spread(&mut v, (20, 20), (2, 2), 4);
        let order: Vec<u16, 16> = v.iter().map(|c| c.index).collect();
        // Rank 0: cell 0's best (score 9, lower index 1), cell 1 (4), cell 3 (5); then cell 0's next.
        assert_eq!(order, [1, 4, 5, 3]);
    }
}
