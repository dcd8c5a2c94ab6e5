//! Back-end tests (compiled only under `cfg(test)`).
//!
//! The split of a step into [`Backend::advance_solve`] and [`Backend::finish_solve`] is checked on
//! real frames in the workspace tests (`slam_determinism`: the back end on its own thread gives
//! the sequential bits) and by the firmware replay; here, its edges.

use super::{Backend, BackendError, BackendParams, BackendStatus};
use crate::geometry::PinholeCamera;
use crate::map::BoardMap;

fn camera() -> PinholeCamera {
    PinholeCamera::new(260.0, 260.0, 160.0, 120.0, 320, 240).unwrap_or_else(|_| unreachable!())
}

#[test]
fn with_no_solve_under_way_the_split_does_nothing() {
    let (mut backend, mut map) = (Backend::new(), BoardMap::new());
    assert!(!backend.is_solving());
    assert_eq!(backend.advance_solve(5_000), Ok(false));
    assert_eq!(backend.finish_solve(&mut map), None);
    assert_eq!(backend.stats().steps, 0, "nothing was charged as a step");
    // An empty map gives no problem to build: the step stays idle.
    assert_eq!(backend.step(&mut map, &camera(), 5_000), Ok(BackendStatus::Idle));
    assert!(!backend.is_busy());
}

/// The bundle-adjustment depth noise reaches both solvers, the tracker's does not; the default
/// tunables are the default weighting.
#[test]
fn tunables_set_the_depth_noise_of_both_solvers() {
    let default = crate::config::Tunables::default();
    assert_eq!(BackendParams::DEFAULT.with_tunables(&default), BackendParams::DEFAULT);
    assert_eq!(default.ba_depth_noise_coeff_per_m, 6.0e-4);
    let quiet = crate::config::Tunables {
        depth_noise_coeff_per_m: 2.0e-4,
        ba_depth_noise_coeff_per_m: 1.0e-3,
        ..default
    };
    let p = BackendParams::DEFAULT.with_tunables(&quiet);
    assert_eq!(p.local.depth_noise_coeff_per_m, 1.0e-3);
    assert_eq!(p.global.depth_noise_coeff_per_m, 1.0e-3);
    assert!(p.is_valid());
}

#[test]
fn advance_solve_checks_the_parameters_like_step() {
    let params = BackendParams { segment_keyframes: 0, ..BackendParams::DEFAULT };
    assert!(!params.is_valid());
    let mut backend = Backend::with_params(params);
    assert_eq!(backend.advance_solve(5_000), Err(BackendError::InvalidParams));
    let mut map = BoardMap::new();
    assert_eq!(backend.step(&mut map, &camera(), 5_000), Err(BackendError::InvalidParams));
}
