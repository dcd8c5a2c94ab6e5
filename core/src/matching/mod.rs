//! Region matching (paper Sec. II.A, III): an ROI template from frame `I_i` is tried under a bank of
//! affine transforms (the paper's "transformation network") over a search window in `I_{i+1}`, then
//! refined to sub-pixel by inverse-compositional affine Lucas-Kanade. Every feature inside the ROI
//! follows the winning map `T(p) = c' + d + A (p - c)` into the next frame.
//!
//! - [`select_rois`]: square ROIs centred where the image variation `v_m` of Eq. 3 is high, one per
//!   grid cell (so they never overlap and spread over the image), best first, up to a fixed cap.
//! - [`match_region`]: one ROI into the next frame, returning a [`RegionMatch`] (the affine map, its
//!   translation, the ZNCC score) or a [`MatchError`] saying why the match was rejected.
//! - [`AFFINE_BANK`]: the fixed bank of 45 maps (3 scales x 5 rotations x 3 shears).
//! - [`track_patch`]: the cheap path when the motion is predicted: the bank reduced to the one
//!   map the prediction induces, a small integer search, translation Lucas-Kanade (module
//!   `track`). About 400 times cheaper than [`match_region`]; the front end uses it for every
//!   landmark and keeps [`match_region`] for recovery when the prediction is poor.
//!
//! # Pipeline and cost of one [`match_region`] call
//!
//! With `h` the template half-size, `n = (2h + 1)^2` template samples, `R` the search radius,
//! `s` the coarse step, `K` the coarse candidates kept and `B` the bank size:
//!
//! 1. coarse: the initial map `A0` alone at offsets `-R..=R` in steps of `s`:
//!    `(2 floor(R/s) + 1)^2` candidates (`R / s <= 8`). If another local maximum of this scan
//!    comes within [`MatchParams::min_peak_margin`] of the best, the match is rejected as
//!    [`MatchError::Ambiguous`] (repeated patterns);
//! 2. bank: every bank map `B_k A0` at each of the `K` best coarse offsets: `K B` candidates;
//! 3. fine: the best map at the integer offsets within `s - 1` of the best offset: `(2s - 1)^2`;
//! 4. refinement: at most `lk_max_iterations` Lucas-Kanade steps of `n` samples each, and one final
//!    ZNCC (`n` samples);
//! 5. forward-backward: the same search from `I_{i+1}` back to `I_i` with the bank reduced to the
//!    inverse of the winning map (steps 1, 3 and 4 only).
//!
//! Each candidate costs `n` bilinear samples (4 pixel reads, 8 flops) plus 6 flops of ZNCC sums.
//! With the defaults (`h = 7`, `n = 225`, `R = 8`, `s = 2`, `K = 2`, `B = 45`): 81 + 90 + 9 = 180
//! candidates = 40,500 samples forward, 81 + 1 + 9 = 91 candidates = 20,475 samples backward, and
//! Lucas-Kanade at most 2 x 16 x 225 = 7,200 samples (it typically converges in 3-6 steps): at
//! most ~68,000 bilinear samples, about 1 M flops, per ROI. Without the forward-backward check:
//! at most ~44,500 samples. The ambiguity scan adds ~81 x 9 comparisons.
//!
//! # Memory
//!
//! No heap. Stack per call: two templates of `(2h + 3)^2` f32 at `h <= 10` (one live at a time
//! per direction, 2116 bytes each), the coarse score grid (289 f32, 1156 bytes), one warped-patch
//! buffer of 441 f32 (1764 bytes) during refinement, and 6x6 f32 normal matrices: under 8 KB.
//!
//! # Determinism
//!
//! Plain f32 adds and multiplies in fixed orders (never `mul_add`), correctly rounded square
//! roots (`ferroslam_fpu::sqrtf`: the FPU on the board, libm on the host), the bank's sines and
//! cosines as literals; ties go to the first candidate in scan order.

mod affine;
mod patch;
mod patch_tracker;
mod refine;
mod region;
mod roi;
mod search;
#[cfg(test)]
mod tests;

use core::fmt;

pub use affine::{AFFINE_BANK, AFFINE_BANK_IDENTITY, AFFINE_BANK_LEN, IDENTITY, Mat2};
pub use patch::{MAX_HALF_SIZE, sample_bilinear};
pub use patch_tracker::{
    MAX_TRACK_COARSE_STEPS, MAX_TRACK_HALF_SIZE, MAX_TRACK_SEARCH_RADIUS, PatchTrack, TrackParams,
    TrackScratch, track_patch, track_patch_with,
};
pub use region::{RegionMatch, match_region};
pub use roi::{MAX_ROI_HALF_SIZE, Roi, RoiParams, select_rois};

