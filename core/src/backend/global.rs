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

use super::Backend;
use crate::geometry::Pose;
use crate::map::{KeyFrameId, Map};
use crate::optim::{BaError, RigId, VariableKind};

/// A segment present in the map: `(segment number, oldest keyframe's seq, that keyframe)`.
type Segment = (u32, u32, KeyFrameId);

impl<
    const K: usize,
    const L: usize,
    const LW: usize,
    const R: usize,
    const P: usize,
    const O: usize,
> Backend<K, L, LW, R, P, O>
{
    /// Builds the segmented global BA problem; returns the work units charged (observations
    /// scanned, four to a unit).
    pub(super) fn build_global(&mut self, map: &Map<K, L>) -> Result<u64, BaError> {
        self.ba.clear();
        self.cameras.clear();
        self.points.clear();
        self.rig_before.clear();
        self.scratch.reset();
        self.built_seq = self.newest_seq;
        let len = self.params.segment_keyframes.max(1);
        let mut segments: Vec<Segment, K> = Vec::new();
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
        let mut rigs: Vec<RigId, K> = Vec::new();
        for (i, &(s, _, oldest)) in segments.iter().enumerate() {
            let Some(k) = map.keyframe(oldest) else { continue };
            let t_sw = k.t_wc.inverse();
            let rig = self.ba.add_rig(&t_sw, i == 0)?;
            if rigs.push(rig).is_err() || self.rig_before.push((s, t_sw)).is_err() {
                return Err(BaError::Full { kind: VariableKind::Rig, capacity: K });
            }
        }
        let mut scanned = 0u64;
        let mut all: Vec<KeyFrameId, K> = Vec::new();
        for (id, k) in map.keyframes() {
            let Some(r) = segments.iter().position(|e| e.0 == k.seq / len) else { continue };
            let (Some(&rig), Some(&(_, t_sw))) = (rigs.get(r), self.rig_before.get(r)) else {
                continue;
            };
            let t_cs = k.t_wc.inverse() * t_sw.inverse();
            let cam = self.ba.add_camera(rig, &t_cs)?;
            if self.cameras.push((id, cam, r > 0)).is_err() || all.push(id).is_err() {
                return Err(BaError::Full { kind: VariableKind::Camera, capacity: K });
            }
            // Segment index + 1 per landmark slot; a second segment marks the landmark joint.
            scanned += k.observations.len() as u64;
            for o in &k.observations {
                let slot = o.landmark.0.index();
                let Some(first) = self.scratch.first_segment.get_mut(slot) else { continue };
                if *first == 0 {
                    // At most K (< 65,535) segments.
                    *first = r as u16 + 1;
                } else if usize::from(*first) != r + 1 {
                    self.mark_joint(slot);
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
    fn choose_joint_points(&mut self, map: &Map<K, L>, all: &[KeyFrameId]) -> u64 {
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
                    // At most P (< 65,535) points.
                    *p = self.points.len() as u16;
                }
            }
        }
        scanned
    }

    /// Writes a finished global BA back: keyframe poses, joint landmarks, and every other
    /// landmark moved with its segment. Keyframes and landmarks made while the solve ran (after
    /// `built_seq`) were not in the problem: they move with their keyframe's segment
    /// (a landmark with its host's), or with the newest segment of the problem when theirs was
    /// not in it, so that the map the front end tracks stays one rigid piece with the segment
    /// it grew from.
    pub(super) fn write_back_global(&mut self, map: &mut Map<K, L>) {
        for &(kf, cam, free) in &self.cameras {
            let (true, Some(t_cw)) = (free, self.ba.camera_pose(cam)) else { continue };
            if let Some(k) = map.keyframe_mut(kf) {
                k.t_wc = t_cw.inverse();
            }
        }
        // Each segment's correction, old world to new world: `T_s'^-1 T_s`.
        let mut delta: Vec<Pose, K> = Vec::new();
        for (r, &(_, t_sw)) in self.rig_before.iter().enumerate() {
            let rig = self
                .cameras
                .iter()
                .find_map(|&(_, cam, _)| self.ba.camera_rig(cam).filter(|rig| rig.index() == r));
            let moved = rig.and_then(|rig| self.ba.rig_pose(rig)).unwrap_or(t_sw);
            let _ = delta.push(moved.inverse() * t_sw);
        }
        let len = self.params.segment_keyframes.max(1);
        let built = self.built_seq;
        // The rig index + 1 a keyframe made after the build moves with (0: none).
        let rig_of_new = |seq: u32| -> u16 {
            let s = seq / len;
            let r = self.rig_before.iter().position(|e| e.0 == s);
            // At most K (< 65,535) rigs.
            r.map_or(self.rig_before.len(), |r| r + 1) as u16
        };
        // New keyframes (not cameras of the problem).
        let mut new_keyframes: Vec<(KeyFrameId, u16), K> = Vec::new();
        for (id, k) in map.keyframes() {
            if k.seq > built && !self.cameras.iter().any(|c| c.0 == id) {
                let _ = new_keyframes.push((id, rig_of_new(k.seq)));
            }
        }
        for &(id, r) in &new_keyframes {
            let Some(d) = r.checked_sub(1).and_then(|r| delta.get(usize::from(r))) else {
                continue;
            };
            if let Some(k) = map.keyframe_mut(id) {
                k.t_wc = d * k.t_wc;
            }
        }
        // Which rig each landmark slot moves with (rig index + 1; 0: not moved), decided before
        // any pose changes: problem points are written below, landmarks hosted by a new keyframe
        // move with it, the others with the segment that observed them at the build.
        for (id, lm) in map.landmarks() {
            let slot = id.0.index();
            let in_problem = self
                .scratch
                .point(slot)
                .and_then(|p| self.points.get(p))
                .is_some_and(|e| e.0 == id);
            let host_seq = map.keyframe(lm.host).map(|k| k.seq);
            let rig = match host_seq {
                _ if in_problem => 0,
                Some(seq) if seq > built => rig_of_new(seq),
                _ => self.scratch.first_segment.get(slot).copied().unwrap_or(0),
            };
            if let Some(f) = self.scratch.first_segment.get_mut(slot) {
                *f = rig;
            }
        }
        for i in 0..L {
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
