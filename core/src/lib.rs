//! ferroslam-core: the no_std, no-heap, deterministic RGB-D SLAM core.
//!
//! Layers, bottom up (see `shared/design.md` for the full map):
//!
//! - [`config`]: every capacity and tunable in one place, with the QVGA (reference board) and VGA
//!   profiles.
//! - [`geometry`]: SE(3) poses on [`nalgebra::Isometry3<f32>`], exp/log, the pinhole camera of the
//!   paper's Eq. 1-2 with Jacobians, depth back-projection, Horn/Umeyama alignment.
//! - [`image`]: borrowed image views with stride, 2x downsampling, the image variation `v_m` and the
//!   total variation `W(I)` of the paper's Eq. 3.
//! - `grid_spread` (inside the crate): the cells of an image grid and the rank-major order that
//!   spreads features, ROIs and tracked landmarks evenly over the image.
//! - [`features`]: the Fast-Hessian detector on a rolling integral buffer, and grid bucketing.
//! - [`matching`]: region matching under a bank of affine transforms, refined by affine
//!   Lucas-Kanade, with a forward-backward check.
//! - [`map`]: fixed-capacity arenas of keyframes and landmarks with typed, generation-checked ids,
//!   and the keyframes' observations.
//! - [`tracking`]: robust SE(3) pose estimation (LM with Huber, RANSAC on 3-point sets), the
//!   constant-velocity motion model.
//! - [`optim`]: fixed-memory, resumable bundle adjustment (local and segmented global BA):
//!   Levenberg-Marquardt on the Schur-reduced camera system, solved matrix-free by PCG.
//! - [`backend`]: local bundle adjustment over a covisibility window, reference landmarks and
//!   segmented global bundle adjustment, in bounded steps.
//! - [`system`]: the facade, `Slam::process(frame)` and `Slam::step_backend(work_quota)`.
//! - [`frame`]: an RGB-D frame as the core sees it, the [`frame::FrameSource`] port that cameras,
//!   recorded datasets and the synthetic renderer implement, and the [`frame::TelemetrySink`] port
//!   that the firmware's serial link and the host's writers implement.
//! - [`wire`]: the versioned serial message schema (pose, status, cost, fault) shared by firmware
//!   and host: postcard bodies, CRC-32, COBS framing, and a stream decoder that resynchronizes.
//!
//! Rules: no heap (every capacity is in a type), no `unsafe`, no panics on bad input (errors are
//! values), f32 arithmetic with transcendental functions through the pure-Rust `libm` on every
//! target so the host and the Cortex-M give the same bits (the square root through
//! `ferroslam_fpu::sqrtf`, the FPU's correctly rounded `VSQRT.F32` on the board and libm's equal
//! result elsewhere); time and ids are inputs, never read from a clock.
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod backend;
pub mod config;
pub mod features;
pub mod frame;
pub mod geometry;
mod grid_spread;
pub mod image;
pub mod map;
pub mod matching;
pub mod optim;
pub mod pose;
pub mod system;
#[cfg(test)]
mod test_rng;
pub mod tracking;
pub mod wire;
