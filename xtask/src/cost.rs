//! `cost.json`: what one run of the firmware in QEMU cost, frame by frame and stage by stage.
//! `firmware-replay` writes it; `budgets` reads it back, so CI boots QEMU once for both the
//! bit-identical check and the budgets.
//!
//! The firmware times each frame in four stages with SysTick (see
//! `ferroslam_firmware::pipeline::run_frame`): acquire (the frame read and halved to QVGA), front
//! end, back-end step (one fixed quota of bundle-adjustment work) and report (the pose message
//! encoded and written). Under QEMU's `-icount shift=0` a tick is exactly 40 instructions, so
//! every figure here is an instruction count, deterministic for a given binary and input, with a
//! resolution of 40 instructions (a clock read costs a few of them, charged to its stage).
//!
//! The file also names the ELF it measured by an FNV-1a hash of its bytes, so that `budgets`
//! refuses to pair it with another build. Each frame may carry what the front end ran on it
//! (the core's `FrontendWork`, from the host replay of the same frames, which `firmware-replay` checks to be
//! bit-identical), so that the costly frames can be told apart by kind.

use std::collections::HashMap;
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use ferroslam_core::tracking::FrontendWork;
use ferroslam_core::wire::{CostMessage, Message, PoseFlags, StatusMessage, TickUnit};
use ferroslam_sim::serial::Capture;
use serde_json::{Value, json};

use crate::stats::Stats;

/// The layout version of `cost.json` (2: front end and back-end step timed apart).
pub const FORMAT: u64 = 3;

/// The kind of frame `work` says, in words, e.g. `2 final stages, 1 guide run, detection (a
/// keyframe)`.
pub fn describe_work(work: &FrontendWork) -> String {
    let plural = |n: u8, one: &str| format!("{n} {one}{}", if n == 1 { "" } else { "s" });
    let mut parts =
        vec![plural(work.final_stages, "final stage"), plural(work.guide_runs, "guide run")];
    if work.rotation_estimated {
        parts.push("the small-image rotation".into());
    }
    if work.detected {
        parts.push("detection (a keyframe)".into());
    }
    parts.join(", ")
}

/// Instructions of one frame, by stage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameCost {
    /// The frame's index in the run.
    pub frame_index: u32,
    /// Whether the frame became a keyframe (detection and keyframe insertion run on it).
    pub keyframe: bool,
    /// What the front end ran on the frame, when known (see [`FirmwareRun::attach_work`]).
    pub work: Option<FrontendWork>,
    /// Reading the frame and halving it to QVGA.
    pub acquire: u64,
    /// The front end.
    pub frontend: u64,
    /// The back-end step after the frame.
    pub backend_step: u64,
    /// Encoding and writing the pose message.
    pub report: u64,
}

impl FrameCost {
    /// Front end + back-end step: what the per-frame instruction bars are about.
    pub fn pipeline(&self) -> u64 {
        self.frontend + self.backend_step
    }

    /// All four stages.
    pub fn total(&self) -> u64 {
        self.acquire + self.pipeline() + self.report
    }
}

/// A stage of [`FrameCost`] as the tables name it: `(key, label, value)`.
pub type Stage = (&'static str, &'static str, fn(&FrameCost) -> u64);

/// The stages, in print order; the key names them in `cost.json` and the budgets' JSON.
pub const STAGES: [Stage; 6] = [
    ("acquire", "acquire: the VGA frame through semihosting, halved to QVGA", |f| f.acquire),
    ("frontend", "front end", |f| f.frontend),
    ("backend_step", "back-end step (fixed quota)", |f| f.backend_step),
    ("pipeline", "pipeline: front end + back-end step", FrameCost::pipeline),
    ("report", "report: pose message encoded and written to the UART", |f| f.report),
    ("total", "total", FrameCost::total),
];

