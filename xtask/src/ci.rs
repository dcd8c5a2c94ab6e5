//! The CI pipeline: each step runs a command and stops the run at the first failure.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{Context, Result, bail};

/// The cross target of the reference board (Cortex-M4F/M7F with single-precision FPU).
pub const THUMB: &str = "thumbv7em-none-eabihf";

/// The real recording every CI run replays.
pub const SEVEN_SCENES: &str = "../shared/datasets/7scenes-redkitchen-1000";
/// The calibration every 7-Scenes replay uses, relative to the workspace root: the colour
/// camera's intrinsics and the depth camera's offset, so that depth is registered to colour
/// (the data set's own `calibration.toml` holds the depth camera's nominal intrinsics only; see
/// the file's header for how its values were estimated).
pub const SEVEN_SCENES_CALIBRATION: &str = "calibration/7scenes-kinect-v1.toml";

/// The calibration file xtask replays `dataset` with: [`SEVEN_SCENES_CALIBRATION`] for the
/// 7-Scenes folder (however it is named: the check compares canonical paths), `None` (the
/// folder's own `calibration.toml`) for any other.
pub fn calibration_for(dataset: &Path) -> Option<PathBuf> {
    let seven = std::fs::canonicalize(root().join(SEVEN_SCENES)).ok()?;
    (std::fs::canonicalize(dataset).ok()? == seven).then(|| root().join(SEVEN_SCENES_CALIBRATION))
}

/// The workspace root: xtask lives in `<root>/xtask`.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map(Path::to_path_buf).unwrap_or_default()
}

/// Runs `program args...` in the workspace root with extra environment, failing on non-zero exit.
fn run(program: &str, args: &[&str], env: &[(&str, &str)]) -> Result<()> {
    let mut cmd = Command::new(program);
    cmd.args(args).current_dir(root());
    for (k, v) in env {
        cmd.env(k, v);
    }
    eprintln!("$ {program} {}", args.join(" "));
    let status = cmd.status().with_context(|| format!("could not start {program}"))?;
    if !status.success() {
        bail!("`{program} {}` failed with {status}", args.join(" "));
    }
    Ok(())
}

fn cargo(args: &[&str]) -> Result<()> {
    run(env!("CARGO"), args, &[])
}

/// One named step of the pipeline, timed.
fn step(name: &str, f: impl FnOnce() -> Result<()>) -> Result<()> {
    eprintln!("\n==> {name}");
    let start = Instant::now();
    f().with_context(|| format!("CI step '{name}' failed"))?;
    eprintln!("<== {name}: ok ({:.1} s)", start.elapsed().as_secs_f64());
    Ok(())
}

/// Every check, in order of cost.
pub fn run_all() -> Result<()> {
    let start = Instant::now();
    step("rustfmt", || cargo(&["fmt", "--all", "--", "--check"]))?;
    step("clippy (host)", || {
        cargo(&["clippy", "--all-targets", "--", "-D", "warnings"])?;
        cargo(&["clippy", "-p", "ferroslam-firmware", "--lib", "--tests", "--", "-D", "warnings"])
    })?;
    step("clippy (thumb)", || {
        cargo(&[
            "clippy",
            "-p",
            "ferroslam-fpu",
            "-p",
            "ferroslam-core",
            "-p",
            "ferroslam-firmware",
            "--target",
            THUMB,
            "--",
            "-D",
            "warnings",
        ])
    })?;
    step("docs", || {
        run(
            env!("CARGO"),
            &[
                "doc",
                "--no-deps",
                "-p",
                "ferroslam-fpu",
                "-p",
                "ferroslam-core",
                "-p",
                "ferroslam-sim",
                "-p",
                "ferroslam-firmware",
            ],
            &[("RUSTDOCFLAGS", "-D warnings")],
        )
    })?;
    step("host tests", || {
        cargo(&["test", "--workspace", "--exclude", "ferroslam-firmware"])?;
        cargo(&["test", "-p", "ferroslam-firmware", "--lib"])
    })?;
    step("thumb build, no allocator", thumb_build_without_allocator)?;
    step("firmware in QEMU, bit-identical to the host replay", firmware_replay)?;
    step("budgets: RAM, flash, stack, instructions per frame (same QEMU run)", budgets)?;
    step("7-Scenes depth calibration follows from the images", || {
        crate::registration::check_file(root().join(SEVEN_SCENES_CALIBRATION))
    })?;
    step("7-Scenes replays (odometry, SLAM), accuracy bars", replay_seven_scenes_both)?;
    step("held-out TUM sequences (issue 4's 0.010 m bar), when present", || {
        crate::heldout::run(&[])
    })?;
    step("demo", || {
        cargo(&["run", "--release", "-p", "ferroslam-sim", "--", "demo", "--out", "target/ci/demo"])
    })?;
    eprintln!("\ncargo xtask ci: all steps passed in {:.0} s", start.elapsed().as_secs_f64());
    Ok(())
}

