//! Spreading items over an image grid so that they cover the image evenly. The feature bucketing
//! (`features`), the ROI selection (`matching`) and the front end's choice of landmarks to track
//! (`tracking`) are built on these pieces; each keeps only its own rule on top.
//!
//! - [`Grid`]: a grid over a `width` x `height` image, of `cols` x `rows` cells or of square
//!   cells of a given side. It gives the cell of a pixel (exact integers) or of a sub-pixel point
//!   (one f32 division), and the pixels of a cell. Cells are numbered in raster order,
//!   `cy * cols + cx`.
//! - [`insert_best_first`]: a bounded best-first list (a cell's best items while they stream in,
//!   or the best few of many), ties kept in arrival order.
//! - Rank-major order ([`spread`]): the best item of every cell first (cells in raster order), then
//!   the second best of every cell, and so on. Every prefix of it spreads over the grid, and a
//!   cell with few items leaves its share to the others.
//!
//! Every rule is integer arithmetic or a fixed f32 expression, and every order is total, so a
//! selection is the same bits on every target.

use core::cmp::Reverse;

use nalgebra::Point2;

/// One axis of a [`Grid`]: `cells` equal cells spanning pixels `0..span` of an image `len` pixels
/// long. `span == len` for [`Grid::with_cells`]; square cells span `cells * side >= len`, the last
/// cell hanging over the image's edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Axis {
    len: usize,
    cells: usize,
    span: usize,
}

impl Axis {
    /// `floor(p * cells / span)` with `p` clamped to the image: exact integers.
    fn cell_of_pixel(self, p: usize) -> usize {
        let p = p.min(self.len.saturating_sub(1));
        let cell = p.saturating_mul(self.cells).checked_div(self.span).unwrap_or(0);
        cell.min(self.cells.saturating_sub(1))
    }

    /// `floor(x / (span / cells))` in f32, clamped to the grid (NaN and negatives give 0).
    fn cell_of_coordinate(self, x: f32) -> usize {
        let cell_px = self.span as f32 / self.cells as f32;
        ((x / cell_px) as usize).min(self.cells.saturating_sub(1))
    }

    /// The pixels `lo..hi` whose [`Self::cell_of_pixel`] is `cell` (empty past the grid).
    fn pixels(self, cell: usize) -> (usize, usize) {
        let edge = |c: usize| c.saturating_mul(self.span).div_ceil(self.cells.max(1)).min(self.len);
        (edge(cell), edge(cell.saturating_add(1)))
    }
}

/// A grid laid over an image, its cells numbered in raster order (`cy * cols + cx`).
///
/// Two rules give an item's cell, and they differ at cell borders by design (each caller's
/// selections depend on its rule): [`Self::cell_of_pixel`] is exact integer arithmetic on a pixel
/// index, [`Self::cell_of_point`] divides a sub-pixel coordinate by the f32 cell size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Grid {
    x: Axis,
    y: Axis,
}

impl Grid {
    /// `cols` x `rows` cells over a `width` x `height` image (each taken as at least 1): pixel
    /// column `px` lies in cell column `floor(px * cols / width)`, and likewise for rows.
    pub(crate) fn with_cells(
        (width, height): (usize, usize),
        (cols, rows): (usize, usize),
    ) -> Self {
        let axis = |len: usize, cells: usize| {
            let len = len.max(1);
            Axis { len, cells: cells.max(1), span: len }
        };
        Self { x: axis(width, cols), y: axis(height, rows) }
    }

    /// Square cells of `side` pixels (at least 1) from the image's top-left corner, as many as
    /// cover the image: the last column and row of cells are cut by the image's edge. An empty
    /// image has no cells.
    pub(crate) fn with_cell_side((width, height): (usize, usize), side: usize) -> Self {
        let side = side.max(1);
        let axis = |len: usize| {
            let cells = len.div_ceil(side);
            Axis { len, cells, span: cells.saturating_mul(side) }
        };
        Self { x: axis(width), y: axis(height) }
    }

