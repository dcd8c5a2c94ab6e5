//! The fuzz targets of the host's newer input formats: MCAP recordings (`replay FILE.mcap`) and
//! anchor scripts (`--anchors FILE`).

use std::path::{Path, PathBuf};

use ferroslam_core::ar::AnchorCommand;
use ferroslam_sim::anchor_script::AnchorScript;
use ferroslam_sim::dataset::CalibrationSource;
use ferroslam_sim::dataset::mcap::McapTopics;
use ferroslam_sim::dataset::mcap::recording;

use super::Outcome;

/// An error's class: its variant and, for a wrapped error, the inner one's (`Mcap(Malformed`).
fn class(e: &impl std::fmt::Debug) -> String {
    format!("{e:?}").chars().take_while(|c| c.is_alphanumeric() || matches!(c, '_' | '(')).collect()
}

/// The file each worker thread writes its input to (the MCAP reader opens a path).
fn scratch(name: &str) -> Result<PathBuf, String> {
    let dir = crate::paths::root().join("target/fuzz/scratch");
    std::fs::create_dir_all(&dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    let thread = format!("{:?}", std::thread::current().id());
    let thread: String = thread.chars().filter(char::is_ascii_digit).collect();
    Ok(dir.join(format!("{name}-{}-{thread}", std::process::id())))
}

/// `mcap`: the bytes as an MCAP file opened as a recording (topics found by their encodings,
/// the file's own calibration), then every colour and depth image decoded. Property: a decoded
/// image has the calibration's pixel count.
pub fn mcap(input: &[u8]) -> Result<Outcome, String> {
    let path = scratch("input.mcap")?;
    std::fs::write(&path, input).map_err(|e| format!("writing {}: {e}", path.display()))?;
    let opened = recording::open(&path, &McapTopics::default(), &CalibrationSource::File);
    let r = match opened {
        Ok(r) => r,
        Err(e) => return Ok(Outcome::refused(class(&e))),
    };
    let pixels = r.sensor.width as usize * r.sensor.height as usize;
    let (mut decoded, mut refused) = (0usize, 0usize);
    for line in 1..=r.rgb.len() {
        match r.images.gray(line) {
            Ok(gray) if gray.len() != pixels => {
                return Err(format!("colour image {line}: {} pixels, not {pixels}", gray.len()));
            }
            Ok(_) => decoded += 1,
            Err(_) => refused += 1,
        }
    }
    for line in 1..=r.depth.len() {
        match r.images.depth(line, r.sensor.depth_scale) {
            Ok(depth) if depth.len() != pixels => {
                return Err(format!("depth image {line}: {} samples, not {pixels}", depth.len()));
            }
            Ok(_) => decoded += 1,
            Err(_) => refused += 1,
        }
    }
    let ground_truth = r.groundtruth.as_ref().map_or(0, |g| g.poses.len());
    Ok(Outcome::accepted(format!(
        "opened: {decoded} images decoded, {refused} refused, ground truth {}",
        ground_truth.min(1)
    )))
}

/// `anchor-script`: the bytes as an anchor script's text. Properties: steps come in frame
/// order, and every accepted command has a finite, positive scale and a finite pixel.
pub fn anchor_script(input: &[u8]) -> Result<Outcome, String> {
    let text = String::from_utf8_lossy(input);
    let script = match AnchorScript::from_toml_str(&text, Path::new("fuzz/anchors.toml"), 1) {
        Ok(s) => s,
        Err(e) => return Ok(Outcome::refused(class(&e))),
    };
    if script.steps.windows(2).any(|w| w[0].frame > w[1].frame) {
        return Err("steps out of frame order".to_owned());
    }
    let mut kinds = [false; 3];
    for step in &script.steps {
        let ok = match step.command {
            AnchorCommand::Place { pixel, scale, .. } => {
                kinds[0] = true;
                pixel.iter().all(|c| c.is_finite()) && scale.is_finite() && scale > 0.0
            }
            AnchorCommand::Scale { scale, .. } => {
                kinds[1] = true;
                scale.is_finite() && scale > 0.0
            }
            AnchorCommand::Remove { .. } => {
                kinds[2] = true;
                true
            }
        };
        if !ok {
            return Err(format!("an accepted step is invalid: {step:?}"));
        }
    }
    Ok(Outcome::accepted(format!("accepted (place, scale, remove): {kinds:?}")))
}
