//! The front end's matching stages (guides, bank recovery, final stage) and the local map's
//! per-frame bookkeeping; see the module documentation of `frontend.rs`.

use nalgebra::Point2;

use super::GuideStage;
use super::tracker::FrameTracker;
use crate::frame::RgbdFrame;
use crate::geometry::{PinholeCamera, Pose, camera_gap};
use crate::grid_spread::{Candidate, Grid, spread};
use crate::map::Map;
use crate::matching::{
    MatchError, MatchParams, TrackParams, TrackScratch, match_region, track_patch_with,
};
use crate::pose::small_image_rotation::estimate_rotation;
use crate::pose::{Correspondence, PoseEstimate, PoseParams, TrackingRng, track_pose};

/// Grid the guides are spread over (columns, rows).
const GUIDE_GRID: (usize, usize) = (4, 3);
/// Grid the final stage's landmarks are spread over (columns, rows).
const TRACK_GRID: (usize, usize) = (8, 6);

/// A final stage with fewer inliers than this fraction of the previous frame's is weak: the next
/// attempt follows (the first attempt's own fraction is [`PREDICTION_FRACTION`]).
const WEAK_FRACTION: f32 = 0.6;

/// The first attempt of [`ATTEMPTS`], the final stage straight from the motion model's
/// prediction, is kept when it has at least this fraction of the previous frame's inliers; below
/// it the guides follow, and the strongest final stage wins. The guides (24 landmarks searched
/// at radius 3, each about twice a final-stage track) are thus paid for only on frames the
/// prediction serves poorly.
///
/// Why 0.8, and why a weak prediction is not kept when a keyframe is due: docs/decisions.md,
/// "Prediction tried before the guides".
const PREDICTION_FRACTION: f32 = 0.8;

/// When the motion model predicts a turn of more than this since the last frame (1 degree), the
/// guides go first ([`GUIDES_FIRST`]): on fast turns the prediction alone serves poorly. Why this
/// value: docs/decisions.md, "Guides first on a fast turn".
const GUIDES_FIRST_TURN_RAD: f32 = core::f32::consts::PI / 180.0;

/// A weak final stage whose pose is within this distance (metres) and [`AGREE_RAD`] of the best
/// weak one before it agrees with it: two start poses gave the same pose, so the frame holds few
/// trackable landmarks rather than a wrong start, and no later attempt is run; the stronger of
/// the two wins. Both bounds are about a pixel at QVGA: 5 mm at 1.5 m, 0.25 degrees at a
/// 265-pixel focal length. Why: docs/decisions.md, "Attempts stop when two agree".
const AGREE_M: f32 = 0.005;

/// The angle (radians) of [`AGREE_M`]'s agreement: 0.25 degrees.
const AGREE_RAD: f32 = 0.25 * core::f32::consts::PI / 180.0;

/// One way to find the final stage's start pose.
#[derive(Clone, Copy)]
enum Attempt {
    /// Guides matched from a prediction (the motion model's, or the small-image rotation's for
    /// that stage), wide search or not, or by the bank for [`GuideStage::AffineBank`].
    Guides(GuideStage, bool),
    /// The prediction itself (the motion model's, or the small-image rotation's for that stage).
    Prediction(GuideStage),
}

/// The attempts in order of cost (see [`Frontend::match_landmarks`]); on a frame turning fast,
/// [`GUIDES_FIRST`]. The last, the affine bank, runs only when no earlier attempt gave a pose at
/// all, weak or not: its 24 region matches cost about ten final stages, so it is kept for frames
/// that would be lost otherwise. A weak pose (at least `min_inliers` inliers) is tracking; the
/// keyframe rule then renews the local map. Why: docs/decisions.md, "Affine bank only when nothing
/// else gave a pose".
const ATTEMPTS: [Attempt; 6] = [
    Attempt::Prediction(GuideStage::MotionModel),
    Attempt::Guides(GuideStage::MotionModel, false),
    Attempt::Guides(GuideStage::SmallImageRotation, false),
    Attempt::Prediction(GuideStage::SmallImageRotation),
    Attempt::Guides(GuideStage::MotionModel, true),
    Attempt::Guides(GuideStage::AffineBank, false),
];