    /// Number of cells, `cols * rows`.
    pub(crate) fn cells(&self) -> usize {
        self.x.cells.saturating_mul(self.y.cells)
    }

    /// The cell of pixel `(px, py)` (clamped to the image), by exact integer arithmetic; 0 on a
    /// grid without cells.
    pub(crate) fn cell_of_pixel(&self, (px, py): (usize, usize)) -> usize {
        self.raster(self.x.cell_of_pixel(px), self.y.cell_of_pixel(py))
    }

    /// The cell of the sub-pixel point `(x, y)` (pixels), each coordinate divided by the f32 cell
    /// size and clamped to the grid; NaN and negative coordinates fall in the first cell column or
    /// row.
    pub(crate) fn cell_of_point(&self, x: f32, y: f32) -> usize {
        self.raster(self.x.cell_of_coordinate(x), self.y.cell_of_coordinate(y))
    }

    /// The pixels of `cell`: columns `x0..x1` and rows `y0..y1`, exactly the pixels whose
    /// [`Self::cell_of_pixel`] is `cell` (empty ranges past the last cell).
    pub(crate) fn cell_bounds(&self, cell: usize) -> ((usize, usize), (usize, usize)) {
        let cx = cell.checked_rem(self.x.cells).unwrap_or(0);
        let cy = cell.checked_div(self.x.cells).unwrap_or(0);
        (self.x.pixels(cx), self.y.pixels(cy))
    }

    fn raster(&self, cx: usize, cy: usize) -> usize {
        cy.saturating_mul(self.x.cells).saturating_add(cx)
    }
}

/// Inserts `item` into the best-first list `list[..len]` whose capacity is `list.len()`, before the
/// first item it `beats` (`beats(existing)` is true when `item` ranks strictly before `existing`),
/// so ties keep their arrival order. When the list is full the last item falls off, or `item` is
/// dropped if it beats none. Returns the new length.
///
/// Cost: at most `list.len()` comparisons and moves. With capacity 1 it keeps the first best.
pub(crate) fn insert_best_first<T>(
    list: &mut [T],
    len: usize,
    item: T,
    beats: impl Fn(&T) -> bool,
) -> usize {
    let cap = list.len();
    let len = len.min(cap);
    let live = list.get(..len).unwrap_or(&[]);
    let pos = live.iter().position(&beats).unwrap_or(len);
    if pos >= cap {
        return len;
    }
    let end = len.min(cap - 1);
    // Shift the weaker ones down by one (the last falls off when the list is full).
    if let Some(tail) = list.get_mut(pos..=end) {
        tail.rotate_right(1);
        if let Some(first) = tail.first_mut() {
            *first = item;
        }
    }
    end + 1
}

/// Where an item stands in rank-major order: its cell and its rank among the cell's items (0 =
/// best). The derived order (rank, then cell) *is* rank-major order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Place {
    rank: u16,
    cell: u16,
}

/// An item to spread over the image: the caller's index, its pixel and its preference within its
/// cell. The front end's candidates are the tracked landmarks predicted inside the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Candidate {
    /// The caller's index (the front end's: into its local map).
    pub index: u16,
    /// Predicted pixel.
    pub uv: Point2<f32>,
    /// Preference within a cell, higher first (e.g. how often it was found).
    pub score: u16,
    place: Place,
}

impl Candidate {
    /// A candidate for the caller's item `index` at `uv`.
    pub(crate) fn new(index: u16, uv: Point2<f32>, score: u16) -> Self {
        Self { index, uv, score, place: Place { rank: 0, cell: 0 } }
    }
}

