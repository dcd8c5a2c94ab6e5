//! [`match_region`]: coarse-to-fine search over the affine bank, Lucas-Kanade refinement, ZNCC and
//! forward-backward acceptance.

use super::affine::{IDENTITY, Mat2, mat_apply, mat_inverse};
use super::patch::{MAX_HALF_SIZE, Template};
use super::refine::refine_affine;
use super::search::{MAX_COARSE_STEPS, search};
use super::{MatchError, MatchParams};
use crate::image::GrayView;

/// A region of `I_i` matched into `I_{i+1}`: the affine map
/// `T(p) = centre_in_target + affine (p - centre)` (pixels), which equals
/// `predicted + offset + affine (p - centre)`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RegionMatch {
    /// The linear part `A` of the map (bank map times initial guess, then refined), row-major.
    pub affine: Mat2,
    /// ROI centre `c` in the template image, pixels.
    pub centre: (f32, f32),
    /// Where the ROI centre lands in the target, `c' + d`, pixels.
    pub centre_in_target: (f32, f32),
    /// `d`: `centre_in_target` minus the predicted centre `c'`, pixels.
    pub offset: (f32, f32),
    /// ZNCC of the template and the refined warped target patch, in [-1, 1].
    pub zncc: f32,
    /// Forward-backward distance, pixels; `None` when the check was skipped.
    pub forward_backward_px: Option<f32>,
}

impl RegionMatch {
    /// The image motion of the ROI centre, `centre_in_target - centre`, pixels.
    pub fn translation(&self) -> (f32, f32) {
        (self.centre_in_target.0 - self.centre.0, self.centre_in_target.1 - self.centre.1)
    }

    /// Maps a point `p` of the template image (e.g. a feature inside the ROI) into the target:
    /// `centre_in_target + affine (p - centre)`, pixels.
    pub fn map_point(&self, p: (f32, f32)) -> (f32, f32) {
        let (dx, dy) = mat_apply(&self.affine, (p.0 - self.centre.0, p.1 - self.centre.1));
        (self.centre_in_target.0 + dx, self.centre_in_target.1 + dy)
    }
}

/// Checks `p` and the centres for values the search cannot use.
fn validate(p: &MatchParams, centre: (f32, f32), predicted: (f32, f32)) -> Result<(), MatchError> {
    let ok = (1..=MAX_HALF_SIZE).contains(&p.half_size)
        && p.coarse_step >= 1
        && p.coarse_step <= 64
        && p.search_radius / p.coarse_step.max(1) <= MAX_COARSE_STEPS
        && p.min_peak_margin.is_none_or(f32::is_finite)
        && !p.bank.is_empty()
        && mat_inverse(&p.initial_affine).is_some()
        && p.min_template_std.is_finite()
        && p.min_zncc.is_finite()
        && p.lk_epsilon_px.is_finite()
        && p.max_refine_shift_px.is_finite()
        && p.forward_backward_max_px.is_none_or(f32::is_finite)
        && centre.0.is_finite()
        && centre.1.is_finite()
        && predicted.0.is_finite()
        && predicted.1.is_finite();
    if ok { Ok(()) } else { Err(MatchError::InvalidParams) }
}

