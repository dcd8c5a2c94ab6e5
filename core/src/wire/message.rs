//! The messages of schema version [`SCHEMA_VERSION`](super::SCHEMA_VERSION): what the firmware
//! reports per frame (pose, cost, each placed anchor), at the end of a run or on request (status),
//! and when something goes wrong (fault); and what the host sends it (anchor commands).
//!
//! Every field has a fixed meaning and unit; floats travel as their IEEE-754 bits (postcard writes
//! `f32`/`f64` little-endian), so the host sees exactly the values the firmware computed.

use nalgebra::{Quaternion, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};

use crate::ar::{Anchor, AnchorCommand};
use crate::geometry::Pose;

/// One message on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Message {
    /// The pose of one frame.
    Pose(PoseMessage),
    /// Running totals of the pipeline and the board.
    Status(StatusMessage),
    /// What one frame cost, by stage.
    Cost(CostMessage),
    /// Something failed; the firmware goes on with the next frame when it can.
    Fault(FaultMessage),
    /// Host to device: an anchor command, for a frame.
    Command(CommandMessage),
    /// Where a placed virtual object stands after a frame: one per anchor, after the frame's
    /// pose.
    Anchor(AnchorMessage),
}

/// The tracking state after a frame (the front end's `FrontendState`, as one byte).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TrackingState {
    /// No keyframe yet.
    Initializing,
    /// The frame was tracked (or made the keyframe).
    Tracking,
    /// The frame could not be tracked; its pose is the motion-model prediction.
    Lost,
}

/// Flags of a [`PoseMessage`], one bit each (unknown bits are kept, never an error).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseFlags(pub u8);

impl PoseFlags {
    /// The pose was estimated from this frame's images (else it is a prediction).
    pub const TRACKED: u8 = 1 << 0;
    /// The frame became the new keyframe.
    pub const KEYFRAME: u8 = 1 << 1;
    /// The motion-model guides gave no pose and a recovery path (the small-image rotation, the
    /// wide search or the affine bank) found it.
    pub const RECOVERY: u8 = 1 << 2;
    /// Tracking restarted at this frame from a new keyframe after a loss (the trajectory is
    /// continuous but not corrected across it).
    pub const REINITIALIZED: u8 = 1 << 3;
    /// Tracking restarted at this frame in a remembered place that geometric verification
    /// accepted: the pose is in the map's frame and may jump from the previous frame's.
    pub const RELOCALIZED: u8 = 1 << 4;
    /// A loop closed on this frame (for the last keyframe): the map and this pose moved by the
    /// loop's correction (the pose may jump from the previous frame's).
    pub const LOOP_CLOSED: u8 = 1 << 5;

    /// Whether every bit of `flag` is set.
    pub const fn contains(self, flag: u8) -> bool {
        self.0 & flag == flag
    }
}

/// The camera pose of one frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseMessage {
    /// 0-based index of the frame since the pipeline started.
    pub frame_index: u32,
    /// Capture time of the frame, seconds on the recording's (or sensor's) clock.
    pub timestamp_s: f64,
    /// Translation of `t_wc` (camera to world), metres: the camera centre in the world frame.
    pub translation_m: [f32; 3],
    /// Rotation of `t_wc` as a unit quaternion `[x, y, z, w]` (TUM order).
    pub rotation_xyzw: [f32; 4],
    /// Tracking state after the frame.
    pub state: TrackingState,
    /// [`PoseFlags`] bits.
    pub flags: PoseFlags,
    /// Pose inliers (0 when not tracked), saturated at `u16::MAX`.
    pub inliers: u16,
    /// Landmarks matched into the frame, saturated at `u16::MAX`.
    pub matches: u16,
}

impl PoseMessage {
    /// `t_wc` as a [`Pose`]; the quaternion is taken as sent (not renormalized), so the values are
    /// the firmware's bits.
    pub fn t_wc(&self) -> Pose {
        let [x, y, z] = self.translation_m;
        let [qx, qy, qz, qw] = self.rotation_xyzw;
        let rotation = UnitQuaternion::new_unchecked(Quaternion::new(qw, qx, qy, qz));
        Pose::from_parts(Translation3::new(x, y, z), rotation)
    }
}

