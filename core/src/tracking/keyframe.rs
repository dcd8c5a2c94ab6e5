//! Keyframe creation for the front end: observations of the tracked inliers, re-anchoring of
//! warped templates, and new landmarks from the Hessian features with valid depth.

use heapless::Vec;
use nalgebra::Point2;

use super::local_map::{PATCH_SIDE, TrackedLandmark};
use super::map_reuse::{FEATURE_WORDS, FeatureSet, contains};
use super::places::{LoopClosure, PlaceQuery, Places, QueryPoint};
use super::tracker::FrameTracker;
use crate::config::capacity;
use crate::features::{Descriptor, Feature, HessianParams};
use crate::frame::RgbdFrame;
use crate::geometry::{PinholeCamera, Pose};
use crate::map::{
    KeyFrameId, LandmarkId, MAX_OBSERVATIONS_PER_KEYFRAME, Map, MapError, Observation, PlaceKey,
};
use crate::pose::InlierMask;
use crate::pose::small_image_rotation::{SMALL_H, SMALL_W};

/// Distance of the neighbours checked for depth discontinuities around a new landmark, pixels.
const DISCONTINUITY_RADIUS_PX: usize = 2;

/// Observations of a keyframe kept for the landmarks it creates (the rest go to its inliers).
const NEW_LANDMARK_RESERVE: usize = MAX_OBSERVATIONS_PER_KEYFRAME / 2;

/// Features of a lost frame offered to relocalization at most (a stack buffer of 28 bytes each).
const QUERY_POINTS: usize = capacity::MAX_TRACKED_LANDMARKS;

/// Features closer than this to the border make no landmark: the template must fit.
const BORDER_PX: f32 = (PATCH_SIDE / 2) as f32 + 0.5;

