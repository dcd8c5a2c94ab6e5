//! The keyframe rule (see [`FrontendParams`]): when a tracked frame becomes a keyframe, and when a
//! due keyframe is put off because its frame was costly.

use super::FrontendParams;
use crate::geometry::Pose;
use crate::map::KeyFrameId;
use crate::pose::PoseEstimate;

/// The keyframe rule's memory (see [`FrontendParams`]): the last keyframe, the inliers its rule
/// compares with, and the due keyframes put off.
#[derive(Debug, Clone)]
pub(super) struct KeyframeRule {
    /// The last keyframe and its camera-to-world pose when it was made.
    pub(super) reference: Option<(KeyFrameId, Pose)>,
    /// Inliers of the first tracked frame after the last keyframe (the rule's base).
    base_inliers: Option<usize>,
    /// Due keyframes put off in a row (costly frames).
    put_off: u8,
    /// The last keyframe's tracked, re-acquired and created landmarks.
    pub(super) last_counts: (usize, usize, usize),
}

impl KeyframeRule {
    pub(super) const fn new() -> Self {
        Self { reference: None, base_inliers: None, put_off: 0, last_counts: (0, 0, 0) }
    }

    /// The last keyframe, if any.
    pub(super) fn reference_keyframe(&self) -> Option<KeyFrameId> {
        self.reference.map(|(id, _)| id)
    }

    /// The decision on a frame tracked at `est` (`costly`: [`FrontendWork::is_costly`]),
    /// counting the keyframes put off in a row.
    ///
    /// [`FrontendWork::is_costly`]: super::FrontendWork::is_costly
    pub(super) fn decide(
        &mut self,
        est: &PoseEstimate,
        costly: bool,
        p: &FrontendParams,
    ) -> KeyframeDecision {
        let base = *self.base_inliers.get_or_insert(est.num_inliers);
        let due = self.is_due(&est.t_cw, est.num_inliers, base, p);
        let decision = decide_keyframe(due, costly, self.put_off, p);
        self.put_off = match decision {
            KeyframeDecision::PutOff => self.put_off.saturating_add(1),
            KeyframeDecision::None | KeyframeDecision::Make { .. } => 0,
        };
        decision
    }

    /// The rule of the module documentation: too few inliers against the base, or moved or
    /// turned too far from the last keyframe.
    fn is_due(&self, t_cw: &Pose, inliers: usize, base: usize, p: &FrontendParams) -> bool {
        // Counts are at most 512: exact in f32.
        let few = (inliers as f32) < p.keyframe_inlier_ratio * base as f32
            || inliers < p.keyframe_min_inliers;
        let moved = self.reference.is_none_or(|(_, t_wk)| {
            let t_ck = t_cw * t_wk;
            t_ck.translation.vector.norm() > p.keyframe_max_translation_m
                || t_ck.rotation.angle() > p.keyframe_max_rotation_rad
        });
        few || moved
    }

    /// Keyframe `kf` was made at `t_wc` with `counts` landmarks (tracked, re-acquired, created).
    pub(super) fn made(&mut self, kf: KeyFrameId, t_wc: Pose, counts: (usize, usize, usize)) {
        self.last_counts = counts;
        self.reference = Some((kf, t_wc));
        self.base_inliers = None;
    }
}

/// What the keyframe rule does on a tracked frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum KeyframeDecision {
    /// No keyframe is due.
    None,
    /// A keyframe is due and put off to the next tracked frame.
    PutOff,
    /// A keyframe is made, with this many pyramid octaves of feature detection.
    Make {
        /// [`HessianParams::octaves`](crate::features::HessianParams::octaves) to detect with.
        octaves: u8,
    },
}

/// The keyframe decision of a tracked frame: `due` is the keyframe rule's verdict, `costly` is
/// [`FrontendWork::is_costly`], `put_off` the keyframes put off in a row before this frame.
pub(super) fn decide_keyframe(
    due: bool,
    costly: bool,
    put_off: u8,
    params: &FrontendParams,
) -> KeyframeDecision {
    match (due, costly) {
        (false, _) => KeyframeDecision::None,
        (true, false) => KeyframeDecision::Make { octaves: params.hessian.octaves },
        (true, true) if put_off < params.keyframe_max_put_off => KeyframeDecision::PutOff,
        (true, true) => KeyframeDecision::Make { octaves: params.costly_keyframe_octaves },
    }
}
