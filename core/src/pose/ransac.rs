//! RANSAC over minimal 3D-3D sets for when the predicted pose is poor, and [`track_pose`], which
//! tries the prediction first.

use nalgebra::Point3;

use super::refine::MIN_CORRESPONDENCES;
use super::{
    Correspondence, InlierMask, PoseError, PoseEstimate, PoseParams, refine_pose, validate_input,
};
use crate::geometry::{PinholeCamera, Pose, align_rigid};

/// A small deterministic random generator (xorshift64*, Vigna 2016) for RANSAC sampling.
///
/// The caller owns it and seeds it, so a replay with the same seed draws the same samples on
/// every target; there is no global generator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackingRng(u64);

impl TrackingRng {
    /// A generator from `seed`; zero (a fixed point of xorshift) is mapped to a constant.
    pub const fn new(seed: u64) -> Self {
        Self(if seed == 0 { 0x9E37_79B9_7F4A_7C15 } else { seed })
    }

    /// The next 32 random bits (the high half of the xorshift64* output).
    pub fn next_u32(&mut self) -> u32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 32) as u32
    }

    /// Uniform in `0..n` (Lemire's multiply-shift; bias below 2^-32 * n); 0 when `n == 0`.
    pub fn below(&mut self, n: usize) -> usize {
        let n = n.min(u32::MAX as usize) as u64;
        ((u64::from(self.next_u32()) * n) >> 32) as usize
    }
}

/// Three distinct uniform indices in `0..n` (`n >= 3`).
fn sample3(rng: &mut TrackingRng, n: usize) -> [usize; 3] {
    let a = rng.below(n);
    let mut b = rng.below(n - 1);
    if b >= a {
        b += 1;
    }
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    let mut c = rng.below(n - 2);
    if c >= lo {
        c += 1;
    }
    if c >= hi {
        c += 1;
    }
    [a, b, c]
}

/// The hypothesis `t_cw` from the depth-carrying correspondences of ranks `ranks` (their order
/// among those with depth): the observed pixels back-projected with their depths, aligned to the
/// map points. `None` for a degenerate sample.
fn hypothesis(camera: &PinholeCamera, corrs: &[Correspondence], ranks: [usize; 3]) -> Option<Pose> {
    let mut src = [Point3::origin(); 3];
    let mut dst = [Point3::origin(); 3];
    for ((rank, s), d) in ranks.iter().zip(src.iter_mut()).zip(dst.iter_mut()) {
        let c = corrs.iter().filter(|c| c.depth_m.is_some()).nth(*rank)?;
        *s = c.p_w;
        *d = camera.back_project(c.uv.x, c.uv.y, c.depth_m?);
    }
    // align_rigid maps src (world) onto dst (camera): exactly t_cw.
    align_rigid(&src, &dst).ok()
}

/// Reprojection inliers of `t_cw` (2-DOF chi-square gate only).
fn score(
    camera: &PinholeCamera,
    corrs: &[Correspondence],
    t_cw: &Pose,
    params: &PoseParams,
) -> InlierMask {
    let gate_px2 =
        params.chi2_reprojection * (params.sensor.pixel_sigma_px * params.sensor.pixel_sigma_px);
    let mut mask = InlierMask::new();
    for (i, c) in corrs.iter().enumerate() {
        let Some(uv) = camera.project_world(t_cw, &c.p_w) else { continue };
        if (uv - c.uv).norm_squared() <= gate_px2 {
            mask.insert(i);
        }
    }
    mask
}

/// Hypotheses needed to draw an all-inlier triple with `confidence` when a fraction
/// `inlier_ratio` is inliers, capped at `cap`.
fn needed_iterations(inlier_ratio: f32, confidence: f32, cap: u32) -> u32 {
    let p_good = inlier_ratio * inlier_ratio * inlier_ratio;
    if p_good >= 1.0 {
        return 1;
    }
    if p_good.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
        return cap;
    }
    let n = libm::logf(1.0 - confidence) / libm::logf(1.0 - p_good);
    // Beyond the cap (or NaN) keeps the cap; `n > 0` since both logarithms are negative.
    if n < cap as f32 { (libm::ceilf(n) as u32).max(1) } else { cap }
}