impl<const W: usize, const H: usize> FrameTracker<W, H> {
    /// Makes a keyframe of `frame` at `t_cw`: the inliers of the last pose (`inliers` over the
    /// current correspondences; `None` when starting tracking) become its observations, templates
    /// warped beyond `reanchor_max_warp` are re-taken from it, and features with valid depth that
    /// are not near an inlier become new landmarks. Features are detected over `octaves`
    /// pyramid octaves (the parameters' own, or fewer on a costly frame).
    ///
    /// Returns the keyframe's id, or `None` when the map cannot take a keyframe, or when starting
    /// tracking and fewer than `min_keyframe_landmarks` landmarks result (the keyframe and its new
    /// landmarks are then removed again).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn make_keyframe<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &mut Map<K, L>,
        places: &mut impl Places,
        t_cw: &Pose,
        inliers: Option<&InlierMask>,
        octaves: u8,
    ) -> Option<KeyFrameId> {
        let t_wc = t_cw.inverse();
        if map.keyframes_full() {
            let local = &self.local;
            retire_oldest(map, places, |id| local.contains(id));
        }
        let kf = map.add_keyframe(t_wc, frame.timestamp_s).ok()?;
        if let Some(k) = map.keyframe_mut(kf) {
            k.place_key = self.place_key();
        }
        let tracked = inliers.map_or(0, |m| self.record_inliers(frame, cam, map, kf, t_cw, m));
        let mut used: FeatureSet = [0; FEATURE_WORDS];
        self.work.detected = true;
        let hessian = HessianParams { octaves, ..self.params.hessian };
        let detected = self.detection.detect(frame, &hessian);
        let reacquired = if detected && inliers.is_some() && self.params.map_reuse {
            self.reacquire(frame, cam, map, kf, t_cw, &mut used)
        } else {
            0
        };
        let created = if detected {
            self.add_new_landmarks(frame, cam, (map, places), (kf, &t_wc), inliers, &used)
        } else {
            0
        };
        if inliers.is_none() && created < self.params.min_keyframe_landmarks {
            self.local.clear();
            let _ = map.remove_keyframe(kf);
            map.remove_orphans(|_| false);
            return None;
        }
        self.keyframing.made(kf, t_wc, (tracked, reacquired, created));
        self.stats.keyframes = self.stats.keyframes.saturating_add(1);
        self.loop_pending = (inliers.is_some() && places.relocalizes()).then_some(kf);
        Some(kf)
    }

    /// The place key of the frame being processed (from its small image; zeros when it has none).
    fn place_key(&self) -> PlaceKey {
        self.recent
            .small_current
            .fine()
            .map_or_else(PlaceKey::default, |px| PlaceKey::of(px, SMALL_W, SMALL_H))
    }

    /// Asks the place memory (and through it the active `map`) where this frame is, after
    /// tracking failed: detects features, offers those with valid depth as query points (at most
    /// [`QUERY_POINTS`], with descriptors) and returns the verified `t_cw`, if any. Its caller
    /// skips it when the place memory does not relocalize ([`Places::relocalizes`]).
    #[inline(never)]
    pub(super) fn query_places<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &Map<K, L>,
        places: &mut impl Places,
    ) -> Option<Pose> {
        self.work.detected = true;
        if !self.detection.detect(frame, &self.params.hessian) {
            return None;
        }
        // Filled in place: a returned vector was copied, 8 KiB more stack.
        let mut points: Vec<QueryPoint, QUERY_POINTS> = Vec::new();
        self.query_points(frame, cam, &mut points);
        let query = PlaceQuery { key: self.place_key(), points: &points, size: frame.gray.size() };
        places.relocalize(&query, map).map(|t_wc| t_wc.inverse())
    }

    /// Asks the place memory whether keyframe `kf` of `map` closes a loop, its observed
    /// landmarks with a descriptor (in its camera) as the query; when it does, moves the map
    /// tracked since the last re-initialization (the keyframes from `track_start` on, the
    /// landmarks they host) and this tracker's state by the correction, and returns the loop
    /// (the frame's pose is the caller's to move). While localizing in a loaded map, the
    /// landmarks matched to the map's points move halfway to them ([`Places::map_points`]). The
    /// caller runs it on a cheap frame after the keyframe's (the keyframe's own frame is the
    /// costliest kind); `size` is the tracking level's. Cost: one pass over the keyframe's
    /// observations, then the place memory's query.
    #[inline(never)]
    pub(super) fn close_loop<const K: usize, const L: usize>(
        &mut self,
        map: &mut Map<K, L>,
        places: &mut impl Places,
        kf: KeyFrameId,
        size: (usize, usize),
    ) -> Option<LoopClosure> {
        let k = map.keyframe(kf)?;
        let t_cw = k.t_wc.inverse();
        let mut points: Vec<QueryPoint, MAX_OBSERVATIONS_PER_KEYFRAME> = Vec::new();
        // The landmark of each query point.
        let mut ids: Vec<LandmarkId, MAX_OBSERVATIONS_PER_KEYFRAME> = Vec::new();
        for obs in &k.observations {
            let Some(lm) = map.landmark(obs.landmark) else { continue };
            let Some(descriptor) = lm.descriptor else { continue };
            let _ = points.push(QueryPoint { uv: obs.uv(), p_c: t_cw * lm.p_w, descriptor });
            let _ = ids.push(obs.landmark);
        }
        let query = PlaceQuery { key: k.place_key, points: &points, size };
        let closure = places.close_loop(&query, map, kf, self.track_start);
        if let Some(closure) = &closure {
            let c = closure.correction;
            map.move_world_from(self.track_start, &c);
            for t in self.local.items_mut() {
                t.move_world(&c);
            }
            if let Some((_, t_wk)) = &mut self.keyframing.reference {
                *t_wk = c * *t_wk;
            }
            self.recent.motion.move_world(&c);
        }
        // Localizing in a loaded map: each landmark the map's place matches moves halfway to
        // the map's point. The run's position and the map's are two measurements of one point
        // of about equal accuracy; their mean, at every keyframe that sees the map, keeps the
        // run on the map without trusting one view's verified pose (docs/decisions.md,
        // "Localization held on the map by its points").
        places.map_points(&query, |i, p_w| {
            if let Some(lm) = ids.get(i).and_then(|&id| map.landmark_mut(id)) {
                lm.p_w = nalgebra::center(&lm.p_w, &p_w);
            }
        });
        closure
    }

    /// Puts the detected features of `frame` with valid depth into `points`, as query points
    /// with descriptors (until it is full).
    fn query_points(
        &self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        points: &mut Vec<QueryPoint, QUERY_POINTS>,
    ) {
        for f in &self.detection.features {
            let Some(z) = landmark_depth(frame, cam, f, &self.params) else { continue };
            let Some(descriptor) = Descriptor::of(&frame.gray, f.x, f.y) else { continue };
            let p_c = cam.back_project(f.x, f.y, z);
            if points.push(QueryPoint { uv: (f.x, f.y), p_c, descriptor }).is_err() {
                break;
            }
        }
    }

    /// Records the inliers as observations of keyframe `kf` and re-anchors the tracked landmarks
    /// whose templates are too warped; returns the observations recorded.
    fn record_inliers<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &mut Map<K, L>,
        kf: KeyFrameId,
        t_cw: &Pose,
        inliers: &InlierMask,
    ) -> usize {
        let t_wc = t_cw.inverse();
        let limit = self.params.reanchor_max_warp;
        let mut recorded = 0;
        // Room is kept for the new landmarks this keyframe makes (they need their first
        // observation); the inliers come in the spread order of the final stage.
        let cap = MAX_OBSERVATIONS_PER_KEYFRAME.saturating_sub(NEW_LANDMARK_RESERVE);
        let items = self.local.items_mut();
        for (k, (corr, &src)) in
            self.scratch.correspondences.iter().zip(&self.scratch.sources).enumerate()
        {
            if !inliers.contains(k) {
                continue;
            }
            let Some(t) = items.get_mut(usize::from(src)) else { continue };
            if recorded >= cap {
                break;
            }
            let uv = (corr.uv.x, corr.uv.y);
            let Some(obs) = Observation::new(t.id, uv, corr.depth_m) else { continue };
            match map.add_observation(kf, obs) {
                Ok(()) => recorded += 1,
                Err(MapError::ObservationsFull) => break,
                Err(_) => continue,
            }
            if t.needs_reanchor(cam, t_cw, limit) {
                let z = corr.depth_m.unwrap_or_else(|| (t_cw * corr.p_w).z);
                t.reanchor(&frame.gray, uv, z, &t_wc);
            }
        }
        recorded
    }

    /// Makes landmarks of the features (detected in `frame`) with valid depth that are not
    /// `used` (re-acquired) nor near an inlier of this frame, up to `max_new_landmarks`; returns
    /// how many were made.
    fn add_new_landmarks<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        (map, places): (&mut Map<K, L>, &mut impl Places),
        (kf, t_wc): (KeyFrameId, &Pose),
        inliers: Option<&InlierMask>,
        used: &FeatureSet,
    ) -> usize {
        let p = self.params;
        let min_d2 = p.new_landmark_min_distance_px * p.new_landmark_min_distance_px;
        // Where this frame's inliers are: a feature near one is most likely the same point.
        // (Landmarks in view that failed to match do not block new ones: they are probably
        // occluded or badly anchored, and culling drops them.)
        let mut taken: Vec<(f32, f32), { capacity::MAX_TRACKED_LANDMARKS }> = Vec::new();
        if let Some(mask) = inliers {
            for (k, c) in self.scratch.correspondences.iter().enumerate() {
                if mask.contains(k) && taken.push((c.uv.x, c.uv.y)).is_err() {
                    break;
                }
            }
        }
        let now = self.frame_index;
        let mut local = self.local.insertions();
        let mut created = 0;
        for i in 0..self.detection.features.len() {
            let Some(&f) = self.detection.features.get(i) else { break };
            if created >= p.max_new_landmarks {
                break;
            }
            if contains(used, i) {
                continue;
            }
            let Some(z) = landmark_depth(frame, cam, &f, &p) else { continue };
            let near = taken.iter().any(|&(u, v)| {
                let (dx, dy) = (u - f.x, v - f.y);
                dx * dx + dy * dy < min_d2
            });
            if near || !local.make_room(now) {
                continue;
            }
            let p_w = t_wc * cam.back_project(f.x, f.y, z);
            let id = match map.add_landmark(p_w, kf) {
                Ok(id) => id,
                Err(_) => {
                    // The landmark arena is full: first drop the landmarks no keyframe observes
                    // and no one tracks, then retire the oldest keyframe (never this one) so its
                    // landmarks become such orphans: the map keeps its newest part.
                    if map.remove_orphans(|id| local.contains(id)) == 0
                        && map.oldest_keyframe() != Some(kf)
                    {
                        retire_oldest(map, places, |id| local.contains(id));
                    }
                    match map.add_landmark(p_w, kf) {
                        Ok(id) => id,
                        Err(_) => break,
                    }
                }
            };
            let tracked = TrackedLandmark::new(id, &frame.gray, (f.x, f.y), z, t_wc, now);
            let obs = Observation::new(id, (f.x, f.y), Some(z));
            let (Some(mut t), Some(obs)) = (tracked, obs) else {
                let _ = map.remove_landmark(id);
                continue;
            };
            if map.add_observation(kf, obs).is_err() {
                let _ = map.remove_landmark(id);
                break;
            }
            t.fused_weight = 1.0 / (z * z * z * z);
            if let Some(lm) = map.landmark_mut(id) {
                lm.descriptor = Descriptor::of(&frame.gray, f.x, f.y);
            }
            if !local.push(t) {
                break;
            }
            created += 1;
        }
        created
    }
}