/// One firmware run: its per-frame costs and the board's final status.
#[derive(Debug, Clone, PartialEq)]
pub struct FirmwareRun {
    /// The dataset replayed.
    pub dataset: String,
    /// The ELF that ran.
    pub elf: PathBuf,
    /// FNV-1a 64 of the ELF's bytes, as 16 hex digits.
    pub elf_fnv1a64: String,
    /// The board's status at the end of the run (peak stack, pipeline bytes, counts).
    pub status: StatusMessage,
    /// Every processed frame, in order.
    pub frames: Vec<FrameCost>,
}

impl FirmwareRun {
    /// The run a UART capture tells of. `dataset` and `elf` are recorded as given.
    ///
    /// # Errors
    /// No final status; a cost message not in instructions or without its pose.
    pub fn from_capture(capture: &Capture, dataset: &Path, elf: &Path) -> Result<Self> {
        let keyframes: HashMap<u32, bool> = capture
            .poses()
            .map(|p| (p.frame_index, p.flags.contains(PoseFlags::KEYFRAME)))
            .collect();
        let frames = capture
            .messages
            .iter()
            .filter_map(|m| if let Message::Cost(c) = m { Some(c) } else { None })
            .map(|c| frame_cost(c, &keyframes))
            .collect::<Result<Vec<_>>>()?;
        let status = capture
            .messages
            .iter()
            .rev()
            .find_map(|m| if let Message::Status(s) = m { Some(*s) } else { None })
            .ok_or_else(|| anyhow!("the firmware sent no final status"))?;
        let bytes = fs::read(elf).with_context(|| format!("reading {}", elf.display()))?;
        Ok(Self {
            dataset: dataset.display().to_string(),
            elf: elf.to_path_buf(),
            elf_fnv1a64: format!("{:016x}", fnv1a64(&bytes)),
            status,
            frames,
        })
    }

    /// Order statistics of every stage, in [`STAGES`] order.
    pub fn stage_stats(&self) -> Vec<(Stage, Stats)> {
        STAGES
            .iter()
            .map(|&stage| {
                let values: Vec<u64> = self.frames.iter().map(stage.2).collect();
                (stage, Stats::of(&values))
            })
            .collect()
    }

    /// Order statistics of the stage keyed `key` in [`STAGES`] (all 0 for an unknown key).
    pub fn stats(&self, key: &str) -> Stats {
        let values: Vec<u64> = STAGES
            .iter()
            .find(|(k, _, _)| *k == key)
            .map(|stage| self.frames.iter().map(stage.2).collect())
            .unwrap_or_default();
        Stats::of(&values)
    }

    /// Gives each frame what the front end ran on it, `work[i]` to the `i`th frame: the host
    /// replay's figures for the same frames (meaningful when the firmware's poses were
    /// bit-identical to the host's).
    ///
    /// # Errors
    /// `work` has another length than the frames.
    pub fn attach_work(&mut self, work: &[FrontendWork]) -> Result<()> {
        if work.len() != self.frames.len() {
            bail!(
                "the host replay has {} frames, the firmware run {}",
                work.len(),
                self.frames.len()
            );
        }
        for (f, w) in self.frames.iter_mut().zip(work) {
            f.work = Some(*w);
        }
        Ok(())
    }

    /// Keyframes among the frames.
    pub fn keyframe_count(&self) -> usize {
        self.frames.iter().filter(|f| f.keyframe).count()
    }

