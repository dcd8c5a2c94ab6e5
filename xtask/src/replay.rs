//! `cargo xtask firmware-replay DATASET [--max-frames N] [--out DIR]`: the firmware in QEMU
//! against the host replay, pose by pose, bit by bit.
//!
//! 1. Writes the first N frames of DATASET at the sensor's resolution (VGA) as raw frame files
//!    back to back (`frames.fsrs`), decoded by the host simulator's dataset loader. The board
//!    sizes that file with semihosting's 32-bit `SYS_FLEN`, so at most 4 GiB of frames (4,660 at
//!    VGA) are played; more is refused before anything is written.
//! 2. Builds the firmware and boots `qemu-mps2` on them (`firmware::run_qemu`): it streams each
//!    frame into its QVGA store two rows at a time, runs the pipeline and sends pose and cost
//!    messages out of UART0 (`uart.bin`).
//! 3. Decodes the capture with the core's wire decoder; any dropped frame or fault fails the run.
//! 4. Runs `ferroslam-sim replay`'s SLAM mode (`ferroslam_sim::run::track`, same back-end quota per
//!    frame as the firmware) on the same frames at QVGA, and compares every pose as it was output
//!    frame by frame: timestamp, translation and quaternion as f32 bits, state,
//!    flags, inliers and matches.
//! 5. Prints one line (`bit-identical` with the frame count, or the first differing frame and
//!    field) and writes into DIR: `cost.json` (per-frame SysTick instruction counts by stage:
//!    acquire, front end, back-end step, report; the board's final status with its peak stack;
//!    see `cost.rs`; `cargo xtask budgets --from DIR` checks the budgets on it), the two
//!    trajectories (`firmware_trajectory.txt`, `host_trajectory.txt`), the UART capture
//!    (`uart.bin`) and the decoded firmware log (`firmware.log`). `frames.fsrs` (~0.9 MB a frame)
//!    is removed after a bit-identical run and kept when something differs.

use std::fmt::Display;
use std::fs;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, Result, anyhow, bail};
use ferroslam_core::config::{QVGA, VGA};
use ferroslam_core::geometry::PinholeCamera;
use ferroslam_core::tracking::FrontendWork;
use ferroslam_core::wire::{FaultCode, Message, PoseFlags, PoseMessage, TrackingState};
use ferroslam_sim::anchor_script::AnchorScript;
use ferroslam_sim::dataset::selection::FrameSelection;
use ferroslam_sim::dataset::{CalibrationSource, Dataset, DatasetOptions};
use ferroslam_sim::run::{self, ArPlan, RunOptions, TrackMode, TrackingRun};
use ferroslam_sim::serial::{Capture, decode_capture, stamped_pose};
use ferroslam_sim::trajectory::{StampedPose, Trajectory};
use serde_json::json;

mod frames;
mod saved;
mod world;

pub use saved::saved_map;
use saved::{compare_saved_maps, place_store_address};
pub use world::COMMANDS;
use world::{compare_anchors, compare_planes, write_commands};

use crate::cost::FirmwareRun;
use crate::firmware::{self, decode_defmt, elf_sections, flash_and_ram};
use crate::stats::millions;

/// Frames compared when `--max-frames` is not given.
pub const DEFAULT_FRAMES: usize = 60;

/// QEMU's time limit: a fixed start-up allowance plus a per-frame allowance (a frame takes well
/// under a second of QEMU time).
fn qemu_timeout(frames: usize) -> Duration {
    Duration::from_secs(60 + 5 * frames as u64)
}

