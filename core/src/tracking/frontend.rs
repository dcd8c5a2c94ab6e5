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
//! ([`capacity::MAX_TRACKED_LANDMARKS`] templates of 16 x 16 pixels), the feature, candidate and
//! correspondence scratch. The map is the caller's (so the back end can share it). Sizes are in
//! `memory-budget.md` (unit-tested). [`Frontend::new`] is `const`: place it in a `static` on the
//! board, box it on a host.

use core::fmt;

use heapless::Vec;

use super::local_map::BoardLocalMap;
use crate::config::capacity;
use crate::features::{FeatureVec, HessianDetector};
use crate::frame::RgbdFrame;
use crate::geometry::{PinholeCamera, Pose};
use crate::grid_spread::Candidate;
use crate::map::{KeyFrameId, Map};
use crate::pose::small_image_rotation::SmallImage;
use crate::pose::{Correspondence, MAX_CORRESPONDENCES, MotionModel, TrackingRng};

pub use super::params::FrontendParams;

/// The front end at the reference board's QVGA profile (320 x 240).
pub type QvgaFrontend = Frontend<320, 240>;
/// The front end at the VGA profile (640 x 480).
pub type VgaFrontend = Frontend<640, 480>;

/// Where the front end is in its life cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrontendState {
    /// No keyframe yet: waiting for a frame with enough depth-carrying features.
    Initializing,
    /// The last frame was tracked (or made a keyframe that restarts tracking).
    Tracking,
    /// The last frame could not be tracked; its pose is a prediction.
    Lost,
}

/// What [`Frontend::process`] made of one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameResult {
    /// Camera-to-world pose of the frame: estimated when `tracked`, otherwise the prediction.
    pub t_wc: Pose,
    /// State after this frame.
    pub state: FrontendState,
    /// Whether `t_wc` was estimated from this frame's images (the very first keyframe counts as
    /// tracked: it defines the world frame).
    pub tracked: bool,
    /// Whether tracking restarted at this frame from a new keyframe at the predicted pose after a
    /// loss (the trajectory is continuous but not corrected across it).
    pub reinitialized: bool,
    /// The keyframe this frame became, if it did.
    pub keyframe: Option<KeyFrameId>,
    /// The most recent keyframe after this frame (the one a back end would attach it to).
    pub reference_keyframe: Option<KeyFrameId>,
    /// Pose inliers (0 when not tracked).
    pub inliers: usize,
    /// Landmarks matched into this frame in the final stage.
    pub matches: usize,
    /// Guide landmarks matched from the motion-model prediction.
    pub guide_matches: usize,
    /// Which guide attempt gave the pose the final stage started from.
    pub guide_stage: GuideStage,
    /// Landmarks in the local map after this frame.
    pub tracked_landmarks: usize,
    /// When this frame became a keyframe: the landmarks it observed that were tracked, those it
    /// re-acquired from the map (map reuse), and those it created.
    pub keyframe_landmarks: (usize, usize, usize),
    /// The costly steps the front end ran on this frame (what its cost is made of).
    pub work: FrontendWork,
}

/// The costly steps the front end ran on one frame: a frame's instructions are mostly these
/// (`memory-budget.md` gives each one's cost on the Cortex-M4). Ordered field by field, so that
/// `cargo xtask budgets` can sort frames by kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrontendWork {
    /// Final stages run (up to `max_tracked` landmarks matched and a pose estimated), the rerun
    /// of the winning one included.
    pub final_stages: u8,
    /// Guide runs (`guide_landmarks` landmarks matched with a wide search, or by the affine bank).
    pub guide_runs: u8,
    /// Whether the rotation was estimated from the small images.
    pub rotation_estimated: bool,
    /// Whether Hessian features were detected (a keyframe was made or attempted).
    pub detected: bool,
}

impl FrontendWork {
    /// Whether the frame's tracking was costly: it ran a second final stage or estimated the
    /// rotation from the small images. A keyframe due on such a frame is put off (see
    /// [`FrontendParams::keyframe_max_put_off`]).
    pub fn is_costly(&self) -> bool {
        self.final_stages >= 2 || self.rotation_estimated
    }
}