    /// `cost.json`'s content; `extra` (ELF sections, UART figures) is merged in at the top level.
    pub fn to_json(&self, extra: Value) -> Value {
        let s = &self.status;
        let per_frame: Vec<Value> = self
            .frames
            .iter()
            .map(|f| {
                json!({
                    "frame_index": f.frame_index,
                    "keyframe": f.keyframe,
                    "work": f.work.map(|w| json!({
                        "final_stages": w.final_stages,
                        "guide_runs": w.guide_runs,
                        "rotation_estimated": w.rotation_estimated,
                        "detected": w.detected,
                    })),
                    "acquire_instructions": f.acquire,
                    "frontend_instructions": f.frontend,
                    "backend_step_instructions": f.backend_step,
                    "pipeline_instructions": f.pipeline(),
                    "report_instructions": f.report,
                    "total_instructions": f.total(),
                })
            })
            .collect();
        let stages: serde_json::Map<String, Value> = self
            .stage_stats()
            .into_iter()
            .map(|((key, _, _), stats)| (key.to_owned(), stats.to_json()))
            .collect();
        let mut doc = json!({
            "format": FORMAT,
            "unit": "instructions (QEMU mps2-an386, -icount shift=0: SysTick ticks x 40)",
            "dataset": self.dataset,
            "frames": self.frames.len(),
            "keyframes": self.keyframe_count(),
            "elf": self.elf.display().to_string(),
            "elf_fnv1a64": self.elf_fnv1a64,
            "status": {
                "frames": s.frames, "tracked_frames": s.tracked_frames,
                "lost_frames": s.lost_frames, "reinitializations": s.reinitializations,
                "relocalizations": s.relocalizations, "keyframes": s.keyframes,
                "recoveries": s.recoveries, "faults": s.faults, "state_bytes": s.state_bytes,
                "stack_peak_bytes": s.stack_peak_bytes,
            },
            "stages": stages,
            "per_frame": per_frame,
        });
        if let (Some(doc), Value::Object(extra)) = (doc.as_object_mut(), extra) {
            doc.extend(extra);
        }
        doc
    }

    /// Reads a `cost.json` written by [`FirmwareRun::to_json`].
    ///
    /// # Errors
    /// An unreadable file, another format, a missing field.
    pub fn read(path: &Path) -> Result<Self> {
        let text =
            fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        let doc: Value =
            serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
        Self::from_json(&doc).with_context(|| format!("{} is not a cost.json", path.display()))
    }

