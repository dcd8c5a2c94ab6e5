//! SLAM mode of `replay` and `demo`: the core's [`Slam`] facade with a fixed back-end quota per
//! frame (deterministic), and the trajectory composed the way ORB-SLAM writes
//! `CameraTrajectory.txt`: each frame's pose relative to its reference keyframe at the time it was
//! tracked, composed with that keyframe's final pose.

use std::collections::HashMap;

use anyhow::{Result, anyhow};
use ferroslam_core::backend::BackendStatus;
use ferroslam_core::frame::FrameSource;
use ferroslam_core::geometry::{PinholeCamera, Pose};
use ferroslam_core::map::KeyFrameId;
use ferroslam_core::system::Slam;

use super::datapath::{BackendReport, OdometryRun, frame_figures, run_with};
use crate::trajectory::{StampedPose, Trajectory};

/// Back-end steps allowed after the last frame to finish the solve under way.
const DRAIN_STEPS: usize = 10_000;

/// One frame's pose relative to its reference keyframe (`None`: the frame had none; the pose is
/// then absolute).
struct Relative {
    timestamp_s: f64,
    keyframe: Option<KeyFrameId>,
    pose: Pose,
}

/// Runs `source` through a boxed `Slam<W, H>` with `quota` back-end units after each frame.
///
/// # Errors
/// As [`run_with`]; a back-end error.
pub fn run<const W: usize, const H: usize, S>(
    source: &mut S,
    expected: usize,
    cam: &PinholeCamera,
    quota: u32,
) -> Result<OdometryRun>
where
    S: FrameSource,
    S::Error: std::error::Error + Send + Sync + 'static,
{
    // About a megabyte: boxed, never on the stack.
    let mut slam: Box<Slam<W, H>> = Box::default();
    let (mut online, mut per_frame, mut relative) = (Vec::new(), Vec::new(), Vec::new());
    // The latest pose of every keyframe seen: keyframes the map retires keep their last one.
    let mut keyframe_pose: HashMap<KeyFrameId, (f64, Pose)> = HashMap::new();
    let data = run_with(source, expected, |frame| {
        let r = slam.process(frame, cam)?;
        online.push(StampedPose { timestamp_s: frame.timestamp_s, t_wc: r.t_wc.cast::<f64>() });
        per_frame.push(frame_figures(frame.timestamp_s, &r));
        let reference =
            r.reference_keyframe.and_then(|k| slam.map().keyframe(k).map(|kf| (k, kf.t_wc)));
        relative.push(match reference {
            Some((k, t_wk)) => Relative {
                timestamp_s: frame.timestamp_s,
                keyframe: Some(k),
                pose: t_wk.inverse() * r.t_wc,
            },
            None => Relative { timestamp_s: frame.timestamp_s, keyframe: None, pose: r.t_wc },
        });
        slam.step_backend(cam, quota).map_err(|e| anyhow!("back end: {e}"))?;
        record_keyframes(&slam, &mut keyframe_pose);
        Ok(())
    })?;
    for _ in 0..DRAIN_STEPS {
        if !slam.backend().is_busy() {
            break;
        }
        if let BackendStatus::Idle =
            slam.step_backend(cam, quota).map_err(|e| anyhow!("back end: {e}"))?
        {
            break;
        }
    }
    record_keyframes(&slam, &mut keyframe_pose);
    let camera = relative
        .iter()
        .map(|r| {
            let t_wc = match r.keyframe.and_then(|k| keyframe_pose.get(&k)) {
                Some((_, t_wk)) => t_wk * r.pose,
                None => r.pose,
            };
            StampedPose { timestamp_s: r.timestamp_s, t_wc: t_wc.cast::<f64>() }
        })
        .collect();
    let mut keyframes: Vec<StampedPose> = keyframe_pose
        .values()
        .map(|&(timestamp_s, t_wc)| StampedPose { timestamp_s, t_wc: t_wc.cast::<f64>() })
        .collect();
    keyframes.sort_by(|a, b| a.timestamp_s.total_cmp(&b.timestamp_s));
    let stats = slam.frontend().stats();
    Ok(OdometryRun {
        data,
        camera: Trajectory::new(camera),
        online: Trajectory::new(online),
        keyframes: Trajectory::new(keyframes),
        per_frame,
        tracked_frames: stats.tracked_frames as usize,
        lost_frames: stats.lost_frames as usize,
        state_bytes: std::mem::size_of::<Slam<W, H>>(),
        backend: Some(backend_report(&slam, quota)),
    })
}

fn record_keyframes<const W: usize, const H: usize>(
    slam: &Slam<W, H>,
    poses: &mut HashMap<KeyFrameId, (f64, Pose)>,
) {
    for (id, k) in slam.map().keyframes() {
        poses.insert(id, (k.timestamp_s, k.t_wc));
    }
}

fn backend_report<const W: usize, const H: usize>(slam: &Slam<W, H>, quota: u32) -> BackendReport {
    let b = slam.backend().stats();
    let window_sizes: Vec<[u32; 2]> = b
        .window_sizes
        .iter()
        .enumerate()
        .filter(|(_, n)| **n > 0)
        .map(|(size, &n)| [u32::try_from(size).unwrap_or(u32::MAX), n])
        .collect();
    let windows: u32 = window_sizes.iter().map(|w| w[1]).sum();
    let weighted: u64 = window_sizes.iter().map(|w| u64::from(w[0]) * u64::from(w[1])).sum();
    let all_points = b.free_points + b.fixed_points;
    BackendReport {
        work_quota_per_frame: quota,
        local_runs: b.local_runs,
        global_runs: b.global_runs,
        window_mean: if windows > 0 { weighted as f64 / f64::from(windows) } else { 0.0 },
        window_sizes,
        map_keyframes: slam.map().num_keyframes(),
        map_landmarks: slam.map().num_landmarks(),
        reference_landmarks: slam.map().landmarks().filter(|(_, l)| l.reference).count(),
        reference_fraction_of_points: if all_points > 0 {
            b.fixed_points as f64 / all_points as f64
        } else {
            0.0
        },
        work_units: b.work_units,
    }
}
