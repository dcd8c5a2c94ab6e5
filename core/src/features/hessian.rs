//! The strip-wise Fast-Hessian detector: per pyramid level, a rolling integral image, rolling
//! response rows of the two middle layers, and non-maximum suppression one sample row behind the
//! newest response row, with the outer layers evaluated only around candidates.

use super::bucket::GridBuckets;
use super::filter::{
    BELOW, FIRST_SAMPLE, LAYERS, LEVEL_FILTER_SIZES, LEVEL_STEPS, Layer, MAX_HALF, Threshold,
    laplacian_positive_at, response_at, response_row,
};
use super::refine::{Cube, is_maximum, plane_below, refine, sigma_of_size};
use super::rolling_integral::IntegralRing;
use super::{Feature, FeatureError, FeatureVec, HessianParams};
use crate::image::GrayView;

/// Response rows kept per middle layer: the NMS centre row and the rows above and below it.
const RESPONSE_RING_ROWS: usize = 3;

/// Layers with a layer on either side: the only ones that can hold a maximum, and the only ones
/// whose responses are computed whole. Their rows share one `W`-wide row of the response ring,
/// `W / 2` samples each: no level has more samples per row (the image is sampled every second
/// pixel, its 2x2 mean, `W / 2` wide, every pixel).
const MIDDLE_LAYERS: usize = LEVEL_FILTER_SIZES.len() - 2;
const _: () = assert!(MIDDLE_LAYERS == 2 && LEVEL_STEPS[0] == 2 && LEVEL_STEPS[1] == 1);

/// The Fast-Hessian detector with its whole workspace, for images up to `W` pixels wide (any
/// height). `W <= MAX_WIDTH` (640) is the intended range.
///
/// Size: `2*W*32` bytes of integral rows, `12*W` bytes of response rows, `W` bytes of marks and
/// 12,392 bytes of grid cells: 37,032 bytes for W = 320, 61,672 bytes for W = 640 (the unit
/// tests check both figures). Build it in a `static` or in place; [`HessianDetector::new`] is
/// `const`.
#[derive(Debug, Clone)]
pub struct HessianDetector<const W: usize> {
    integral: IntegralRing<W>,
    /// Responses of the middle layers 1 and 2 of the level being scanned: layer `k` at
    /// `[ring row][(k - 1) * (W / 2) + x / step]`.
    middle: [[f32; W]; RESPONSE_RING_ROWS],
    /// Which samples of `middle` are above the threshold, a bit each: those of layer `k` in
    /// ring row `r` from byte `(2 * r + k - 1) * W.div_ceil(16)` (only `3 * W / 8` bytes used:
    /// an array length cannot be computed from `W`).
    marks: [u8; W],
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
            marks: [0; W],
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
    /// // ~36 KiB: on the board, keep it in a `static` (e.g. a `StaticCell`), not on the stack.
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
        let Self { integral, middle, marks, buckets } = self;
        Scan { integral, middle, marks }.run(img, params, &mut |f| buckets.insert(&f))?;
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
        let Self { integral, middle, marks, .. } = self;
        Scan { integral, middle, marks }.run(img, params, sink)
    }
}

/// The last sample coordinate of a level `n` pixels wide (or high) sampled every `step` pixels:
/// the largest multiple of `step` where the largest filter fits, `coord + MAX_HALF <= n - 1`.
pub(super) fn last_sample(n: usize, step: usize) -> Option<usize> {
    n.checked_sub(MAX_HALF + 1).map(|v| v / step * step)
}

/// The sample grid of one pyramid level: samples at multiples of `step` from [`FIRST_SAMPLE`]
/// to `last_x` (inclusive, in pixels of the level) along a row.
#[derive(Debug, Clone, Copy)]
pub(super) struct Grid {
    /// 0 for the image, 1 for its 2x2 mean.
    pub level: usize,
    /// Sampling step, in pixels of the level.
    pub step: usize,
    pub last_x: usize,
}

impl Grid {
    /// The grid of level `level`, `w` x `h` pixels; `None` when it has no sample with a sample on
    /// either side (nothing to suppress against).
    pub(super) fn new(level: usize, w: usize, h: usize) -> Option<Self> {
        let step = *LEVEL_STEPS.get(level)?;
        let (last_x, last_y) = (last_sample(w, step)?, last_sample(h, step)?);
        let min = FIRST_SAMPLE + 2 * step;
        (last_x >= min && last_y >= min).then_some(Self { level, step, last_x })
    }

