//! The frame-to-map RGB-D front end: [`Frontend::process`] turns each [`RgbdFrame`] into a camera
//! pose, tracking the landmarks of its local map and adding keyframes and landmarks to the
//! [`Map`].
//!
//! # Per frame
//!
//! 1. Predict `t_cw` with the [`MotionModel`] (constant velocity; the last pose with one pose of
//!    history; the identity before the first keyframe).
//! 2. Without tracked landmarks (state [`FrontendState::Initializing`], or after a loss): make a
//!    keyframe of the frame at the predicted pose (step 6). The first keyframe defines the world
//!    frame (identity pose).
//! 3. Start pose of the final stage: first the prediction itself; its final stage is kept when it
//!    has at least 80% of the previous frame's inliers. Otherwise (and first, when the prediction
//!    turns more than a degree since the last frame) the guides: the tracked landmarks predicted
//!    inside the image are spread over a 4 x 3 grid and the best `guide_landmarks` (most often
//!    found first) are matched with a wide search ([`track_patch`](crate::matching::track_patch),
//!    each landmark's template warped by the map the predicted motion induces on it); their
//!    robust pose is the start of the final stage. When the final stage from them is weak (under
//!    60% of the previous frame's inliers) or they give no pose, cheaper-first attempts follow:
//!    the guides and the prediction from a rotation re-estimated on small blurry images, the
//!    guides with a wider search; the strongest final stage wins. Only when none gave a pose at
//!    all are the same landmarks searched with the affine bank
//!    ([`match_region`](crate::matching::match_region)), the costliest attempt (see
//!    `frontend_match.rs`; why this order: docs/decisions.md, "Prediction tried before the
//!    guides").
//! 4. Final stage: from the start pose, up to `max_tracked` landmarks spread over an 8 x 6 grid
//!    are matched with a small search and sub-pixel refinement;
//!    [`track_pose`](crate::pose::track_pose) estimates `t_cw` from the matches (pixel and, where the
//!    frame has it, depth).
//! 5. Bookkeeping: each landmark counts the frames it was visible and found (a pose inlier);
//!    landmarks found too rarely or not for long are dropped from the local map (not from the
//!    map). In odometry mode (`fuse_depth`) each inlier's measured depth is fused into its
//!    landmark's position.
//! 6. Keyframe rule (see [`FrontendParams`]): after a tracked frame, a keyframe is made when the
//!    inliers fall below `keyframe_inlier_ratio` of those of the frame after the last keyframe or
//!    below `keyframe_min_inliers`, or when the camera moved more than
//!    `keyframe_max_translation_m` or turned more than `keyframe_max_rotation_rad` from the last
//!    keyframe. On a costly frame ([`FrontendWork::is_costly`]) a due keyframe is put off to the
//!    next tracked frame, at most `keyframe_max_put_off` frames in a row, and then made with
//!    `costly_keyframe_octaves` pyramid octaves (`decide_keyframe`; the costliest frames on the
//!    board were costly frames that also made a keyframe). A keyframe records its inliers as
//!    observations, re-anchors the landmarks whose templates are too warped, and turns the
//!    detected Hessian features with valid depth that are not near an inlier into new landmarks
//!    (see `frontend_keyframe.rs`).
//! 7. Loss: when tracking fails (too few matches or inliers, no pose), the frame is
//!    [`FrontendState::Lost`] and its output is the prediction with `tracked == false`: the
//!    trajectory never jumps. The next frame is tried against the local map first; if that fails
//!    too, the local map is emptied and a keyframe is made at that frame's predicted pose (the
//!    trajectory stays continuous, with whatever drift the prediction has), and tracking resumes
//!    from it. Its [`FrameResult::tracked`] is `false` and [`FrameResult::reinitialized`] `true`.
//!
//! # After bundle adjustment
//!
//! When bundle adjustment moves the last keyframe, the motion model's poses and the last output
//! pose stay where tracking put them, so the next prediction is off by that move (ORB-SLAM instead
//! re-expresses the last frame relative to its reference keyframe). Why: docs/decisions.md, "Last
//! poses not moved with the reference keyframe".
//!
//! # Memory
//!
//! Everything is inline, no heap: the Hessian detector, the local map
//! ([`MAX_TRACKED_LANDMARKS`](crate::config::capacity::MAX_TRACKED_LANDMARKS) templates of 16 x 16 pixels), the feature, candidate and
//! correspondence scratch. The map is the caller's (so the back end can share it). Sizes are in
//! `memory-budget.md` (unit-tested). [`Frontend::new`] is `const`: place it in a `static` on the
//! board, box it on a host.