/// The one-way match: search, refine, score. Shared by the forward and the backward pass.
fn match_one_way(
    template_img: &GrayView<'_>,
    centre: (f32, f32),
    target: &GrayView<'_>,
    predicted: (f32, f32),
    p: &MatchParams,
    bank: &[Mat2],
) -> Result<RegionMatch, MatchError> {
    let t = Template::extract(template_img, centre, p.half_size)
        .ok_or(MatchError::TemplateOutOfImage)?;
    let std_dev = t.norm / ferroslam_fpu::sqrtf(t.len() as f32);
    if std_dev.is_nan() || std_dev < p.min_template_std {
        return Err(MatchError::FlatTemplate { std_dev });
    }
    let found = search(&t, target, predicted, p, bank).ok_or(MatchError::NoCandidate)?;
    if let (Some(margin), Some(second)) = (p.min_peak_margin, found.second_peak)
        && second > found.coarse_peak - margin
    {
        return Err(MatchError::Ambiguous { best: found.coarse_peak, second });
    }
    let best = found.best;
    let start = (predicted.0 + best.offset.0 as f32, predicted.1 + best.offset.1 as f32);
    let (c, a) =
        refine_affine(&t, target, start, best.affine, p.lk_max_iterations, p.lk_epsilon_px)
            .ok_or(MatchError::RefinementFailed)?;
    let (sx, sy) = (c.0 - start.0, c.1 - start.1);
    let shift2 = sx * sx + sy * sy;
    if shift2.is_nan() || shift2 > p.max_refine_shift_px * p.max_refine_shift_px {
        return Err(MatchError::RefinementFailed);
    }
    let zncc = t.zncc(target, c, &a).ok_or(MatchError::RefinementFailed)?;
    if zncc.is_nan() || zncc < p.min_zncc {
        return Err(MatchError::LowCorrelation { zncc });
    }
    Ok(RegionMatch {
        affine: a,
        centre,
        centre_in_target: c,
        offset: (c.0 - predicted.0, c.1 - predicted.1),
        zncc,
        forward_backward_px: None,
    })
}

/// Matches the square ROI of `template_img` centred at `centre` into `target`, searching around
/// the `predicted` centre (from a motion model). All coordinates are pixels, origin at the
/// top-left pixel's centre.
///
/// Runs the coarse-to-fine search over the bank (see the module documentation for the stages and
/// their cost), refines the winner by affine Lucas-Kanade, and accepts it when its ZNCC is at least
/// [`MatchParams::min_zncc`] and, unless disabled, the match from `target` back to
/// `template_img` (predicted by the reversed motion `centre - predicted`, with the inverse map as
/// its only bank entry) lands within [`MatchParams::forward_backward_max_px`] of `centre`.
/// Candidates whose samples leave the target are skipped, never read out of bounds.
///
/// # Errors
/// [`MatchError::InvalidParams`], [`MatchError::TemplateOutOfImage`],
/// [`MatchError::FlatTemplate`], [`MatchError::NoCandidate`], [`MatchError::Ambiguous`],
/// [`MatchError::RefinementFailed`], [`MatchError::LowCorrelation`] or
/// [`MatchError::ForwardBackward`], as each one describes.
pub fn match_region(
    template_img: &GrayView<'_>,
    centre: (f32, f32),
    target: &GrayView<'_>,
    predicted: (f32, f32),
    params: &MatchParams,
) -> Result<RegionMatch, MatchError> {
    validate(params, centre, predicted)?;
    let mut m = match_one_way(template_img, centre, target, predicted, params, params.bank)?;
    let Some(max_fb) = params.forward_backward_max_px else {
        return Ok(m);
    };
    let inverse = mat_inverse(&m.affine).ok_or(MatchError::RefinementFailed)?;
    let back_params = MatchParams { initial_affine: inverse, min_template_std: 0.0, ..*params };
    // The reversed motion model: the forward prediction moved `centre` by `predicted - centre`.
    let back_predicted = (
        m.centre_in_target.0 - (predicted.0 - centre.0),
        m.centre_in_target.1 - (predicted.1 - centre.1),
    );
    let back = match_one_way(
        target,
        m.centre_in_target,
        template_img,
        back_predicted,
        &back_params,
        &[IDENTITY],
    )
    .map_err(|_| MatchError::ForwardBackward { error_px: f32::INFINITY })?;
    let (ex, ey) = (back.centre_in_target.0 - centre.0, back.centre_in_target.1 - centre.1);
    let error_px = ferroslam_fpu::sqrtf(ex * ex + ey * ey);
    if error_px.is_nan() || error_px > max_fb {
        return Err(MatchError::ForwardBackward { error_px });
    }
    m.forward_backward_px = Some(error_px);
    Ok(m)
}