/// What the keyframe rule does on a tracked frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum KeyframeDecision {
    /// No keyframe is due.
    None,
    /// A keyframe is due and put off to the next tracked frame.
    PutOff,
    /// A keyframe is made, with this many pyramid octaves of feature detection.
    Make {
        /// [`HessianParams::octaves`](crate::features::HessianParams::octaves) to detect with.
        octaves: u8,
    },
}

/// The keyframe decision of a tracked frame: `due` is the keyframe rule's verdict, `costly` is
/// [`FrontendWork::is_costly`], `put_off` the keyframes put off in a row before this frame.
pub(super) fn decide_keyframe(
    due: bool,
    costly: bool,
    put_off: u8,
    params: &FrontendParams,
) -> KeyframeDecision {
    match (due, costly) {
        (false, _) => KeyframeDecision::None,
        (true, false) => KeyframeDecision::Make { octaves: params.hessian.octaves },
        (true, true) if put_off < params.keyframe_max_put_off => KeyframeDecision::PutOff,
        (true, true) => KeyframeDecision::Make { octaves: params.costly_keyframe_octaves },
    }
}

/// The attempts of the guide stage, in the order they are tried (see the module documentation):
/// which one gave the pose the final stage started from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GuideStage {
    /// The guides matched from the motion model's prediction.
    MotionModel,
    /// The guides matched after re-predicting the rotation from small blurry images.
    SmallImageRotation,
    /// The guides matched with the wide search.
    WideSearch,
    /// The guides matched by the affine bank.
    AffineBank,
    /// The final stage started from the prediction itself (tried first, or after guides that
    /// gave no pose), or the frame was not tracked against the local map.
    None,
}

impl GuideStage {
    /// Whether a recovery path gave the pose: the small-image rotation, the wide search or the
    /// affine bank.
    pub fn is_recovery(self) -> bool {
        matches!(self, Self::SmallImageRotation | Self::WideSearch | Self::AffineBank)
    }
}

/// The [`FrontendError::SizeMismatch`] of `frame` and `cam` for a front end of `W x H`, built
/// apart from the check (cold, not inlined): built inline, it made the compiler's code for the
/// inlined front end costlier on the board. Why: docs/decisions.md, "Tracking code generation on
/// the Cortex-M4".
#[cold]
#[inline(never)]
fn size_mismatch<const W: usize, const H: usize>(
    frame: &RgbdFrame<'_>,
    cam: &PinholeCamera,
) -> FrontendError {
    FrontendError::SizeMismatch {
        gray: frame.gray.size(),
        depth: frame.depth.size(),
        camera: (cam.width(), cam.height()),
        capacity: (W, H),
    }
}

/// Why a frame could not be processed at all (bad input; a hard frame is [`FrontendState::Lost`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FrontendError {
    /// The gray image, depth image and camera do not have one size, or it exceeds the front end's.
    SizeMismatch {
        /// The gray image's width and height, pixels.
        gray: (usize, usize),
        /// The width and height the depth image covers, in gray pixels (a coarser depth level
        /// covers its samples' blocks).
        depth: (usize, usize),
        /// The camera's width and height, pixels.
        camera: (usize, usize),
        /// The largest frame the front end holds (`W`, `H`), pixels.
        capacity: (usize, usize),
    },
    /// The timestamp is not finite or does not follow the previous frame's.
    TimestampNotIncreasing {
        /// Previous timestamp, seconds.
        previous_s: f64,
        /// This frame's timestamp, seconds.
        current_s: f64,
    },
    /// A [`FrontendParams`] value is out of range.
    InvalidParams,
}

impl fmt::Display for FrontendError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::SizeMismatch { gray, depth, camera, capacity } => write!(
                f,
                "gray image {}x{}, depth covering {}x{}, camera {}x{}: the three must have one \
                 size, at most the {}x{} that the front end holds",
                gray.0, gray.1, depth.0, depth.1, camera.0, camera.1, capacity.0, capacity.1
            ),
            Self::TimestampNotIncreasing { previous_s, current_s } => {
                write!(f, "timestamp {current_s} s does not follow {previous_s} s")
            }
            Self::InvalidParams => write!(f, "front-end parameters out of range"),
        }
    }
}

impl core::error::Error for FrontendError {}

