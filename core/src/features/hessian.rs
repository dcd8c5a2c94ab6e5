//! The strip-wise Fast-Hessian detector: per pyramid level, a rolling integral image, rolling
//! response rows of the two middle layers, and non-maximum suppression one sample row behind the
//! newest response row, with the outer layers evaluated only around candidates.

use super::bucket::GridBuckets;
use super::filter::{
    FIRST_SAMPLE, LAYERS, LEVEL_FILTER_SIZES, LEVEL_STEP, Layer, MAX_HALF, laplacian_positive_at,
    response_at, response_row,
};
use super::refine::{Cube, is_maximum, plane_below, refine, sigma_of_size};
use super::ring::{IntegralRing, half_row};
use super::{Feature, FeatureError, FeatureVec, HessianParams};
use crate::image::GrayView;

/// Response rows kept per middle layer: the NMS centre row and the rows above and below it.
const RESPONSE_RING_ROWS: usize = 3;

/// The Fast-Hessian detector with its whole workspace, for images up to `W` pixels wide (any
/// height). `W <= MAX_WIDTH` (640) is the intended range.
///
/// Size: `2*W*33` bytes of integral rows and column sums, `12*W` bytes of response rows and
/// 12,392 bytes of grid cells: 37,352 bytes for W = 320, 62,312 bytes for W = 640 (the unit tests
/// check both figures). Build it in a `static` or in place; [`HessianDetector::new`] is `const`.
#[derive(Debug)]
pub struct HessianDetector<const W: usize> {
    integral: IntegralRing<W>,
    /// Responses of the middle layers 1 and 2 of the level being scanned: middle layer `m`
    /// (0 for layer 1) at `[ring row][m * (W / 2) + x / LEVEL_STEP]`.
    middle: [[f32; W]; RESPONSE_RING_ROWS],
    buckets: GridBuckets,
}

/// The detector for the reference board's QVGA profile (320 pixels wide).
pub type QvgaHessianDetector = HessianDetector<320>;
/// The detector for the VGA profile (640 pixels wide).
pub type VgaHessianDetector = HessianDetector<640>;

impl<const W: usize> Default for HessianDetector<W> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const W: usize> HessianDetector<W> {
    /// A detector with a zeroed workspace (`const`, so it can initialize a `static`).
    pub const fn new() -> Self {
        Self {
            integral: IntegralRing::new(),
            middle: [[0.0; W]; RESPONSE_RING_ROWS],
            buckets: GridBuckets::new(),
        }
    }

    /// Detects features in `img` and writes the bucketed selection into `out` (cleared first),
    /// in selection order (each cell's strongest first, see [`HessianParams::per_cell_cap`]).
    /// An image too small for the first level gives no features.
    ///
    /// ```
    /// use ferroslam_core::features::{FeatureVec, HessianParams, QvgaHessianDetector};
    /// use ferroslam_core::image::GrayView;
    ///
    /// // ~37 KiB: on the board, keep it in a `static` (e.g. a `StaticCell`), not on the stack.
    /// let mut detector = QvgaHessianDetector::new();
    /// let pixels = [128u8; 64 * 48];
    /// let img = GrayView::packed(&pixels, 64, 48)?;
    /// let mut features = FeatureVec::new();
    /// detector.detect(&img, &HessianParams::default(), &mut features)?;
    /// assert!(features.is_empty()); // a flat image has no blobs
    /// # Ok::<(), Box<dyn core::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`FeatureError::ImageTooWide`] if `img` is wider than `W`; [`FeatureError::InvalidParams`]
    /// if `params` fails [`HessianParams::validate`]. `out` is empty then.
    // Never inlined: a large function called once per keyframe gains nothing from it, and
    // callgrind can then count its instructions by name (`--toggle-collect='*::detect'`).
    #[inline(never)]
    pub fn detect(
        &mut self,
        img: &GrayView<'_>,
        params: &HessianParams,
        out: &mut FeatureVec,
    ) -> Result<(), FeatureError> {
        out.clear();
        params.validate()?;
        self.buckets.reset(params, img.width(), img.height());
        let Self { integral, middle, buckets } = self;
        Scan { integral, middle }.run(img, params, &mut |f| buckets.insert(&f))?;
        self.buckets.select(usize::from(params.max_features), out)
    }

    /// Calls `sink` with every refined local maximum above the threshold, before bucketing, in a
    /// fixed scan order (level, then the sample row, middle layer and column).
    ///
    /// # Errors
    /// As [`HessianDetector::detect`].
    pub fn detect_candidates(
        &mut self,
        img: &GrayView<'_>,
        params: &HessianParams,
        sink: &mut dyn FnMut(Feature),
    ) -> Result<(), FeatureError> {
        params.validate()?;
        let Self { integral, middle, .. } = self;
        Scan { integral, middle }.run(img, params, sink)
    }
}

