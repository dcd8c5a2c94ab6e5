//! Local BA: the window around a new keyframe, the problem built from the map, and its result
//! written back.
//!
//! # The window
//!
//! Starting from the new keyframe, each level adds the keyframes sharing at least
//! `min_shared_landmarks` landmarks with the window so far, most shared first (newer first on
//! ties), until `window_max` keyframes. Two levels reach the keyframes that see the new
//! keyframe's surroundings from further away, which is what lets the window grow towards the
//! paper's 50-65 keyframes in a large map while staying local in a small one.
//!
//! # The problem
//!
//! Points: the landmarks the window observes (reference landmarks fixed), kept when the window
//! and its fixed neighbours observe them at least twice. Fixed poses: the other keyframes that
//! observe those points, most observations first, up to the adjuster's rig capacity. When there
//! is none (a young map), the window's oldest keyframe is fixed instead: something must hold the
//! gauge. Observations: every observation of a point by a window or fixed keyframe, within the
//! adjuster's capacity.

use heapless::Vec;

use super::Backend;
use crate::config::capacity;
use crate::map::{KeyFrameId, Map};
use crate::optim::{BaError, VariableKind};

/// A window keyframe is free only with at least this many observations of the problem's points.
const MIN_FREE_KEYFRAME_OBSERVATIONS: usize = 20;

/// Marks a keyframe in the window (before cameras are numbered).
const IN_WINDOW: u16 = u16::MAX;
/// Marks a fixed neighbour (before cameras are numbered).
const FIXED: u16 = u16::MAX - 1;

/// The back end's fixed scratch, indexed by arena slot of a map of `K` keyframes and `L`
/// landmarks (`LW` words of bits cover the `L` slots), for an adjuster of `P` points.
#[derive(Debug)]
pub(super) struct Scratch<const K: usize, const L: usize, const LW: usize, const P: usize> {
    /// Landmark slot: problem point index + 1 (0: not in the problem).
    pub(super) point_of: [u16; L],
    /// Per point: observations counted, then the next slot to fill.
    pub(super) count: [u16; P],
    /// Landmark slots seen by the window so far (one bit each).
    pub(super) marked: [u32; LW],
    /// Keyframe slot: camera index + 1, or [`IN_WINDOW`] / [`FIXED`] while choosing, 0: none.
    pub(super) role: [u16; K],
    /// Global BA: landmark slot's first segment + 1 (0: none yet).
    pub(super) first_segment: [u16; L],
}

impl<const K: usize, const L: usize, const LW: usize, const P: usize> Scratch<K, L, LW, P> {
    pub(super) const fn new() -> Self {
        Self {
            point_of: [0; L],
            count: [0; P],
            marked: [0; LW],
            role: [0; K],
            first_segment: [0; L],
        }
    }

    /// Clears everything (bounded: fixed-size arrays).
    pub(super) fn reset(&mut self) {
        self.point_of.iter_mut().for_each(|v| *v = 0);
        self.count.iter_mut().for_each(|v| *v = 0);
        self.marked.iter_mut().for_each(|v| *v = 0);
        self.role.iter_mut().for_each(|v| *v = 0);
        self.first_segment.iter_mut().for_each(|v| *v = 0);
    }

    fn mark(&mut self, slot: usize) {
        if let Some(w) = self.marked.get_mut(slot / 32) {
            *w |= 1 << (slot % 32);
        }
    }

    fn is_marked(&self, slot: usize) -> bool {
        self.marked.get(slot / 32).is_some_and(|w| w & (1 << (slot % 32)) != 0)
    }

    fn role(&self, kf: KeyFrameId) -> u16 {
        self.role.get(kf.0.index()).copied().unwrap_or(0)
    }

    fn set_role(&mut self, kf: KeyFrameId, r: u16) {
        if let Some(slot) = self.role.get_mut(kf.0.index()) {
            *slot = r;
        }
    }

