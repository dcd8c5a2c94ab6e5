//! [`FrontendParams`]: every tunable of the odometry front end, with `const` defaults.

use super::PoseParams;
use super::keyframe::LandmarkFilter;
use crate::config::Tunables;
use crate::features::HessianParams;
use crate::matching::{MatchParams, TrackParams};

/// Tunables of [`Frontend`](super::frontend::Frontend). Distances in pixels are at the processing
/// resolution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrontendParams {
    /// Feature detection for new keyframes. Default: [`HessianParams::default`] with the
    /// threshold lowered from 100 to 30 (at 100, QVGA Kinect frames of 7-Scenes give only ~40
    /// landmarks per keyframe; at 30 about 130).
    pub hessian: HessianParams,
    /// Guide stage: the first `guide_landmarks` landmarks tracked from the motion-model
    /// prediction, with a wide search. Default [`TrackParams::GUIDE`].
    pub guide: TrackParams,
    /// Final stage: every landmark tracked from the guides' pose. Default [`TrackParams::FINE`].
    pub track: TrackParams,
    /// Recovery: the affine-bank region matching of the guide landmarks, used when the guides
    /// give no pose (its `initial_affine` is replaced per landmark by the map the predicted
    /// motion induces). Default [`MatchParams::DEFAULT`].
    pub matching: MatchParams,
    /// Landmarks matched in the guide stage (and in a recovery). Default 24.
    pub guide_landmarks: usize,
    /// The guides' pose is used when it has at least this many inliers. Default 8.
    pub min_guide_inliers: usize,
    /// Pose estimation.
    pub pose: PoseParams,
    /// Nearest usable depth, metres; default [`Tunables::depth_min_m`]'s default (see
    /// [`Self::with_tunables`]).
    pub depth_min_m: f32,
    /// Farthest usable depth, metres; default [`Tunables::depth_max_m`]'s default.
    pub depth_max_m: f32,
    /// A keyframe feature is dropped when a neighbour 2 pixels away differs in depth by more than
    /// this fraction of its depth, or has none (occlusion edges). Default 0.05.
    pub max_relative_depth_step: f32,
    /// Landmarks per keyframe at most (bounds the per-frame matching cost). Default 200.
    pub max_landmarks: usize,
    /// Each frame stops matching once this many landmarks matched (they come in the keyframe's
    /// bucketed order, so they still spread over the image). Bounds the per-frame cost.
    /// Default 200.
    pub max_tracked: usize,
    /// A keyframe needs at least this many landmarks. Default 30.
    pub min_keyframe_landmarks: usize,
    /// Tracking needs at least this many matches. Default 12.
    pub min_matches: usize,
    /// A tracked pose needs at least this many inliers. Default 12.
    pub min_inliers: usize,
    /// Keyframe rule: new keyframe when inliers `<` this fraction of the keyframe's landmarks.
    /// Default 0.5.
    pub keyframe_inlier_ratio: f32,
    /// Keyframe rule: new keyframe when inliers `<` this. Default 40.
    pub keyframe_min_inliers: usize,
    /// Keyframe rule: new keyframe when the camera is farther than this from the keyframe,
    /// metres. Default 0.25.
    pub keyframe_max_translation_m: f32,
    /// Keyframe rule: new keyframe when the camera has turned more than this from the keyframe,
    /// radians. Default 0.26 (15 degrees).
    pub keyframe_max_rotation_rad: f32,
}

impl FrontendParams {
    /// The defaults, documented per field; matching and pose values equal their own `Default`s,
    /// detection too except its threshold (a unit test checks it).
    pub const DEFAULT: Self = Self {
        // 30 instead of the detector's 100: at QVGA on 7-Scenes, 100 left ~40 landmarks per
        // keyframe and lost 38 of the first 100 frames; 30 gives ~130 and loses none.
        hessian: HessianParams { threshold: 30.0, ..HessianParams::DEFAULT },
        guide: TrackParams::GUIDE,
        track: TrackParams::FINE,
        matching: MatchParams::DEFAULT,
        guide_landmarks: 24,
        min_guide_inliers: 8,
        pose: PoseParams::DEFAULT,
        depth_min_m: 0.3,
        depth_max_m: 4.0,
        max_relative_depth_step: 0.05,
        max_landmarks: 200,
        max_tracked: 200,
        min_keyframe_landmarks: 30,
        min_matches: 12,
        min_inliers: 12,
        keyframe_inlier_ratio: 0.5,
        keyframe_min_inliers: 40,
        keyframe_max_translation_m: 0.25,
        keyframe_max_rotation_rad: 0.26,
    };

    /// These parameters with the depth range of `tunables`.
    pub const fn with_tunables(self, tunables: &Tunables) -> Self {
        Self { depth_min_m: tunables.depth_min_m, depth_max_m: tunables.depth_max_m, ..self }
    }

    /// Whether the front end's own values are in range (detection, matching and pose parameters
    /// are checked by their own functions when used).
    pub fn is_valid(&self) -> bool {
        let pos = |x: f32| x.is_finite() && x > 0.0;
        pos(self.depth_min_m)
            && pos(self.depth_max_m)
            && self.depth_min_m < self.depth_max_m
            && pos(self.max_relative_depth_step)
            && self.max_landmarks > 0
            && self.max_tracked > 0
            && self.guide_landmarks >= 3
            && self.min_guide_inliers >= 3
            && self.guide.is_valid()
            && self.track.is_valid()
            && self.keyframe_inlier_ratio.is_finite()
            && pos(self.keyframe_max_translation_m)
            && pos(self.keyframe_max_rotation_rad)
            && self.pose.is_valid()
            && self.hessian.validate().is_ok()
    }

    /// The keyframe landmark filter these parameters describe.
    pub(crate) fn landmark_filter(&self) -> LandmarkFilter {
        LandmarkFilter {
            depth_min_m: self.depth_min_m,
            depth_max_m: self.depth_max_m,
            max_relative_depth_step: self.max_relative_depth_step,
            discontinuity_radius_px: 2,
            border_px: self.matching.half_size as f32 + 2.0,
            max_landmarks: self.max_landmarks,
        }
    }
}

impl Default for FrontendParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}
