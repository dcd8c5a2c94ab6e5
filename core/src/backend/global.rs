//! Segmented global BA: one pose per segment of consecutive keyframes, the joint landmarks, and
//! the write-back that moves every other landmark with its segment.
//!
//! Keyframe `k` belongs to segment `seq(k) / segment_keyframes`. Each segment present in the map
//! is a rig whose pose is its oldest keyframe's `t_cw`; every keyframe hangs from its segment's
//! rig by the offset it has now, so relative poses inside a segment stay fixed. The oldest
//! segment is fixed (the gauge). Points: the landmarks observed from two or more segments (the
//! joints between them); reference landmarks among them are fixed. A landmark seen from one
//! segment only is not in the problem: when the solve moves its segment by `delta`, the landmark
//! moves by the same `delta`, so it stays where that segment's keyframes see it.

use heapless::Vec;

use super::{BA_CAMERAS, Backend};
use crate::config::capacity;
use crate::geometry::Pose;
use crate::map::{KeyFrameId, Map};
use crate::optim::{BaError, RigId, VariableKind};

/// A segment present in the map: `(segment number, oldest keyframe's seq, that keyframe)`.
type Segment = (u32, u32, KeyFrameId);

impl Backend {
    /// Builds the segmented global BA problem; returns the work units charged (observations
    /// scanned, four to a unit).
    pub(super) fn build_global<const K: usize, const L: usize>(
        &mut self,
        map: &Map<K, L>,
    ) -> Result<u64, BaError> {
        self.ba.clear();
        self.cameras.clear();
        self.points.clear();
        self.rig_before.clear();
        self.scratch.reset();
        let len = self.params.segment_keyframes.max(1);
        let mut segments: Vec<Segment, BA_CAMERAS> = Vec::new();
        for (id, k) in map.keyframes() {
            let s = k.seq / len;
            match segments.iter_mut().find(|e| e.0 == s) {
                Some(e) if k.seq < e.1 => (e.1, e.2) = (k.seq, id),
                Some(_) => {}
                None => {
                    if segments.push((s, k.seq, id)).is_err() {
                        break;
                    }
                }
            }
        }
        segments.sort_unstable_by_key(|e| e.0);
        let mut rigs: Vec<RigId, BA_CAMERAS> = Vec::new();
        for (i, &(_, _, oldest)) in segments.iter().enumerate() {
            let Some(k) = map.keyframe(oldest) else { continue };
            let t_sw = k.t_wc.inverse();
            let rig = self.ba.add_rig(&t_sw, i == 0)?;
            if rigs.push(rig).is_err() || self.rig_before.push(t_sw).is_err() {
                return Err(BaError::Full { kind: VariableKind::Rig, capacity: BA_CAMERAS });
            }
        }
        let mut scanned = 0u64;
        let mut all: Vec<KeyFrameId, { capacity::MAX_KEYFRAMES }> = Vec::new();
        for (id, k) in map.keyframes() {
            let Some(r) = segments.iter().position(|e| e.0 == k.seq / len) else { continue };
            let (Some(&rig), Some(t_sw)) = (rigs.get(r), self.rig_before.get(r)) else { continue };
            let t_cs = k.t_wc.inverse() * t_sw.inverse();
            let cam = self.ba.add_camera(rig, &t_cs)?;
            if self.cameras.push((id, cam, r > 0)).is_err() || all.push(id).is_err() {
                return Err(BaError::Full { kind: VariableKind::Camera, capacity: BA_CAMERAS });
            }
            // Segment index + 1 per landmark slot; a second segment marks the landmark joint.
            scanned += k.observations.len() as u64;
            for o in &k.observations {
                let slot = o.landmark.0.index();
                match self.scratch.first_segment.get(slot).copied() {
                    // At most BA_CAMERAS (< 65,535) segments.
                    Some(0) => {
                        self.scratch.first_segment[slot & (capacity::MAX_LANDMARKS - 1)] =
                            r as u16 + 1
                    }
                    Some(first) if usize::from(first) != r + 1 => self.mark_joint(slot),
                    _ => {}
                }
            }
        }
        scanned += self.choose_joint_points(map, &all);
        scanned += self.count_observations_of(map, &all);
        self.add_points(map)?;
        scanned += self.fill_observations(map)?;
        Ok(scanned / 4)
    }

    /// Makes every live joint landmark a provisional point (up to capacity); returns the
    /// observations scanned.
    fn choose_joint_points<const K: usize, const L: usize>(
        &mut self,
        map: &Map<K, L>,
        all: &[KeyFrameId],
    ) -> u64 {
        let mut scanned = 0u64;
        for &id in all {
            let Some(k) = map.keyframe(id) else { continue };
            scanned += k.observations.len() as u64;
            for o in &k.observations {
                let slot = o.landmark.0.index();
                let Some(lm) = map.landmark(o.landmark) else { continue };
                if !self.is_joint(slot) || self.scratch.point(slot).is_some() {
                    continue;
                }
                if self.points.push((o.landmark, None, !lm.reference)).is_err() {
                    return scanned;
                }
                if let Some(p) = self.scratch.point_of.get_mut(slot) {
                    // At most BA_POINTS (< 65,535) points.
                    *p = self.points.len() as u16;
                }
            }
        }
        scanned
    }

    /// Writes a finished global BA back: keyframe poses, joint landmarks, and every other
    /// landmark moved with its segment.
    pub(super) fn write_back_global<const K: usize, const L: usize>(
        &mut self,
        map: &mut Map<K, L>,
    ) {
        for &(kf, cam, free) in &self.cameras {
            let (true, Some(t_cw)) = (free, self.ba.camera_pose(cam)) else { continue };
            if let Some(k) = map.keyframe_mut(kf) {
                k.t_wc = t_cw.inverse();
            }
        }
        // Each segment's correction, old world to new world: `T_s'^-1 T_s`.
        let mut delta: Vec<Pose, BA_CAMERAS> = Vec::new();
        for (r, t_sw) in self.rig_before.iter().enumerate() {
            let rig = self
                .cameras
                .iter()
                .find_map(|&(_, cam, _)| self.ba.camera_rig(cam).filter(|rig| rig.index() == r));
            let moved = rig.and_then(|rig| self.ba.rig_pose(rig)).unwrap_or(*t_sw);
            let _ = delta.push(moved.inverse() * t_sw);
        }
        for i in 0..L.min(capacity::MAX_LANDMARKS) {
            if self.scratch.point(i).is_some() {
                continue;
            }
            let seg = self.scratch.first_segment.get(i).copied().unwrap_or(0);
            let Some(d) = seg.checked_sub(1).and_then(|r| delta.get(usize::from(r))) else {
                continue;
            };
            if let Some(lm) = map.landmark_at_mut(i) {
                lm.p_w = d * lm.p_w;
            }
        }
        for i in 0..self.points.len() {
            let Some(&(lm, Some(pid), true)) = self.points.get(i) else { continue };
            let Some(p_w) = self.ba.point(pid) else { continue };
            if let Some(l) = map.landmark_mut(lm) {
                l.p_w = p_w;
            }
            self.count_optimization(map, lm);
        }
        self.stats.global_runs = self.stats.global_runs.saturating_add(1);
    }

    fn mark_joint(&mut self, slot: usize) {
        if let Some(w) = self.scratch.marked.get_mut(slot / 32) {
            *w |= 1 << (slot % 32);
        }
    }

    fn is_joint(&self, slot: usize) -> bool {
        self.scratch.marked.get(slot / 32).is_some_and(|w| w & (1 << (slot % 32)) != 0)
    }
}