/// The last sample coordinate of a level `n` pixels wide (or high): the largest multiple of
/// [`LEVEL_STEP`] where the largest filter fits, `coord + MAX_HALF <= n - 1`.
pub(super) fn last_sample(n: usize) -> Option<usize> {
    n.checked_sub(MAX_HALF + 1).map(|v| v / LEVEL_STEP * LEVEL_STEP)
}

/// The sample grid of one pyramid level: samples at multiples of [`LEVEL_STEP`] from
/// [`FIRST_SAMPLE`] to `last_x` (inclusive, in pixels of the level) along a row.
#[derive(Debug, Clone, Copy)]
pub(super) struct Grid {
    /// 0 for the image, 1 for its 2x2 mean.
    pub level: usize,
    pub last_x: usize,
}

impl Grid {
    /// The grid of level `level`, `w` x `h` pixels; `None` when it has no sample with a sample on
    /// either side (nothing to suppress against).
    pub(super) fn new(level: usize, w: usize, h: usize) -> Option<Self> {
        let (last_x, last_y) = (last_sample(w)?, last_sample(h)?);
        let min = FIRST_SAMPLE + 2 * LEVEL_STEP;
        (last_x >= min && last_y >= min).then_some(Self { level, last_x })
    }

    /// Image coordinate of level coordinate `c`: pixel `c` of level 1 covers image pixels `2c`
    /// and `2c + 1`, so its centre is at `2c + 0.5`.
    fn to_image(self, c: f32) -> f32 {
        if self.level == 0 { c } else { 2.0 * c + 0.5 }
    }

    /// Image pixels per pixel of the level.
    fn factor(self) -> f32 {
        if self.level == 0 { 1.0 } else { 2.0 }
    }
}

/// Mutable borrows of the scan's scratch, split from the grid buckets.
struct Scan<'a, const W: usize> {
    integral: &'a mut IntegralRing<W>,
    middle: &'a mut [[f32; W]; RESPONSE_RING_ROWS],
}

