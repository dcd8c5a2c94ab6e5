//! The map's points over a whole run, for a person to look at (report.html's 3D view): the
//! board's map holds a few keyframes' landmarks at a time, so each landmark is kept at the last
//! position a keyframe's snapshot saw, after it leaves the map too.

use std::collections::BTreeMap;

use ferroslam_core::map::{KeyFrameId, Landmark, LandmarkId};
use serde::Serialize;

/// Points kept at most (the page stays a few megabytes); the rest are dropped, counted.
const MAX_POINTS: usize = 60_000;

/// The map's points of a run, in the run's world frame, metres.
#[derive(Debug, Clone, Default, Serialize)]
pub struct MapCloud {
    /// Every landmark the map held at a keyframe, at its last seen position.
    pub points: Vec<[f32; 3]>,
    /// The landmarks made by the last keyframe (the paper's points new in the current
    /// keyframe), also in `points`.
    pub newest: Vec<[f32; 3]>,
    /// Landmarks left out over the cap of 60,000 points.
    pub dropped: usize,
}

/// Landmarks seen so far, by id (ids carry their slot's generation, so a reused slot is a new
/// point).
#[derive(Debug, Default)]
pub(super) struct MapPoints {
    latest: BTreeMap<LandmarkId, [f32; 3]>,
}

impl MapPoints {
    /// The map's landmarks now (after a keyframe, and at the end of the run).
    pub(super) fn observe<'a>(
        &mut self,
        landmarks: impl Iterator<Item = (LandmarkId, &'a Landmark)>,
    ) {
        for (id, l) in landmarks {
            self.latest.insert(id, l.p_w.coords.into());
        }
    }

    /// The cloud, with the points of the `last` keyframe among `landmarks` (the final map's).
    pub(super) fn finish<'a>(
        self,
        last: Option<KeyFrameId>,
        landmarks: impl Iterator<Item = (LandmarkId, &'a Landmark)>,
    ) -> MapCloud {
        let newest = landmarks
            .filter(|(_, l)| Some(l.host) == last)
            .map(|(_, l)| l.p_w.coords.into())
            .collect();
        let dropped = self.latest.len().saturating_sub(MAX_POINTS);
        let points = self.latest.into_values().take(MAX_POINTS).collect();
        MapCloud { points, newest, dropped }
    }
}