use super::FrontendParams;
use super::keyframe::{Detection, KeyframeDecision, KeyframeRule};
use super::landmark_matching::MatchScratch;
use super::local_map::BoardLocalMap;
use super::result::{
    FrameResult, FrontendError, FrontendState, FrontendStats, FrontendWork, GuideStage,
    size_mismatch,
};
use crate::frame::RgbdFrame;
use crate::geometry::{PinholeCamera, Pose};
use crate::map::Map;
use crate::pose::small_image_rotation::SmallImage;
use crate::pose::{MotionModel, TrackingRng};

/// The front end at the reference board's QVGA profile (320 x 240).
pub type QvgaFrontend = Frontend<320, 240>;
/// The front end at the VGA profile (640 x 480).
pub type VgaFrontend = Frontend<640, 480>;

/// The front end for images up to `W` x `H` (see the module documentation). Its state is
/// grouped by the concern that owns it: the recent past (`Recent`, here), the keyframe rule
/// and the detector (`keyframe.rs`), the matching scratch (`landmark_matching.rs`) and the local
/// map (`local_map.rs`).
#[derive(Debug, Clone)]
pub struct Frontend<const W: usize, const H: usize> {
    pub(super) params: FrontendParams,
    pub(super) recent: Recent,
    pub(super) keyframing: KeyframeRule,
    pub(super) detection: Detection<W>,
    pub(super) local: BoardLocalMap,
    pub(super) scratch: MatchScratch,
    pub(super) rng: TrackingRng,
    pub(super) stats: FrontendStats,
    /// Frames processed, as a frame number for the local map's bookkeeping.
    pub(super) frame_index: u32,
    /// The costly steps run on the frame being processed.
    pub(super) work: FrontendWork,
}

/// What the front end keeps of the frames before this one.
#[derive(Debug, Clone)]
pub(super) struct Recent {
    /// The state after the last frame.
    state: FrontendState,
    /// The last frame's timestamp (seconds) and output `t_cw`.
    last: Option<(f64, Pose)>,
    /// The last frame's pose inliers (0 when it was not tracked).
    pub(super) inliers: usize,
    /// Constant-velocity prediction from the tracked poses.
    motion: MotionModel,
    /// This frame and the previous one as small blurry images (the rotation's re-estimate).
    pub(super) small_current: SmallImage,
    pub(super) small_previous: SmallImage,
}

impl Recent {
    const fn new() -> Self {
        Self {
            state: FrontendState::Initializing,
            last: None,
            inliers: 0,
            motion: MotionModel::new(),
            small_current: SmallImage::new(),
            small_previous: SmallImage::new(),
        }
    }

    /// The last frame's output `t_cw`.
    pub(super) fn last_t_cw(&self) -> Option<Pose> {
        self.last.map(|(_, t_cw)| t_cw)
    }

    /// The predicted `t_cw`: constant velocity while tracking, else the last output pose, else
    /// the identity.
    fn predict(&self, timestamp_s: f64) -> Pose {
        if let Ok(Some(t_cw)) = self.motion.predict(timestamp_s) {
            return t_cw;
        }
        self.last_t_cw().unwrap_or_else(Pose::identity)
    }

    /// Remembers the frame at `timestamp_s` as `result` left it; its small image becomes the
    /// previous one.
    fn remember(&mut self, timestamp_s: f64, result: &FrameResult) {
        self.state = result.state;
        self.last = Some((timestamp_s, result.t_wc.inverse()));
        self.inliers = result.inliers;
        core::mem::swap(&mut self.small_current, &mut self.small_previous);
    }
}