/// The options of `firmware-replay`.
#[derive(Debug, Clone)]
pub struct ReplayOptions {
    /// The TUM-layout dataset folder.
    pub dataset: PathBuf,
    /// A calibration file instead of the folder's `calibration.toml` (`--calibration FILE`;
    /// default [`crate::paths::calibration_for`] the dataset).
    pub calibration: Option<PathBuf>,
    /// Frames to run (the earliest).
    pub max_frames: usize,
    /// The recording's frames in another order (`--frames A-B,C-D,...`, as `ferroslam-sim
    /// replay --frames`), before `max_frames` applies.
    pub frames: Option<FrameSelection>,
    /// Output folder.
    pub out: PathBuf,
    /// More QEMU arguments (`profile-firmware`'s `-plugin`); none from the command line.
    pub qemu_args: Vec<String>,
    /// What the run starts from and saves (`--save-map`, `--boot-from DIR`, `--localize`).
    pub maps: BoardMaps,
    /// An anchor script (`--anchors FILE`, as `ferroslam-sim replay --anchors`): its commands
    /// go to the board over its serial link's receive side (`commands.bin`), and the host
    /// replay applies them as the board does; the anchors must come out the same.
    pub anchors: Option<PathBuf>,
}

/// The saved maps of a firmware replay: the board's flash image and the host's map file.
#[derive(Debug, Clone, Default)]
pub struct BoardMaps {
    /// Save at the end: the firmware commits its store and writes the flash region to
    /// `flash.bin`, the host replay saves `host-map.fsmp`, and the map in the flash image must be
    /// the host's byte for byte.
    pub save: bool,
    /// A previous saving run's output folder: the board boots with its `flash.bin` in the flash
    /// region (a second power-on), the host replay loads its `host-map.fsmp`.
    pub boot_from: Option<PathBuf>,
    /// Localization only in the map booted from.
    pub localize: bool,
}

/// The flash image a saving firmware replay writes into its output folder.
pub const FLASH_IMAGE: &str = "flash.bin";
/// The map file the host replay of a saving firmware replay writes.
pub const HOST_MAP: &str = "host-map.fsmp";

impl ReplayOptions {
    /// Parses `DATASET [--calibration FILE] [--max-frames N] [--frames A-B,...] [--out DIR]`;
    /// `default_out` when `--out` is missing.
    pub fn parse(args: &[String], default_out: PathBuf) -> Result<Self> {
        let (mut dataset, mut calibration, mut frames) = (None, None, None);
        let (mut max_frames, mut out) = (DEFAULT_FRAMES, default_out);
        let mut maps = BoardMaps::default();
        let mut anchors = None;
        let mut it = args.iter();
        while let Some(a) = it.next() {
            match a.as_str() {
                "--max-frames" => {
                    let v = it.next().ok_or_else(|| anyhow!("--max-frames needs a value"))?;
                    max_frames = v.parse().with_context(|| format!("--max-frames {v}"))?;
                }
                "--out" => out = it.next().ok_or_else(|| anyhow!("--out needs a value"))?.into(),
                "--frames" => {
                    let v = it.next().ok_or_else(|| anyhow!("--frames needs a value"))?;
                    frames = Some(v.parse().with_context(|| format!("--frames {v}"))?);
                }
                "--calibration" => {
                    let v = it.next().ok_or_else(|| anyhow!("--calibration needs a value"))?;
                    calibration = Some(PathBuf::from(v));
                }
                "--anchors" => {
                    let v = it.next().ok_or_else(|| anyhow!("--anchors needs a script"))?;
                    anchors = Some(PathBuf::from(v));
                }
                "--save-map" => maps.save = true,
                "--localize" => maps.localize = true,
                "--boot-from" => {
                    let v = it.next().ok_or_else(|| anyhow!("--boot-from needs a folder"))?;
                    maps.boot_from = Some(PathBuf::from(v));
                }
                flag if flag.starts_with("--") => bail!("unknown option {flag}"),
                path if dataset.is_none() => dataset = Some(PathBuf::from(path)),
                extra => bail!("unexpected argument {extra}"),
            }
        }
        let dataset = dataset.ok_or_else(|| {
            anyhow!(
                "usage: firmware-replay DATASET [--calibration FILE] [--max-frames N] [--frames \
                 A-B,...] [--out DIR] [--save-map] [--boot-from DIR [--localize]] [--anchors \
                 FILE]"
            )
        })?;
        let calibration = calibration.or_else(|| crate::paths::calibration_for(&dataset));
        if max_frames == 0 {
            bail!("--max-frames must be at least 1");
        }
        if maps.localize && maps.boot_from.is_none() {
            bail!("--localize needs a map to localize in (--boot-from DIR)");
        }
        Ok(Self {
            dataset,
            calibration,
            max_frames,
            frames,
            out,
            qemu_args: Vec::new(),
            maps,
            anchors,
        })
    }
}

