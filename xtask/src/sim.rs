//! The host simulator as CI runs it: `ferroslam-sim replay` through `cargo run --release`, its
//! `report.json` read back and held to an accuracy bar. Shared by `ci` and `heldout`.

use std::path::Path;

use anyhow::{Context, Result, bail};

use crate::cargo::cargo;

/// Replays `dataset` (with `calibration`, else its own) at QVGA from its first frame in `mode`
/// into `out`; fails when a frame was not tracked or the ATE RMSE is over `bar_m` (when given).
/// Returns the frames processed and the ATE RMSE in metres; `label` names the data in messages.
pub fn replay_with_bar(
    label: &str,
    dataset: &Path,
    calibration: Option<&Path>,
    mode: &str,
    bar_m: Option<f64>,
    out: &Path,
) -> Result<(u64, f64)> {
    let (dataset, out_arg) = (dataset.to_string_lossy(), out.to_string_lossy());
    let calibration = calibration.map(Path::to_string_lossy);
    let mut args = vec!["run", "--release", "-p", "ferroslam-sim", "--", "replay", &dataset];
    if let Some(c) = &calibration {
        args.extend(["--calibration", c]);
    }
    args.extend(["--out", &out_arg, "--mode", mode, "--profile", "qvga"]);
    cargo(&args)?;
    let report = read_report(out)?;
    let count =
        |key: &str| report[key].as_u64().with_context(|| format!("report.json has no count {key}"));
    let (frames, tracked) = (count("frames")?, count("tracked_frames")?);
    let ate = report["ate_rmse_m"].as_f64().context("report.json has no ate_rmse_m")?;
    let bar = bar_m.map_or_else(|| "no bar".to_string(), |b| format!("bar {b:.3} m"));
    eprintln!("{label} {mode}: {frames} frames, {tracked} tracked, ATE RMSE {ate:.4} m ({bar})");
    if frames == 0 || tracked != frames {
        bail!("{label} {mode}: {frames} frames processed and {tracked} tracked; all must be");
    }
    if let Some(bar_m) = bar_m.filter(|b| ate > *b) {
        bail!("{label} {mode}: ATE RMSE {ate:.4} m is over the bar of {bar_m:.3} m");
    }
    Ok((frames, ate))
}

/// The `report.json` a `ferroslam-sim replay --out dir` wrote.
pub fn read_report(dir: &Path) -> Result<serde_json::Value> {
    let path = dir.join("report.json");
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("reading {} (did the replay write it?)", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))
}