impl<const W: usize, const H: usize> Default for Frontend<W, H> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const W: usize, const H: usize> Frontend<W, H> {
    /// A front end with [`FrontendParams::DEFAULT`] (`const`, so it can initialize a `static`).
    pub const fn new() -> Self {
        Self::with_params(FrontendParams::DEFAULT)
    }

    /// A front end with `params` (checked on every [`Self::process`]).
    pub const fn with_params(params: FrontendParams) -> Self {
        Self {
            params,
            recent: Recent::new(),
            keyframing: KeyframeRule::new(),
            detection: Detection::new(),
            local: BoardLocalMap::new(),
            scratch: MatchScratch::new(),
            rng: TrackingRng::new(params.rng_seed),
            stats: FrontendStats {
                frames: 0,
                tracked_frames: 0,
                lost_frames: 0,
                reinitializations: 0,
                keyframes: 0,
                keyframes_put_off: 0,
                bank_recoveries: 0,
            },
            frame_index: 0,
            work: FrontendWork {
                final_stages: 0,
                guide_runs: 0,
                rotation_estimated: false,
                detected: false,
            },
        }
    }

    /// The parameters in use.
    pub fn params(&self) -> &FrontendParams {
        &self.params
    }

    /// The state after the last frame.
    pub fn state(&self) -> FrontendState {
        self.recent.state
    }

    /// Running totals.
    pub fn stats(&self) -> FrontendStats {
        self.stats
    }

    /// The landmarks tracked now.
    pub fn local_map(&self) -> &BoardLocalMap {
        &self.local
    }

