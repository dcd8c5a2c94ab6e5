//! Map reuse: at each keyframe, landmarks of the map that the tracker no longer follows are
//! looked for again among the keyframe's features, so that coming back to a place re-observes the
//! landmarks made there instead of making new ones (the drift accumulated in between then shows
//! up as a disagreement the pose estimate and bundle adjustment can correct).
//!
//! A landmark is re-acquired by a feature when the landmark projects within
//! [`REACQUIRE_RADIUS_PX`] of it from the keyframe's pose, the feature's measured depth agrees
//! with the landmark's predicted depth (within `REACQUIRE_DEPTH_TOLERANCE`), and their
//! [`Descriptor`]s differ in at most [`MAX_DESCRIPTOR_DISTANCE`] bits, with the second-best
//! feature at least [`DESCRIPTOR_MARGIN`] bits worse (no look-alike). Landmarks are taken in arena
//! order and a feature serves one landmark only, so the outcome is a pure function of the input.
//! The landmark then gets an observation from the keyframe and a fresh template in the local map.
//!
//! # Why it is off by default ([`FrontendParams::map_reuse`](super::FrontendParams::map_reuse))
//!
//! It makes SLAM worse, on 7-Scenes and on the demo; odometry does not mind it. A re-acquired
//! landmark ties the new keyframe to old ones, so two levels of covisibility reach most of the
//! map: the local windows grow, and at the board's quota each takes longer to solve, so its result
//! lands late. The figures: docs/decisions.md, "Map reuse off by default".

use heapless::Vec;

use super::local_map::TrackedLandmark;
use super::tracker::FrameTracker;
use crate::config::capacity;
use crate::features::Descriptor;
use crate::frame::RgbdFrame;
use crate::geometry::{PinholeCamera, Pose};
use crate::map::{KeyFrameId, LandmarkId, Map, Observation};

/// How far a re-acquiring feature may be from the landmark's projection, pixels (drift since the
/// landmark was last tracked).
pub const REACQUIRE_RADIUS_PX: f32 = 10.0;
/// Largest descriptor distance of a re-acquisition, bits of 64.
pub const MAX_DESCRIPTOR_DISTANCE: u32 = 12;
/// The second-best feature must be at least this many bits further than the best.
pub const DESCRIPTOR_MARGIN: u32 = 4;
/// Landmarks one keyframe re-acquires at most.
pub const MAX_REACQUIRED: usize = 48;
/// Depth agreement of a re-acquisition: `|z_feature - z_predicted| <= a + b z`, metres.
const REACQUIRE_DEPTH_TOLERANCE: (f32, f32) = (0.05, 0.04);
/// Words of the feature bitsets.
pub(super) const FEATURE_WORDS: usize = capacity::MAX_FEATURES_PER_FRAME.div_ceil(32);

/// Features of the current keyframe already given a landmark (one bit each).
pub(super) type FeatureSet = [u32; FEATURE_WORDS];

/// Whether bit `i` of the bitset `set` (a [`FeatureSet`] or any other) is set.
pub(super) fn contains(set: &[u32], i: usize) -> bool {
    set.get(i / 32).is_some_and(|w| w & (1 << (i % 32)) != 0)
}

/// Sets bit `i` of the bitset `set` (ignored past its end).
fn insert(set: &mut [u32], i: usize) {
    if let Some(w) = set.get_mut(i / 32) {
        *w |= 1 << (i % 32);
    }
}