    fn from_json(doc: &Value) -> Result<Self> {
        if doc["format"].as_u64() != Some(FORMAT) {
            bail!(
                "format {} (this xtask reads {FORMAT}: run firmware-replay again)",
                doc["format"]
            );
        }
        let text = |v: &Value, k: &str| -> Result<String> {
            v[k].as_str().map(str::to_owned).ok_or_else(|| anyhow!("no string `{k}`"))
        };
        let int = |v: &Value, k: &str| -> Result<u64> {
            v[k].as_u64().ok_or_else(|| anyhow!("no integer `{k}`"))
        };
        let int32 = |v: &Value, k: &str| -> Result<u32> { Ok(u32::try_from(int(v, k)?)?) };
        let s = &doc["status"];
        let status = StatusMessage {
            frames: int32(s, "frames")?,
            tracked_frames: int32(s, "tracked_frames")?,
            lost_frames: int32(s, "lost_frames")?,
            reinitializations: int32(s, "reinitializations")?,
            relocalizations: int32(s, "relocalizations")?,
            keyframes: int32(s, "keyframes")?,
            recoveries: int32(s, "recoveries")?,
            faults: int32(s, "faults")?,
            state_bytes: int32(s, "state_bytes")?,
            stack_peak_bytes: int32(s, "stack_peak_bytes")?,
        };
        let frames = doc["per_frame"]
            .as_array()
            .ok_or_else(|| anyhow!("no `per_frame` array"))?
            .iter()
            .map(|f| {
                Ok(FrameCost {
                    frame_index: int32(f, "frame_index")?,
                    keyframe: f["keyframe"].as_bool().ok_or_else(|| anyhow!("no `keyframe`"))?,
                    work: work_from_json(&f["work"])?,
                    acquire: int(f, "acquire_instructions")?,
                    frontend: int(f, "frontend_instructions")?,
                    backend_step: int(f, "backend_step_instructions")?,
                    report: int(f, "report_instructions")?,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            dataset: text(doc, "dataset")?,
            elf: PathBuf::from(text(doc, "elf")?),
            elf_fnv1a64: text(doc, "elf_fnv1a64")?,
            status,
            frames,
        })
    }
}

/// A frame's `work` object (`null` or absent: not known).
fn work_from_json(w: &Value) -> Result<Option<FrontendWork>> {
    if w.is_null() {
        return Ok(None);
    }
    let count = |k: &str| -> Result<u8> {
        let v = w[k].as_u64().ok_or_else(|| anyhow!("no integer `work.{k}`"))?;
        Ok(u8::try_from(v)?)
    };
    let flag = |k: &str| w[k].as_bool().ok_or_else(|| anyhow!("no `work.{k}`"));
    Ok(Some(FrontendWork {
        final_stages: count("final_stages")?,
        guide_runs: count("guide_runs")?,
        rotation_estimated: flag("rotation_estimated")?,
        detected: flag("detected")?,
    }))
}

/// One cost message as instructions, with its frame's keyframe flag.
fn frame_cost(c: &CostMessage, keyframes: &HashMap<u32, bool>) -> Result<FrameCost> {
    let TickUnit::Instructions { per_tick } = c.unit else {
        bail!("frame {}: the cost is in core cycles, not instructions", c.frame_index);
    };
    let k = u64::from(per_tick);
    let keyframe = *keyframes
        .get(&c.frame_index)
        .ok_or_else(|| anyhow!("frame {}: a cost message without its pose", c.frame_index))?;
    Ok(FrameCost {
        frame_index: c.frame_index,
        keyframe,
        work: None,
        acquire: u64::from(c.acquire_ticks) * k,
        frontend: u64::from(c.frontend_ticks) * k,
        backend_step: u64::from(c.backend_ticks) * k,
        report: u64::from(c.report_ticks) * k,
    })
}

/// FNV-1a, 64 bits: a fingerprint of a build (not a cryptographic hash).
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    bytes
        .iter()
        .fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    fn run() -> FirmwareRun {
        let frame = |i: u32, keyframe, frontend| FrameCost {
            frame_index: i,
            keyframe,
            work: None,
            acquire: 5_000_000,
            frontend,
            backend_step: 1_000 * u64::from(i),
            report: 2_000,
        };
        FirmwareRun {
            dataset: "data".into(),
            elf: "fw.elf".into(),
            elf_fnv1a64: format!("{:016x}", fnv1a64(b"elf")),
            status: StatusMessage {
                frames: 3,
                keyframes: 1,
                stack_peak_bytes: 30_000,
                ..Default::default()
            },
            frames: vec![
                frame(0, true, 90_000_000),
                frame(1, false, 9_000_000),
                frame(2, false, 10_000_000),
            ],
        }
    }

    #[test]
    fn cost_json_round_trips() {
        let r = run();
        let doc = r.to_json(json!({"uart": {"bytes": 7}}));
        assert_eq!(doc["uart"]["bytes"], 7);
        assert_eq!(doc["stages"]["pipeline"]["median"], 10_002_000);
        assert_eq!(doc["stages"]["pipeline"]["max"], 90_000_000);
        assert_eq!(doc["per_frame"][2]["total_instructions"], 5_000_000 + 10_002_000 + 2_000);
        assert_eq!(FirmwareRun::from_json(&doc).unwrap(), r);
        assert_eq!(r.keyframe_count(), 1);
        let mut old = doc;
        old["format"] = json!(1);
        assert!(FirmwareRun::from_json(&old).is_err());
    }

    #[test]
    fn work_is_attached_and_round_trips() {
        let mut r = run();
        let w = |final_stages, detected| FrontendWork {
            final_stages,
            guide_runs: final_stages - 1,
            rotation_estimated: false,
            detected,
        };
        assert!(r.attach_work(&[w(1, true)]).is_err());
        r.attach_work(&[w(1, true), w(2, false), w(1, false)]).unwrap();
        let doc = r.to_json(json!({}));
        assert_eq!(doc["per_frame"][1]["work"]["final_stages"], 2);
        assert_eq!(FirmwareRun::from_json(&doc).unwrap(), r);
        assert_eq!(
            describe_work(&w(2, true)),
            "2 final stages, 1 guide run, detection (a keyframe)"
        );
        let mut unknown = doc;
        unknown["per_frame"][0]["work"] = Value::Null;
        assert_eq!(FirmwareRun::from_json(&unknown).unwrap().frames[0].work, None);
    }

    #[test]
    fn fnv1a64_known_values() {
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
    }
}
