//! ferroslam-core: the no_std, no-heap, deterministic RGB-D SLAM core of an industrial robot's
//! vision module. Everything the product computes is here; the firmware and the host simulator
//! only feed it frames, schedule its steps and carry its messages.
//!
//! # The layers, top down
//!
//! Each layer imports only the layers below it.
//!
//! - [`system`]: the facade. [`system::Slam`]`<P>` holds the front end, the map and the back end
//!   of a profile `P`; [`system::Slam::process`] tracks a frame, [`system::Slam::step_backend`]
//!   advances the back end by a fixed quota of work, and [`system::Slam::overlap`] lends the two
//!   apart so the back end's solve can run beside the next frame's tracking with the same bits.
//!   It also turns results into [`wire`] messages.
//! - [`loops`] (beside `backend`): the place memory: keyframes leaving the map remembered in a
//!   long-term store, relocalization of a lost frame in a remembered place, verified by 3D-3D
//!   RANSAC, and loops that bring a map restarted off the known one back onto it (drift
//!   correction through the segment graph is to come); saved to and loaded from a map file.
//! - [`ar`] (beside `backend`): planes detected on depth, and anchors for virtual objects placed
//!   on them by commands, moved with the map when a loop closes.
//! - [`backend`]: local bundle adjustment over a covisibility window, reference landmarks and
//!   segmented global bundle adjustment, in bounded steps ([`backend::SolveJob`]).
//! - [`tracking`]: the frame-to-map front end: the local map of tracked landmarks, the guide and
//!   final matching stages, keyframes and new landmarks.
//! - [`persist`] (beside `map`): the map file, the long-term store's records behind a versioned,
//!   checksummed header (the power-cut-safe log on NOR flash is to come).
//! - [`map`]: fixed-capacity arenas of keyframes and landmarks with typed, generation-checked ids,
//!   and the keyframes' observations (the active map in RAM; a long-term store in flash will join
//!   it behind a storage port).
//! - [`frame`]: the ports: an RGB-D frame as the core sees it, [`frame::FrameSource`] (cameras,
//!   recorded datasets, the renderer) and [`frame::TelemetrySink`] (the serial link, host writers).
//! - [`optim`]: fixed-memory, resumable bundle adjustment: Levenberg-Marquardt on the
//!   Schur-reduced camera system, solved matrix-free by PCG, cut into work units.
//! - [`pose`]: the reusable pose estimator: robust SE(3) refinement with pixels and depth, RANSAC
//!   on minimal sets, the constant-velocity motion model, the rotation from small blurry images.
//! - [`matching`]: region matching under a bank of affine transforms refined by affine
//!   Lucas-Kanade, and the patch tracker under a predicted warp.
//! - [`features`]: the Fast-Hessian detector on a rolling integral buffer, grid bucketing, and
//!   binary descriptors.
//! - [`wire`]: the versioned serial schema (pose, status, cost, fault): postcard bodies, CRC-32,
//!   COBS framing and a stream decoder that resynchronizes; message types only.
//! - [`image`]: borrowed image views with stride, 2x downsampling, the image variation `v_m` and
//!   the total variation `W(I)` of the paper's Eq. 3.
//! - [`geometry`]: SE(3) poses on [`nalgebra::Isometry3<f32>`], exp/log, the pinhole camera of the
//!   paper's Eq. 1-2 with Jacobians, depth back-projection, Horn/Umeyama alignment.
//! - `grid_spread` (inside the crate): the cells of an image grid and the rank-major order that
//!   spreads features, ROIs and tracked landmarks evenly over the image.
//! - [`config`]: the ground floor: every capacity, the profiles ([`config::Qvga`] is the reference
//!   board's), the sensor's measurement model and the shared defaults; it imports nothing.
//!
//! # Rules
//!
//! No heap (every capacity is in a type; a full container returns an error or applies a stated
//! policy), no `unsafe`, no panics on bad input (errors are values), f32 arithmetic with
//! transcendental functions through the pure-Rust `libm` on every target so that the host and the
//! Cortex-M give the same bits (the square root through `ferroslam_fpu::sqrtf`, the FPU's
//! correctly rounded `VSQRT.F32` on the board and libm's equal result elsewhere); time, random
//! seeds and ids are inputs, never read from a clock. Why each measured choice was made:
//! `docs/decisions.md` in the repository.
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod ar;
pub mod backend;
pub mod config;
pub mod features;
pub mod frame;
pub mod geometry;
mod grid_spread;
pub mod image;
pub mod loops;
pub mod map;
pub mod matching;
pub mod optim;
pub mod persist;
pub mod pose;
pub mod system;
#[cfg(test)]
mod test_rng;
pub mod tracking;
pub mod wire;