    /// Processes one frame (see the module documentation) against `map`, which it extends with
    /// keyframes and landmarks. `cam` must describe the frame's size.
    ///
    /// # Errors
    /// [`FrontendError::SizeMismatch`], [`FrontendError::TimestampNotIncreasing`] or
    /// [`FrontendError::InvalidParams`]; nothing changes then. A frame that cannot be tracked
    /// (black, no depth) is not an error: it gives [`FrontendState::Lost`] (or stays
    /// [`FrontendState::Initializing`]).
    pub fn process<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &mut Map<K, L>,
    ) -> Result<FrameResult, FrontendError> {
        self.check_input(frame, cam)?;
        let predicted_t_cw = self.recent.predict(frame.timestamp_s);
        self.stats.frames = self.stats.frames.saturating_add(1);
        self.frame_index = self.frame_index.wrapping_add(1);
        self.work = FrontendWork::default();
        self.recent.small_current.build(&frame.gray);
        // Ids of a map the caller cleared or replaced no longer resolve: start over then.
        if self.keyframing.reference.is_some_and(|(id, _)| map.keyframe(id).is_none()) {
            self.local.clear();
            self.keyframing.reference = None;
        }
        let result = if self.local.is_empty() || self.keyframing.reference.is_none() {
            self.initialize(frame, cam, map, &predicted_t_cw)
        } else {
            self.track_or_recover(frame, cam, map, &predicted_t_cw)
        };
        if result.tracked {
            self.stats.tracked_frames = self.stats.tracked_frames.saturating_add(1);
        }
        if result.state == FrontendState::Lost {
            self.stats.lost_frames = self.stats.lost_frames.saturating_add(1);
        }
        if result.reinitialized {
            self.stats.reinitializations = self.stats.reinitializations.saturating_add(1);
        }
        self.recent.remember(frame.timestamp_s, &result);
        let keyframe_landmarks =
            if result.keyframe.is_some() { self.keyframing.last_counts } else { (0, 0, 0) };
        Ok(FrameResult {
            tracked_landmarks: self.local.len(),
            keyframe_landmarks,
            work: self.work,
            ..result
        })
    }

    fn check_input(&self, frame: &RgbdFrame<'_>, cam: &PinholeCamera) -> Result<(), FrontendError> {
        let (width, height) = frame.gray.size();
        let fits = width <= W && height <= H;
        if !fits
            || frame.depth.size() != (width, height)
            || (cam.width(), cam.height()) != (width, height)
        {
            return Err(size_mismatch::<W, H>(frame, cam));
        }
        if !self.params.is_valid() {
            return Err(FrontendError::InvalidParams);
        }
        let previous_s = self.recent.last.map_or(f64::NEG_INFINITY, |(t, _)| t);
        if !frame.timestamp_s.is_finite() || frame.timestamp_s <= previous_s {
            return Err(FrontendError::TimestampNotIncreasing {
                previous_s,
                current_s: frame.timestamp_s,
            });
        }
        Ok(())
    }

    /// Starts (or restarts) tracking from a keyframe made of `frame` at `t_cw`.
    fn initialize<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &mut Map<K, L>,
        t_cw: &Pose,
    ) -> FrameResult {
        let first = self.stats.keyframes == 0;
        self.local.clear();
        self.scratch.correspondences.clear();
        self.scratch.sources.clear();
        let made = self.make_keyframe(frame, cam, map, t_cw, None, self.params.hessian.octaves);
        let state = match (made, first) {
            (Some(_), _) => FrontendState::Tracking,
            (None, true) => FrontendState::Initializing,
            (None, false) => FrontendState::Lost,
        };
        self.recent.motion.reset();
        if made.is_some() {
            // Cannot fail: timestamps were checked to increase.
            let _ = self.recent.motion.update(frame.timestamp_s, t_cw);
        }
        FrameResult {
            t_wc: t_cw.inverse(),
            state,
            tracked: made.is_some() && first,
            reinitialized: made.is_some() && !first,
            keyframe: made,
            reference_keyframe: self.keyframing.reference_keyframe(),
            inliers: 0,
            matches: 0,
            guide_matches: 0,
            guide_stage: GuideStage::None,
            tracked_landmarks: 0,
            keyframe_landmarks: (0, 0, 0),
            work: FrontendWork::default(),
        }
    }

    /// Tracks the local map; on failure right after a loss, re-initializes.
    fn track_or_recover<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &mut Map<K, L>,
        predicted_t_cw: &Pose,
    ) -> FrameResult {
        let was_lost = self.recent.state == FrontendState::Lost;
        let summary = self.match_landmarks(frame, cam, map, predicted_t_cw);
        // The inlier mask indexes the scratch: it must hold the winning final stage.
        debug_assert!(
            summary.estimate.is_none() || summary.matches == self.scratch.correspondences.len(),
            "the scratch does not hold the winning final stage"
        );
        let lost = FrameResult {
            t_wc: predicted_t_cw.inverse(),
            state: FrontendState::Lost,
            tracked: false,
            reinitialized: false,
            keyframe: None,
            reference_keyframe: self.keyframing.reference_keyframe(),
            inliers: 0,
            matches: summary.matches,
            guide_matches: summary.guides,
            guide_stage: summary.stage,
            tracked_landmarks: 0,
            keyframe_landmarks: (0, 0, 0),
            work: FrontendWork::default(),
        };
        if summary.stage == GuideStage::AffineBank {
            self.stats.bank_recoveries = self.stats.bank_recoveries.saturating_add(1);
        }
        let Some(est) = summary.estimate else {
            if was_lost {
                let r = self.initialize(frame, cam, map, predicted_t_cw);
                return FrameResult {
                    matches: summary.matches,
                    guide_matches: summary.guides,
                    ..r
                };
            }
            return lost;
        };
        // Cannot fail: timestamps were checked to increase.
        let _ = self.recent.motion.update(frame.timestamp_s, &est.t_cw);
        self.update_local_map(cam, map, &est);
        let keyframe = match self.keyframing.decide(&est, self.work.is_costly(), &self.params) {
            KeyframeDecision::None => None,
            KeyframeDecision::PutOff => {
                self.stats.keyframes_put_off = self.stats.keyframes_put_off.saturating_add(1);
                None
            }
            KeyframeDecision::Make { octaves } => {
                self.make_keyframe(frame, cam, map, &est.t_cw, Some(&est.inliers), octaves)
            }
        };
        self.cull_local_map();
        FrameResult {
            t_wc: est.t_cw.inverse(),
            state: FrontendState::Tracking,
            tracked: true,
            keyframe,
            reference_keyframe: self.keyframing.reference_keyframe(),
            inliers: est.num_inliers,
            ..lost
        }
    }
}

#[cfg(test)]
#[path = "tests.rs"]
mod tests;