/// Running totals since the pipeline started, and what the board knows of its own resources.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StatusMessage {
    /// Frames processed.
    pub frames: u32,
    /// Frames whose pose was estimated from the images.
    pub tracked_frames: u32,
    /// Frames in the lost state.
    pub lost_frames: u32,
    /// Frames where tracking restarted at the predicted pose after a loss.
    pub reinitializations: u32,
    /// Frames where tracking restarted in a verified remembered place.
    pub relocalizations: u32,
    /// Keyframes made.
    pub keyframes: u32,
    /// Frames that took the recovery path ([`PoseFlags::RECOVERY`]).
    pub recoveries: u32,
    /// Faults reported.
    pub faults: u32,
    /// Bytes of pipeline state (`size_of` the pipeline on the board).
    pub state_bytes: u32,
    /// Peak stack use measured by the board, bytes; 0 when not measured.
    pub stack_peak_bytes: u32,
}

/// What one tick of a [`CostMessage`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TickUnit {
    /// One core clock cycle (SysTick or DWT on the core clock of a real board).
    CoreCycle,
    /// A fixed number of executed instructions (QEMU with `-icount shift=0`: SysTick at 25 MHz
    /// against a 1 GHz virtual instruction clock gives 40 instructions per tick).
    Instructions {
        /// Instructions per tick.
        per_tick: u16,
    },
}

/// What one frame cost, by stage, in [`TickUnit`]s.
///
/// Schema version 2 split version 1's `process_ticks` into the front end
/// ([`CostMessage::frontend_ticks`]) and the back-end step that follows it
/// ([`CostMessage::backend_ticks`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CostMessage {
    /// The frame ([`PoseMessage::frame_index`]).
    pub frame_index: u32,
    /// What a tick is.
    pub unit: TickUnit,
    /// Acquiring the frame: reading the sensor (or file) and downsampling it to the profile.
    pub acquire_ticks: u32,
    /// The front end on the frame (tracking, and the keyframe decision and insertion).
    pub frontend_ticks: u32,
    /// The back-end step after the frame (one bounded quota of bundle-adjustment work).
    pub backend_ticks: u32,
    /// Encoding and writing the frame's pose message.
    pub report_ticks: u32,
}

impl CostMessage {
    /// Instructions of the four stages together, when the unit is instructions.
    pub fn total_instructions(&self) -> Option<u64> {
        match self.unit {
            TickUnit::Instructions { per_tick } => {
                let ticks = u64::from(self.acquire_ticks)
                    + u64::from(self.frontend_ticks)
                    + u64::from(self.backend_ticks)
                    + u64::from(self.report_ticks);
                Some(ticks * u64::from(per_tick))
            }
            TickUnit::CoreCycle => None,
        }
    }
}

/// What failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FaultCode {
    /// The frame source failed (bus error, sensor timeout, short frame, unreadable file).
    FrameSource,
    /// The pipeline rejected the frame (size, timestamp, parameters).
    FrameRejected,
    /// A telemetry message could not be encoded.
    Telemetry,
    /// The board's configuration is unusable (bad command line, bad calibration).
    Configuration,
    /// The stack reached its limit.
    StackOverflow,
    /// An anchor command was not applied (`detail`: `ar::AnchorError::code`; 0 for a command
    /// frame that did not decode).
    Command,
}

/// A fault and where it happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultMessage {
    /// The frame being handled ([`PoseMessage::frame_index`] it would have had).
    pub frame_index: u32,
    /// What failed.
    pub code: FaultCode,
    /// A code of the failing component (its error variant), 0 when it has none.
    pub detail: u32,
}

/// Host to device: apply `command` in frame `frame_index` ([`PoseMessage::frame_index`]), or in
/// the first frame the device processes after it when that frame is past. Commands go in the
/// order they are to apply.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CommandMessage {
    /// The frame the command applies in.
    pub frame_index: u32,
    /// What to do; pixels at the device's processing resolution.
    pub command: AnchorCommand,
}

/// A placed virtual object after a frame, in the world frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AnchorMessage {
    /// The frame ([`PoseMessage::frame_index`]).
    pub frame_index: u32,
    /// The caller's object id.
    pub object: u16,
    /// Where it stands, metres.
    pub position_m: [f32; 3],
    /// Its up: the unit normal of the plane under it.
    pub up: [f32; 3],
    /// Its scale (1: the object's own size).
    pub scale: f32,
}

impl AnchorMessage {
    /// `anchor` after frame `frame_index`.
    pub fn of(frame_index: u32, anchor: &Anchor) -> Self {
        Self {
            frame_index,
            object: anchor.object,
            position_m: anchor.p_w,
            up: anchor.up_w,
            scale: anchor.scale,
        }
    }
}
