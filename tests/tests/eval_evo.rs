//! `ferroslam-sim eval` against evo 1.38.1 on real trajectories.
//!
//! The ground truth is the real 7-Scenes redkitchen trajectory in `../shared/datasets/` (or, for the
//! TUM-like case, that trajectory upsampled to ~100 Hz); the estimates were generated from it
//! (drift, noise, another world frame, jittered, missing and unmatched timestamps, other rates) by
//! `tests/fixtures/evo/generate.py`, which also ran `evo_ape`/`evo_rpe` and stored their numbers in
//! `tests/fixtures/evo/expected.json` (commands in that folder's README.md). Every statistic must
//! agree to 1e-4 (metres or degrees) and every count exactly.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use ferroslam_sim::eval::{self, ErrorStats, EvalReport};
use ferroslam_sim::plot;
use serde_json::Value;

const TOLERANCE: f64 = 1e-4;
const STATS: [&str; 7] = ["rmse", "mean", "median", "std", "min", "max", "sse"];

fn fixtures_dir() -> PathBuf {
    ferroslam_tests::workspace_root().join("tests").join("fixtures").join("evo")
}

fn expected() -> Result<Value> {
    let path = fixtures_dir().join("expected.json");
    let text = std::fs::read_to_string(&path).with_context(|| path.display().to_string())?;
    Ok(serde_json::from_str(&text)?)
}

/// `shared:DATASET/FILE` (under `../shared/datasets/`) or `fixture:FILE` (under tests/fixtures/evo/).
fn resolve(spec: &str) -> Result<PathBuf> {
    match spec.split_once(':') {
        Some(("shared", rel)) => {
            let (dataset, file) = rel.split_once('/').context("shared:DATASET/FILE")?;
            Ok(ferroslam_tests::shared_dataset(dataset).join(file))
        }
        Some(("fixture", rel)) => Ok(fixtures_dir().join(rel)),
        _ => bail!("bad path spec {spec}"),
    }
}

fn stat(s: &ErrorStats, name: &str) -> Result<f64> {
    Ok(match name {
        "rmse" => s.rmse,
        "mean" => s.mean,
        "median" => s.median,
        "std" => s.std,
        "min" => s.min,
        "max" => s.max,
        "sse" => s.sse,
        _ => bail!("unknown statistic {name}"),
    })
}

/// Compares one statistics block: counts exactly, statistics to [`TOLERANCE`]; returns the largest
/// |ours - evo|.
fn compare(case: &str, what: &str, ours: &ErrorStats, evo: &Value) -> Result<f64> {
    let count = evo["count"].as_u64().context("count")?;
    if ours.count as u64 != count {
        bail!("{case} {what}: {} errors, evo {count}", ours.count);
    }
    let mut worst = 0.0_f64;
    for name in STATS {
        let theirs = evo[name].as_f64().with_context(|| format!("{case} {what} {name}"))?;
        let mine = stat(ours, name)?;
        let diff = (mine - theirs).abs();
        if diff.is_nan() || diff > TOLERANCE {
            bail!("{case} {what} {name}: ours {mine} evo {theirs} (|diff| {diff:e})");
        }
        worst = worst.max(diff);
    }
    eprintln!("{case:>20} {what:<18} max |ours - evo| = {worst:.3e}");
    Ok(worst)
}

fn count(case: &Value, key: &str) -> Result<usize> {
    Ok(usize::try_from(case[key].as_u64().with_context(|| key.to_string())?)?)
}

fn evaluate_case(case: &Value) -> Result<EvalReport> {
    let gt = resolve(case["gt"].as_str().context("gt")?)?;
    let est = resolve(case["est"].as_str().context("est")?)?;
    eval::run_eval(&gt, &est, eval::DEFAULT_MAX_DT_S)
        .with_context(|| format!("{} vs {}", gt.display(), est.display()))
}

#[test]
fn matches_evo_on_every_fixture() -> Result<()> {
    let expected = expected()?;
    assert_eq!(expected["evo_version"], "v1.38.1");
    assert_eq!(expected["max_dt_s"].as_f64(), Some(eval::DEFAULT_MAX_DT_S));
    let cases = expected["cases"].as_object().context("cases")?;
    assert_eq!(cases.len(), 4);
    let mut worst = 0.0_f64;
    for (name, case) in cases {
        let report = evaluate_case(case)?;
        assert_eq!(report.gt_poses, count(case, "gt_poses")?, "{name}");
        assert_eq!(report.est_poses, count(case, "est_poses")?, "{name}");
        assert_eq!(report.matched_poses, count(case, "matched_poses")?, "{name}: matched");
        let frame = &report.rpe_per_frame;
        let second = report.rpe_per_second.context("no per-second RPE")?;
        let blocks = [
            ("ATE [m]", &report.ate, "ape"),
            ("RPE/f trans [m]", &frame.trans, "rpe_frame_trans"),
            ("RPE/f rot [deg]", &frame.rot, "rpe_frame_rot"),
            ("RPE/s trans [m]", &second.trans, "rpe_second_trans"),
            ("RPE/s rot [deg]", &second.rot, "rpe_second_rot"),
        ];
        for (what, ours, key) in blocks {
            worst = worst.max(compare(name, what, ours, &case[key])?);
        }
        assert_eq!(frame.pairs, frame.trans.count);
    }
    eprintln!("overall max |ours - evo| = {worst:.3e}");
    Ok(())
}

#[test]
fn the_fixtures_exercise_the_association_corner_cases() -> Result<()> {
    let expected = expected()?;
    let cases = &expected["cases"];
    // Estimate longer than the ground truth: the ground truth drives the association and one
    // estimate pose is matched twice (evo keeps the repeat).
    let long = evaluate_case(&cases["est_60hz_gap"])?;
    assert!(long.est_poses > long.gt_poses);
    let mut stamps: Vec<f64> = long.matches.iter().map(|m| m.est.timestamp_s).collect();
    let matched = stamps.len();
    stamps.dedup();
    assert_eq!(stamps.len() + 1, matched);
    // Estimate poses outside the ground truth's time span stay unmatched.
    for name in ["drift_jitter_30hz", "tum_like_100hz_gt"] {
        let r = evaluate_case(&cases[name])?;
        assert!(r.matched_poses < r.est_poses.min(r.gt_poses), "{name}");
    }
    Ok(())
}

#[test]
fn report_renders_and_plots() -> Result<()> {
    let expected = expected()?;
    let report = evaluate_case(&expected["cases"]["tum_like_100hz_gt"])?;
    let text = report.to_string();
    assert!(text.contains("ATE [m]") && text.contains("matched poses: 345"), "{text}");
    let json = serde_json::to_value(&report).unwrap();
    assert!(json["ate"]["rmse"].as_f64().unwrap() > 0.0);
    assert!(json.get("matches").is_none());
    let dir = tempfile::tempdir().unwrap();
    let (top, ate) = (dir.path().join("trajectory.svg"), dir.path().join("ate.svg"));
    plot::plot_report(&report, &top, &ate, &[]).unwrap();
    for path in [top, ate] {
        let svg = std::fs::read_to_string(&path).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("<polyline"), "{}", path.display());
    }
    Ok(())
}

#[test]
fn reading_errors_name_the_file() -> Result<()> {
    let missing = fixtures_dir().join("no_such_file.txt");
    let gt = resolve("shared:7scenes-redkitchen-1000/groundtruth.txt")?;
    let err = eval::run_eval(&gt, &missing, eval::DEFAULT_MAX_DT_S).unwrap_err();
    assert!(err.to_string().contains("no_such_file.txt"), "{err}");
    Ok(())
}