/// Builds core and the firmware for the Cortex-M target and proves no binary links an allocator:
/// core is `#![no_std]` without `alloc`, the firmware defines no `#[global_allocator]`, and no ELF
/// holds an allocator symbol. Both binaries linking proves their memory maps hold their statics.
fn thumb_build_without_allocator() -> Result<()> {
    cargo(&["build", "--release", "-p", "ferroslam-core", "--target", THUMB])?;
    cargo(&["build", "--release", "-p", "ferroslam-firmware", "--target", THUMB])?;
    for bin in crate::firmware::BINARIES {
        no_allocator_in(&crate::firmware::elf_path(&root(), bin))?;
    }
    Ok(())
}

/// Fails when the ELF at `elf` holds an allocator symbol; prints its flash and RAM figures.
fn no_allocator_in(elf: &Path) -> Result<()> {
    let symbols = crate::firmware::nm(elf, &[])?;
    let alloc: Vec<&str> = symbols
        .lines()
        .filter(|l| {
            l.contains("__rust_alloc")
                || l.contains("__rg_alloc")
                || l.contains("__rust_no_alloc_shim")
        })
        .collect();
    if !alloc.is_empty() {
        bail!("the firmware links an allocator: {alloc:?}");
    }
    eprintln!("{}: {} symbols, none from an allocator", elf.display(), symbols.lines().count());
    if let Some(sections) = crate::firmware::elf_sections(elf) {
        let (flash, ram) = crate::firmware::flash_and_ram(&sections);
        eprintln!("  flash {flash} B, static RAM {ram} B ({sections:?})");
    }
    Ok(())
}

/// Frames of 7-Scenes the CI's firmware replay compares: all of them (~50 s; the issue asks for
/// at least 60).
const FIRMWARE_REPLAY_FRAMES: usize = 1000;

/// The firmware in QEMU on the first frames of 7-Scenes, every pose bit-identical to the host
/// replay's (see `replay.rs`).
fn firmware_replay() -> Result<()> {
    let opts = crate::replay::ReplayOptions {
        dataset: root().join(SEVEN_SCENES),
        calibration: Some(root().join(SEVEN_SCENES_CALIBRATION)),
        max_frames: FIRMWARE_REPLAY_FRAMES,
        out: firmware_replay_dir(),
        qemu_args: Vec::new(),
    };
    crate::replay::run(&root(), &opts)
}

/// Where CI's firmware replay writes (`cost.json` among the rest), read again by [`budgets`].
fn firmware_replay_dir() -> PathBuf {
    root().join("target").join("ci").join("firmware-replay")
}

/// The budgets of `memory-budget.md` on the firmware replay's `cost.json`, without a second QEMU
/// run; the figures as JSON in `target/ci/budgets.json`.
fn budgets() -> Result<()> {
    let opts = crate::budgets::Options {
        from: Some(firmware_replay_dir()),
        json: Some(root().join("target").join("ci").join("budgets.json")),
        ..crate::budgets::Options::new(&root())
    };
    crate::budgets::run_with(&root(), &opts)
}

/// The front end's 7-Scenes bar (issue 3): ATE RMSE of the odometry mode, metres.
const SEVEN_SCENES_ODOMETRY_BAR_M: f64 = 0.060;
/// The back end's 7-Scenes bar (issue 4): ATE RMSE of the SLAM mode, metres; SLAM must also beat
/// the odometry mode on the same frames.
///
/// Both replays use the product's defaults (RANSAC seed included) from the first frame. How much
/// of their ATE is chance is measured by `cargo xtask spread --seeds 3` (4 seeds x 12 start
/// frames, 0 to 550): odometry mean 0.0373 m (worst 0.0439), SLAM mean 0.0331 m (worst 0.0453),
/// SLAM better in 41 of 48 paired runs. On start frames never tuned on (`--skips 25,75,...,575`
/// and `10,60,...,560`) SLAM's worst runs were 0.0524 and 0.0490 m (`memory-budget.md`). The
/// default runs (odometry 0.0423 m, SLAM 0.0352 m) hold both bars with about a centimetre to
/// spare; the checks guard the default run, not every start.
const SEVEN_SCENES_SLAM_BAR_M: f64 = 0.050;

/// Replays 7-Scenes at QVGA in `mode` into `target/ci/replay-7scenes-<mode>`, checks that all
/// 1000 frames were tracked and the ATE RMSE is within `bar_m`, and returns the ATE.
fn replay_seven_scenes(mode: &str, bar_m: f64) -> Result<f64> {
    let out = root().join(format!("target/ci/replay-7scenes-{mode}"));
    let dataset = root().join(SEVEN_SCENES);
    let calibration = root().join(SEVEN_SCENES_CALIBRATION);
    let (frames, ate) =
        replay_with_bar("7-Scenes", &dataset, Some(&calibration), mode, Some(bar_m), &out)?;
    if frames != 1000 {
        bail!("7-Scenes {mode}: {frames} frames processed; all 1000 must be");
    }
    Ok(ate)
}

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

/// The odometry and SLAM replays of 7-Scenes with their bars, and SLAM better than odometry.
fn replay_seven_scenes_both() -> Result<()> {
    let odometry = replay_seven_scenes("odometry", SEVEN_SCENES_ODOMETRY_BAR_M)?;
    let slam = replay_seven_scenes("slam", SEVEN_SCENES_SLAM_BAR_M)?;
    if slam >= odometry {
        bail!("7-Scenes: SLAM ({slam:.4} m) is not better than odometry ({odometry:.4} m)");
    }
    Ok(())
}