/// Hands the map's oldest keyframe to the place memory, then retires it with the landmarks no
/// keyframe observes any more except the `tracked` ones (the map's full-arena policy).
fn retire_oldest<const K: usize, const L: usize>(
    map: &mut Map<K, L>,
    places: &mut impl Places,
    tracked: impl FnMut(crate::map::LandmarkId) -> bool,
) {
    if let Some(oldest) = map.oldest_keyframe() {
        places.remember(map, oldest);
    }
    let _ = map.retire_oldest_keyframe(tracked);
}

/// The depth of feature `f` if it may become a landmark: far enough from the border for its
/// template, depth in range and no depth discontinuity around it.
fn landmark_depth(
    frame: &RgbdFrame<'_>,
    cam: &PinholeCamera,
    f: &Feature,
    p: &super::FrontendParams,
) -> Option<f32> {
    if !cam.in_image(&Point2::new(f.x, f.y), BORDER_PX) {
        return None;
    }
    // Inside the image by the check above: the casts are exact.
    let (x, y) = (libm::roundf(f.x) as usize, libm::roundf(f.y) as usize);
    let z = frame
        .depth
        .depth_at(f.x, f.y, p.max_relative_depth_step)
        .filter(|&z| z >= p.sensor().depth_min_m && z <= p.sensor().depth_max_m)?;
    let r = DISCONTINUITY_RADIUS_PX;
    let neighbours = [(x + r, y), (x.wrapping_sub(r), y), (x, y + r), (x, y.wrapping_sub(r))];
    for (nx, ny) in neighbours {
        let zn = frame.depth.depth_m(nx, ny)?;
        if (zn - z).abs() > p.max_relative_depth_step * z {
            return None;
        }
    }
    Some(z)
}
