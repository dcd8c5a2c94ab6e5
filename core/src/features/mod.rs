//! Fast-Hessian features (SURF's detector): box-filter det(H) on an integral image, 3x3x3
//! non-maximum suppression over position and scale, sub-pixel and sub-scale refinement, and grid
//! bucketing so that the kept features spread evenly over the frame.
//!
//! # Pipeline
//!
//! Two pyramid levels are scanned one after the other ([`LEVELS`]): the image, then its 2x2 mean
//! (rounded as [`crate::image::downsample_gray_2x`] does, made row by row and never held). On
//! each level:
//!
//! 1. A rolling integral image of the last [`INTEGRAL_RING_ROWS`] (32) rows, modulo 2^16: each
//!    row is added once, so neither a full-frame integral image (307 KB at 320x240) nor the
//!    half-size image is ever held. Every box sum the filters take is below 2^16 (they are
//!    summed lobe by lobe), so wrapping `u16` arithmetic gives it exactly.
//! 2. SURF's first octave: the box-filter second derivatives `Dxx`, `Dyy`, `Dxy` of four filter
//!    sizes ([`LEVEL_FILTER_SIZES`]: 9/15/21/27 pixels of the level), normalized by the filter
//!    area, give `det(H) = Dxx*Dyy - (0.9*Dxy)^2`. The image is sampled every second pixel
//!    (SURF's `init_sample = 2`), its 2x2 mean every pixel ([`LEVEL_STEPS`]): filter sizes 9-27
//!    and 18-54 of the image, both every second image pixel.
//! 3. Only the two middle layers (15 and 21) can hold a maximum, so only their response rows are
//!    computed and kept (three rows each, enough for non-maximum suppression one row behind),
//!    and `Dxy` only where `Dxx*Dyy` exceeds the threshold (det(H) cannot exceed it elsewhere).
//!    A middle-layer sample above the threshold that beats its 8 neighbours in its own layer and
//!    9 in the other middle layer is then compared with the 9 samples of the outer layer (9 or
//!    27), evaluated on demand from the integral rows: the outer layers are never computed whole.
//! 4. A 3D quadratic (Taylor) fit refines position and scale, and the candidate is dropped if any
//!    offset exceeds one sample (as OpenCV's SURF does; the maximum is unique in its 3x3x3
//!    neighbourhood, ties going to the first sample in scan order, so no neighbour reports it).
//! 5. Candidates go into a grid of cells; each cell keeps its strongest ones (see
//!    [`HessianParams::per_cell_cap`] for the selection rule).
//!
//! The result is bit-identical to a full-frame computation of all four layers of both levels (the
//! unit tests check this against a full-frame reference): box sums are exact integers, the
//! values skipped in steps 3 are provably below every candidate, and every float is computed by
//! the same expressions in the same order, with `+ - * /` only (no fused multiply-add). Sampling
//! every second pixel costs no accuracy on blobs: the fit places Gaussian blobs within 0.1 pixel
//! (unit tests).
//!
//! # Cost
//!
//! Per frame: one integral update per pixel of both levels, then two `Dxx`/`Dyy` evaluations (16
//! integral reads each) per sample, a quarter of the image's pixels per level. On 7-Scenes QVGA
//! frames [`HessianDetector::detect`] costs about 4.2 M host x86-64 instructions (the
//! `detect_bench` example under callgrind) and yields about 140 features at the front end's
//! threshold of 30. On the Cortex-M4 a keyframe's detection (about 55,000 middle-layer samples)
//! costs about 5.8 M instructions, 3.3 M of them for `Dxx`/`Dyy` and the threshold test (about 60
//! per sample, in two passes, see the filter module). How it got there: docs/decisions.md,
//! "Fast-Hessian detector cost".
//!
//! # Memory
//!
//! [`HessianDetector<W>`] owns all scratch; place it in a `static` or initialize it in place.
//! Its size is `2*W*INTEGRAL_RING_ROWS` bytes of integral rows, `4*W*3` bytes of middle-layer
//! response rows, `W` bytes of marks (a bit per middle-layer sample above the threshold, for
//! suppression to visit only those) and about `16*MAX_GRID_CELLS*MAX_PER_CELL` bytes of cell
//! candidates: [`QvgaHessianDetector`] (W = 320) is 37,032 bytes (about 36 KiB),
//! [`VgaHessianDetector`] (W = 640) 61,672 bytes. The output vector
//! (`MAX_FEATURES_PER_FRAME` x 20 bytes = 10,240 bytes) belongs to the caller.

mod bucket;
mod descriptor;
mod filter;
mod hessian;
mod refine;
mod rolling_integral;

#[cfg(test)]
mod tests;

pub use bucket::{MAX_GRID_CELLS, MAX_PER_CELL};
pub use descriptor::Descriptor;
pub use filter::{INTEGRAL_RING_ROWS, LEVEL_FILTER_SIZES, LEVEL_STEPS, LEVELS};
pub use hessian::{HessianDetector, QvgaHessianDetector, VgaHessianDetector};