/// Why a region could not be matched.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum MatchError {
    /// A parameter is out of range (half-size 0 or above [`MAX_HALF_SIZE`], zero coarse step,
    /// `search_radius / coarse_step` above 8, empty bank, non-finite threshold or centre, singular
    /// initial map).
    InvalidParams,
    /// The template (with its one-pixel margin) does not fit inside the template image.
    TemplateOutOfImage,
    /// The template is too flat to match: its gray-level standard deviation is below
    /// [`MatchParams::min_template_std`].
    FlatTemplate {
        /// Standard deviation of the template, gray levels.
        std_dev: f32,
    },
    /// No candidate of the search window lies inside the target image (or every one was flat).
    NoCandidate,
    /// The Lucas-Kanade refinement left the image, diverged or met a singular system.
    RefinementFailed,
    /// The best match correlates below [`MatchParams::min_zncc`].
    LowCorrelation {
        /// ZNCC of the refined match, in [-1, 1].
        zncc: f32,
    },
    /// The coarse scan holds a second peak within [`MatchParams::min_peak_margin`] of the best
    /// (typically a repeated pattern).
    Ambiguous {
        /// ZNCC of the best coarse candidate.
        best: f32,
        /// ZNCC of the best other local maximum of the coarse scan.
        second: f32,
    },
    /// Matching back from the target lands too far from the template centre.
    ForwardBackward {
        /// Distance between the back-matched centre and the original centre, pixels; infinite
        /// when the backward match itself was rejected.
        error_px: f32,
    },
}

impl fmt::Display for MatchError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::InvalidParams => write!(f, "invalid region-matching parameters"),
            Self::TemplateOutOfImage => write!(f, "template does not fit inside the image"),
            Self::FlatTemplate { std_dev } => {
                write!(f, "template too flat to match (std dev {std_dev} gray levels)")
            }
            Self::NoCandidate => write!(f, "no search candidate inside the target image"),
            Self::RefinementFailed => write!(f, "sub-pixel refinement failed"),
            Self::LowCorrelation { zncc } => write!(f, "best match correlates too weakly ({zncc})"),
            Self::Ambiguous { best, second } => {
                write!(f, "ambiguous match (peaks {best} and {second})")
            }
            Self::ForwardBackward { error_px } => {
                write!(f, "forward-backward check failed ({error_px} px)")
            }
        }
    }
}

impl core::error::Error for MatchError {}

/// Tunables of [`match_region`]. All distances are in pixels of the images passed in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchParams {
    /// Template half-size `h`: the template is `(2h + 1)` pixels square. 1..=[`MAX_HALF_SIZE`];
    /// default 7 (15 x 15 at QVGA).
    pub half_size: usize,
    /// Search radius `R` around the predicted centre, pixels (each axis); default 8.
    /// `R / coarse_step` may be at most 8.
    pub search_radius: usize,
    /// Coarse step `s` of the first, identity-map search stage, pixels (1..=64); default 2.
    pub coarse_step: usize,
    /// Coarse offsets kept for the bank stage, 1..=4; default 2.
    pub coarse_candidates: usize,
    /// The bank of maps tried around the initial map; default [`AFFINE_BANK`].
    pub bank: &'static [Mat2],
    /// Initial guess `A0` of the linear part (e.g. the predicted map from an older keyframe to the
    /// target); the bank is tried as `B_k A0`. Default [`IDENTITY`].
    pub initial_affine: Mat2,
    /// Templates whose gray-level standard deviation is below this are rejected as flat; default
    /// 3.0 gray levels.
    pub min_template_std: f32,
    /// Matches whose refined ZNCC is below this are rejected; default 0.8.
    pub min_zncc: f32,
    /// Most Lucas-Kanade iterations; default 16.
    pub lk_max_iterations: usize,
    /// Lucas-Kanade stops when the translation update is below this, pixels; default 0.002.
    pub lk_epsilon_px: f32,
    /// Refinement may move the centre at most this far from the best search candidate, pixels;
    /// default 2.0.
    pub max_refine_shift_px: f32,
    /// Ambiguity test: the match is rejected when another local maximum of the coarse scan (more
    /// than one coarse step from the best) scores within this ZNCC margin of the best. `None`
    /// skips the test; default `Some(0.05)`.
    pub min_peak_margin: Option<f32>,
    /// Forward-backward check: the back-matched centre must land within this distance of the
    /// template centre, pixels. `None` skips the check (about a third of the cost of a match);
    /// default `Some(0.5)`.
    pub forward_backward_max_px: Option<f32>,
}

impl MatchParams {
    /// The defaults, usable in `const` contexts (what [`Default`] gives).
    pub const DEFAULT: Self = Self {
        half_size: 7,
        search_radius: 8,
        coarse_step: 2,
        coarse_candidates: 2,
        bank: &AFFINE_BANK,
        initial_affine: IDENTITY,
        min_template_std: 3.0,
        min_zncc: 0.8,
        lk_max_iterations: 16,
        lk_epsilon_px: 0.002,
        max_refine_shift_px: 2.0,
        min_peak_margin: Some(0.05),
        forward_backward_max_px: Some(0.5),
    };
}

impl Default for MatchParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}