impl<const W: usize, const H: usize> FrameTracker<W, H> {
    /// Re-acquires map landmarks the local map does not hold among `self.detection.features` (detected in
    /// `frame`, the new keyframe `kf` at `t_cw`); marks the features used in `used`; returns how
    /// many landmarks were re-acquired.
    pub(super) fn reacquire<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &mut Map<K, L>,
        kf: KeyFrameId,
        t_cw: &Pose,
        used: &mut FeatureSet,
    ) -> usize {
        let mut tracked = [0u32; capacity::MAX_LANDMARKS.div_ceil(32)];
        for t in self.local.items() {
            insert(&mut tracked, t.id.0.index());
        }
        // A map larger than the board's (the host-scale one) has slots past the bitset: those are
        // looked up in the local map itself.
        let local = &self.local;
        let is_tracked = |id: LandmarkId| {
            let slot = id.0.index();
            match tracked.get(slot / 32) {
                Some(w) => w & (1 << (slot % 32)) != 0,
                None => local.items().iter().any(|t| t.id == id),
            }
        };
        // Each feature's depth and descriptor, computed when first needed.
        let mut cache = FeatureCache::new();
        let mut found: Vec<(LandmarkId, usize, f32), MAX_REACQUIRED> = Vec::new();
        for (id, lm) in map.landmarks() {
            if found.is_full() {
                break;
            }
            let Some(desc) = lm.descriptor.filter(|_| !is_tracked(id)) else { continue };
            let p_c = t_cw * lm.p_w;
            let z = p_c.z;
            let sensor = self.params.sensor();
            if !(z >= sensor.depth_min_m && z <= sensor.depth_max_m) {
                continue;
            }
            let Some(uv) = cam.project(&p_c).filter(|uv| cam.in_image(uv, REACQUIRE_RADIUS_PX))
            else {
                continue;
            };
            let tolerance = REACQUIRE_DEPTH_TOLERANCE.0 + REACQUIRE_DEPTH_TOLERANCE.1 * z;
            let (mut best, mut second) = ((u32::MAX, usize::MAX, 0.0f32), u32::MAX);
            for (i, f) in self.detection.features.iter().enumerate() {
                let (dx, dy) = (f.x - uv.x, f.y - uv.y);
                if dx * dx + dy * dy > REACQUIRE_RADIUS_PX * REACQUIRE_RADIUS_PX
                    || contains(used, i)
                {
                    continue;
                }
                let Some((zf, df)) = cache.get_or_compute(i, || {
                    let zf = frame.depth.depth_at(f.x, f.y, self.params.max_relative_depth_step);
                    (zf.unwrap_or(0.0), Descriptor::of(&frame.gray, f.x, f.y))
                }) else {
                    continue;
                };
                let (Some(df), true) = (df, (zf - z).abs() <= tolerance) else { continue };
                let d = df.distance(desc);
                if d < best.0 {
                    (best, second) = ((d, i, zf), best.0);
                } else if d < second {
                    second = d;
                }
            }
            let distinct = second.saturating_sub(best.0) >= DESCRIPTOR_MARGIN;
            if best.0 <= MAX_DESCRIPTOR_DISTANCE && distinct && !found.iter().any(|e| e.1 == best.1)
            {
                let _ = found.push((id, best.1, best.2));
            }
        }
        let t_wc = t_cw.inverse();
        let now = self.frame_index;
        let mut local = self.local.insertions();
        let mut n = 0;
        for &(id, i, zf) in &found {
            let Some(&f) = self.detection.features.get(i) else { continue };
            let Some(obs) = Observation::new(id, (f.x, f.y), Some(zf)) else { continue };
            if !local.make_room(now) || map.add_observation(kf, obs).is_err() {
                break;
            }
            insert(used, i);
            let Some(t) = TrackedLandmark::new(id, &frame.gray, (f.x, f.y), zf, &t_wc, now) else {
                continue;
            };
            if !local.push(t) {
                break;
            }
            n += 1;
        }
        n
    }
}

/// Each detected feature's depth (0 without one) and descriptor, computed the first time a
/// landmark asks for it, stored as arrays (6.2 KB on the stack where a vector of
/// `Option<(f32, Option<Descriptor>)>` took 12.3 KB).
struct FeatureCache {
    depth: [f32; capacity::MAX_FEATURES_PER_FRAME],
    descriptor: [u64; capacity::MAX_FEATURES_PER_FRAME],
    /// Computed entries, one bit each.
    computed: FeatureSet,
    /// Entries whose descriptor exists, one bit each.
    described: FeatureSet,
}

impl FeatureCache {
    fn new() -> Self {
        Self {
            depth: [0.0; capacity::MAX_FEATURES_PER_FRAME],
            descriptor: [0; capacity::MAX_FEATURES_PER_FRAME],
            computed: [0; FEATURE_WORDS],
            described: [0; FEATURE_WORDS],
        }
    }

    /// Entry `i`, from `compute` the first time; `None` past the capacity.
    fn get_or_compute(
        &mut self,
        i: usize,
        compute: impl FnOnce() -> (f32, Option<Descriptor>),
    ) -> Option<(f32, Option<Descriptor>)> {
        if i >= capacity::MAX_FEATURES_PER_FRAME {
            return None;
        }
        if !contains(&self.computed, i) {
            let (z, d) = compute();
            insert(&mut self.computed, i);
            if let (Some(d), Some(slot)) = (d, self.descriptor.get_mut(i)) {
                *slot = d.0;
                insert(&mut self.described, i);
            }
            if let Some(slot) = self.depth.get_mut(i) {
                *slot = z;
            }
        }
        let z = self.depth.get(i).copied()?;
        let d =
            contains(&self.described, i).then(|| self.descriptor.get(i).copied().map(Descriptor));
        Some((z, d.flatten()))
    }
}