/// Runs the comparison (see the module documentation).
///
/// # Errors
/// A dataset, build or QEMU failure; a firmware fault or a dropped frame; any difference.
pub fn run(root: &Path, opts: &ReplayOptions) -> Result<()> {
    fs::create_dir_all(&opts.out).with_context(|| format!("creating {}", opts.out.display()))?;
    let out = fs::canonicalize(&opts.out)?;
    let calibration =
        opts.calibration.clone().map_or(CalibrationSource::File, CalibrationSource::Path);
    let vga = DatasetOptions {
        calibration,
        profile: VGA,
        max_frames: Some(opts.max_frames),
        frames: opts.frames.clone(),
        ..Default::default()
    };
    let sensor = Dataset::open(&opts.dataset, &vga)?;
    let frames = sensor.len();
    frames::write_frames(&sensor, &out.join("frames.fsrs"))?;
    drop(sensor);

    let qvga = DatasetOptions { profile: QVGA, ..vga };
    let dataset = Dataset::open(&opts.dataset, &qvga)?;
    let c = *dataset.calibration();
    let cam = PinholeCamera::new(c.fx, c.fy, c.cx, c.cy, c.width as usize, c.height as usize)
        .map_err(|e| anyhow!("calibration: {e}"))?;

    let elf = firmware::build_firmware(root, "qemu-mps2")?;
    let _ = fs::remove_file(out.join("uart.bin"));
    let mut append =
        format!("frames.fsrs {} {} {} {} {} {}", c.fx, c.fy, c.cx, c.cy, c.width, c.height);
    let mut qemu_args = opts.qemu_args.clone();
    let mut host_maps = run::MapFiles { localize: opts.maps.localize, ..Default::default() };
    if let Some(from) = &opts.maps.boot_from {
        let image = fs::canonicalize(from.join(FLASH_IMAGE)).with_context(|| {
            format!("no flash image {} to boot from", from.join(FLASH_IMAGE).display())
        })?;
        let addr = place_store_address(&elf)?;
        qemu_args.extend([
            "-device".to_owned(),
            format!("loader,file={},addr={addr:#x},force-raw=on", image.display()),
        ]);
        host_maps.load = Some(from.join(HOST_MAP));
    }
    if opts.maps.localize {
        append += " localize";
    }
    let script = match &opts.anchors {
        Some(path) => {
            let script = AnchorScript::load(path, QVGA.downsample_levels)?;
            write_commands(&script, &out.join(COMMANDS))?;
            append += &format!(" commands={COMMANDS}");
            Some(script)
        }
        None => None,
    };
    if opts.maps.save {
        let _ = fs::remove_file(out.join(FLASH_IMAGE));
        append += &format!(" save={FLASH_IMAGE}");
        host_maps.save = Some(out.join(HOST_MAP));
    }
    let run =
        firmware::run_qemu(&elf, &out, &append, "uart.bin", &qemu_args, qemu_timeout(frames))?;
    let elf_bytes = fs::read(&elf).with_context(|| format!("reading {}", elf.display()))?;
    let (log, log_error) = decode_defmt(&elf_bytes, &run.defmt);
    fs::write(out.join("firmware.log"), log.join("\n") + "\n")?;
    if !run.success {
        for line in log.iter().rev().take(10).rev() {
            eprintln!("  [firmware] {line}");
        }
        let stderr = fs::read_to_string(out.join("qemu-stderr.txt")).unwrap_or_default();
        bail!(
            "firmware failed in QEMU ({}; log tail above, all in {}){}{}",
            run.status,
            out.join("firmware.log").display(),
            log_error.map_or(String::new(), |e| format!("; log decoding: {e}")),
            if stderr.trim().is_empty() {
                String::new()
            } else {
                format!("; QEMU: {}", stderr.trim())
            }
        );
    }
    let capture = decode_capture(&fs::read(out.join("uart.bin")).context("reading uart.bin")?);
    check_capture(&capture)?;

    eprintln!("host replay of the same {frames} frames at QVGA ...");
    let mut reader = dataset.into_reader(8);
    // The firmware's settings: the board's map, quota and place memory (`TrackMode::SLAM`).
    let options = RunOptions {
        maps: host_maps,
        ar: script.map(ArPlan::Script),
        ..RunOptions::new(QVGA, TrackMode::SLAM)
    };
    let host = run::track(&mut reader, frames, &cam, &options)?;
    let fw_poses: Vec<PoseMessage> = capture.poses().copied().collect();
    write_trajectories(&out, &fw_poses, &host)?;
    let work: Vec<FrontendWork> = host
        .per_frame
        .iter()
        .map(|f| FrontendWork {
            final_stages: f.final_stages,
            guide_runs: f.guide_runs,
            rotation_estimated: f.rotation_estimated,
            detected: f.detected,
        })
        .collect();
    let summary = write_cost_json(&out, &opts.dataset, &elf, &capture, &work)?;

    let saved = if opts.maps.save { Some(compare_saved_maps(&out)?) } else { None };
    let planes = compare_planes(&log, &host);
    let anchors = opts.anchors.as_ref().map(|_| compare_anchors(&log, &capture, &host));
    match first_difference(&fw_poses, &host) {
        None => {
            // ~0.9 MB a frame, and rewritten by every run: kept only when something differs.
            let _ = fs::remove_file(out.join("frames.fsrs"));
            println!(
                "firmware-replay: {frames} frames bit-identical to the host replay (timestamp, \
                 t_wc translation and quaternion bits, state, flags, inliers, matches); {summary}; \
                 QEMU {:.1} s",
                run.elapsed.as_secs_f64()
            );
            println!("firmware-replay: {}", planes?);
            if let Some(anchors) = anchors {
                println!("firmware-replay: {}", anchors?);
            }
            match saved {
                Some(Ok(line)) => println!("firmware-replay: {line}"),
                Some(Err(e)) => return Err(e),
                None => {}
            }
            Ok(())
        }
        Some(diff) => {
            println!("firmware-replay: DIFFERENT at {diff}");
            bail!("the firmware's poses differ from the host's (first: {diff})")
        }
    }
}

