//! The planes of a run in the world frame ([`PlaneMap`]): each keyframe's planes, moved into the
//! world by the keyframe's pose, merged with a plane already kept when they are the same surface.

use heapless::Vec;
use nalgebra::Point3;

use super::planes::{Plane, dot};
use crate::geometry::Pose;

/// Planes a [`PlaneMap`] keeps.
pub const MAX_MAP_PLANES: usize = 32;

/// When two planes are one surface. Metres and radians.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlaneMergeParams {
    /// Their normals are within this angle (and point the same way). Default 5 degrees: a
    /// plane's normal is good to a fraction of a degree, a keyframe's pose to about one.
    pub max_normal_angle_rad: f32,
    /// Each one's centroid is within this distance of the other plane. Default 0.03 m: a few
    /// centimetres of drift between keyframes, well under a box's height over the floor.
    pub max_distance_m: f32,
}

impl PlaneMergeParams {
    /// The defaults, documented per field.
    pub const DEFAULT: Self =
        Self { max_normal_angle_rad: 5.0 * core::f32::consts::PI / 180.0, max_distance_m: 0.03 };
}

impl Default for PlaneMergeParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// A plane of the world and how it was seen.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MapPlane {
    /// The plane, in the world frame: the observations' normals and centroids averaged,
    /// weighted by their samples; `cells` the most any observation covered (its largest share
    /// of a frame), `samples` their sum.
    pub plane: Plane,
    /// Observations merged into it.
    pub observations: u16,
    /// The track its first observation came in: tracking restarts before it
    /// ([`PlaneMap::restart_track`]). A loop's correction moves the current track's planes.
    pub track: u16,
}

/// What a [`PlaneMap::observe`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Observed {
    /// Merged into the kept plane at this index.
    Merged(usize),
    /// Kept as a new plane at this index (in place of the least supported one, when full).
    Added(usize),
    /// Not kept: the map is full of planes better supported than it.
    Dropped,
}

/// The world's planes, at most [`MAX_MAP_PLANES`] (about 1.5 KiB). When full, a new plane takes
/// the place of the one with the fewest samples if it has more; otherwise it is dropped (and
/// counted): the best supported surfaces are the ones anchors go on.
///
/// Planes seen since tracking last restarted off the map are in that track's world until a loop
/// brings it back; [`Self::correct`] moves them with it, as the tracker moves the track's
/// keyframes.
#[derive(Debug, Clone, Default)]
pub struct PlaneMap {
    planes: Vec<MapPlane, MAX_MAP_PLANES>,
    dropped: u32,
    /// The current track: tracking restarts so far.
    track: u16,
    /// Calls that may have changed the planes (wrapping): what tells a saved map they changed.
    changes: u32,
}

impl PlaneMap {
    /// An empty map (`const`, for a `static`).
    pub const fn new() -> Self {
        Self { planes: Vec::new(), dropped: 0, track: 0, changes: 0 }
    }

    /// A map of `planes` saved by an earlier run ([`super::SavedWorld`]): the remembered world,
    /// an earlier track than the current one, so a loop moves this run's planes onto them and
    /// never them.
    pub fn restored(planes: &[MapPlane]) -> Self {
        let mut map = Self::new();
        for m in planes.iter().take(MAX_MAP_PLANES) {
            let _ = map.planes.push(MapPlane { track: 0, ..*m });
        }
        map.track = 1;
        map
    }

    /// The planes kept, in the order they were added.
    pub fn planes(&self) -> &[MapPlane] {
        &self.planes
    }

    /// Observations dropped because the map was full.
    pub fn dropped(&self) -> u32 {
        self.dropped
    }

    /// Forgets every plane.
    pub fn clear(&mut self) {
        self.changes = self.changes.wrapping_add(1);
        self.planes.clear();
        self.dropped = 0;
        self.track = 0;
    }

    /// Calls so far that may have changed the planes (wrapping; it counts at least every change,
    /// so an equal count means the same planes): a save skips planes it already holds.
    pub fn changes(&self) -> u32 {
        self.changes
    }

    /// The current track (tracking restarts so far).
    pub fn track(&self) -> u16 {
        self.track
    }

    /// Tracking restarted off the map, in a world frame of its own: planes observed from now on
    /// are the new track's.
    pub fn restart_track(&mut self) {
        self.track = self.track.wrapping_add(1);
    }

