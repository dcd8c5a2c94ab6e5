//! The core's results as [`wire`](crate::wire) messages: the wire schema knows message types
//! only, and this is where the front end's results meet them.

use crate::tracking::{FrameResult, FrontendState, FrontendStats};
use crate::wire::{PoseFlags, PoseMessage, StatusMessage, TrackingState};

impl From<FrontendState> for TrackingState {
    fn from(s: FrontendState) -> Self {
        match s {
            FrontendState::Initializing => Self::Initializing,
            FrontendState::Tracking => Self::Tracking,
            FrontendState::Lost => Self::Lost,
        }
    }
}

impl PoseMessage {
    /// The message for the front end's result `r` of frame `frame_index` captured at
    /// `timestamp_s`. The pose's f32 values are copied bit for bit.
    pub fn from_frame_result(frame_index: u32, timestamp_s: f64, r: &FrameResult) -> Self {
        let t = &r.t_wc.translation.vector;
        let q = r.t_wc.rotation.coords;
        let mut flags = 0;
        for (on, bit) in [
            (r.tracked, PoseFlags::TRACKED),
            (r.keyframe.is_some(), PoseFlags::KEYFRAME),
            (r.guide_stage.is_recovery(), PoseFlags::RECOVERY),
            (r.reinitialized, PoseFlags::REINITIALIZED),
            (r.relocalized, PoseFlags::RELOCALIZED),
            (r.loop_closure.is_some(), PoseFlags::LOOP_CLOSED),
        ] {
            if on {
                flags |= bit;
            }
        }
        Self {
            frame_index,
            timestamp_s,
            translation_m: [t.x, t.y, t.z],
            // nalgebra stores quaternion coordinates as [i, j, k, w].
            rotation_xyzw: [q.x, q.y, q.z, q.w],
            state: r.state.into(),
            flags: PoseFlags(flags),
            inliers: saturate_u16(r.inliers),
            matches: saturate_u16(r.matches),
        }
    }
}

impl StatusMessage {
    /// The totals of the front end's `stats`, with the board's figures.
    pub fn from_stats(stats: &FrontendStats, faults: u32, state_bytes: u32) -> Self {
        Self {
            frames: stats.frames,
            tracked_frames: stats.tracked_frames,
            lost_frames: stats.lost_frames,
            reinitializations: stats.reinitializations,
            relocalizations: stats.relocalizations,
            keyframes: stats.keyframes,
            recoveries: stats.bank_recoveries,
            faults,
            state_bytes,
            stack_peak_bytes: 0,
        }
    }
}

/// `n` as `u16`, saturated.
fn saturate_u16(n: usize) -> u16 {
    u16::try_from(n).unwrap_or(u16::MAX)
}