/// A capture is usable when nothing was dropped and the firmware reported no fault.
fn check_capture(capture: &Capture) -> Result<()> {
    let s = capture.stats;
    if s.frames_dropped > 0 || s.frames_unknown_version > 0 || s.bytes_skipped > 0 {
        bail!(
            "the UART capture is damaged: {} frames dropped, {} of an unknown version, {} bytes \
             skipped ({:?})",
            s.frames_dropped,
            s.frames_unknown_version,
            s.bytes_skipped,
            capture.dropped.first()
        );
    }
    // A command the board refused is a fault it reports; `compare_anchors` checks those against
    // the host's.
    let fault = capture.messages.iter().find_map(|m| match m {
        Message::Fault(f) if f.code != FaultCode::Command => Some(f),
        _ => None,
    });
    if let Some(f) = fault {
        bail!("the firmware reported a fault: {f:?}");
    }
    if !capture.messages.iter().any(|m| matches!(m, Message::Status(_))) {
        bail!("the firmware sent no final status: the run did not finish");
    }
    Ok(())
}

/// `name: firmware X, host Y` when `fw != host`.
fn field<T: PartialEq + Display>(name: &str, fw: T, host: T) -> Option<String> {
    (fw != host).then(|| format!("{name}: firmware {fw}, host {host}"))
}