    /// The point index of a landmark slot, if it is in the problem.
    pub(super) fn point(&self, slot: usize) -> Option<usize> {
        self.point_of.get(slot).and_then(|&p| p.checked_sub(1)).map(usize::from)
    }
}

/// A keyframe considered for the window or as a fixed neighbour: `(shared, seq, id)`.
type Ranked = (u16, u32, KeyFrameId);

impl<
    const K: usize,
    const L: usize,
    const LW: usize,
    const R: usize,
    const P: usize,
    const O: usize,
> Backend<K, L, LW, R, P, O>
{
    /// Builds the local BA problem around `kf` (see the module documentation); returns the work
    /// units charged (observations scanned, four to a unit).
    pub(super) fn build_local(&mut self, map: &Map<K, L>, kf: KeyFrameId) -> Result<u64, BaError> {
        self.ba.clear();
        self.cameras.clear();
        self.points.clear();
        self.scratch.reset();
        let mut scanned = 0u64;
        let mut window: Vec<KeyFrameId, { capacity::LOCAL_WINDOW_MAX }> = Vec::new();
        if map.keyframe(kf).is_none() || window.push(kf).is_err() {
            return Ok(0);
        }
        self.scratch.set_role(kf, IN_WINDOW);
        scanned += self.mark_landmarks(map, kf);
        for _ in 0..self.params.window_levels {
            let before = window.len();
            let mut ranked: Vec<Ranked, K> = Vec::new();
            for (id, k) in map.keyframes() {
                if self.scratch.role(id) != 0 {
                    continue;
                }
                let shared = k
                    .observations
                    .iter()
                    .filter(|o| {
                        map.landmark(o.landmark).is_some()
                            && self.scratch.is_marked(o.landmark.0.index())
                    })
                    .count();
                scanned += k.observations.len() as u64;
                let shared = u16::try_from(shared).unwrap_or(u16::MAX);
                if shared >= self.params.min_shared_landmarks
                    && ranked.push((shared, k.seq, id)).is_err()
                {
                    break;
                }
            }
            ranked.sort_unstable_by_key(|r| core::cmp::Reverse((r.0, r.1)));
            for &(_, _, id) in &ranked {
                if window.len() >= self.params.window_max || window.push(id).is_err() {
                    break;
                }
                self.scratch.set_role(id, IN_WINDOW);
            }
            for &id in window.iter().skip(before) {
                scanned += self.mark_landmarks(map, id);
            }
            if window.len() == before {
                break;
            }
        }
        if let Some(n) = self.stats.window_sizes.get_mut(window.len()) {
            *n = n.saturating_add(1);
        }
        scanned += self.choose_points(map, &window);
        let fixed = self.choose_fixed(map, &window, &mut scanned);
        let mut both: Vec<KeyFrameId, R> = Vec::new();
        for &id in window.iter().chain(&fixed) {
            let _ = both.push(id);
        }
        scanned += self.count_observations_of(map, &both);
        self.add_cameras(map, &window, &fixed)?;
        self.add_points(map)?;
        scanned += self.fill_observations(map)?;
        Ok(scanned / 4)
    }

    /// Marks the landmarks keyframe `id` observes; returns the observations scanned.
    fn mark_landmarks(&mut self, map: &Map<K, L>, id: KeyFrameId) -> u64 {
        let Some(k) = map.keyframe(id) else { return 0 };
        for o in &k.observations {
            if map.landmark(o.landmark).is_some() {
                self.scratch.mark(o.landmark.0.index());
            }
        }
        k.observations.len() as u64
    }

    /// Makes every live landmark the window observes a provisional point (up to capacity).
    fn choose_points(&mut self, map: &Map<K, L>, window: &[KeyFrameId]) -> u64 {
        let mut scanned = 0u64;
        for &id in window {
            let Some(k) = map.keyframe(id) else { continue };
            scanned += k.observations.len() as u64;
            for o in &k.observations {
                let slot = o.landmark.0.index();
                let Some(lm) = map.landmark(o.landmark) else { continue };
                if self.scratch.point(slot).is_some() {
                    continue;
                }
                let Ok(()) = self.points.push((o.landmark, None, !lm.reference)) else {
                    return scanned;
                };
                if let Some(p) = self.scratch.point_of.get_mut(slot) {
                    // At most P (< 65,535) points.
                    *p = self.points.len() as u16;
                }
            }
        }
        scanned
    }

    /// The keyframes outside the window that observe the points, most observations first, up to
    /// the rig capacity left; marked [`FIXED`].
    fn choose_fixed(
        &mut self,
        map: &Map<K, L>,
        window: &[KeyFrameId],
        scanned: &mut u64,
    ) -> Vec<KeyFrameId, R> {
        let mut ranked: Vec<Ranked, K> = Vec::new();
        for (id, k) in map.keyframes() {
            if self.scratch.role(id) != 0 {
                continue;
            }
            *scanned += k.observations.len() as u64;
            let seen = k.observations.iter().filter(|o| {
                map.landmark(o.landmark).is_some()
                    && self.scratch.point(o.landmark.0.index()).is_some()
            });
            let n = u16::try_from(seen.count()).unwrap_or(u16::MAX);
            if n > 0 && ranked.push((n, k.seq, id)).is_err() {
                break;
            }
        }
        ranked.sort_unstable_by_key(|r| core::cmp::Reverse((r.0, r.1)));
        let mut fixed = Vec::new();
        for &(_, _, id) in &ranked {
            if window.len() + fixed.len() >= R || fixed.push(id).is_err() {
                break;
            }
            self.scratch.set_role(id, FIXED);
        }
        fixed
    }

    /// Counts the observations of each provisional point by `keyframes`, then drops the points
    /// seen fewer than twice and those past the observation capacity.
    pub(super) fn count_observations_of(
        &mut self,
        map: &Map<K, L>,
        keyframes: &[KeyFrameId],
    ) -> u64 {
        let mut scanned = 0u64;
        for &id in keyframes {
            let Some(k) = map.keyframe(id) else { continue };
            scanned += k.observations.len() as u64;
            for o in &k.observations {
                if map.landmark(o.landmark).is_none() {
                    continue;
                }
                let p = self.scratch.point(o.landmark.0.index());
                if let Some(c) = p.and_then(|p| self.scratch.count.get_mut(p)) {
                    *c = c.saturating_add(1);
                }
            }
        }
        // Renumber the points kept, in order, within the observation capacity.
        let mut kept = 0usize;
        let mut total = 0usize;
        for i in 0..self.points.len() {
            let (Some(&(id, _, free)), Some(&n)) = (self.points.get(i), self.scratch.count.get(i))
            else {
                break;
            };
            let slot = id.0.index();
            let keep = n >= 2 && total + usize::from(n) <= O;
            if let Some(p) = self.scratch.point_of.get_mut(slot) {
                // At most P points.
                *p = if keep { kept as u16 + 1 } else { 0 };
            }
            if keep {
                total += usize::from(n);
                if let (Some(dst), Some(c)) =
                    (self.points.get_mut(kept), self.scratch.count.get_mut(kept))
                {
                    *dst = (id, None, free);
                    *c = n;
                }
                kept += 1;
            }
        }
        self.points.truncate(kept);
        scanned
    }

    /// Adds the window's keyframes (free, but the oldest when there is no fixed neighbour) and
    /// the fixed neighbours as cameras.
    fn add_cameras(
        &mut self,
        map: &Map<K, L>,
        window: &[KeyFrameId],
        fixed: &[KeyFrameId],
    ) -> Result<(), BaError> {
        let gauge = if fixed.is_empty() {
            window
                .iter()
                .filter_map(|&id| map.keyframe(id).map(|k| (k.seq, id)))
                .min()
                .map(|(_, id)| id)
        } else {
            None
        };
        // A keyframe seeing few of the points is too weakly held to move: BA would be free to
        // swing it, so it stays fixed.
        let mut all: Vec<(KeyFrameId, bool), R> = Vec::new();
        for &id in window {
            let held = self.observations_of_points(map, id) >= MIN_FREE_KEYFRAME_OBSERVATIONS;
            let _ = all.push((id, Some(id) != gauge && held));
        }
        for &id in fixed {
            let _ = all.push((id, false));
        }
        for (id, free) in all {
            let Some(k) = map.keyframe(id) else { continue };
            let cam = self.ba.add_keyframe(&k.t_wc.inverse(), !free)?;
            if self.cameras.push((id, cam, free)).is_err() {
                return Err(BaError::Full { kind: VariableKind::Camera, capacity: K });
            }
            // At most K (< 65,535) cameras.
            self.scratch.set_role(id, self.cameras.len() as u16);
        }
        Ok(())
    }

    /// Observations keyframe `id` makes of the problem's points.
    fn observations_of_points(&self, map: &Map<K, L>, id: KeyFrameId) -> usize {
        map.keyframe(id).map_or(0, |k| {
            let in_problem = |o: &&crate::map::Observation| {
                map.landmark(o.landmark).is_some()
                    && self.scratch.point(o.landmark.0.index()).is_some()
            };
            k.observations.iter().filter(in_problem).count()
        })
    }

    /// Adds the points with their counted observation slots (fill cursors reset to 0).
    pub(super) fn add_points(&mut self, map: &Map<K, L>) -> Result<(), BaError> {
        for i in 0..self.points.len() {
            let (Some(entry), Some(n)) = (self.points.get_mut(i), self.scratch.count.get_mut(i))
            else {
                break;
            };
            let p_w = map.landmark(entry.0).map_or(nalgebra::Point3::origin(), |l| l.p_w);
            entry.1 = Some(self.ba.add_point_with_slots(&p_w, !entry.2, usize::from(*n))?);
            *n = 0;
        }
        Ok(())
    }

    /// Sets every observation slot from the cameras' keyframes; returns observations scanned.
    pub(super) fn fill_observations(&mut self, map: &Map<K, L>) -> Result<u64, BaError> {
        let mut scanned = 0u64;
        for c in 0..self.cameras.len() {
            let Some(&(kf, cam, _)) = self.cameras.get(c) else { break };
            let Some(k) = map.keyframe(kf) else { continue };
            scanned += k.observations.len() as u64;
            for o in &k.observations {
                if map.landmark(o.landmark).is_none() {
                    continue;
                }
                let Some(p) = self.scratch.point(o.landmark.0.index()) else { continue };
                let (Some(&(_, Some(pid), _)), Some(cursor)) =
                    (self.points.get(p), self.scratch.count.get_mut(p))
                else {
                    continue;
                };
                let (u, v) = o.uv();
                self.ba.set_observation(
                    pid,
                    usize::from(*cursor),
                    cam,
                    nalgebra::Point2::new(u, v),
                    o.depth_m(),
                )?;
                *cursor += 1;
            }
        }
        Ok(scanned)
    }

    /// Writes a finished local BA's free poses and points back to the map.
    pub(super) fn write_back_local(&mut self, map: &mut Map<K, L>) {
        for &(kf, cam, free) in &self.cameras {
            let (true, Some(t_cw)) = (free, self.ba.camera_pose(cam)) else { continue };
            if let Some(k) = map.keyframe_mut(kf) {
                k.t_wc = t_cw.inverse();
            }
        }
        let (mut free_n, mut fixed_n) = (0u64, 0u64);
        for i in 0..self.points.len() {
            let Some(&(lm, pid, free)) = self.points.get(i) else { break };
            let Some(pid) = pid else { continue };
            if !free {
                fixed_n += 1;
                continue;
            }
            free_n += 1;
            let Some(p_w) = self.ba.point(pid) else { continue };
            if let Some(l) = map.landmark_mut(lm) {
                l.p_w = p_w;
            }
            self.count_optimization(map, lm);
        }
        self.stats.free_points += free_n;
        self.stats.fixed_points += fixed_n;
        self.stats.local_runs = self.stats.local_runs.saturating_add(1);
    }
}
