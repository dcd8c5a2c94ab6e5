//! Helpers shared by the integration tests that run the `ferroslam-sim` binary as a user runs it.

#![allow(dead_code)] // each test file is its own crate and uses only some of these

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the `ferroslam-sim` binary of this build with `args`, to its exit.
pub fn sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ferroslam-sim")).args(args).output().expect("the binary runs")
}

/// What a run wrote to its standard error, as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The 7-Scenes recording beside the repository (`../shared/datasets`).
pub fn seven_scenes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/datasets/7scenes-redkitchen-1000")
}