/// The first field that differs, as `frame N (t = T s), FIELD: firmware X, host Y`.
///
/// The firmware sends a message for every frame; the host's `online` trajectory leaves out the
/// frames without a pose (state `initializing`: before the first keyframe, or, in a loaded map,
/// before the first relocalization). Those frames are compared by everything but the pose.
fn first_difference(fw: &[PoseMessage], host: &TrackingRun) -> Option<String> {
    if fw.len() != host.per_frame.len() {
        return Some(format!(
            "the firmware sent {} poses for the host replay's {} frames",
            fw.len(),
            host.per_frame.len()
        ));
    }
    let mut online = host.online.poses.iter();
    for (i, (p, hf)) in fw.iter().zip(&host.per_frame).enumerate() {
        let h = if hf.state == "initializing" {
            None
        } else {
            let Some(h) = online.next() else {
                return Some(format!(
                    "frame {i}: the host replay has {} poses, fewer than its frames with one",
                    host.online.len()
                ));
            };
            Some(h)
        };
        let state = match p.state {
            TrackingState::Initializing => "initializing",
            TrackingState::Tracking => "tracking",
            TrackingState::Lost => "lost",
        };
        let bits = |v: f32| format!("{v:e} ({:#010x})", v.to_bits());
        let pose = |h: &StampedPose| {
            let t = h.t_wc.translation.vector;
            let q = h.t_wc.rotation.coords;
            // The host's poses are the core's f32 values widened to f64: narrowing is exact.
            #[allow(clippy::cast_possible_truncation)]
            let host_t = [t.x as f32, t.y as f32, t.z as f32];
            #[allow(clippy::cast_possible_truncation)]
            let host_q = [q.x as f32, q.y as f32, q.z as f32, q.w as f32];
            (0..3)
                .find_map(|k| {
                    field(&format!("translation_m[{k}]"), bits(p.translation_m[k]), bits(host_t[k]))
                })
                .or_else(|| {
                    (0..4).find_map(|k| {
                        let name = format!("rotation_xyzw[{k}]");
                        field(&name, bits(p.rotation_xyzw[k]), bits(host_q[k]))
                    })
                })
        };
        let diff = field("frame_index", p.frame_index as usize, i)
            .or_else(|| {
                field(
                    "timestamp_s",
                    format!("{} ({:#x})", p.timestamp_s, p.timestamp_s.to_bits()),
                    format!("{} ({:#x})", hf.timestamp_s, hf.timestamp_s.to_bits()),
                )
            })
            .or_else(|| h.and_then(pose))
            .or_else(|| field("state", state, hf.state))
            .or_else(|| field("tracked", p.flags.contains(PoseFlags::TRACKED), hf.tracked))
            .or_else(|| field("keyframe", p.flags.contains(PoseFlags::KEYFRAME), hf.keyframe))
            .or_else(|| field("recovery", p.flags.contains(PoseFlags::RECOVERY), hf.recovery))
            .or_else(|| {
                let reinit = p.flags.contains(PoseFlags::REINITIALIZED);
                field("reinitialized", reinit, hf.reinitialized)
            })
            .or_else(|| {
                let reloc = p.flags.contains(PoseFlags::RELOCALIZED);
                field("relocalized", reloc, hf.relocalized)
            })
            .or_else(|| {
                let closed = p.flags.contains(PoseFlags::LOOP_CLOSED);
                field("loop_closed", closed, hf.loop_closed)
            })
            .or_else(|| field("inliers", usize::from(p.inliers), hf.inliers.min(65535)))
            .or_else(|| field("matches", usize::from(p.matches), hf.matches.min(65535)));
        if let Some(d) = diff {
            return Some(format!("frame {i} (t = {} s), {d}", hf.timestamp_s));
        }
    }
    online.next().map(|_| {
        format!("the host replay has {} poses, more than its frames with one", host.online.len())
    })
}