/// The order on a frame the motion model predicts turning faster than [`GUIDES_FIRST_TURN_RAD`]:
/// the guides from the motion model before the prediction itself.
const GUIDES_FIRST: [Attempt; 6] = {
    let mut attempts = ATTEMPTS;
    attempts.swap(0, 1);
    attempts
};

/// What [`Frontend::match_landmarks`] did.
#[derive(Debug, Clone, Copy)]
pub(super) struct MatchSummary {
    /// Correspondences of the final stage.
    pub matches: usize,
    /// Guide matches.
    pub guides: usize,
    /// The guide attempt that gave the start pose.
    pub stage: GuideStage,
    /// The pose, when tracking succeeded (enough matches and inliers).
    pub estimate: Option<PoseEstimate>,
}

/// Whether [`Frontend::match_landmarks`] runs the affine bank: last, as [`ATTEMPTS`] says; not
/// at all (a place memory is asked first, the cheaper re-acquisition); or alone (after the place
/// memory found nothing).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Bank {
    Last,
    Skip,
    Only,
}

/// How one landmark is matched: the predicted-warp patch tracker, or the affine bank.
#[derive(Clone, Copy)]
enum Matcher<'a> {
    Patch(&'a TrackParams),
    Bank(&'a MatchParams),
}

impl Matcher<'_> {
    /// Pixels a predicted position must keep from the border for the search to fit.
    fn margin(&self) -> f32 {
        match self {
            Self::Patch(t) => (t.half_size + t.search_radius + 1) as f32,
            Self::Bank(m) => (m.half_size + m.search_radius + 1) as f32,
        }
    }
}