use crate::config::capacity::MAX_FEATURES_PER_FRAME;
use core::fmt;

/// The features of one frame, as [`HessianDetector::detect`] returns them.
pub type FeatureVec = heapless::Vec<Feature, MAX_FEATURES_PER_FRAME>;

/// One detected interest point.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Feature {
    /// Column, in pixels; pixel centres are at integers, 0 at the left pixel's centre.
    pub x: f32,
    /// Row, in pixels; pixel centres are at integers, 0 at the top pixel's centre.
    pub y: f32,
    /// Scale as SURF's Gaussian sigma, in pixels: `1.2 * filter_size / 9` at the refined filter
    /// size in image pixels (on the 2x2 mean image, twice its size there). For a Gaussian blob of
    /// standard deviation `s` it is about `0.75 * s` (measured: the box filters are wider than
    /// the Gaussians this rule assigns them).
    pub scale: f32,
    /// det(H) of the area-normalized box filters at the detection sample, in (gray levels)^2.
    pub response: f32,
    /// The sign of the Laplacian (trace of H): `true` for a dark blob on a bright background,
    /// `false` for a bright blob on a dark background. Only features of equal sign can match.
    pub laplacian_positive: bool,
}

/// Why detection could not run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FeatureError {
    /// The image is wider than the detector's workspace.
    ImageTooWide {
        /// Width of the image, in pixels.
        width: usize,
        /// Widest image the detector accepts, in pixels.
        max: usize,
    },
    /// A [`HessianParams`] field is out of its documented range.
    InvalidParams {
        /// Name of the offending field.
        field: &'static str,
    },
}

impl fmt::Display for FeatureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::ImageTooWide { width, max } => {
                write!(f, "image is {width} pixels wide, the detector accepts at most {max}")
            }
            Self::InvalidParams { field } => {
                write!(f, "detector parameter `{field}` is out of range")
            }
        }
    }
}

impl core::error::Error for FeatureError {}

/// Run-time settings of the Fast-Hessian detector and its grid bucketing.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HessianParams {
    /// Minimum det(H) of a feature, in (gray levels)^2 with the box filters normalized by their
    /// area (OpenCV's `hessianThreshold` scale). Finite and `>= 0`. Default 100.
    pub threshold: f32,
    /// Pyramid levels scanned ([`LEVELS`]): 1 (the image: filter sizes 9-27, maxima at sigma
    /// 2.0-2.8 px, refined within 1.2-3.6) or 2 (adds its 2x2 mean: sizes 18-54 of the image,
    /// maxima at sigma 4.0-5.6 px, refined within 2.4-7.2). Default 2.
    pub octaves: u8,
    /// Grid columns for bucketing, `>= 1`. Default 8.
    pub grid_cols: u8,
    /// Grid rows for bucketing, `>= 1`; `grid_cols * grid_rows <= MAX_GRID_CELLS`. Default 6.
    pub grid_rows: u8,
    /// Most features kept per grid cell, `1..=MAX_PER_CELL`. Default 12.
    ///
    /// Selection rule: every cell keeps its `per_cell_cap` strongest candidates; then features are
    /// taken in rounds, round `k` taking each cell's `k`-th strongest, until `max_features` is
    /// reached. A cell with few candidates drops out of later rounds, so its unused share goes to
    /// the other cells (never beyond their cap). When the last round does not fit, its strongest
    /// candidates win. Ties are broken by response, then row, column and scale (smaller first).
    pub per_cell_cap: u8,
    /// Total features kept, `1..=MAX_FEATURES_PER_FRAME`. Default 512.
    pub max_features: u16,
}

impl HessianParams {
    /// The defaults, usable in `const` contexts (what [`Default`] gives).
    pub const DEFAULT: Self = Self {
        threshold: 100.0,
        octaves: 2,
        grid_cols: 8,
        grid_rows: 6,
        per_cell_cap: 12,
        max_features: MAX_FEATURES_PER_FRAME as u16,
    };
}

impl Default for HessianParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl HessianParams {
    /// Checks every field against its documented range.
    ///
    /// # Errors
    /// [`FeatureError::InvalidParams`] naming the first offending field.
    pub fn validate(&self) -> Result<(), FeatureError> {
        let bad = |field| Err(FeatureError::InvalidParams { field });
        if !self.threshold.is_finite() || self.threshold < 0.0 {
            return bad("threshold");
        }
        if self.octaves == 0 || usize::from(self.octaves) > LEVELS {
            return bad("octaves");
        }
        if self.grid_cols == 0 || self.grid_rows == 0 {
            return bad("grid_cols/grid_rows");
        }
        if usize::from(self.grid_cols) * usize::from(self.grid_rows) > MAX_GRID_CELLS {
            return bad("grid_cols/grid_rows");
        }
        if self.per_cell_cap == 0 || usize::from(self.per_cell_cap) > MAX_PER_CELL {
            return bad("per_cell_cap");
        }
        if self.max_features == 0 || usize::from(self.max_features) > MAX_FEATURES_PER_FRAME {
            return bad("max_features");
        }
        Ok(())
    }
}