/// Writes `firmware_trajectory.txt` and `host_trajectory.txt` (TUM): the frames with a pose (the
/// firmware's messages for frames in state `initializing` carry none and are left out).
fn write_trajectories(out: &Path, fw: &[PoseMessage], host: &TrackingRun) -> Result<()> {
    let posed = fw.iter().filter(|p| p.state != TrackingState::Initializing);
    Trajectory::new(posed.map(stamped_pose).collect())
        .write_tum(&out.join("firmware_trajectory.txt"))?;
    host.online.write_tum(&out.join("host_trajectory.txt"))?;
    Ok(())
}

/// Writes `cost.json` (see `cost.rs`), each frame with what the host's front end ran on it,
/// and returns a one-line summary of its figures.
fn write_cost_json(
    out: &Path,
    dataset: &Path,
    elf: &Path,
    capture: &Capture,
    work: &[FrontendWork],
) -> Result<String> {
    let mut run = FirmwareRun::from_capture(capture, dataset, elf)?;
    run.attach_work(work)?;
    let sections = elf_sections(elf).unwrap_or_default();
    let (flash, ram) = flash_and_ram(&sections);
    let stack = run.status.stack_peak_bytes;
    let extra = json!({
        "firmware": {
            "flash_bytes": flash,
            "static_ram_bytes": ram,
            "stack_peak_bytes": stack,
            "sections": sections.iter().map(|(n, s)| json!({"name": n, "bytes": s})).collect::<Vec<_>>(),
        },
        "uart": {
            "bytes": capture.stats.bytes_received,
            "frames_decoded": capture.stats.frames_decoded,
            "frames_dropped": capture.stats.frames_dropped,
            "bytes_skipped": capture.stats.bytes_skipped,
        },
    });
    let path = out.join("cost.json");
    fs::write(&path, serde_json::to_string_pretty(&run.to_json(extra))? + "\n")
        .with_context(|| format!("writing {}", path.display()))?;
    let (pipeline, frontend, backend) =
        (run.stats("pipeline"), run.stats("frontend"), run.stats("backend_step"));
    Ok(format!(
        "pipeline instructions per frame median {} (front end {}, back-end step {}), max {}; \
         static RAM {ram} B + peak stack {stack} B = {} B; cost.json in {}",
        millions(pipeline.median),
        millions(frontend.median),
        millions(backend.median),
        millions(pipeline.max),
        ram + u64::from(stack),
        out.display()
    ))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;
    use ferroslam_sim::run::{DataPathRun, TrackedFrame};

    fn pose(i: u32) -> PoseMessage {
        PoseMessage {
            frame_index: i,
            timestamp_s: 5.0 + f64::from(i),
            translation_m: [0.1, 0.2, 0.3 * i as f32],
            rotation_xyzw: [0.0, 0.6, 0.0, 0.8],
            state: TrackingState::Tracking,
            flags: PoseFlags(PoseFlags::TRACKED),
            inliers: 40,
            matches: 50,
        }
    }

    /// The host run the poses `fw` say happened.
    fn host_of(fw: &[PoseMessage]) -> TrackingRun {
        let per_frame = fw
            .iter()
            .map(|p| TrackedFrame {
                timestamp_s: p.timestamp_s,
                state: "tracking",
                tracked: true,
                keyframe: false,
                inliers: 40,
                matches: 50,
                guide_matches: 0,
                guide_stage: "motion-model",
                recovery: false,
                reinitialized: false,
                relocalized: false,
                loop_closed: false,
                final_stages: 1,
                guide_runs: 0,
                rotation_estimated: false,
                detected: false,
            })
            .collect();
        let data = DataPathRun {
            frames: fw.len(),
            width: 320,
            height: 240,
            per_frame: Vec::new(),
            source_wait_s: 0.0,
            process_s: 0.0,
        };
        TrackingRun {
            data,
            camera: Trajectory::new(fw.iter().map(stamped_pose).collect()),
            online: Trajectory::new(fw.iter().map(stamped_pose).collect()),
            keyframes: Trajectory::new(Vec::new()),
            per_frame,
            tracked_frames: fw.len(),
            lost_frames: 0,
            reinitialized_frames: 0,
            relocalized_frames: 0,
            initializing_frames: 0,
            places: None,
            state_bytes: 0,
            backend: None,
            planes: None,
            ar: None,
            map_points: None,
        }
    }

    #[test]
    fn the_first_differing_frame_and_field_are_named() {
        let fw: Vec<PoseMessage> = (0..4).map(pose).collect();
        let host = host_of(&fw);
        assert_eq!(first_difference(&fw, &host), None);
        // One bit of one quaternion component of frame 2.
        let mut changed = fw.clone();
        changed[2].rotation_xyzw[1] = f32::from_bits(changed[2].rotation_xyzw[1].to_bits() ^ 1);
        let diff = first_difference(&changed, &host).unwrap();
        assert!(diff.starts_with("frame 2 (t = 7 s), rotation_xyzw[1]: firmware"), "{diff}");
        let mut fewer = fw.clone();
        fewer.pop();
        assert!(first_difference(&fewer, &host).unwrap().contains("sent 3 poses for"));
        let mut lost = fw;
        lost[1].state = TrackingState::Lost;
        let diff = first_difference(&lost, &host).unwrap();
        assert!(diff.contains("state: firmware lost, host tracking"), "{diff}");
    }

    /// A run in a loaded map: the first two frames have no pose until one relocalizes. The host
    /// leaves them out of its trajectory; the firmware sends them (state `initializing`, no
    /// pose), and they are compared by everything but the pose.
    #[test]
    fn frames_without_a_pose_are_compared_by_state_alone() {
        let mut fw: Vec<PoseMessage> = (0..4).map(pose).collect();
        for p in &mut fw[..2] {
            (p.state, p.flags, p.inliers, p.matches) =
                (TrackingState::Initializing, PoseFlags(0), 0, 0);
            (p.translation_m, p.rotation_xyzw) = ([0.0; 3], [0.0, 0.0, 0.0, 1.0]);
        }
        fw[2].flags = PoseFlags(PoseFlags::TRACKED | PoseFlags::RELOCALIZED);
        let mut host = host_of(&fw);
        host.online = Trajectory::new(fw[2..].iter().map(stamped_pose).collect());
        for f in &mut host.per_frame[..2] {
            (f.state, f.tracked, f.inliers, f.matches) = ("initializing", false, 0, 0);
        }
        host.per_frame[2].relocalized = true;
        assert_eq!(first_difference(&fw, &host), None);
        // The first pose is still checked bit for bit, against the host's first pose.
        let mut moved = fw.clone();
        moved[2].translation_m[0] = 0.5;
        let diff = first_difference(&moved, &host).unwrap();
        assert!(diff.starts_with("frame 2 (t = 7 s), translation_m[0]: firmware"), "{diff}");
        // A frame the firmware tracked where the host had no pose yet.
        let mut early = fw.clone();
        early[1].state = TrackingState::Tracking;
        let diff = first_difference(&early, &host).unwrap();
        assert!(diff.contains("frame 1 (t = 6 s), state: firmware tracking, host initializing"));
        // A host pose left over.
        host.per_frame[3].state = "initializing";
        fw[3].state = TrackingState::Initializing;
        fw[3].flags = PoseFlags(0);
        host.per_frame[3].tracked = false;
        let diff = first_difference(&fw, &host).unwrap();
        assert!(diff.contains("more than its frames with one"), "{diff}");
    }

    #[test]
    fn options_parse() {
        let args: Vec<String> =
            ["data", "--max-frames", "7", "--out", "o"].iter().map(|s| s.to_string()).collect();
        let o = ReplayOptions::parse(&args, "d".into()).unwrap();
        assert_eq!((o.dataset, o.max_frames, o.out), ("data".into(), 7, "o".into()));
        assert!(ReplayOptions::parse(&[], "d".into()).is_err());
        assert!(
            ReplayOptions::parse(&["x".into(), "--max-frames".into(), "0".into()], "d".into())
                .is_err()
        );
    }
}
