//! The front end at its tracking level: its state, grouped by the concern that owns it, its
//! constructors and the frame entry; the rest of `tracking` implements its behaviour
//! (`pipeline.rs` the per-frame pipeline, `landmark_matching.rs`, `keyframe.rs`, `map_reuse.rs`).
//! `super::Frontend` hands it each frame on the pyramid level it tracks on.

use heapless::Vec;

use super::FrontendParams;
use super::keyframe_rule::KeyframeRule;
use super::local_map::BoardLocalMap;
use super::places::Places;
use super::result::{
    FrameOutcome, FrameResult, FrontendError, FrontendState, FrontendStats, FrontendWork,
};
use crate::config::{REFERENCE_WIDTH_PX, capacity, pixel_scale};
use crate::features::{FeatureVec, HessianDetector, HessianParams};
use crate::frame::RgbdFrame;
use crate::geometry::{PinholeCamera, Pose};
use crate::grid_spread::Candidate;
use crate::map::{KeyFrameId, Map};
use crate::pose::small_image_rotation::SmallImage;
use crate::pose::{Correspondence, MAX_CORRESPONDENCES, MotionModel, TrackingRng};

/// The front end on frames of its tracking level, up to `W` x `H` pixels (see the module
/// documentation). Its state is grouped by the concern that owns it: the recent past (`Recent`,
/// here), the keyframe rule and the detector (`keyframe.rs`), the matching scratch
/// (`landmark_matching.rs`) and the local map (`local_map.rs`).
#[derive(Debug, Clone)]
pub struct FrameTracker<const W: usize, const H: usize> {
    /// The parameters as given, stated for [`REFERENCE_WIDTH_PX`](crate::config::REFERENCE_WIDTH_PX).
    stated: FrontendParams,
    /// The parameters in use: `stated` scaled to the tracking level's width.
    pub(super) params: FrontendParams,
    /// The tracking level's width `params` was scaled for, pixels (0: not yet).
    scaled_for_width: usize,
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
    /// The last keyframe made while tracking, until a cheap frame asks whether it closes a loop.
    pub(super) loop_pending: Option<KeyFrameId>,
    /// Creation number of the keyframe tracking last re-initialized at (0 before any): the map
    /// from it on is one rigid piece, which a loop correction moves.
    pub(super) track_start: u32,
}

/// What the front end keeps of the frames before this one.
#[derive(Debug, Clone)]
pub(super) struct Recent {
    /// The state after the last frame.
    pub(super) state: FrontendState,
    /// The last frame's timestamp (seconds) and output `t_cw`.
    pub(super) last: Option<(f64, Pose)>,
    /// The last frame's pose inliers (0 when it was not tracked).
    pub(super) inliers: usize,
    /// Frames lost in a row up to the last one.
    pub(super) lost_run: u32,
    /// Constant-velocity prediction from the tracked poses.
    pub(super) motion: MotionModel,
    /// The output `t_cw` of the last frame not lost: the pose of `small_previous`.
    pub(super) seen_t_cw: Option<Pose>,
    /// This frame, and the last frame not lost before it, as small blurry images (the
    /// rotation's re-estimate).
    pub(super) small_current: SmallImage,
    pub(super) small_previous: SmallImage,
}

