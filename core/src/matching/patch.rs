//! Bilinear sampling, the ROI template and its zero-mean normalized cross-correlation (ZNCC).
//!
//! A template of half-size `h` is the square grid of offsets `u = (i, j)`, `i, j in -h..=h`
//! (pixels), sampled from the template image at `c + u`. It is stored with a one-sample margin
//! (`(2h + 3)^2` values) so that the central-difference gradients the Lucas-Kanade refinement
//! needs come from the same buffer.

use super::affine::{Mat2, mat_apply};
use crate::image::GrayView;

/// Largest template half-size in pixels (21 x 21 templates).
pub const MAX_HALF_SIZE: usize = 10;

/// Side of the stored template, margin included, at [`MAX_HALF_SIZE`].
const MAX_SIDE: usize = 2 * MAX_HALF_SIZE + 3;

/// Samples of the largest stored template, margin included (529 f32 = 2116 bytes of stack).
pub(crate) const MAX_STORED: usize = MAX_SIDE * MAX_SIDE;

/// Samples in the largest template grid (441).
pub(crate) const MAX_GRID: usize = (2 * MAX_HALF_SIZE + 1) * (2 * MAX_HALF_SIZE + 1);

/// Gray value at the real position `(x, y)` by bilinear interpolation, or `None` when the position
/// is not finite or its 2x2 neighbourhood leaves the image (a position exactly on the last row or
/// column is inside).
pub fn sample_bilinear(img: &GrayView<'_>, x: f32, y: f32) -> Option<f32> {
    let (w, h) = img.size();
    // NaN fails both comparisons; the casts below only see values in 0..=w-1.
    if !(x >= 0.0 && y >= 0.0 && x <= (w - 1) as f32 && y <= (h - 1) as f32) {
        return None;
    }
    let (x0, y0) = (x as usize, y as usize);
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let x1 = (x0 + 1).min(w - 1);
    let y1 = (y0 + 1).min(h - 1);
    let r0 = img.row(y0)?;
    let r1 = img.row(y1)?;
    let p00 = f32::from(*r0.get(x0)?);
    let p10 = f32::from(*r0.get(x1)?);
    let p01 = f32::from(*r1.get(x0)?);
    let p11 = f32::from(*r1.get(x1)?);
    let top = p00 + fx * (p10 - p00);
    let bottom = p01 + fx * (p11 - p01);
    Some(top + fy * (bottom - top))
}

/// The grid offsets `(i, j)` of a template of half-size `half`, row by row (j outer, i inner).
pub(crate) fn grid(half: usize) -> impl Iterator<Item = (f32, f32)> {
    let h = half as i32;
    (-h..=h).flat_map(move |j| (-h..=h).map(move |i| (i as f32, j as f32)))
}

/// An ROI template: samples with a one-pixel margin, their mean and zero-mean norm over the grid.
#[derive(Debug, Clone)]
pub(crate) struct Template {
    half: usize,
    values: [f32; MAX_STORED],
    /// Mean over the `(2h + 1)^2` grid samples (gray levels).
    pub mean: f32,
    /// `sqrt(sum (T - mean)^2)` over the grid (gray levels).
    pub norm: f32,
}

impl Template {
    /// Samples `img` around `centre` on the grid of half-size `half` (at most [`MAX_HALF_SIZE`]),
    /// margin included. `None` when a sample leaves the image.
    pub fn extract(img: &GrayView<'_>, centre: (f32, f32), half: usize) -> Option<Self> {
        if half == 0 || half > MAX_HALF_SIZE {
            return None;
        }
        let mut t = Self { half, values: [0.0; MAX_STORED], mean: 0.0, norm: 0.0 };
        let side = 2 * half + 3;
        let m = (half + 1) as f32;
        for (k, v) in t.values.iter_mut().take(side * side).enumerate() {
            let (i, j) = ((k % side) as f32 - m, (k / side) as f32 - m);
            *v = sample_bilinear(img, centre.0 + i, centre.1 + j)?;
        }
        let n = ((2 * half + 1) * (2 * half + 1)) as f32;
        let sum: f32 = grid(half).map(|u| t.at(u)).sum();
        t.mean = sum / n;
        let ss: f32 = grid(half).map(|u| t.at(u) - t.mean).map(|d| d * d).sum();
        t.norm = ferroslam_fpu::sqrtf(ss);
        Some(t)
    }

    /// Half-size in pixels.
    pub fn half(&self) -> usize {
        self.half
    }

    /// Number of grid samples, `(2h + 1)^2`.
    pub fn len(&self) -> usize {
        (2 * self.half + 1) * (2 * self.half + 1)
    }

    /// The stored sample at integer offset `u` (margin included: `|i|, |j| <= h + 1`); 0 outside.
    pub fn at(&self, (i, j): (f32, f32)) -> f32 {
        let side = 2 * self.half + 3;
        let m = (self.half + 1) as f32;
        // Offsets are small integers held in f32; the cast is exact.
        let (x, y) = ((i + m) as usize, (j + m) as usize);
        self.values.get(y * side + x).copied().unwrap_or(0.0)
    }

    /// The central-difference gradient `(dT/dx, dT/dy)` at grid offset `u`, gray levels per pixel.
    pub fn gradient(&self, (i, j): (f32, f32)) -> (f32, f32) {
        let gx = (self.at((i + 1.0, j)) - self.at((i - 1.0, j))) * 0.5;
        let gy = (self.at((i, j + 1.0)) - self.at((i, j - 1.0))) * 0.5;
        (gx, gy)
    }

    /// ZNCC (clamped to [-1, 1]) of the template with `target` sampled at `centre + m u` over the grid, or
    /// `None` when a sample leaves the target or the sampled patch is flat.
    ///
    /// Cost: `(2h + 1)^2` bilinear samples and about 8 flops each.
    pub fn zncc(&self, target: &GrayView<'_>, centre: (f32, f32), m: &Mat2) -> Option<f32> {
        // Shifting by 128 keeps the one-pass sums small enough for f32 (|s| <= 128, n <= 441).
        let (mut s1, mut s2, mut st) = (0.0f32, 0.0f32, 0.0f32);
        for u in grid(self.half) {
            let (dx, dy) = mat_apply(m, u);
            let s = sample_bilinear(target, centre.0 + dx, centre.1 + dy)? - 128.0;
            s1 += s;
            s2 += s * s;
            st += s * (self.at(u) - self.mean);
        }
        let n = self.len() as f32;
        let var = s2 - s1 * s1 / n;
        // A patch with less than ~0.05 gray levels of spread carries no correlation.
        if var.is_nan() || var <= 1e-3 * n || self.norm.is_nan() || self.norm <= 0.0 {
            return None;
        }
        // Rounding can push a perfect match a few ulps past 1.
        Some((st / (ferroslam_fpu::sqrtf(var) * self.norm)).clamp(-1.0, 1.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_interpolates_and_checks_bounds() {
        let px = [0u8, 100, 50, 150];
        let img = GrayView::packed(&px, 2, 2).unwrap();
        assert_eq!(sample_bilinear(&img, 0.5, 0.0), Some(50.0));
        assert_eq!(sample_bilinear(&img, 0.5, 0.5), Some(75.0));
        assert_eq!(sample_bilinear(&img, 1.0, 1.0), Some(150.0));
        assert_eq!(sample_bilinear(&img, 1.01, 0.0), None);
        assert_eq!(sample_bilinear(&img, -0.01, 0.0), None);
        assert_eq!(sample_bilinear(&img, f32::NAN, 0.0), None);
        assert_eq!(sample_bilinear(&img, f32::INFINITY, 0.0), None);
    }
}
