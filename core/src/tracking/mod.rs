//! The frame-to-map RGB-D front end: [`Frontend::process`] turns each RGB-D frame into a camera
//! pose, tracking the landmarks of its local map with the patch tracker ([`crate::matching`]),
//! estimating the pose with [`crate::pose`], and adding keyframes and landmarks to the
//! [`crate::map`].
//!
//! Files by concern: `frontend.rs` (the state, grouped by the concern that owns each part, and its
//! constructors), `pipeline.rs` (the per-frame pipeline below), `landmark_matching.rs` (the guide
//! and final stages), `keyframe_rule.rs` (when a keyframe is made), `keyframe.rs` (making one:
//! observations, re-anchoring, new landmarks), `map_reuse.rs` (re-acquiring map landmarks),
//! `local_map.rs` (the tracked landmarks and their templates), `places.rs` (the port to the
//! place memory), `result.rs` (what a frame gives back), `params.rs` (every tunable). Candidates are spread over the image by
//! `crate::grid_spread`.
//!
//! # Per frame
//!
//! 1. Predict `t_cw` with the [`MotionModel`](crate::pose::MotionModel) (constant velocity; the last pose with one pose of
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
//!    guides with a wider search; the strongest final stage wins. A weak final stage whose pose
//!    agrees with the best weak one before it (within 5 mm and 0.25 degrees) ends the attempts:
//!    two start poses found the same pose. Only when none gave a pose at
//!    all are the same landmarks searched with the affine bank
//!    ([`match_region`](crate::matching::match_region)), the costliest attempt (see
//!    `landmark_matching.rs`; why this order: docs/decisions.md, "Prediction tried before the
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
//!    (see `keyframe.rs`).
//! 7. Loss: when the attempts before the affine bank give no pose, a frame given a place memory
//!    ([`Places`], through [`Frontend::process_with`]; `crate::loops` implements it) asks it where
//!    it is before the bank (the costliest attempt, which then runs only when no place is
//!    verified): features are detected, and a remembered place or a keyframe of the active map
//!    that geometric verification accepts gives the pose. Tracking then restarts from a
//!    keyframe made there, in the map's frame ([`FrameOutcome::Relocalized`]; the output may jump,
//!    and says so). Otherwise the frame is [`FrontendState::Lost`] and its output is the
//!    prediction with `tracked == false`. The next frames are tried against the local map (and the
//!    place memory) first; when one fails too (with a place memory: after
//!    [`RELOCALIZE_FRAMES`] lost frames in a row), the local map is
//!    emptied and a keyframe is made at that frame's predicted pose (the trajectory stays continuous, with whatever drift the
//!    prediction has), and tracking resumes from it. Its [`FrameResult::tracked`] is `false` and
//!    [`FrameResult::reinitialized`] `true`.
//!
//! A keyframe the map retires to make room (its oldest) is handed to the place memory first, so
//! that the robot remembers the places it left ([`Places::remember`]).
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

pub mod frontend;
mod keyframe;
mod keyframe_rule;
mod landmark_matching;
pub mod local_map;
mod map_reuse;
mod params;
mod pipeline;
mod places;
mod result;
mod tracker;

pub use frontend::{Frontend, QvgaFrontend, VgaFrontend};
pub use local_map::{
    BoardLocalMap, Insertions, LocalMap, PATCH_SIDE, TrackedLandmark, induced_affine,
};
pub use params::FrontendParams;
pub use pipeline::RELOCALIZE_FRAMES;
pub use places::{LoopClosure, NoPlaces, PlaceQuery, Places, QueryPoint};
pub use result::{
    FrameOutcome, FrameResult, FrontendError, FrontendState, FrontendStats, FrontendWork,
    GuideStage,
};

#[cfg(test)]
mod tests;
