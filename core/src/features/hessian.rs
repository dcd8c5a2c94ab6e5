//! The strip-wise Fast-Hessian detector: a rolling integral image, rolling response rows and
//! non-maximum suppression one sample row behind the newest response row.

use super::bucket::GridBuckets;
use super::filter::{
    Cube, INTEGRAL_RING_ROWS, IntegralRows, OCTAVES, Octave, Taps, is_strict_maximum, refine,
    sigma_of_size,
};
use super::{Feature, FeatureError, FeatureVec, HessianParams};
use crate::image::GrayView;

/// Response rows kept per layer: the NMS centre row and the rows above and below it.
const RESPONSE_RING_ROWS: usize = 3;
/// Layers per octave.
const LAYERS: usize = 4;

/// The rolling integral image: row `y` of the image's integral lives in slot `y % ring rows`.
#[derive(Debug)]
struct IntegralRing<const W: usize> {
    rows: [[u32; W]; INTEGRAL_RING_ROWS],
    /// Column sums of every image row added so far (mod 2^32).
    column_sums: [u32; W],
}

impl<const W: usize> IntegralRows for IntegralRing<W> {
    fn row(&self, y: usize) -> &[u32] {
        self.rows.get(y % INTEGRAL_RING_ROWS).map_or(&[], |r| &r[..])
    }
}

impl<const W: usize> IntegralRing<W> {
    /// Adds image row `y` (the rows must come in order from 0).
    fn push(&mut self, y: usize, pixels: &[u8]) {
        if y == 0 {
            self.column_sums.fill(0);
        }
        let Some(dst) = self.rows.get_mut(y % INTEGRAL_RING_ROWS) else { return };
        let mut acc = 0u32;
        for ((d, cs), &p) in dst.iter_mut().zip(self.column_sums.iter_mut()).zip(pixels) {
            *cs = cs.wrapping_add(u32::from(p));
            acc = acc.wrapping_add(*cs);
            *d = acc;
        }
    }
}

/// The Fast-Hessian detector with its whole workspace, for images up to `W` pixels wide (any
/// height). `W <= MAX_WIDTH` (640) is the intended range.
///
/// Size: `4*W*53` bytes of integral rows and column sums, `72*W` bytes of response rows and
/// 12,392 bytes of grid cells: 103,272 bytes for W = 320, 194,152 bytes for W = 640 (the unit tests
/// check both figures). Build it in a `static` or in place; [`HessianDetector::new`] is `const`.
#[derive(Debug)]
pub struct HessianDetector<const W: usize> {
    integral: IntegralRing<W>,
    /// Octave 0: `[layer][ring row][x]`.
    responses0: [[[f32; W]; RESPONSE_RING_ROWS]; LAYERS],
    /// Octave 1 (every second pixel): layer `k` in `[k / 2][ring row][(k % 2) * W / 2 + x / 2]`.
    responses1: [[[f32; W]; RESPONSE_RING_ROWS]; LAYERS / 2],
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
            integral: IntegralRing { rows: [[0; W]; INTEGRAL_RING_ROWS], column_sums: [0; W] },
            responses0: [[[0.0; W]; RESPONSE_RING_ROWS]; LAYERS],
            responses1: [[[0.0; W]; RESPONSE_RING_ROWS]; LAYERS / 2],
            buckets: GridBuckets::new(),
        }
    }

    /// Detects features in `img` and writes the bucketed selection into `out` (cleared first),
    /// in selection order (each cell's strongest first, see [`HessianParams::per_cell_cap`]).
    /// An image too small for the smallest octave gives no features.
    ///
    /// ```
    /// use ferroslam_core::features::{FeatureVec, HessianParams, QvgaHessianDetector};
    /// use ferroslam_core::image::GrayView;
    ///
    /// // ~101 KiB: on the board, keep it in a `static` (e.g. a `StaticCell`), not on the stack.
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
        let Self { integral, responses0, responses1, buckets } = self;
        let mut scan = Scan { integral, responses0, responses1 };
        scan.run(img, params, &mut |f| buckets.insert(&f))?;
        self.buckets.select(usize::from(params.max_features), out)
    }

    /// Calls `sink` with every refined local maximum above the threshold, before bucketing, in a
    /// fixed scan order (by the image row that completes the sample's neighbourhood, then octave,
    /// layer and column).
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
        let Self { integral, responses0, responses1, .. } = self;
        Scan { integral, responses0, responses1 }.run(img, params, sink)
    }
}

/// Mutable borrows of the scan's scratch, split from the grid buckets.
struct Scan<'a, const W: usize> {
    integral: &'a mut IntegralRing<W>,
    responses0: &'a mut [[[f32; W]; RESPONSE_RING_ROWS]; LAYERS],
    responses1: &'a mut [[[f32; W]; RESPONSE_RING_ROWS]; LAYERS / 2],
}