/// Running totals since [`Frontend::new`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrontendStats {
    /// Frames processed.
    pub frames: u32,
    /// Frames whose pose was estimated from the images.
    pub tracked_frames: u32,
    /// Frames in state [`FrontendState::Lost`].
    pub lost_frames: u32,
    /// Times tracking restarted from a new keyframe after a loss.
    pub reinitializations: u32,
    /// Keyframes made.
    pub keyframes: u32,
    /// Frames on which a due keyframe was put off because the frame was costly (see
    /// [`FrontendParams::keyframe_max_put_off`]).
    pub keyframes_put_off: u32,
    /// Frames whose guide landmarks could not give a pose from the motion model, so the affine
    /// bank was searched.
    pub bank_recoveries: u32,
}

/// The front end for images up to `W` x `H` (see the module documentation).
#[derive(Debug, Clone)]
pub struct Frontend<const W: usize, const H: usize> {
    pub(super) params: FrontendParams,
    pub(super) detector: HessianDetector<W>,
    pub(super) features: FeatureVec,
    pub(super) local: BoardLocalMap,
    pub(super) correspondences: Vec<Correspondence, MAX_CORRESPONDENCES>,
    /// Local-map index of each correspondence.
    pub(super) sources: Vec<u16, MAX_CORRESPONDENCES>,
    pub(super) candidates: Vec<Candidate, { capacity::MAX_TRACKED_LANDMARKS }>,
    pub(super) motion: MotionModel,
    pub(super) rng: TrackingRng,
    state: FrontendState,
    last: Option<(f64, Pose)>,
    pub(super) stats: FrontendStats,
    /// Frames processed, as a frame number for the local map's bookkeeping.
    pub(super) frame_index: u32,
    /// The last keyframe and its camera-to-world pose when it was made.
    pub(super) reference: Option<(KeyFrameId, Pose)>,
    /// Inliers of the first tracked frame after the last keyframe (the keyframe rule's base).
    pub(super) inliers_after_keyframe: Option<usize>,
    /// This frame and the previous one as small blurry images (rotation recovery).
    pub(super) small_current: SmallImage,
    pub(super) small_previous: SmallImage,
    /// The previous frame's output `t_cw`.
    pub(super) previous_t_cw: Option<Pose>,
    /// The previous frame's pose inliers (0 when it was not tracked).
    pub(super) previous_inliers: usize,
    /// The last keyframe's tracked and created landmarks.
    pub(super) last_keyframe_counts: (usize, usize, usize),
    /// Due keyframes put off in a row (costly frames).
    pub(super) keyframes_put_off: u8,
    /// The costly steps run on the frame being processed.
    pub(super) work: FrontendWork,
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
            detector: HessianDetector::new(),
            features: FeatureVec::new(),
            local: BoardLocalMap::new(),
            correspondences: Vec::new(),
            sources: Vec::new(),
            candidates: Vec::new(),
            motion: MotionModel::new(),
            rng: TrackingRng::new(params.rng_seed),
            state: FrontendState::Initializing,
            last: None,
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
            reference: None,
            inliers_after_keyframe: None,
            small_current: SmallImage::new(),
            small_previous: SmallImage::new(),
            previous_t_cw: None,
            previous_inliers: 0,
            last_keyframe_counts: (0, 0, 0),
            keyframes_put_off: 0,
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
        self.state
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
        let predicted_t_cw = self.predict(frame.timestamp_s);
        self.stats.frames = self.stats.frames.saturating_add(1);
        self.frame_index = self.frame_index.wrapping_add(1);
        self.work = FrontendWork::default();
        self.small_current.build(&frame.gray);
        // Ids of a map the caller cleared or replaced no longer resolve: start over then.
        if self.reference.is_some_and(|(id, _)| map.keyframe(id).is_none()) {
            self.local.clear();
            self.reference = None;
        }
        let result = if self.local.is_empty() || self.reference.is_none() {
            self.initialize(frame, cam, map, &predicted_t_cw)
        } else {
            self.track_or_recover(frame, cam, map, &predicted_t_cw)
        };
        self.state = result.state;
        if result.tracked {
            self.stats.tracked_frames = self.stats.tracked_frames.saturating_add(1);
        }
        if result.state == FrontendState::Lost {
            self.stats.lost_frames = self.stats.lost_frames.saturating_add(1);
        }
        if result.reinitialized {
            self.stats.reinitializations = self.stats.reinitializations.saturating_add(1);
        }
        self.last = Some((frame.timestamp_s, result.t_wc.inverse()));
        self.previous_t_cw = Some(result.t_wc.inverse());
        self.previous_inliers = result.inliers;
        core::mem::swap(&mut self.small_current, &mut self.small_previous);
        let keyframe_landmarks =
            if result.keyframe.is_some() { self.last_keyframe_counts } else { (0, 0, 0) };
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
        let previous_s = self.last.map_or(f64::NEG_INFINITY, |(t, _)| t);
        if !frame.timestamp_s.is_finite() || frame.timestamp_s <= previous_s {
            return Err(FrontendError::TimestampNotIncreasing {
                previous_s,
                current_s: frame.timestamp_s,
            });
        }
        Ok(())
    }

    /// The predicted `t_cw`: constant velocity while tracking, else the last output pose, else
    /// the identity.
    fn predict(&self, timestamp_s: f64) -> Pose {
        if let Ok(Some(t_cw)) = self.motion.predict(timestamp_s) {
            return t_cw;
        }
        self.last.map_or_else(Pose::identity, |(_, t_cw)| t_cw)
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
        self.correspondences.clear();
        self.sources.clear();
        let made = self.make_keyframe(frame, cam, map, t_cw, None, self.params.hessian.octaves);
        let state = match (made, first) {
            (Some(_), _) => FrontendState::Tracking,
            (None, true) => FrontendState::Initializing,
            (None, false) => FrontendState::Lost,
        };
        self.motion.reset();
        if made.is_some() {
            // Cannot fail: timestamps were checked to increase.
            let _ = self.motion.update(frame.timestamp_s, t_cw);
        }
        FrameResult {
            t_wc: t_cw.inverse(),
            state,
            tracked: made.is_some() && first,
            reinitialized: made.is_some() && !first,
            keyframe: made,
            reference_keyframe: self.reference.map(|(id, _)| id),
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
        let was_lost = self.state == FrontendState::Lost;
        let summary = self.match_landmarks(frame, cam, map, predicted_t_cw);
        // The inlier mask indexes the scratch: it must hold the winning final stage.
        debug_assert!(
            summary.estimate.is_none() || summary.matches == self.correspondences.len(),
            "the scratch does not hold the winning final stage"
        );
        let lost = FrameResult {
            t_wc: predicted_t_cw.inverse(),
            state: FrontendState::Lost,
            tracked: false,
            reinitialized: false,
            keyframe: None,
            reference_keyframe: self.reference.map(|(id, _)| id),
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
        let _ = self.motion.update(frame.timestamp_s, &est.t_cw);
        self.update_local_map(cam, map, &est);
        let base = *self.inliers_after_keyframe.get_or_insert(est.num_inliers);
        let due = self.needs_keyframe(&est.t_cw, est.num_inliers, base);
        let decision =
            decide_keyframe(due, self.work.is_costly(), self.keyframes_put_off, &self.params);
        let keyframe = match decision {
            KeyframeDecision::None => {
                self.keyframes_put_off = 0;
                None
            }
            KeyframeDecision::PutOff => {
                self.keyframes_put_off = self.keyframes_put_off.saturating_add(1);
                self.stats.keyframes_put_off = self.stats.keyframes_put_off.saturating_add(1);
                None
            }
            KeyframeDecision::Make { octaves } => {
                self.keyframes_put_off = 0;
                self.make_keyframe(frame, cam, map, &est.t_cw, Some(&est.inliers), octaves)
            }
        };
        self.cull_local_map();
        FrameResult {
            t_wc: est.t_cw.inverse(),
            state: FrontendState::Tracking,
            tracked: true,
            keyframe,
            reference_keyframe: self.reference.map(|(id, _)| id),
            inliers: est.num_inliers,
            ..lost
        }
    }

    /// The keyframe rule of the module documentation.
    fn needs_keyframe(&self, t_cw: &Pose, inliers: usize, base: usize) -> bool {
        let p = &self.params;
        // Counts are at most 512: exact in f32.
        let few = (inliers as f32) < p.keyframe_inlier_ratio * base as f32
            || inliers < p.keyframe_min_inliers;
        let moved = self.reference.is_none_or(|(_, t_wk)| {
            let t_ck = t_cw * t_wk;
            t_ck.translation.vector.norm() > p.keyframe_max_translation_m
                || t_ck.rotation.angle() > p.keyframe_max_rotation_rad
        });
        few || moved
    }
}

#[cfg(test)]
#[path = "tests.rs"]
mod tests;
