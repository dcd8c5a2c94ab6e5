//! The frame-to-map front end: [`Frontend::process`] turns each RGB-D frame into a camera pose,
//! tracking the landmarks of its local map with the patch tracker ([`crate::matching`]), estimating
//! the pose with [`crate::pose`], and adding keyframes and landmarks to the [`crate::map`].
//!
//! Files by concern, each owning its part of the front end's state: `frontend.rs` (the per-frame
//! pipeline and what it keeps of recent frames), `landmark_matching.rs` (the guide and final
//! stages, and their scratch), `keyframe.rs` (the keyframe rule, detection, keyframes and new
//! landmarks), `map_reuse.rs` (re-acquiring map landmarks), `local_map.rs` (the tracked landmarks
//! and their templates), `result.rs` (what a frame gives back), `params.rs` (every tunable). The
//! candidates are spread over the image by `crate::grid_spread`.

pub mod frontend;
mod keyframe;
mod landmark_matching;
pub mod local_map;
mod map_reuse;
mod params;
mod result;

pub use frontend::{Frontend, QvgaFrontend, VgaFrontend};
pub use local_map::{
    BoardLocalMap, Insertions, LocalMap, PATCH_SIDE, TrackedLandmark, induced_affine,
};
pub use params::FrontendParams;
pub use result::{
    FrameResult, FrontendError, FrontendState, FrontendStats, FrontendWork, GuideStage,
};
