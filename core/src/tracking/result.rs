//! What the front end gives back for a frame, and its running figures: [`FrameResult`],
//! [`FrontendState`], [`GuideStage`], [`FrontendWork`], [`FrontendStats`] and [`FrontendError`].

use core::fmt;

use crate::frame::RgbdFrame;
use crate::geometry::{PinholeCamera, Pose};
use crate::map::KeyFrameId;

use super::places::LoopClosure;

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

/// What became of one frame: every frame is exactly one of these (see
/// [`FrameResult::outcome`]; [`FrontendStats`] counts each).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameOutcome {
    /// Its pose was estimated from its images (the very first keyframe counts: it defines the
    /// world frame).
    Tracked,
    /// Tracking restarted from a keyframe made at its predicted pose after a loss: a pose, but
    /// not one the images confirmed.
    Reinitialized,
    /// Not tracked against the local map, but found in a remembered place (the long-term store)
    /// and verified there: tracking restarted from a keyframe at that pose, in the map's frame.
    Relocalized,
    /// Not tracked: its pose is the motion model's prediction.
    Lost,
    /// No keyframe yet (no world frame): the front end waits for a frame with enough
    /// depth-carrying features.
    Initializing,
}

/// What [`Frontend::process`](super::Frontend::process) made of one frame.
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
    /// Whether tracking restarted at this frame from a remembered place after tracking failed:
    /// `t_wc` is the verified pose in the map's frame (it may jump from the previous frame's).
    pub relocalized: bool,
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
    /// The loop closed on this frame (for the last keyframe made, which looks for one on the
    /// first cheap frame after it): the map was moved by its correction, and `t_wc` is in the
    /// corrected frame (it jumps from the previous frame's by the correction).
    pub loop_closure: Option<LoopClosure>,
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
    /// [`FrontendParams::keyframe_max_put_off`](super::FrontendParams::keyframe_max_put_off)).
    pub fn is_costly(&self) -> bool {
        self.final_stages >= 2 || self.rotation_estimated
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

impl FrameResult {
    /// A frame at `t_wc` in `state` that nothing tracked, matched, made or closed (a frame's
    /// result before what happened to it is filled in), attached to `reference_keyframe`.
    pub(super) fn untracked(
        t_wc: Pose,
        state: FrontendState,
        reference_keyframe: Option<KeyFrameId>,
    ) -> Self {
        Self {
            t_wc,
            state,
            tracked: false,
            reinitialized: false,
            relocalized: false,
            keyframe: None,
            reference_keyframe,
            inliers: 0,
            matches: 0,
            guide_matches: 0,
            guide_stage: GuideStage::None,
            tracked_landmarks: 0,
            keyframe_landmarks: (0, 0, 0),
            work: FrontendWork::default(),
            loop_closure: None,
        }
    }

    /// What became of the frame.
    pub fn outcome(&self) -> FrameOutcome {
        match (self.tracked, self.reinitialized, self.state) {
            (true, _, _) => FrameOutcome::Tracked,
            _ if self.relocalized => FrameOutcome::Relocalized,
            (false, true, _) => FrameOutcome::Reinitialized,
            (false, false, FrontendState::Initializing) => FrameOutcome::Initializing,
            (false, false, _) => FrameOutcome::Lost,
        }
    }
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
pub(super) fn size_mismatch<const W: usize, const H: usize>(
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
    /// A [`FrontendParams`](super::FrontendParams) value is out of range.
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

/// Running totals since [`Frontend::new`](super::Frontend::new).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrontendStats {
    /// Frames processed: `tracked_frames + reinitializations + relocalizations + lost_frames +
    /// initializing_frames` (each frame has one [`FrameOutcome`]).
    pub frames: u32,
    /// Frames whose pose was estimated from the images ([`FrameOutcome::Tracked`]).
    pub tracked_frames: u32,
    /// Frames not tracked, their pose a prediction ([`FrameOutcome::Lost`]).
    pub lost_frames: u32,
    /// Frames where tracking restarted from a new keyframe after a loss
    /// ([`FrameOutcome::Reinitialized`]).
    pub reinitializations: u32,
    /// Frames where tracking restarted from a verified remembered place
    /// ([`FrameOutcome::Relocalized`]).
    pub relocalizations: u32,
    /// Frames before the first keyframe ([`FrameOutcome::Initializing`]).
    pub initializing_frames: u32,
    /// Keyframes made.
    pub keyframes: u32,
    /// Frames on which a due keyframe was put off because the frame was costly (see
    /// [`FrontendParams::keyframe_max_put_off`](super::FrontendParams::keyframe_max_put_off)).
    pub keyframes_put_off: u32,
    /// Frames whose guide landmarks could not give a pose from the motion model, so the affine
    /// bank was searched.
    pub bank_recoveries: u32,
}
