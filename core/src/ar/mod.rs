//! Augmented reality: planes detected on depth, in the camera's frame and then the world's, for
//! anchoring virtual objects (the paper's last experiment).
//!
//! - [`PlaneDetector`]: one frame's planes from its depth image, by a fixed grid of cells (each
//!   fitted with a plane, kept when flat within the sensor's depth noise) grown into regions of
//!   neighbouring cells that agree, each refitted on all its cells' points (a cell-grid method
//!   in the spirit of PEAC and CAPE: no per-pixel work after the fit, fixed memory, a bounded
//!   cost of one pass over the sampled pixels plus one over the cells).
//! - [`Plane`]: a plane's normal, offset, centroid and support; [`Plane::transformed`] moves it
//!   into the world frame with the camera's pose.
//! - [`PlaneMap`]: the world's planes, each keyframe's merged into the one it is the same
//!   surface as. Built from the keyframes' final poses, it follows bundle adjustment and loops;
//!   built as frames come, a loop's correction moves the planes of the track it corrects
//!   ([`PlaneMap::correct`]).
//! - [`Anchor`]: a virtual object placed by a pixel of a frame where its ray meets the plane under
//!   it, drawn where a camera pose projects it.
//! - [`Anchors`]: the placed objects, changed by [`AnchorCommand`]s (place, scale, remove), each
//!   following the keyframe it was placed against through bundle adjustment and loop corrections.
//!
//! Why these choices and thresholds, and what they measured: docs/decisions.md, "Planes from a
//! grid of cells on depth". SLAM also finds planes as it runs, on the board as on a host
//! ([`crate::system::OnlinePlanes`]), and places anchors on them (`Slam::command`: the commands a
//! board receives on its serial link).
//! - [`World`] and [`SavedWorld`]: the planes and anchors saved with the map, after its place
//!   records, and read back by the next run.

mod anchor;
mod anchors;
mod eigen;
mod plane_map;
mod planes;
mod world;

pub use anchor::{Anchor, AnchorError};
pub use anchors::{AnchorCommand, Anchors, PlacingFrame};
pub use plane_map::{MAX_MAP_PLANES, MapPlane, Observed, PlaneMap, PlaneMergeParams};
pub use planes::{
    FramePlanes, MAX_FRAME_PLANES, PLANE_GRID, Plane, PlaneDetector, PlaneError, PlaneParams,
};
pub use world::{SavedWorld, WORLD_UNITS, World, WorldError, is_world_unit};

#[cfg(test)]
mod tests;
