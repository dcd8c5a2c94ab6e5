//! The frame-to-keyframe RGB-D odometry front end: [`Frontend::process`] turns each
//! [`RgbdFrame`] into a camera pose.
//!
//! # Per frame
//!
//! 1. Predict `t_cw` with the [`MotionModel`] (constant velocity; the last pose with one pose of
//!    history; the identity before the first keyframe).
//! 2. Without a keyframe (state [`FrontendState::Initializing`]): detect Hessian features, keep
//!    those with a valid depth (in `[depth_min_m, depth_max_m]`, no discontinuity around them),
//!    back-project them to world landmarks at the predicted pose and store the gray image. The first
//!    keyframe defines the world frame (identity pose).
//! 3. With a keyframe: project every landmark with the prediction; where it lands inside the image
//!    (template half-size plus one pixel of margin), [`match_region`] the keyframe patch around its
//!    keyframe pixel into the current image, starting from the affine map the predicted relative
//!    motion induces on a fronto-parallel patch at the landmark's depth. Each match gives a
//!    [`Correspondence`] (landmark, matched pixel, current depth there when valid), and
//!    [`track_pose`] estimates `t_cw` from them.
//! 4. Keyframe rule (see [`FrontendParams`]): after a tracked frame, a new keyframe is made from it
//!    when the pose inliers fall below `keyframe_inlier_ratio` of the keyframe's landmarks or below
//!    `keyframe_min_inliers`, or when the camera has moved more than `keyframe_max_translation_m`
//!    or turned more than `keyframe_max_rotation_rad` from the keyframe.
//! 5. Loss: when tracking fails (too few matches or inliers, no pose), the frame is
//!    [`FrontendState::Lost`] and its output is the prediction with `tracked == false`: the
//!    trajectory never jumps. The next frame is tried against the same keyframe first; if that
//!    fails too, a new keyframe is made at that frame's predicted pose (so the trajectory stays
//!    continuous, with whatever drift the prediction has), and tracking resumes from it.
//!
//! # Memory
//!
//! Everything is inline, no heap: the Hessian detector, a [`Keyframe`] (gray image copy and
//! landmarks), the feature and correspondence scratch vectors. `size_of::<QvgaFrontend>()` is
//! 217,560 bytes (detector 103,272, keyframe 89,144, features 10,248, correspondences ~14 KB) and
//! `size_of::<VgaFrontend>()` 538,840 bytes, on a 64-bit host (unit-tested). [`Frontend::new`] is
//! `const`: place it in a `static` on the board, box it (or build it on a big stack) on a host.

use core::fmt;

use heapless::Vec;
use nalgebra::{Point2, Point3};

use super::keyframe::{Keyframe, depth_in_range};
use super::{
    Correspondence, MAX_CORRESPONDENCES, MotionModel, PoseError, PoseParams, TrackingRng,
    track_pose,
};
use crate::features::{FeatureError, FeatureVec, HessianDetector};
use crate::frame::RgbdFrame;
use crate::geometry::{PinholeCamera, Pose};
use crate::matching::{
    IDENTITY, Mat2, MatchError, MatchParams, TrackParams, match_region, track_patch,
};

pub use super::frontend_params::FrontendParams;

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
    /// The last frame was tracked against the keyframe (or made the keyframe).
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
    /// Whether `t_wc` was estimated from this frame's images (the first keyframe counts as
    /// tracked: it defines the world frame).
    pub tracked: bool,
    /// Whether this frame became the new keyframe.
    pub keyframe_created: bool,
    /// Pose inliers (0 when not tracked).
    pub inliers: usize,
    /// Landmarks matched into this frame.
    pub matches: usize,
    /// Guide landmarks matched from the motion-model prediction (0 before the first keyframe).
    pub guide_matches: usize,
    /// Whether the guides gave no pose and the affine bank was searched.
    pub bank_recovery: bool,
}

/// What [`Frontend::match_landmarks`] did.
#[derive(Debug, Clone, Copy)]
struct MatchSummary {
    /// Correspondences of the final stage.
    matches: usize,
    /// The pose the final stage started from.
    start_t_cw: Pose,
    /// Guide matches.
    guides: usize,
    /// Whether the bank was searched.
    bank_recovery: bool,
}

/// Why a frame could not be processed at all (bad input; a hard frame is [`FrontendState::Lost`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FrontendError {
    /// The gray image, depth image and camera do not have one size, or it exceeds the front end's.
    SizeMismatch {
        /// Gray image width, pixels.
        width: usize,
        /// Gray image height, pixels.
        height: usize,
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
            Self::SizeMismatch { width, height } => {
                write!(f, "frame {width}x{height} does not match the depth, camera or capacity")
            }
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
    /// Keyframes made.
    pub keyframes: u32,
    /// Frames whose guide landmarks could not give a pose from the motion model, so the affine
    /// bank was searched (see the module documentation).
    pub bank_recoveries: u32,
}