impl Recent {
    const fn new() -> Self {
        Self {
            state: FrontendState::Initializing,
            last: None,
            inliers: 0,
            lost_run: 0,
            motion: MotionModel::new(),
            seen_t_cw: None,
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
    pub(super) fn predict(&self, timestamp_s: f64) -> Pose {
        if let Ok(Some(t_cw)) = self.motion.predict(timestamp_s) {
            return t_cw;
        }
        self.last_t_cw().unwrap_or_else(Pose::identity)
    }

    /// Remembers the frame at `timestamp_s` as `result` left it; unless it was lost, its small
    /// image becomes the previous one.
    pub(super) fn remember(&mut self, timestamp_s: f64, result: &FrameResult) {
        self.state = result.state;
        self.last = Some((timestamp_s, result.t_wc.inverse()));
        self.inliers = result.inliers;
        self.lost_run =
            if result.state == FrontendState::Lost { self.lost_run.saturating_add(1) } else { 0 };
        // A lost frame's small image is not the rotation's reference: it may show nothing of the
        // scene (a covered lens, another scene), and its pose is only the prediction.
        if result.state != FrontendState::Lost {
            self.seen_t_cw = Some(result.t_wc.inverse());
            core::mem::swap(&mut self.small_current, &mut self.small_previous);
        }
    }
}

impl<const W: usize, const H: usize> Default for FrameTracker<W, H> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const W: usize, const H: usize> FrameTracker<W, H> {
    /// A front end with [`FrontendParams::DEFAULT`] (`const`, so it can initialize a `static`).
    pub const fn new() -> Self {
        Self::with_params(FrontendParams::DEFAULT)
    }

    /// A front end with `params` (checked on every [`Self::process`]).
    pub const fn with_params(params: FrontendParams) -> Self {
        Self {
            stated: params,
            params,
            scaled_for_width: REFERENCE_WIDTH_PX,
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
                relocalizations: 0,
                initializing_frames: 0,
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
            loop_pending: None,
            track_start: 0,
        }
    }

    /// The parameters as given (stated for the reference width).
    pub fn stated_params(&self) -> &FrontendParams {
        &self.stated
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

    /// Processes one frame on the tracking level (its size checked by [`super::Frontend`], `cam`
    /// the level's camera) against `map`, which it extends with keyframes and landmarks.
    ///
    /// # Errors
    /// [`FrontendError::TimestampNotIncreasing`] or [`FrontendError::InvalidParams`]; nothing
    /// changes then.
    pub(super) fn process<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &mut Map<K, L>,
        places: &mut impl Places,
    ) -> Result<FrameResult, FrontendError> {
        self.check_input(frame)?;
        let width = frame.gray.width();
        if width != self.scaled_for_width {
            self.params = self.stated.at_pixel_scale(pixel_scale(width));
            self.scaled_for_width = width;
        }
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
        let result = if self.stats.keyframes == 0 && places.holds_places() {
            self.start_in_places(frame, cam, map, places)
        } else if self.local.is_empty() || self.keyframing.reference.is_none() {
            self.initialize(frame, cam, map, places, &predicted_t_cw)
        } else {
            self.track_or_recover(frame, cam, map, places, &predicted_t_cw)
        };
        let s = &mut self.stats;
        let count = match result.outcome() {
            FrameOutcome::Tracked => &mut s.tracked_frames,
            FrameOutcome::Reinitialized => &mut s.reinitializations,
            FrameOutcome::Relocalized => &mut s.relocalizations,
            FrameOutcome::Lost => &mut s.lost_frames,
            FrameOutcome::Initializing => &mut s.initializing_frames,
        };
        *count = count.saturating_add(1);
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

    fn check_input(&self, frame: &RgbdFrame<'_>) -> Result<(), FrontendError> {
        if !self.stated.is_valid() {
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
}

/// The detector and the features it found in the last keyframe's frame (or lost frame's).
#[derive(Debug, Clone)]
pub(super) struct Detection<const W: usize> {
    pub(super) detector: HessianDetector<W>,
    /// The last detection's features (map reuse reads them too).
    pub(super) features: FeatureVec,
    /// What `features` were detected on: the frame's timestamp bits and the parameters (`None`
    /// after a failed detection).
    of: Option<(u64, HessianParams)>,
}

impl<const W: usize> Detection<W> {
    pub(super) const fn new() -> Self {
        Self { detector: HessianDetector::new(), features: FeatureVec::new(), of: None }
    }

    /// Detects features of `frame` with `params` into `features`, unless they already hold that
    /// detection (a relocalized frame's query detected them; the keyframe it makes reuses them:
    /// the same bits for half the cost). Returns whether `features` hold the detection.
    pub(super) fn detect(&mut self, frame: &RgbdFrame<'_>, params: &HessianParams) -> bool {
        let of = Some((frame.timestamp_s.to_bits(), *params));
        if self.of == of {
            return true;
        }
        let ok = self.detector.detect(&frame.gray, params, &mut self.features).is_ok();
        self.of = if ok { of } else { None };
        ok
    }
}

/// The matching stages' scratch: the landmarks tried (`candidates`), and the correspondences
/// found with the local-map index of each (`sources`). After [`Frontend::match_landmarks`] it
/// holds the winning final stage, which the keyframe and the local map's bookkeeping read.
#[derive(Debug, Clone)]
pub(super) struct MatchScratch {
    pub(super) candidates: Vec<Candidate, { capacity::MAX_TRACKED_LANDMARKS }>,
    pub(super) correspondences: Vec<Correspondence, MAX_CORRESPONDENCES>,
    /// Local-map index of each correspondence.
    pub(super) sources: Vec<u16, MAX_CORRESPONDENCES>,
}

impl MatchScratch {
    pub(super) const fn new() -> Self {
        Self { candidates: Vec::new(), correspondences: Vec::new(), sources: Vec::new() }
    }
}