impl<const W: usize> Scan<'_, W> {
    fn run(
        &mut self,
        img: &GrayView<'_>,
        params: &HessianParams,
        sink: &mut dyn FnMut(Feature),
    ) -> Result<(), FeatureError> {
        let w = img.width();
        if w > W {
            return Err(FeatureError::ImageTooWide { width: w, max: W });
        }
        for (r, pixels) in img.rows().enumerate() {
            self.integral.push(r, pixels);
            for oct in OCTAVES.iter().take(usize::from(params.octaves)) {
                // Response row `y` needs integral rows up to `y + half`: it is ready now.
                let Some(y) = r.checked_sub(oct.half()) else { continue };
                let s = oct.step;
                if y < oct.first_sample() || y % s != 0 {
                    continue;
                }
                self.response_row(oct, y, w);
                // NMS runs one sample row behind, once three response rows are held.
                if y >= oct.first_sample() + 2 * s {
                    self.suppress_row(oct, y - s, w, params.threshold, sink);
                }
            }
        }
        Ok(())
    }

    /// Sample columns `(first, last)` (inclusive, in samples) of octave `oct` for width `w`.
    fn sample_columns(oct: &Octave, w: usize) -> Option<(usize, usize)> {
        let s = oct.step;
        let last_x = w.checked_sub(oct.half() + 1)?;
        let first = oct.first_sample() / s;
        let last = last_x / s;
        (first <= last).then_some((first, last))
    }

    fn layer_row(&self, oct: &Octave, layer: usize, y: usize) -> &[f32] {
        let slot = (y / oct.step) % RESPONSE_RING_ROWS;
        let row = if oct.index == 0 {
            self.responses0.get(layer).and_then(|l| l.get(slot)).map(|r| &r[..])
        } else {
            let off = (layer % 2) * (W / 2);
            let half = self.responses1.get(layer / 2).and_then(|l| l.get(slot));
            half.and_then(|r| r.get(off..off + W / 2))
        };
        row.unwrap_or(&[])
    }

    /// Evaluates det(H) of the four layers of octave `o` along image row `y`.
    fn response_row(&mut self, oct: &Octave, y: usize, w: usize) {
        let Some((first, last)) = Self::sample_columns(oct, w) else { return };
        let s = oct.step;
        for (layer, &size) in oct.sizes.iter().enumerate() {
            // The taps borrow the integral ring, the output borrows a response ring: split them.
            let taps = Taps::new(&*self.integral, size, y);
            let slot = (y / s) % RESPONSE_RING_ROWS;
            let dst: &mut [f32] = if oct.index == 0 {
                self.responses0
                    .get_mut(layer)
                    .and_then(|l| l.get_mut(slot))
                    .map_or(&mut [], |r| &mut r[..])
            } else {
                let off = (layer % 2) * (W / 2);
                let half = self.responses1.get_mut(layer / 2).and_then(|l| l.get_mut(slot));
                half.and_then(|r| r.get_mut(off..off + W / 2)).unwrap_or(&mut [])
            };
            for (i, d) in dst.iter_mut().enumerate().take(last + 1).skip(first) {
                *d = taps.response(i * s);
            }
        }
    }

    /// Non-maximum suppression and refinement along sample row `yc` of octave `o`.
    fn suppress_row(
        &self,
        oct: &Octave,
        yc: usize,
        w: usize,
        threshold: f32,
        sink: &mut dyn FnMut(Feature),
    ) {
        let Some((first, last)) = Self::sample_columns(oct, w) else { return };
        let s = oct.step;
        let sizes = oct.sizes;
        for m in 1..LAYERS - 1 {
            let rows = |layer: usize| {
                [
                    self.layer_row(oct, layer, yc.saturating_sub(s)),
                    self.layer_row(oct, layer, yc),
                    self.layer_row(oct, layer, yc + s),
                ]
            };
            let planes = [rows(m - 1), rows(m), rows(m + 1)];
            let centre = planes[1][1];
            for i in first + 1..last {
                if !centre.get(i).is_some_and(|&v| v > threshold) {
                    continue;
                }
                let Some(cube) = gather(&planes, i) else { continue };
                let size = sizes.get(m).copied().unwrap_or(0);
                let Some(f) = candidate(&cube, threshold, oct, i, yc, size) else { continue };
                let taps = Taps::new(&*self.integral, size, yc);
                sink(Feature { laplacian_positive: taps.laplacian_positive(i * s), ..f });
            }
        }
    }
}

/// The 3x3x3 cube around column `i` of three layers' three rows.
pub(super) fn gather(planes: &[[&[f32]; 3]; 3], i: usize) -> Option<Cube> {
    let mut cube: Cube = [[[0.0; 3]; 3]; 3];
    for (dst_plane, plane) in cube.iter_mut().zip(planes) {
        for (dst_row, row) in dst_plane.iter_mut().zip(plane) {
            dst_row.copy_from_slice(row.get(i.checked_sub(1)?..=i + 1)?);
        }
    }
    Some(cube)
}

/// The refined feature of a cube centred on sample `(i, yc)` of layer size `size` in octave `o`,
/// if it is a strict local maximum above `threshold` whose quadratic fit stays within half a
/// sample. The Laplacian sign is left `false` for the caller to fill.
pub(super) fn candidate(
    cube: &Cube,
    threshold: f32,
    oct: &Octave,
    i: usize,
    yc: usize,
    size: usize,
) -> Option<Feature> {
    if !is_strict_maximum(cube, threshold) {
        return None;
    }
    let [ox, oy, os] = refine(cube)?;
    let s = oct.step as f32;
    let size_step = oct.size_step() as f32;
    Some(Feature {
        x: (i as f32 + ox) * s,
        y: yc as f32 + oy * s,
        scale: sigma_of_size(size as f32 + os * size_step),
        response: cube[1][1][1],
        laplacian_positive: false,
    })
}