/// Estimates `t_cw` without a prior: RANSAC over triples of depth-carrying correspondences,
/// then [`refine_pose`] from the best hypothesis on its inliers.
///
/// Each hypothesis back-projects three observed pixels with their depths and aligns them to
/// their map points ([`align_rigid`]); it is scored by the number of correspondences whose
/// reprojection passes [`PoseParams::chi2_reprojection`] (first best kept on ties). Sampling
/// draws from `rng` only; at most [`PoseParams::ransac_iterations`] hypotheses, fewer once
/// [`PoseParams::ransac_confidence`] is reached for the best inlier ratio (over all
/// correspondences). Cost per hypothesis: one pass projecting every correspondence. Stack:
/// two [`InlierMask`]s and the refinement's.
///
/// # Errors
/// Those of [`refine_pose`]; [`PoseError::TooFewCorrespondences`] with fewer than 3
/// depth-carrying correspondences; [`PoseError::NoConsensus`] if no hypothesis reaches
/// [`PoseParams::min_inliers`] (also when every sample is degenerate).
pub fn ransac_pose(
    camera: &PinholeCamera,
    correspondences: &[Correspondence],
    params: &PoseParams,
    rng: &mut TrackingRng,
) -> Result<PoseEstimate, PoseError> {
    validate_input(correspondences)?;
    if !params.is_valid() {
        return Err(PoseError::InvalidParams);
    }
    let with_depth = correspondences.iter().filter(|c| c.depth_m.is_some()).count();
    if with_depth < MIN_CORRESPONDENCES {
        return Err(PoseError::TooFewCorrespondences {
            count: with_depth,
            required: MIN_CORRESPONDENCES,
        });
    }
    let mut best: Option<(Pose, InlierMask, usize)> = None;
    let mut needed = params.ransac_iterations;
    let mut done = 0;
    while done < needed {
        done += 1;
        let Some(t_cw) = hypothesis(camera, correspondences, sample3(rng, with_depth)) else {
            continue;
        };
        let mask = score(camera, correspondences, &t_cw, params);
        let count = mask.count();
        if best.as_ref().is_none_or(|(_, _, n)| count > *n) {
            best = Some((t_cw, mask, count));
            // Both counts are at most 512: exact in f32.
            let ratio = count as f32 / correspondences.len() as f32;
            needed = needed_iterations(ratio, params.ransac_confidence, params.ransac_iterations);
        }
    }
    let required = (params.min_inliers as usize).max(MIN_CORRESPONDENCES);
    match best {
        Some((t_cw, mask, count)) if count >= required => {
            refine_pose(camera, correspondences, &t_cw, Some(&mask), params)
        }
        other => Err(PoseError::NoConsensus { best_inliers: other.map_or(0, |(_, _, n)| n) }),
    }
}

/// Frame-to-map pose: refine `prediction` (e.g. from the [`MotionModel`](super::MotionModel))
/// and fall back to [`ransac_pose`] when there is none, when refining it fails, or when it keeps
/// fewer than [`PoseParams::min_inlier_ratio`] of the correspondences.
///
/// Of two valid estimates (refined prediction with a low ratio, RANSAC) the one with more inliers
/// wins; the prediction's on ties.
///
/// # Errors
/// Input and parameter errors as [`refine_pose`]; otherwise RANSAC's error when neither path
/// gives a valid pose.
pub fn track_pose(
    camera: &PinholeCamera,
    correspondences: &[Correspondence],
    prediction: Option<&Pose>,
    params: &PoseParams,
    rng: &mut TrackingRng,
) -> Result<PoseEstimate, PoseError> {
    validate_input(correspondences)?;
    if !params.is_valid() {
        return Err(PoseError::InvalidParams);
    }
    // Input and parameters are valid, so a failure here is about the prediction: fall back.
    let predicted =
        prediction.and_then(|t_cw| refine_pose(camera, correspondences, t_cw, None, params).ok());
    if let Some(est) = &predicted {
        // Counts are at most 512: exact in f32.
        let ratio = est.num_inliers as f32 / correspondences.len() as f32;
        if ratio >= params.min_inlier_ratio {
            return Ok(*est);
        }
    }
    match (predicted, ransac_pose(camera, correspondences, params, rng)) {
        (Some(p), Ok(r)) => Ok(if r.num_inliers > p.num_inliers { r } else { p }),
        (Some(p), Err(_)) => Ok(p),
        (None, result) => result,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_are_distinct_and_in_range() {
        let mut rng = TrackingRng::new(0);
        let mut hits = [0u32; 5];
        for _ in 0..3000 {
            let [a, b, c] = sample3(&mut rng, 5);
            assert!(a != b && b != c && a != c && a < 5 && b < 5 && c < 5);
            for i in [a, b, c] {
                hits[i] += 1;
            }
        }
        // Each index in 3/5 of the draws.
        assert!(hits.iter().all(|&h| (1650..1950).contains(&h)), "{hits:?}");
    }

    #[test]
    fn iteration_count_follows_the_ransac_formula() {
        assert_eq!(needed_iterations(0.0, 0.99, 100), 100);
        assert_eq!(needed_iterations(1.0, 0.99, 100), 1);
        assert_eq!(needed_iterations(f32::NAN, 0.99, 100), 100);
        // ln(0.01) / ln(1 - 0.5^3) = 34.5
        assert_eq!(needed_iterations(0.5, 0.99, 100), 35);
        assert_eq!(needed_iterations(0.1, 0.99, 100), 100);
    }
}
