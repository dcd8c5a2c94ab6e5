//! [`FrontendParams`]: every tunable of the front end, with `const` defaults.

use crate::config::SensorModel;
use crate::features::HessianParams;
use crate::matching::{MatchParams, TrackParams};
use crate::pose::PoseParams;

/// Tunables of [`Frontend`](super::frontend::Frontend). Distances in pixels are stated for
/// [`REFERENCE_WIDTH_PX`](crate::config::REFERENCE_WIDTH_PX) (the board's QVGA); the front end
/// tracks on the pyramid level nearest it and scales them to that level's width
/// ([`Self::at_pixel_scale`]), so they mean the same at any resolution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrontendParams {
    /// Feature detection for new keyframes. Default: [`HessianParams::default`] with the
    /// threshold lowered from 100 to 30 (why: docs/decisions.md, "Feature detection
    /// threshold"), both pyramid levels (why: docs/decisions.md, "Detection on both pyramid
    /// levels").
    pub hessian: HessianParams,
    /// Guide stage: `guide_landmarks` landmarks tracked from the motion-model prediction with a
    /// wide search. Default [`TrackParams::GUIDE`].
    pub guide: TrackParams,
    /// Guide stage again, when the first gave no pose: a wider search. Default
    /// [`TrackParams::GUIDE_WIDE`].
    pub guide_wide: TrackParams,
    /// Final stage: every selected landmark tracked from the start pose (the prediction's, or
    /// the guides'). Default [`TrackParams::FINE`].
    pub track: TrackParams,
    /// Recovery: the affine-bank region matching of the guide landmarks, used when no cheaper
    /// attempt gave a pose (its `initial_affine` is replaced per landmark by the map the
    /// predicted motion induces). Default: [`MatchParams::DEFAULT`] with a 9 x 9 template (the
    /// landmark templates are 16 x 16 pixels) and no forward-backward check (it would search
    /// inside the template).
    pub matching: MatchParams,
    /// Landmarks matched in the guide stage (and in a recovery), spread over a 4 x 3 grid.
    /// Default 24 (16 measured and not adopted: docs/decisions.md, "Tracking levers measured and
    /// not adopted").
    pub guide_landmarks: usize,
    /// The guides' pose is used when it has at least this many inliers. Default 8.
    pub min_guide_inliers: usize,
    /// Pose estimation.
    pub pose: PoseParams,
    /// A feature is not made a landmark when a neighbour 2 pixels away differs in depth by more
    /// than this fraction of its depth, or has none (occlusion edges). Default 0.05.
    pub max_relative_depth_step: f32,
    /// New landmarks one keyframe creates at most. Default 200.
    pub max_new_landmarks: usize,
    /// Landmarks matched per frame at most, spread over an 8 x 6 grid (bounds the per-frame
    /// cost, about 30 k host instructions per landmark). Default 140, with
    /// `keyframe_min_inliers` scaled along (56 = 0.4 x 140): the largest count whose front end
    /// meets issue 3's 6 M host-instruction median. Why this value: docs/decisions.md,
    /// "Landmarks tracked per frame".
    pub max_tracked: usize,
    /// A keyframe that starts (or restarts) tracking needs at least this many landmarks.
    /// Default 30.
    pub min_keyframe_landmarks: usize,
    /// Tracking needs at least this many matches. Default 12.
    pub min_matches: usize,
    /// A tracked pose needs at least this many inliers. Default 12.
    pub min_inliers: usize,
    /// Keyframe rule: new keyframe when the inliers fall below this fraction of the inliers the
    /// frame after the last keyframe had. Default 0.7.
    pub keyframe_inlier_ratio: f32,
    /// Keyframe rule: new keyframe when inliers `<` this. Default 56 (see `max_tracked`).
    pub keyframe_min_inliers: usize,
    /// A keyframe due on a costly frame ([`FrontendWork::is_costly`]: it ran a second final
    /// stage or estimated the rotation from the small images) is put off to the next tracked
    /// frame, at most this many frames in a row; after that it is made on the costly frame
    /// with `costly_keyframe_octaves`. 0 makes every keyframe when due. Default 3.
    ///
    /// Why: a costly frame that also makes a keyframe (feature detection, new landmarks) was
    /// the costliest frame on the board, over issue 6's bar on instructions per frame; with
    /// this rule it is not. Figures and the levers not adopted: docs/decisions.md, "Keyframes on
    /// costly frames".
    ///
    /// [`FrontendWork::is_costly`]: super::FrontendWork::is_costly
    pub keyframe_max_put_off: u8,
    /// Pyramid octaves of the feature detection when a keyframe is made on a costly frame (the
    /// put-offs are used up): the image level alone costs about half the detection of both.
    /// Must be a valid [`HessianParams::octaves`]. Default 1.
    pub costly_keyframe_octaves: u8,
    /// Keyframe rule: new keyframe when the camera is farther than this from the last keyframe,
    /// metres. Default 0.25.
    pub keyframe_max_translation_m: f32,
    /// Keyframe rule: new keyframe when the camera has turned more than this from the last
    /// keyframe, radians. Default 0.26 (15 degrees).
    pub keyframe_max_rotation_rad: f32,
    /// A keyframe feature within this distance of a tracked landmark's pixel makes no new
    /// landmark (it is most likely the same point). Default 6 pixels.
    pub new_landmark_min_distance_px: f32,
    /// At a keyframe, a tracked landmark whose warp from its anchoring frame has an entry of
    /// `A - I` beyond this is re-anchored (template re-taken). Default 0.12.
    pub reanchor_max_warp: f32,
    /// Odometry mode: fuse each inlier's measured depth into its landmark's position (an
    /// inverse-variance running mean); off when a back end refines positions. Default `true`.
    pub fuse_depth: bool,
    /// Depth fusion stops adding weight after about this many measurements at the landmark's
    /// depth, so a landmark keeps following new evidence. Default 20.
    pub max_fused_measurements: f32,
    /// A tracked landmark is dropped when it was visible at least `cull_min_visible` times and
    /// found in less than this fraction of them. Default 0.3.
    pub cull_min_found_ratio: f32,
    /// See `cull_min_found_ratio`. Default 10.
    pub cull_min_visible: u16,
    /// A tracked landmark not found for this many frames is dropped. Default 60.
    pub cull_max_unseen_frames: u32,
    /// Seed of the pose estimator's random sampling (RANSAC). Default `0x5EED_F00D`.
    pub rng_seed: u64,
    /// Map reuse: at each keyframe, look for the map's untracked landmarks among its features
    /// (see `map_reuse.rs`). Default `false`: it makes SLAM worse (why: docs/decisions.md,
    /// "Map reuse off by default").
    pub map_reuse: bool,
}

