//! The per-frame pipeline of the module documentation after the input checks and the prediction
//! of [`Frontend::process`]: tracking the local map, or starting (again) from a keyframe.

use super::keyframe_rule::KeyframeDecision;
use super::landmark_matching::Bank;
use super::places::Places;
use super::result::{FrameResult, FrontendState, GuideStage};
use super::tracker::FrameTracker;
use crate::frame::RgbdFrame;
use crate::geometry::{PinholeCamera, Pose};
use crate::map::Map;

/// Frames in a row a front end with a place memory stays lost, asking it, before it restarts
/// tracking at the prediction (1 without one: the frame after a loss restarts). Why:
/// docs/decisions.md, "Five lost frames ask before tracking restarts".
pub const RELOCALIZE_FRAMES: u32 = 5;

impl<const W: usize, const H: usize> FrameTracker<W, H> {
    /// Starts (or restarts) tracking from a keyframe made of `frame` at `t_cw`.
    pub(super) fn initialize<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &mut Map<K, L>,
        places: &mut impl Places,
        t_cw: &Pose,
    ) -> FrameResult {
        let first = self.stats.keyframes == 0;
        self.local.clear();
        self.scratch.correspondences.clear();
        self.scratch.sources.clear();
        let octaves = self.params.hessian.octaves;
        let made = self.make_keyframe(frame, cam, map, places, t_cw, None, octaves);
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
            tracked: made.is_some() && first,
            reinitialized: made.is_some() && !first,
            keyframe: made,
            ..FrameResult::untracked(t_cw.inverse(), state, self.keyframing.reference_keyframe())
        }
    }

    /// Starts tracking in a place memory that already holds places (a loaded map): the first
    /// keyframe is made at the pose a remembered place verifies, so the run continues in the
    /// loaded map's world frame. Until one verifies, frames stay before the first keyframe
    /// (no pose, no new world frame).
    pub(super) fn start_in_places<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &mut Map<K, L>,
        places: &mut impl Places,
    ) -> FrameResult {
        if let Some(t_cw) = self.query_places(frame, cam, map, places) {
            // The run's keyframes follow the loaded map's in creation order. `track_start`
            // stays 0: the run continues the loaded map as if tracked through, so a loop to one
            // of its places is held, not applied (docs/decisions.md, "Loops across runs").
            map.number_from(places.first_free_seq());
            let r = self.initialize(frame, cam, map, places, &t_cw);
            if r.keyframe.is_some() {
                return FrameResult { tracked: false, relocalized: true, ..r };
            }
        }
        FrameResult::untracked(Pose::identity(), FrontendState::Initializing, None)
    }

    /// Tracks the local map; on failure, relocalizes in a remembered place, or else
    /// re-initializes when the previous frame was lost too.
    pub(super) fn track_or_recover<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &mut Map<K, L>,
        places: &mut impl Places,
        predicted_t_cw: &Pose,
    ) -> FrameResult {
        // With a place memory, the frames after a loss keep asking it before tracking restarts
        // at a prediction: a known place found late is better than a new map built off it.
        let lost_enough = if places.relocalizes() { RELOCALIZE_FRAMES } else { 1 };
        let was_lost = self.recent.lost_run >= lost_enough;
        // With a place memory, a frame no cheaper attempt tracked asks it before the affine bank
        // (the costliest attempt); the bank runs when no place is verified. Why: docs/decisions.md,
        // "Relocalization before the affine bank".
        let relocalizes = places.relocalizes();
        let bank = if relocalizes { Bank::Skip } else { Bank::Last };
        let mut summary = self.match_landmarks(frame, cam, map, predicted_t_cw, bank);
        if summary.estimate.is_none() && relocalizes {
            if let Some(t_cw) = self.query_places(frame, cam, map, places) {
                let r = self.initialize(frame, cam, map, places, &t_cw);
                if r.keyframe.is_some() {
                    return FrameResult {
                        reinitialized: false,
                        relocalized: true,
                        matches: summary.matches,
                        guide_matches: summary.guides,
                        ..r
                    };
                }
            }
            let guides = summary.guides;
            summary = self.match_landmarks(frame, cam, map, predicted_t_cw, Bank::Only);
            summary.guides = summary.guides.max(guides);
        }
        // The inlier mask indexes the scratch: it must hold the winning final stage.
        debug_assert!(
            summary.estimate.is_none() || summary.matches == self.scratch.correspondences.len(),
            "the scratch does not hold the winning final stage"
        );
        let reference = self.keyframing.reference_keyframe();
        let lost = FrameResult {
            matches: summary.matches,
            guide_matches: summary.guides,
            guide_stage: summary.stage,
            ..FrameResult::untracked(predicted_t_cw.inverse(), FrontendState::Lost, reference)
        };
        if summary.stage == GuideStage::AffineBank {
            self.stats.bank_recoveries = self.stats.bank_recoveries.saturating_add(1);
        }
        let Some(est) = summary.estimate else {
            if was_lost {
                let r = self.initialize(frame, cam, map, places, predicted_t_cw);
                if let Some(k) = r.keyframe.and_then(|kf| map.keyframe(kf)) {
                    self.track_start = k.seq;
                }
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
                self.make_keyframe(frame, cam, map, places, &est.t_cw, Some(&est.inliers), octaves)
            }
        };
        self.cull_local_map();
        // The last keyframe looks for a loop on a frame that made none and ran no costly step;
        // a loop moves the map, and this frame's pose with it.
        let mut loop_closure = None;
        if keyframe.is_none()
            && !self.work.is_costly()
            && let Some(kf) = self.loop_pending.take()
        {
            loop_closure = self.close_loop(map, places, kf, frame.gray.size());
        }
        let t_wc = est.t_cw.inverse();
        FrameResult {
            t_wc: loop_closure.map_or(t_wc, |c| c.correction * t_wc),
            state: FrontendState::Tracking,
            tracked: true,
            keyframe,
            reference_keyframe: self.keyframing.reference_keyframe(),
            inliers: est.num_inliers,
            loop_closure,
            ..lost
        }
    }
}