impl<const W: usize> Scan<'_, W> {
    fn run(
        &mut self,
        img: &GrayView<'_>,
        params: &HessianParams,
        sink: &mut dyn FnMut(Feature),
    ) -> Result<(), FeatureError> {
        let (w, h) = img.size();
        if w > W {
            return Err(FeatureError::ImageTooWide { width: w, max: W });
        }
        let t = params.threshold;
        if let Some(grid) = Grid::new(0, w, h) {
            for (r, pixels) in img.rows().enumerate() {
                self.integral.push(r, pixels.iter().copied());
                self.after_row(grid, r, t, sink);
            }
        }
        if params.octaves >= 2
            && let Some(grid) = Grid::new(1, w / 2, h / 2)
        {
            let mut rows = img.rows();
            let pairs = core::iter::from_fn(|| Some((rows.next()?, rows.next()?)));
            for (r, (top, bottom)) in pairs.enumerate() {
                self.integral.push(r, half_row(top, bottom));
                self.after_row(grid, r, t, sink);
            }
        }
        Ok(())
    }

    /// Work once integral row `r` is in: the middle layers' response row `r - MAX_HALF` (the
    /// last whose filters it completes), then suppression one sample row above it (whose outer
    /// layers, evaluated on demand at `+- LEVEL_STEP` rows, need integral rows up to `r`).
    fn after_row(&mut self, grid: Grid, r: usize, threshold: f32, sink: &mut dyn FnMut(Feature)) {
        let Some(y) = r.checked_sub(MAX_HALF) else { return };
        if y < FIRST_SAMPLE || y % LEVEL_STEP != 0 {
            return;
        }
        self.middle_rows(grid, y);
        if y >= FIRST_SAMPLE + 2 * LEVEL_STEP {
            self.suppress_row(grid, y - LEVEL_STEP, threshold, sink);
        }
    }

    /// Evaluates det(H) of the middle layers along sample row `y`.
    fn middle_rows(&mut self, grid: Grid, y: usize) {
        let slot = (y / LEVEL_STEP) % RESPONSE_RING_ROWS;
        let Some(dst) = self.middle.get_mut(slot) else { return };
        let (k0, k1) = (FIRST_SAMPLE / LEVEL_STEP, grid.last_x / LEVEL_STEP);
        for (m, layer) in [LAYERS[1], LAYERS[2]].iter().enumerate() {
            let off = m * (W / 2);
            if let Some(out) = dst.get_mut(off + k0..=off + k1) {
                response_row(&*self.integral, layer, FIRST_SAMPLE, y, out);
            }
        }
    }

    /// Sample rows `yc - step`, `yc`, `yc + step` of middle layer `m`.
    fn middle_planes(&self, m: usize, yc: usize) -> [&[f32]; 3] {
        let row = |y: usize| {
            let r = self.middle.get((y / LEVEL_STEP) % RESPONSE_RING_ROWS);
            r.and_then(|r| r.get(m * (W / 2)..(m + 1) * (W / 2))).unwrap_or(&[])
        };
        [row(yc - LEVEL_STEP), row(yc), row(yc + LEVEL_STEP)]
    }

    /// Non-maximum suppression and refinement along sample row `yc` (`yc >= FIRST + step`).
    fn suppress_row(&self, grid: Grid, yc: usize, t: f32, sink: &mut dyn FnMut(Feature)) {
        let (k0, k1) = (FIRST_SAMPLE / LEVEL_STEP, grid.last_x / LEVEL_STEP);
        let lower = self.middle_planes(0, yc);
        let upper = self.middle_planes(1, yc);
        // Middle layer 0 (layer 1) has layer 0 below it, evaluated on demand; middle layer 1
        // (layer 2) has layer 3 above it.
        let passes = [(0, lower, upper, LAYERS[0], LAYERS[1]), (1, upper, lower, LAYERS[3], LAYERS[2])];
        for (m, own, other, outer, layer) in passes {
            for i in k0 + 1..k1 {
                let Some(&v) = own[1].get(i) else { break };
                // Most samples fail here: `!(v > t)` also rejects NaN.
                if !(v > t) {
                    continue;
                }
                let Some(own_plane) = plane(&own, i) else { continue };
                if !plane_below(v, &own_plane, 1) {
                    continue;
                }
                // The other middle layer is above middle layer 0 and below middle layer 1.
                let Some(other_plane) = plane(&other, i) else { continue };
                if !plane_below(v, &other_plane, 2 - 2 * m) {
                    continue;
                }
                let Some(outer_plane) = self.outer_plane(&outer, 2 * m, i, yc, v) else {
                    continue;
                };
                let cube =
                    if m == 0 { [outer_plane, own_plane, other_plane] } else {
                        [other_plane, own_plane, outer_plane]
                    };
                let Some(f) = candidate(&cube, t, grid, i, yc, &layer) else { continue };
                let x = i * LEVEL_STEP;
                let Some(lap) = laplacian_positive_at(&*self.integral, &layer, x, yc) else {
                    continue;
                };
                sink(Feature { laplacian_positive: lap, ..f });
            }
        }
    }

    /// The 3x3 responses of `layer` around sample `(i, yc)`, evaluated from the integral rows, at
    /// scale index `s` of the cube (0 below the centre's layer, 2 above); `None` as soon as one
    /// keeps `v` from being the maximum (see [`is_maximum`]).
    fn outer_plane(
        &self,
        layer: &Layer,
        s: usize,
        i: usize,
        yc: usize,
        v: f32,
    ) -> Option<[[f32; 3]; 3]> {
        let mut p = [[0.0; 3]; 3];
        for (dy, row) in p.iter_mut().enumerate() {
            let y = (yc + dy * LEVEL_STEP).checked_sub(LEVEL_STEP)?;
            for (dx, r) in row.iter_mut().enumerate() {
                let x = ((i + dx) * LEVEL_STEP).checked_sub(LEVEL_STEP)?;
                *r = response_at(&*self.integral, layer, x, y)?;
                // Layers below the centre's precede it (must be smaller), layers above follow.
                if *r > v || (*r == v && s == 0) {
                    return None;
                }
            }
        }
        Some(p)
    }
}

/// The 3x3 block around sample `i` of three response rows.
pub(super) fn plane(rows: &[&[f32]; 3], i: usize) -> Option<[[f32; 3]; 3]> {
    let mut p = [[0.0; 3]; 3];
    for (dst, row) in p.iter_mut().zip(rows) {
        dst.copy_from_slice(row.get(i.checked_sub(1)?..=i + 1)?);
    }
    Some(p)
}

/// The refined feature of a cube centred on sample `(i, yc)` of `layer` in the level of `grid`,
/// in image coordinates, if it is a strict local maximum above `threshold` whose quadratic fit
/// stays within one sample. The Laplacian sign is left `false` for the caller to fill.
pub(super) fn candidate(
    cube: &Cube,
    threshold: f32,
    grid: Grid,
    i: usize,
    yc: usize,
    layer: &Layer,
) -> Option<Feature> {
    if !is_maximum(cube, threshold) {
        return None;
    }
    let [ox, oy, os] = refine(cube)?;
    let s = LEVEL_STEP as f32;
    let size_step = (LEVEL_FILTER_SIZES[1] - LEVEL_FILTER_SIZES[0]) as f32;
    let size = layer.size as f32 + os * size_step;
    Some(Feature {
        x: grid.to_image((i as f32 + ox) * s),
        y: grid.to_image(yc as f32 + oy * s),
        scale: sigma_of_size(size * grid.factor()),
        response: cube[1][1][1],
        laplacian_positive: false,
    })
}