/// Orders `cands` in rank-major order over `grid` (cells by [`Grid::cell_of_point`]): the best
/// candidate of every cell first, cells in raster order, then the second best of every cell, and
/// so on. Within a cell, higher `score` first, then lower `index`: the order is a pure function of
/// the input. Truncating the result keeps a spread subset.
///
/// Cost: two unstable sorts of `cands`, no allocation.
pub(crate) fn spread(cands: &mut [Candidate], grid: &Grid) {
    for c in cands.iter_mut() {
        c.place.cell = u16::try_from(grid.cell_of_point(c.uv.x, c.uv.y)).unwrap_or(u16::MAX);
    }
    // Rank within each cell: sort by cell, best first, and count along each run.
    cands.sort_unstable_by_key(|c| (c.place.cell, Reverse(c.score), c.index));
    let mut prev_cell = u16::MAX;
    let mut rank = 0u16;
    for c in cands.iter_mut() {
        rank = if c.place.cell == prev_cell { rank.saturating_add(1) } else { 0 };
        prev_cell = c.place.cell;
        c.place.rank = rank;
    }
    cands.sort_unstable_by_key(|c| (c.place, c.index));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_fall_in_cells_by_exact_integers() {
        // 10 px in 3 cells: floor(p * 3 / 10).
        let g = Grid::with_cells((10, 4), (3, 2));
        let cols: [usize; 12] = core::array::from_fn(|p| g.cell_of_pixel((p, 0)));
        // Pixels past the image (10, 11) are clamped to the last one.
        assert_eq!(cols, [0, 0, 0, 0, 1, 1, 1, 2, 2, 2, 2, 2]);
        assert_eq!(g.cells(), 6);
        assert_eq!(g.cell_of_pixel((0, 1)), 0);
        assert_eq!(g.cell_of_pixel((0, 2)), 3);
        assert_eq!(g.cell_of_pixel((9, 3)), 5);
        // Zero sizes are taken as 1: one cell.
        let one = Grid::with_cells((0, 0), (0, 0));
        assert_eq!((one.cells(), one.cell_of_pixel((5, 5))), (1, 0));
    }

    #[test]
    fn points_fall_in_cells_by_the_f32_cell_size() {
        let g = Grid::with_cells((10, 4), (3, 2));
        // Cells are 3.333 px wide: 3.4 lies in cell 1, although pixel 3 lies in cell 0.
        assert_eq!(g.cell_of_point(3.4, 0.0), 1);
        assert_eq!(g.cell_of_pixel((3, 0)), 0);
        assert_eq!(g.cell_of_point(3.3, 1.9), 0);
        assert_eq!(g.cell_of_point(3.3, 2.0), 3);
        // Clamped to the grid; NaN and negatives fall in the first column or row.
        assert_eq!(g.cell_of_point(1e9, 1e9), 5);
        assert_eq!(g.cell_of_point(-5.0, f32::NAN), 0);
    }

    #[test]
    fn cell_bounds_hold_exactly_the_cells_pixels() {
        let grids = [
            Grid::with_cells((10, 4), (3, 2)),
            Grid::with_cells((7, 7), (7, 1)),
            Grid::with_cells((320, 240), (8, 6)),
            Grid::with_cell_side((100, 50), 40),
            Grid::with_cell_side((80, 41), 40),
            Grid::with_cell_side((5, 3), 1),
        ];
        for g in grids {
            let mut pixels = 0;
            for cell in 0..g.cells() {
                let ((x0, x1), (y0, y1)) = g.cell_bounds(cell);
                assert!(x0 < x1 && y0 < y1, "{g:?} cell {cell}");
                for (px, py) in (y0..y1).flat_map(|y| (x0..x1).map(move |x| (x, y))) {
                    assert_eq!(g.cell_of_pixel((px, py)), cell, "{g:?} ({px}, {py})");
                    pixels += 1;
                }
            }
            assert_eq!(pixels, g.x.len * g.y.len, "{g:?}: every pixel in one cell");
        }
    }

    #[test]
    fn square_cells_cover_the_image_from_its_corner() {
        let g = Grid::with_cell_side((100, 50), 40);
        assert_eq!(g.cells(), 6);
        assert_eq!(g.cell_bounds(0), ((0, 40), (0, 40)));
        assert_eq!(g.cell_bounds(2), ((80, 100), (0, 40)));
        assert_eq!(g.cell_bounds(4), ((40, 80), (40, 50)));
        assert_eq!(g.cell_bounds(6), ((0, 40), (50, 50)), "past the grid: empty");
        assert_eq!(Grid::with_cell_side((0, 50), 40).cells(), 0);
        let huge = Grid::with_cell_side((320, 240), usize::MAX);
        assert_eq!((huge.cells(), huge.cell_bounds(0)), (1, ((0, 320), (0, 240))));
    }

    #[test]
    fn best_first_lists_keep_the_best_in_arrival_order_of_ties() {
        let mut list = [0u32; 3];
        let mut len = 0;
        for score in [5, 7, 5, 9, 1, 7] {
            len = insert_best_first(&mut list, len, score, |&e| score > e);
        }
        assert_eq!((len, list), (3, [9, 7, 7]));
        // Ties: the earlier one stays ahead (tagged by arrival), a tie with the last is dropped.
        let mut list = [(0u32, 0usize); 2];
        let mut len = 0;
        for (i, score) in [4, 4, 4].into_iter().enumerate() {
            len = insert_best_first(&mut list, len, (score, i), |e| score > e.0);
        }
        assert_eq!((len, list), (2, [(4, 0), (4, 1)]));
        // Capacity 1 keeps the first best; capacity 0 keeps nothing.
        let mut one = [0u32; 1];
        let mut len = 0;
        for score in [3, 8, 2, 8] {
            len = insert_best_first(&mut one, len, score, |&e| score > e);
        }
        assert_eq!((len, one), (1, [8]));
        assert_eq!(insert_best_first(&mut [0u32; 0], 0, 1, |_| true), 0);
    }

    fn spread_indices(items: &[(f32, f32, u16)], grid: &Grid) -> heapless::Vec<u16, 16> {
        let mut v: heapless::Vec<Candidate, 16> = items
            .iter()
            .enumerate()
            .map(|(i, &(x, y, s))| Candidate::new(i as u16, Point2::new(x, y), s))
            .collect();
        spread(&mut v, grid);
        v.iter().map(|c| c.index).collect()
    }

    #[test]
    fn prefixes_cover_every_occupied_cell_first() {
        // Cell 0 (top-left) has four candidates, cells 1 and 3 one each.
        let items = [
            (1.0, 1.0, 5),
            (2.0, 2.0, 9),
            (3.0, 3.0, 1),
            (4.0, 4.0, 9),
            (15.0, 1.0, 0),
            (15.0, 15.0, 2),
        ];
        let order = spread_indices(&items, &Grid::with_cells((20, 20), (2, 2)));
        // Rank 0: cell 0's best (score 9, lower index 1), cell 1 (4), cell 3 (5); then cell 0's
        // second (3), third (0) and fourth (2).
        assert_eq!(order, [1, 4, 5, 3, 0, 2]);
    }

    #[test]
    fn rank_major_order_takes_cells_in_raster_order_in_every_round() {
        // 3 x 1 grid over 30 x 10: cells 0, 1 and 2 hold 2, 1 and 4 candidates.
        let items = [
            (25.0, 5.0, 1), // 0: cell 2, rank 3
            (5.0, 5.0, 1),  // 1: cell 0, rank 1
            (15.0, 5.0, 4), // 2: cell 1, rank 0
            (21.0, 5.0, 3), // 3: cell 2, rank 1 (ties with 5: lower index first)
            (29.0, 5.0, 7), // 4: cell 2, rank 0
            (28.0, 5.0, 3), // 5: cell 2, rank 2
            (6.0, 5.0, 2),  // 6: cell 0, rank 0
        ];
        let order = spread_indices(&items, &Grid::with_cells((30, 10), (3, 1)));
        assert_eq!(order, [6, 2, 4, 1, 3, 5, 0]);
    }
}