    /// A loop's correction of the current track's world (`t_new_old`: from the track's world to
    /// the remembered one, as a loop closure gives it): moves the planes the track added, and
    /// merges each that is then the same surface as a plane of an earlier track into it (the
    /// surface seen again, from the restarted map, before the loop). Cost: one pass over the
    /// planes per moved plane.
    pub fn correct(&mut self, t_new_old: &Pose, params: &PlaneMergeParams) {
        self.changes = self.changes.wrapping_add(1);
        let track = self.track;
        for m in self.planes.iter_mut().filter(|m| m.track == track) {
            m.plane = m.plane.transformed(t_new_old);
        }
        let mut i = 0;
        while let Some(&moved) = self.planes.get(i) {
            let earlier = |m: &MapPlane| m.track != track;
            let same = (moved.track == track)
                .then(|| self.same_surface(&moved.plane, earlier, params))
                .flatten();
            match same.and_then(|j| self.planes.get_mut(j)) {
                Some(kept) => {
                    kept.plane = merged(&kept.plane, &moved.plane);
                    kept.observations = kept.observations.saturating_add(moved.observations);
                    self.planes.remove(i);
                }
                None => i += 1,
            }
        }
    }

    /// Takes `plane` (in the world frame): merged into the kept plane it is the same surface as
    /// (the closest, by centroid distance), or kept as a new one of the current track.
    pub fn observe(&mut self, plane: &Plane, params: &PlaneMergeParams) -> Observed {
        self.changes = self.changes.wrapping_add(1);
        if let Some(i) = self.same_surface(plane, |_| true, params) {
            if let Some(m) = self.planes.get_mut(i) {
                m.plane = merged(&m.plane, plane);
                m.observations = m.observations.saturating_add(1);
            }
            return Observed::Merged(i);
        }
        let new = MapPlane { plane: *plane, observations: 1, track: self.track };
        if self.planes.push(new).is_ok() {
            return Observed::Added(self.planes.len() - 1);
        }
        let weakest = self.planes.iter().enumerate().min_by_key(|(_, m)| m.plane.samples);
        match weakest {
            Some((i, m)) if m.plane.samples < plane.samples => {
                if let Some(slot) = self.planes.get_mut(i) {
                    *slot = new;
                }
                Observed::Added(i)
            }
            _ => {
                self.dropped = self.dropped.saturating_add(1);
                Observed::Dropped
            }
        }
    }
}

impl PlaneMap {
    /// The kept plane among those `candidate` accepts that `plane` is the same surface as: normals
    /// within the angle, each centroid within the distance of the other plane; the closest by
    /// centroid distance.
    fn same_surface(
        &self,
        plane: &Plane,
        candidate: impl Fn(&MapPlane) -> bool,
        params: &PlaneMergeParams,
    ) -> Option<usize> {
        let cos_max = libm::cosf(params.max_normal_angle_rad);
        self.planes
            .iter()
            .enumerate()
            .filter(|(_, m)| {
                let kept = &m.plane;
                candidate(m)
                    && dot(&kept.normal, &plane.normal) >= cos_max
                    && distance(kept, &plane.centroid).abs() <= params.max_distance_m
                    && distance(plane, &kept.centroid).abs() <= params.max_distance_m
            })
            .min_by(|(_, a), (_, b)| {
                let d = |m: &MapPlane| distance(&m.plane, &plane.centroid).abs();
                d(a).total_cmp(&d(b))
            })
            .map(|(i, _)| i)
    }
}

/// `a` and `b` as one plane: normals and centroids averaged by samples, the normal renormalized.
fn merged(a: &Plane, b: &Plane) -> Plane {
    // Counts are at most a few million: f32 weights are exact enough.
    let (wa, wb) = (a.samples as f32, b.samples as f32);
    let total = (wa + wb).max(1.0);
    let n = [0, 1, 2].map(|k| (wa * a.normal[k] + wb * b.normal[k]) / total);
    let norm = ferroslam_fpu::sqrtf(dot(&n, &n));
    let normal = if norm > 0.0 { n.map(|c| c / norm) } else { a.normal };
    let centroid = [0, 1, 2].map(|k| (wa * a.centroid[k] + wb * b.centroid[k]) / total);
    let rms_m = ferroslam_fpu::sqrtf((wa * a.rms_m * a.rms_m + wb * b.rms_m * b.rms_m) / total);
    Plane {
        normal,
        offset_m: -dot(&normal, &centroid),
        centroid,
        rms_m,
        cells: a.cells.max(b.cells),
        samples: a.samples.saturating_add(b.samples),
    }
}

fn distance(plane: &Plane, p: &[f32; 3]) -> f32 {
    plane.distance(&Point3::from(*p))
}