    /// Sample indices `(first, last)` (inclusive) along a row.
    fn samples(self) -> (usize, usize) {
        (FIRST_SAMPLE / self.step, self.last_x / self.step)
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
    marks: &'a mut [u8; W],
}

/// The row of the response ring (and of the marks) that holds sample row `y` of `grid`.
fn ring_slot(grid: Grid, y: usize) -> usize {
    (y / grid.step) % RESPONSE_RING_ROWS
}

impl<const W: usize> Scan<'_, W> {
    /// Bytes of marks per middle-layer response row: a bit for each of its `W / 2` samples,
    /// rounded up (see [`HessianDetector`]'s `marks`).
    const MARK_BYTES: usize = W.div_ceil(16);

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
        let t = &[Threshold::new(t, &LAYERS[1]), Threshold::new(t, &LAYERS[2])];
        if let Some(grid) = Grid::new(0, w, h) {
            for (r, pixels) in img.rows().enumerate() {
                self.integral.push(r, pixels);
                self.after_row(grid, r, t, sink);
            }
        }
        if params.octaves >= 2
            && let Some(grid) = Grid::new(1, w / 2, h / 2)
        {
            let mut rows = img.rows();
            let pairs = core::iter::from_fn(|| Some((rows.next()?, rows.next()?)));
            for (r, (top, bottom)) in pairs.enumerate() {
                self.integral.push_half(r, top, bottom);
                self.after_row(grid, r, t, sink);
            }
        }
        Ok(())
    }

    /// Work once integral row `r` is in: the middle layers' response row `r - MAX_HALF` (the
    /// last whose filters it completes), then suppression one sample row above it (whose outer
    /// layers, evaluated on demand at `+- step` rows, need integral rows up to `r`).
    fn after_row(
        &mut self,
        grid: Grid,
        r: usize,
        threshold: &[Threshold; MIDDLE_LAYERS],
        sink: &mut dyn FnMut(Feature),
    ) {
        let Some(y) = r.checked_sub(MAX_HALF) else { return };
        if y < FIRST_SAMPLE || y % grid.step != 0 {
            return;
        }
        self.middle_rows(grid, y, threshold);
        if y >= FIRST_SAMPLE + 2 * grid.step {
            self.suppress_row(grid, y - grid.step, threshold[0].value(), sink);
        }
    }

    /// Evaluates det(H) of the middle layers along sample row `y` ([`BELOW`] where it cannot
    /// exceed the threshold) and marks the samples above it.
    fn middle_rows(&mut self, grid: Grid, y: usize, threshold: &[Threshold; MIDDLE_LAYERS]) {
        let slot = ring_slot(grid, y);
        let Some(dst) = self.middle.get_mut(slot) else { return };
        let (k0, k1) = grid.samples();
        let half = W / 2;
        let marks = self.marks.chunks_mut(Self::MARK_BYTES).skip(MIDDLE_LAYERS * slot);
        let layers = LAYERS.iter().skip(1).zip(threshold).zip(marks);
        for (row, ((layer, t), marks)) in dst.chunks_exact_mut(half).zip(layers) {
            marks.fill(0);
            if let Some(out) = row.get_mut(k0..=k1) {
                let at = (FIRST_SAMPLE, y);
                response_row(&*self.integral, layer, grid.step, at, t, (out, marks));
            }
        }
    }

    /// The marks of sample row `y` of layer `k` (a middle layer): bit `j` for sample `k0 + j`
    /// (see [`HessianDetector`]'s `marks`).
    fn marks(&self, grid: Grid, k: usize, y: usize) -> &[u8] {
        let index = MIDDLE_LAYERS * ring_slot(grid, y) + k - 1;
        self.marks.chunks(Self::MARK_BYTES).nth(index).unwrap_or(&[])
    }

    /// Sample rows `yc - step`, `yc`, `yc + step` of layer `k` (a middle layer).
    fn middle_planes(&self, grid: Grid, k: usize, yc: usize) -> [&[f32]; 3] {
        let row = |y: usize| {
            let r = self.middle.get(ring_slot(grid, y));
            let at = k.wrapping_sub(1) * (W / 2);
            r.and_then(|r| r.get(at..at + W / 2)).unwrap_or(&[])
        };
        [row(yc - grid.step), row(yc), row(yc + grid.step)]
    }

    /// Non-maximum suppression and refinement along sample row `yc` (`yc >= FIRST + step`).
    fn suppress_row(&self, grid: Grid, yc: usize, t: f32, sink: &mut dyn FnMut(Feature)) {
        let (k0, k1) = grid.samples();
        for k in 1..LAYERS.len() - 1 {
            let own = self.middle_planes(grid, k, yc);
            // Only the marked samples (above the threshold, a few percent) are visited, in
            // order; the marks of row `yc` were set when its responses were computed.
            for (byte, &bits) in self.marks(grid, k, yc).iter().enumerate() {
                let mut bits = bits;
                while bits != 0 {
                    let i = k0 + 8 * byte + bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    if i > k0 && i < k1 {
                        self.try_sample(grid, (k, &own), (i, yc), t, sink);
                    }
                }
            }
        }
    }

    /// Non-maximum suppression and refinement at sample `(i, yc)` of middle layer `k`, if its
    /// response is above the threshold `t`; `own` holds the layer's rows around `yc`.
    fn try_sample(
        &self,
        grid: Grid,
        (k, own): (usize, &[&[f32]; 3]),
        at: (usize, usize),
        t: f32,
        sink: &mut dyn FnMut(Feature),
    ) -> Option<()> {
        let (i, yc) = at;
        let layer = LAYERS.get(k)?;
        let v = *own[1].get(i)?;
        // Marked samples are above `t`; the test also rejects NaN and [`BELOW`].
        (v > t).then_some(())?;
        let own_plane = plane(own, i)?;
        if !plane_below(v, &own_plane, 1) {
            return None;
        }
        // The held neighbour layer first: it is cheaper than one evaluated on demand.
        let (below, above) = if k == 1 {
            let above = self.neighbour(grid, k + 1, 2, at, v)?;
            (self.neighbour(grid, k - 1, 0, at, v)?, above)
        } else {
            let below = self.neighbour(grid, k - 1, 0, at, v)?;
            (below, self.neighbour(grid, k + 1, 2, at, v)?)
        };
        // Refinement reads every value: replace the ones not computed by exact ones.
        let own_plane = self.exact(own_plane, layer, grid.step, at, true)?;
        let f = candidate(&[below, own_plane, above], t, grid, i, yc, layer)?;
        let lap = laplacian_positive_at(&*self.integral, layer, i * grid.step, yc)?;
        sink(Feature { laplacian_positive: lap, ..f });
        Some(())
    }

    /// The exact 3x3 responses of layer `k` around sample `(i, yc)`, the cube's scale index `s`
    /// (0 below the centre's layer, 2 above), if none keeps `v` from being the maximum (see
    /// [`is_maximum`]): from the held rows for a middle layer, evaluated for an outer one.
    fn neighbour(
        &self,
        grid: Grid,
        k: usize,
        s: usize,
        (i, yc): (usize, usize),
        v: f32,
    ) -> Option<[[f32; 3]; 3]> {
        let layer = LAYERS.get(k)?;
        if k == 0 || k + 1 == LAYERS.len() {
            return self.outer_plane(layer, grid.step, s, (i, yc), v);
        }
        let p = plane(&self.middle_planes(grid, k, yc), i)?;
        if !plane_below(v, &p, s) {
            return None;
        }
        self.exact(p, layer, grid.step, (i, yc), false)
    }

    /// `plane`, the 3x3 responses of `layer` around sample `(i, yc)`, with [`BELOW`] replaced
    /// by the exact response where refinement reads it: everywhere in the candidate's own layer
    /// (`corners`), the centre and its four neighbours in the layers below and above.
    fn exact(
        &self,
        mut plane: [[f32; 3]; 3],
        layer: &Layer,
        step: usize,
        (i, yc): (usize, usize),
        corners: bool,
    ) -> Option<[[f32; 3]; 3]> {
        for (dy, row) in plane.iter_mut().enumerate() {
            for (dx, r) in row.iter_mut().enumerate() {
                if *r == BELOW && (corners || dx == 1 || dy == 1) {
                    let (x, y) = ((i + dx) * step, yc + dy * step);
                    *r = response_at(&*self.integral, layer, x.checked_sub(step)?, y - step)?;
                }
            }
        }
        Some(plane)
    }

    /// The 3x3 responses of `layer` around sample `(i, yc)`, evaluated from the integral rows, at
    /// scale index `s` of the cube (0 below the centre's layer, 2 above); `None` as soon as one
    /// keeps `v` from being the maximum (see [`is_maximum`]). The centre goes first: it is the
    /// one most likely to be larger.
    fn outer_plane(
        &self,
        layer: &Layer,
        step: usize,
        s: usize,
        (i, yc): (usize, usize),
        v: f32,
    ) -> Option<[[f32; 3]; 3]> {
        const ORDER: [(usize, usize); 9] =
            [(1, 1), (0, 1), (1, 0), (1, 2), (2, 1), (0, 0), (0, 2), (2, 0), (2, 2)];
        let mut p = [[0.0; 3]; 3];
        for (dy, dx) in ORDER {
            let y = (yc + dy * step).checked_sub(step)?;
            let x = ((i + dx) * step).checked_sub(step)?;
            let r = response_at(&*self.integral, layer, x, y)?;
            // Layers below the centre's precede it (must be smaller), layers above follow.
            if r > v || (r == v && s == 0) {
                return None;
            }
            *p.get_mut(dy)?.get_mut(dx)? = r;
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
    let s = grid.step as f32;
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
