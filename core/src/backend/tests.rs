//! Back-end tests (compiled only under `cfg(test)`).