/// The odometry front end for images up to `W` x `H` (see the module documentation).
#[derive(Debug)]
pub struct Frontend<const W: usize, const H: usize> {
    params: FrontendParams,
    detector: HessianDetector<W>,
    features: FeatureVec,
    keyframe: Keyframe<W, H>,
    has_keyframe: bool,
    correspondences: Vec<Correspondence, MAX_CORRESPONDENCES>,
    motion: MotionModel,
    rng: TrackingRng,
    state: FrontendState,
    last: Option<(f64, Pose)>,
    stats: FrontendStats,
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
            keyframe: Keyframe::new(),
            has_keyframe: false,
            correspondences: Vec::new(),
            motion: MotionModel::new(),
            rng: TrackingRng::new(0x5EED_F00D),
            state: FrontendState::Initializing,
            last: None,
            stats: FrontendStats {
                frames: 0,
                tracked_frames: 0,
                lost_frames: 0,
                keyframes: 0,
                bank_recoveries: 0,
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

    /// The current keyframe, if one was made.
    pub fn keyframe(&self) -> Option<&Keyframe<W, H>> {
        self.has_keyframe.then_some(&self.keyframe)
    }

    /// Processes one frame (see the module documentation). `cam` must describe the frame's size.
    ///
    /// # Errors
    /// [`FrontendError::SizeMismatch`], [`FrontendError::TimestampNotIncreasing`] or
    /// [`FrontendError::InvalidParams`]; the state is unchanged then. A frame that cannot be
    /// tracked (black, no depth) is not an error: it gives [`FrontendState::Lost`] (or stays
    /// [`FrontendState::Initializing`]).
    pub fn process(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
    ) -> Result<FrameResult, FrontendError> {
        self.check_input(frame, cam)?;
        let predicted_t_cw = self.predict(frame.timestamp_s);
        self.stats.frames = self.stats.frames.saturating_add(1);
        let result = if self.has_keyframe {
            self.track_or_recover(frame, cam, &predicted_t_cw)
        } else {
            self.initialize(frame, cam, &predicted_t_cw, true)
        };
        self.state = result.state;
        if result.tracked {
            self.stats.tracked_frames = self.stats.tracked_frames.saturating_add(1);
        }
        if result.state == FrontendState::Lost {
            self.stats.lost_frames = self.stats.lost_frames.saturating_add(1);
        }
        self.last = Some((frame.timestamp_s, result.t_wc.inverse()));
        Ok(result)
    }

    fn check_input(&self, frame: &RgbdFrame<'_>, cam: &PinholeCamera) -> Result<(), FrontendError> {
        let (width, height) = frame.gray.size();
        let fits = width <= W && height <= H;
        if !fits
            || frame.depth.size() != (width, height)
            || (cam.width(), cam.height()) != (width, height)
        {
            return Err(FrontendError::SizeMismatch { width, height });
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

    /// Makes a keyframe of `frame` at the predicted pose; `tracked_if_first` marks the very
    /// first keyframe as tracked (it defines the world frame).
    fn initialize(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        t_cw: &Pose,
        tracked_if_first: bool,
    ) -> FrameResult {
        let first = !self.has_keyframe && self.stats.keyframes == 0;
        let made = self.make_keyframe(frame, cam, t_cw);
        let (state, tracked) = match (made, first) {
            (true, _) => (FrontendState::Tracking, first && tracked_if_first),
            (false, true) => (FrontendState::Initializing, false),
            (false, false) => (FrontendState::Lost, false),
        };
        self.motion.reset();
        if made {
            // Cannot fail: timestamps were checked to increase.
            let _ = self.motion.update(frame.timestamp_s, t_cw);
        }
        FrameResult {
            t_wc: t_cw.inverse(),
            state,
            tracked,
            keyframe_created: made,
            inliers: 0,
            matches: 0,
            guide_matches: 0,
            bank_recovery: false,
        }
    }

    /// Detects features and replaces the keyframe when enough of them have depth.
    fn make_keyframe(&mut self, frame: &RgbdFrame<'_>, cam: &PinholeCamera, t_cw: &Pose) -> bool {
        let detected = self.detector.detect(&frame.gray, &self.params.hessian, &mut self.features);
        if let Err(FeatureError::ImageTooWide { .. } | FeatureError::InvalidParams { .. }) =
            detected
        {
            return false;
        }
        let filter = self.params.landmark_filter();
        let min = self.params.min_keyframe_landmarks;
        let t_wc = t_cw.inverse();
        match self.keyframe.rebuild(frame, cam, &t_wc, &self.features, &filter, min) {
            Ok(n) if n >= min => {
                self.has_keyframe = true;
                self.stats.keyframes = self.stats.keyframes.saturating_add(1);
                true
            }
            _ => false,
        }
    }

    /// Tracks against the keyframe; on failure right after a loss, re-initializes.
    fn track_or_recover(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        predicted_t_cw: &Pose,
    ) -> FrameResult {
        let was_lost = self.state == FrontendState::Lost;
        let summary = self.match_landmarks(frame, cam, predicted_t_cw);
        let (matches, start_t_cw) = (summary.matches, summary.start_t_cw);
        let estimate = if matches >= self.params.min_matches {
            let (corrs, pose) = (&self.correspondences, &self.params.pose);
            track_pose(cam, corrs, Some(&start_t_cw), pose, &mut self.rng)
        } else {
            Err(PoseError::TooFewCorrespondences {
                count: matches,
                required: self.params.min_matches,
            })
        };
        match estimate {
            Ok(est) if est.num_inliers >= self.params.min_inliers => {
                // Cannot fail: timestamps were checked to increase.
                let _ = self.motion.update(frame.timestamp_s, &est.t_cw);
                let new_kf = self.needs_keyframe(&est.t_cw, est.num_inliers)
                    && self.make_keyframe(frame, cam, &est.t_cw);
                FrameResult {
                    t_wc: est.t_cw.inverse(),
                    state: FrontendState::Tracking,
                    tracked: true,
                    keyframe_created: new_kf,
                    inliers: est.num_inliers,
                    matches,
                    guide_matches: summary.guides,
                    bank_recovery: summary.bank_recovery,
                }
            }
            _ if was_lost => {
                let mut r = self.initialize(frame, cam, predicted_t_cw, false);
                r.matches = matches;
                r.guide_matches = summary.guides;
                r.bank_recovery = summary.bank_recovery;
                r
            }
            _ => FrameResult {
                t_wc: predicted_t_cw.inverse(),
                state: FrontendState::Lost,
                tracked: false,
                keyframe_created: false,
                inliers: 0,
                matches,
                guide_matches: summary.guides,
                bank_recovery: summary.bank_recovery,
            },
        }
    }

    /// The keyframe rule of the module documentation.
    fn needs_keyframe(&self, t_cw: &Pose, inliers: usize) -> bool {
        let p = &self.params;
        let landmarks = self.keyframe.landmarks().len();
        // Counts are at most 512: exact in f32.
        let few = (inliers as f32) < p.keyframe_inlier_ratio * landmarks as f32
            || inliers < p.keyframe_min_inliers;
        let t_ck = t_cw * self.keyframe.t_wc();
        let moved = t_ck.translation.vector.norm() > p.keyframe_max_translation_m
            || t_ck.rotation.angle() > p.keyframe_max_rotation_rad;
        few || moved
    }

    /// Matches the keyframe's landmarks into `frame` in three stages (see the module
    /// documentation): guides from `predicted_t_cw`, their pose (or the bank recovery), then every
    /// landmark from that pose. Fills `self.correspondences`.
    fn match_landmarks(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        predicted_t_cw: &Pose,
    ) -> MatchSummary {
        self.correspondences.clear();
        let mut summary = MatchSummary {
            matches: 0,
            start_t_cw: *predicted_t_cw,
            guides: 0,
            bank_recovery: false,
        };
        let Some(kf_img) = self.keyframe.image() else { return summary };
        let p = &self.params;
        let ctx = MatchContext { kf: &self.keyframe, kf_img: &kf_img, frame, cam, params: p };
        let corrs = &mut self.correspondences;
        ctx.track(predicted_t_cw, Matcher::Patch(&p.guide), p.guide_landmarks, corrs);
        summary.guides = corrs.len();
        let mut start = guide_pose(cam, corrs, predicted_t_cw, p, &mut self.rng);
        if start.is_none() {
            summary.bank_recovery = true;
            // The prediction was too poor for the guides: search the affine bank instead.
            corrs.clear();
            ctx.track(predicted_t_cw, Matcher::Bank(&p.matching), p.guide_landmarks, corrs);
            self.stats.bank_recoveries = self.stats.bank_recoveries.saturating_add(1);
            start = guide_pose(cam, corrs, predicted_t_cw, p, &mut self.rng);
        }
        summary.start_t_cw = start.unwrap_or(*predicted_t_cw);
        corrs.clear();
        ctx.track(&summary.start_t_cw, Matcher::Patch(&p.track), p.max_tracked, corrs);
        summary.matches = corrs.len();
        summary
    }
}

/// The pose of the guide correspondences, when it has at least `min_guide_inliers` inliers.
fn guide_pose(
    cam: &PinholeCamera,
    corrs: &[Correspondence],
    predicted_t_cw: &Pose,
    p: &FrontendParams,
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

/// How one landmark is matched: the predicted-warp patch tracker, or the affine bank.
#[derive(Clone, Copy)]
enum Matcher<'a> {
    Patch(&'a TrackParams),
    Bank(&'a crate::matching::MatchParams),
}

/// What matching a landmark into the current frame reads.
struct MatchContext<'a, const W: usize, const H: usize> {
    kf: &'a Keyframe<W, H>,
    kf_img: &'a crate::image::GrayView<'a>,
    frame: &'a RgbdFrame<'a>,
    cam: &'a PinholeCamera,
    params: &'a FrontendParams,
}

impl<const W: usize, const H: usize> MatchContext<'_, W, H> {
    /// Matches landmarks, in the keyframe's (bucketed, so spread) order, into the frame from the
    /// pose `t_cw`, pushing a correspondence per match into `out` until `max_matches` matched;
    /// landmarks whose search would leave the image are skipped.
    fn track(
        &self,
        t_cw: &Pose,
        matcher: Matcher<'_>,
        max_matches: usize,
        out: &mut Vec<Correspondence, MAX_CORRESPONDENCES>,
    ) {
        let t_ck = t_cw * self.kf.t_wc();
        let margin = match matcher {
            Matcher::Patch(t) => (t.half_size + t.search_radius + 1) as f32,
            Matcher::Bank(m) => m.half_size as f32 + 1.0,
        };
        let (zmin, zmax) = (self.params.depth_min_m, self.params.depth_max_m);
        for lm in self.kf.landmarks() {
            if out.len() >= max_matches {
                break;
            }
            let Some(uv) = self.cam.project_world(t_cw, &lm.p_w) else { continue };
            if !self.cam.in_image(&uv, margin) {
                continue;
            }
            let affine = induced_affine(self.cam, &t_ck, lm.uv_kf, lm.depth_kf_m);
            let gray = &self.frame.gray;
            let matched = match matcher {
                Matcher::Patch(t) => {
                    let pred = (uv.x, uv.y);
                    track_patch(self.kf_img, lm.uv_kf, &affine, gray, pred, t)
                        .or_else(|e| match e {
                            // Lucas-Kanade alone missed: one search at radius 1, then again.
                            MatchError::RefinementFailed | MatchError::LowCorrelation { .. }
                                if t.search_radius == 0 =>
                            {
                                let wider = TrackParams { search_radius: 1, ..*t };
                                track_patch(self.kf_img, lm.uv_kf, &affine, gray, pred, &wider)
                            }
                            e => Err(e),
                        })
                        .map(|m| m.uv)
                }
                Matcher::Bank(m) => {
                    let params = MatchParams { initial_affine: affine, ..*m };
                    match_region(self.kf_img, lm.uv_kf, gray, (uv.x, uv.y), &params)
                        .map(|m| m.centre_in_target)
                }
            };
            let Ok((u, v)) = matched else { continue };
            let (x, y) = (libm::roundf(u), libm::roundf(v));
            let depth_m = if x >= 0.0 && y >= 0.0 {
                depth_in_range(&self.frame.depth, x as usize, y as usize, zmin, zmax)
            } else {
                None
            };
            let c = Correspondence { p_w: lm.p_w, uv: Point2::new(u, v), depth_m };
            if !c.is_valid() || out.push(c).is_err() {
                continue;
            }
        }
    }
}

/// The linear map `d(uv_cur) / d(uv_kf)` that the motion `t_ck` (keyframe camera to current
/// camera) induces at keyframe pixel `uv_kf` on a fronto-parallel patch at depth `z_m`, by finite
/// differences of one pixel; the identity when a projection fails or the map is singular.
fn induced_affine(cam: &PinholeCamera, t_ck: &Pose, uv_kf: (f32, f32), z_m: f32) -> Mat2 {
    let map = |du: f32, dv: f32| -> Option<Point2<f32>> {
        let p_k: Point3<f32> = cam.back_project(uv_kf.0 + du, uv_kf.1 + dv, z_m);
        cam.project(&(t_ck * p_k))
    };
    let (Some(c), Some(cu), Some(cv)) = (map(0.0, 0.0), map(1.0, 0.0), map(0.0, 1.0)) else {
        return IDENTITY;
    };
    let a = [[cu.x - c.x, cv.x - c.x], [cu.y - c.y, cv.y - c.y]];
    // A plausible map scales areas by 1/16..16; anything else (or NaN) falls back to identity.
    let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
    if det > 1.0 / 16.0 && det < 16.0 { a } else { IDENTITY }
}

#[cfg(test)]
#[path = "frontend_tests.rs"]
mod tests;
