//! Where things are: the workspace root, the cross target, the real recording CI replays and its
//! calibration, and the folders xtask writes into. Imports nothing of xtask; every other module
//! may use it.

use std::path::{Path, PathBuf};

/// The cross target of the reference board (Cortex-M4F/M7F with single-precision FPU).
pub const THUMB: &str = "thumbv7em-none-eabihf";

/// The real recording every CI run replays, relative to the workspace root.
pub const SEVEN_SCENES: &str = "../shared/datasets/7scenes-redkitchen-1000";
/// The calibration every 7-Scenes replay uses, relative to the workspace root: the colour
/// camera's intrinsics and the depth camera's offset, so that depth is registered to colour
/// (the data set's own `calibration.toml` holds the depth camera's nominal intrinsics only; see
/// the file's header for how its values were estimated: `ferroslam-sim calibrate-depth`).
pub const SEVEN_SCENES_CALIBRATION: &str = "calibration/7scenes-kinect-v1.toml";

/// The workspace root: xtask lives in `<root>/xtask`.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map(Path::to_path_buf).unwrap_or_default()
}

/// The calibration file xtask replays `dataset` with: [`SEVEN_SCENES_CALIBRATION`] for the
/// 7-Scenes folder (however it is named: the check compares canonical paths), `None` (the
/// folder's own `calibration.toml`) for any other.
pub fn calibration_for(dataset: &Path) -> Option<PathBuf> {
    let seven = std::fs::canonicalize(root().join(SEVEN_SCENES)).ok()?;
    (std::fs::canonicalize(dataset).ok()? == seven).then(|| root().join(SEVEN_SCENES_CALIBRATION))
}

/// Where `cargo xtask ci` writes its step `name`'s output: `<root>/target/ci/<name>`.
pub fn ci_out(name: &str) -> PathBuf {
    root().join("target").join("ci").join(name)
}

/// Where a `cargo xtask` command writes by default: `<root>/target/xtask/<name>`.
pub fn xtask_out(name: &str) -> PathBuf {
    root().join("target").join("xtask").join(name)
}
