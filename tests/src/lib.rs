//! Shared helpers for the workspace integration tests under `tests/tests/`, and the list of core
//! structures whose size `memory-budget.md` states ([`structures`], also read by `cargo xtask
//! budgets`).

pub mod structures;

use std::path::PathBuf;

/// The workspace root (the folder holding the top-level `Cargo.toml`).
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `../shared/datasets/NAME` beside the workspace, where CI and tests read real recordings.
pub fn shared_dataset(name: &str) -> PathBuf {
    workspace_root().join("..").join("shared").join("datasets").join(name)
}