impl<const W: usize, const H: usize> FrameTracker<W, H> {
    /// Matches the local map into `frame` and estimates the pose: each attempt of the module
    /// documentation gives a start pose for the final stage, in order of cost, until a final
    /// stage is strong (at least [`WEAK_FRACTION`] of the previous frame's inliers, or
    /// [`PREDICTION_FRACTION`] for the prediction tried first) or a weak one agrees with the best
    /// weak one before it ([`AGREE_M`]); the strongest result wins, and the bank is skipped once
    /// any attempt gave a pose (see [`ATTEMPTS`] and [`GUIDES_FIRST`]).
    /// Leaves the winner's candidates, correspondences and their sources in the scratch vectors:
    /// when a later attempt (a final stage, or guides, which use the same scratch) replaced
    /// them, the winner's final stage is run again.
    pub(super) fn match_landmarks<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &Map<K, L>,
        predicted_t_cw: &Pose,
        bank: Bank,
    ) -> MatchSummary {
        let p = self.params;
        // Counts are at most 512: exact in f32.
        let previous = self.recent.inliers as f32;
        let mut best: Option<(Pose, GuideStage, usize, PoseEstimate)> = None;
        let mut last_start = None;
        let mut guides = 0;
        // The small-image rotation's prediction, computed once when first needed.
        let mut rotated: Option<Option<Pose>> = None;
        let turning = self.recent.last_t_cw().is_some_and(|prev| {
            (predicted_t_cw * prev.inverse()).rotation.angle() > GUIDES_FIRST_TURN_RAD
        });
        let order = if turning { GUIDES_FIRST } else { ATTEMPTS };
        for (i, attempt) in order.into_iter().enumerate() {
            let stage = match attempt {
                Attempt::Guides(stage, _) | Attempt::Prediction(stage) => stage,
            };
            let is_bank = stage == GuideStage::AffineBank;
            if (bank == Bank::Skip && is_bank) || (bank == Bank::Only && !is_bank) {
                continue;
            }
            let prediction = if stage == GuideStage::SmallImageRotation {
                let r =
                    *rotated.get_or_insert_with(|| self.rotation_prediction(cam, predicted_t_cw));
                match r {
                    Some(t_cw) => t_cw,
                    None => continue,
                }
            } else {
                *predicted_t_cw
            };
            let start = match attempt {
                Attempt::Guides(stage, wide) => {
                    let matcher = match (stage, wide) {
                        (GuideStage::AffineBank, _) => Matcher::Bank(&p.matching),
                        (_, true) => Matcher::Patch(&p.guide_wide),
                        (_, false) => Matcher::Patch(&p.guide),
                    };
                    if matches!(matcher, Matcher::Bank(_)) && best.is_some() {
                        break;
                    }
                    let size = frame.gray.size();
                    // The guides replace the scratch the last final stage left.
                    last_start = None;
                    self.collect_candidates(cam, map, &prediction, matcher.margin());
                    spread(&mut self.scratch.candidates, &Grid::with_cells(size, GUIDE_GRID));
                    self.scratch.candidates.truncate(p.guide_landmarks);
                    self.match_candidates(frame, cam, map, &prediction, matcher);
                    self.work.guide_runs = self.work.guide_runs.saturating_add(1);
                    guides = self.scratch.correspondences.len();
                    let corrs = &self.scratch.correspondences;
                    match guide_pose(cam, corrs, &prediction, &p, &mut self.rng) {
                        Some(t_cw) => (t_cw, stage),
                        None => continue,
                    }
                }
                Attempt::Prediction(_) => (prediction, GuideStage::None),
            };
            let (matches, estimate) = self.final_stage(frame, cam, map, &start.0);
            last_start = Some(start.0);
            let Some(est) = estimate else { continue };
            // Counts are at most 512: exact in f32.
            let fraction = match attempt {
                Attempt::Prediction(GuideStage::MotionModel) if i == 0 => PREDICTION_FRACTION,
                _ => WEAK_FRACTION,
            };
            if est.num_inliers as f32 >= fraction * previous {
                return MatchSummary { matches, guides, stage: start.1, estimate };
            }
            let agrees = best.as_ref().is_some_and(|b| poses_agree(&b.3.t_cw, &est.t_cw));
            if best.as_ref().is_none_or(|b| est.num_inliers > b.3.num_inliers) {
                best = Some((start.0, start.1, matches, est));
            }
            if agrees {
                break;
            }
        }
        let Some((start, stage, matches, est)) = best else {
            let matches = self.scratch.correspondences.len();
            return MatchSummary { matches, guides, stage: GuideStage::None, estimate: None };
        };
        if last_start == Some(start) {
            return MatchSummary { matches, guides, stage, estimate: Some(est) };
        }
        // A later attempt overwrote the scratch: redo the best one.
        let (matches, estimate) = self.final_stage(frame, cam, map, &start);
        MatchSummary { matches, guides, stage, estimate }
    }

    /// The final stage from `start`: matches and, with enough of them, the pose.
    fn final_stage<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &Map<K, L>,
        start: &Pose,
    ) -> (usize, Option<PoseEstimate>) {
        let p = self.params;
        self.work.final_stages = self.work.final_stages.saturating_add(1);
        let fine = Matcher::Patch(&p.track);
        self.collect_candidates(cam, map, start, fine.margin());
        spread(&mut self.scratch.candidates, &Grid::with_cells(frame.gray.size(), TRACK_GRID));
        self.scratch.candidates.truncate(p.max_tracked);
        self.match_candidates(frame, cam, map, start, fine);
        let matches = self.scratch.correspondences.len();
        let estimate = (matches >= p.min_matches)
            .then(|| {
                track_pose(cam, &self.scratch.correspondences, Some(start), &p.pose, &mut self.rng)
            })
            .and_then(Result::ok)
            .filter(|est| est.num_inliers >= p.min_inliers);
        (matches, estimate)
    }

    /// The last frame's pose turned by the rotation the small blurry images show between it and
    /// this frame (see [`crate::pose::small_image_rotation`]), starting from the rotation
    /// `predicted_t_cw` implies. The last frame not lost: a lost one's image and pose are not a
    /// reference.
    fn rotation_prediction(&mut self, cam: &PinholeCamera, predicted_t_cw: &Pose) -> Option<Pose> {
        let prev = self.recent.seen_t_cw?;
        self.work.rotation_estimated = true;
        let initial = (predicted_t_cw * prev.inverse()).rotation;
        let small = &self.recent;
        let r_cp = estimate_rotation(&small.small_previous, &small.small_current, cam, &initial)?;
        Some(Pose::from_parts(nalgebra::Translation3::identity(), r_cp) * prev)
    }

    /// Fills `candidates` with the local-map landmarks that `t_cw` projects at least `margin`
    /// pixels inside the image.
    fn collect_candidates<const K: usize, const L: usize>(
        &mut self,
        cam: &PinholeCamera,
        map: &Map<K, L>,
        t_cw: &Pose,
        margin: f32,
    ) {
        self.scratch.candidates.clear();
        for (i, t) in self.local.items().iter().enumerate() {
            let Some(lm) = map.landmark(t.id) else { continue };
            let Some(uv) = cam.project_world(t_cw, &lm.p_w) else { continue };
            if !cam.in_image(&uv, margin) {
                continue;
            }
            // At most MAX_TRACKED_LANDMARKS (< 65,536) items: the index fits.
            let c = Candidate::new(i as u16, uv, t.found);
            if self.scratch.candidates.push(c).is_err() {
                break;
            }
        }
    }

    /// Matches every candidate into `frame` from the pose `t_cw`, replacing the correspondences
    /// and their sources.
    fn match_candidates<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &Map<K, L>,
        t_cw: &Pose,
        matcher: Matcher<'_>,
    ) {
        self.scratch.correspondences.clear();
        self.scratch.sources.clear();
        let (zmin, zmax) = (self.params.sensor().depth_min_m, self.params.sensor().depth_max_m);
        // One tracking workspace for all the candidates, not one zeroed per track.
        let mut scratch = TrackScratch::new();
        for c in &self.scratch.candidates {
            let Some(t) = self.local.items().get(usize::from(c.index)) else { continue };
            let Some((template, centre)) = t.template() else { continue };
            let affine = t.warp_to(cam, t_cw);
            let pred = (c.uv.x, c.uv.y);
            let gray = &frame.gray;
            let matched = match matcher {
                Matcher::Patch(tp) => {
                    let s = &mut scratch;
                    track_patch_with(s, &template, centre, &affine, gray, pred, tp)
                        .or_else(|e| match e {
                            // Lucas-Kanade alone missed: one search at radius 1.
                            MatchError::RefinementFailed | MatchError::LowCorrelation { .. }
                                if tp.search_radius == 0 =>
                            {
                                let wider = TrackParams { search_radius: 1, ..*tp };
                                track_patch_with(s, &template, centre, &affine, gray, pred, &wider)
                            }
                            e => Err(e),
                        })
                        .map(|m| m.uv)
                }
                Matcher::Bank(m) => {
                    let params = MatchParams { initial_affine: affine, ..*m };
                    match_region(&template, centre, gray, pred, &params).map(|m| m.centre_in_target)
                }
            };
            let Ok((u, v)) = matched else { continue };
            let depth_m = frame
                .depth
                .depth_at(u, v, self.params.max_relative_depth_step)
                .filter(|&z| z >= zmin && z <= zmax);
            let Some(lm) = map.landmark(t.id) else { continue };
            let corr = Correspondence { p_w: lm.p_w, uv: Point2::new(u, v), depth_m };
            if !corr.is_valid() || self.scratch.correspondences.push(corr).is_err() {
                continue;
            }
            // Same capacity as the correspondences: cannot fail after their push succeeded.
            let _ = self.scratch.sources.push(c.index);
        }
    }

    /// After a tracked frame: counts visibility and finds, and (odometry mode) fuses the inliers'
    /// depths into their landmarks.
    pub(super) fn update_local_map<const K: usize, const L: usize>(
        &mut self,
        cam: &PinholeCamera,
        map: &mut Map<K, L>,
        est: &PoseEstimate,
    ) {
        let items = self.local.items_mut();
        for c in &self.scratch.candidates {
            if let Some(t) = items.get_mut(usize::from(c.index)) {
                t.visible = t.visible.saturating_add(1);
            }
        }
        let t_wc = est.t_cw.inverse();
        let max_n = self.params.max_fused_measurements;
        for (k, (corr, &src)) in
            self.scratch.correspondences.iter().zip(&self.scratch.sources).enumerate()
        {
            let Some(t) = items.get_mut(usize::from(src)) else { continue };
            if !est.inliers.contains(k) {
                continue;
            }
            t.found = t.found.saturating_add(1);
            t.last_found_frame = self.frame_index;
            let (Some(z), true) = (corr.depth_m, self.params.fuse_depth) else { continue };
            let Some(lm) = map.landmark_mut(t.id) else { continue };
            // Inverse-variance weight of a depth with sigma_z ~ z^2, normalized at 1 m.
            let w = 1.0 / (z * z * z * z);
            let total = t.fused_weight + w;
            // Only the distance along the ray from the anchoring camera changes: that bearing was
            // measured to sub-pixel precision, the depths are what is noisy.
            let p_obs = t_wc * cam.back_project(corr.uv.x, corr.uv.y, z);
            let centre = t.anchor_centre();
            let ray = lm.p_w - centre;
            let d = ray.norm();
            if d > 0.0 {
                let dir = ray / d;
                let d_obs = (p_obs - centre).dot(&dir);
                lm.p_w = centre + dir * (d + (d_obs - d) * (w / total));
            }
            t.fused_weight = total.min(max_n * w);
        }
    }

    /// Drops from the local map the landmarks found too rarely or not for too long.
    pub(super) fn cull_local_map(&mut self) {
        let p = self.params;
        let now = self.frame_index;
        self.local.retain(|t| {
            let unreliable =
                t.visible >= p.cull_min_visible && t.found_ratio() < p.cull_min_found_ratio;
            let stale = now.wrapping_sub(t.last_found_frame) > p.cull_max_unseen_frames;
            !unreliable && !stale
        });
    }
}

/// The pose of the guide correspondences, when it has at least `min_guide_inliers` inliers.
fn guide_pose(
    cam: &PinholeCamera,
    corrs: &[Correspondence],
    predicted_t_cw: &Pose,
    p: &super::FrontendParams,
    rng: &mut TrackingRng,
) -> Option<Pose> {
    if corrs.len() < p.min_guide_inliers {
        return None;
    }
    // The guides are few: their pose needs `min_guide_inliers`, not the final pose's count.
    let min_inliers = u32::try_from(p.min_guide_inliers).unwrap_or(u32::MAX);
    let params = PoseParams { min_inliers, ..p.pose };
    track_pose(cam, corrs, Some(predicted_t_cw), &params, rng)
        .ok()
        .filter(|est| est.num_inliers >= p.min_guide_inliers)
        .map(|est| est.t_cw)
}

/// Whether two world-to-camera poses of the same frame agree: their camera centres within
/// [`AGREE_M`] and their orientations within [`AGREE_RAD`].
fn poses_agree(a_cw: &Pose, b_cw: &Pose) -> bool {
    let (moved, turned) = camera_gap(&a_cw.inverse(), &b_cw.inverse());
    moved <= AGREE_M && turned <= AGREE_RAD
}