impl FrontendParams {
    /// The defaults, documented per field; matching and pose values equal their own `Default`s
    /// except where a field's documentation says otherwise (a unit test checks it).
    pub const DEFAULT: Self = Self {
        // 30 instead of the detector's 100: docs/decisions.md, "Feature detection threshold".
        hessian: HessianParams { threshold: 30.0, ..HessianParams::DEFAULT },
        guide: TrackParams::GUIDE,
        guide_wide: TrackParams::GUIDE_WIDE,
        track: TrackParams::FINE,
        matching: MatchParams {
            half_size: 4,
            forward_backward_max_px: None,
            ..MatchParams::DEFAULT
        },
        guide_landmarks: 24,
        min_guide_inliers: 8,
        pose: PoseParams::DEFAULT,
        max_relative_depth_step: 0.05,
        max_new_landmarks: 200,
        max_tracked: 140,
        min_keyframe_landmarks: 30,
        min_matches: 12,
        min_inliers: 12,
        keyframe_inlier_ratio: 0.7,
        keyframe_min_inliers: 56,
        keyframe_max_put_off: 3,
        costly_keyframe_octaves: 1,
        keyframe_max_translation_m: 0.25,
        keyframe_max_rotation_rad: 0.26,
        new_landmark_min_distance_px: 6.0,
        reanchor_max_warp: 0.12,
        fuse_depth: true,
        max_fused_measurements: 20.0,
        cull_min_found_ratio: 0.3,
        cull_min_visible: 10,
        cull_max_unseen_frames: 60,
        rng_seed: 0x5EED_F00D,
        map_reuse: false,
    };

    /// These parameters with the sensor's measurement model (depth range, noise; the pose
    /// estimator weighs with it).
    pub const fn with_sensor(self, sensor: SensorModel) -> Self {
        Self { pose: PoseParams { sensor, ..self.pose }, ..self }
    }

    /// These parameters with their pixel values (search radii and steps, refinement shifts,
    /// distances between new landmarks), stated for
    /// [`REFERENCE_WIDTH_PX`](crate::config::REFERENCE_WIDTH_PX), scaled by `scale` (a tracking
    /// level's width over it; see [`pixel_scale`](crate::config::pixel_scale)), so that they mean
    /// the same share of the image at any resolution. Template sizes stay: the local map keeps
    /// templates of a fixed size. `scale` 1 gives the parameters unchanged.
    pub fn at_pixel_scale(self, scale: f32) -> Self {
        if scale == 1.0 || !(scale.is_finite() && scale > 0.0) {
            return self;
        }
        // Rounded to whole pixels, at least 1 where the stated value is.
        let px =
            |n: usize| if n == 0 { 0 } else { libm::roundf(n as f32 * scale).max(1.0) as usize };
        let track = |t: TrackParams| TrackParams {
            search_radius: px(t.search_radius),
            search_step: px(t.search_step),
            max_refine_shift_px: t.max_refine_shift_px * scale,
            ..t
        };
        Self {
            guide: track(self.guide),
            guide_wide: track(self.guide_wide),
            track: track(self.track),
            matching: MatchParams {
                search_radius: px(self.matching.search_radius),
                max_refine_shift_px: self.matching.max_refine_shift_px * scale,
                ..self.matching
            },
            new_landmark_min_distance_px: self.new_landmark_min_distance_px * scale,
            ..self
        }
    }

    /// The sensor's measurement model in use (the pose estimator's).
    pub const fn sensor(&self) -> &SensorModel {
        &self.pose.sensor
    }

    /// Whether the front end's own values are in range (detection, matching and pose parameters
    /// are checked by their own functions when used).
    pub fn is_valid(&self) -> bool {
        let pos = |x: f32| x.is_finite() && x > 0.0;
        pos(self.max_relative_depth_step)
            && self.max_tracked > 0
            && self.guide_landmarks >= 3
            && self.min_guide_inliers >= 3
            && self.guide.is_valid()
            && self.guide_wide.is_valid()
            && self.track.is_valid()
            && self.keyframe_inlier_ratio.is_finite()
            && pos(self.keyframe_max_translation_m)
            && pos(self.keyframe_max_rotation_rad)
            && self.new_landmark_min_distance_px.is_finite()
            && pos(self.reanchor_max_warp)
            && pos(self.max_fused_measurements)
            && self.cull_min_found_ratio.is_finite()
            && self.pose.is_valid()
            && self.hessian.validate().is_ok()
            && HessianParams { octaves: self.costly_keyframe_octaves, ..self.hessian }
                .validate()
                .is_ok()
    }
}

impl Default for FrontendParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}
