//! What a profile's types must do for [`Slam`](super::Slam), and which types each profile of
//! [`crate::config`] takes: [`ProfileTypes`] names the front end, map and back end once per
//! profile, and the traits here are the few operations `Slam` and its callers use on them
//! whatever their capacities.

use crate::backend::{Backend, BackendError, BackendParams, BackendStats, BackendStatus, SolveJob};
use crate::config::{HostQvga, HostVga, Profile, Qvga, Vga, tracking_buffer_pixels};
use crate::frame::RgbdFrame;
use crate::geometry::PinholeCamera;
use crate::map::{KeyFrame, KeyFrameId, Landmark, LandmarkId, Map};
use crate::tracking::{
    FrameResult, Frontend, FrontendError, FrontendParams, FrontendStats, Places,
};

use super::{SLAM_FRONTEND, Slam};

/// The front end, map and back end of a profile: what a `Slam<P>` holds.
pub trait ProfileTypes: Profile + Sized {
    /// The front end at the profile's resolution.
    type Frontend: Tracker<Self::Map> + core::fmt::Debug;
    /// The map at the profile's capacities.
    type Map: MapAccess + core::fmt::Debug;
    /// The back end sized for the map.
    type Backend: Adjuster<Self::Map> + core::fmt::Debug;

    /// A `Slam` at start with [`SLAM_FRONTEND`] and [`BackendParams::DEFAULT`] (a `const`, so
    /// that a `static` can hold one).
    const NEW: Slam<Self>;

    /// The three at start with the given parameters.
    fn start(
        frontend: FrontendParams,
        backend: BackendParams,
    ) -> (Self::Frontend, Self::Map, Self::Backend);
}

/// A front end tracking frames into a map of type `M`.
pub trait Tracker<M> {
    /// Tracks one frame into `map`, with `places` as its place memory (see
    /// [`Frontend::process`]).
    ///
    /// # Errors
    /// As [`Frontend::process`].
    fn process(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &mut M,
        places: &mut impl Places,
    ) -> Result<FrameResult, FrontendError>;

    /// Running totals.
    fn stats(&self) -> FrontendStats;

    /// The camera of the level it tracks frames seen by `cam` on, which the map's observations
    /// are in (see [`Frontend::tracking_camera`]).
    fn tracking_camera(&self, cam: &PinholeCamera) -> PinholeCamera;

    /// The parameters as given (see [`Frontend::params`]).
    fn params(&self) -> &FrontendParams;
}

/// Reading a map whatever its capacities (see [`Map`]).
pub trait MapAccess {
    /// Keyframes held.
    fn num_keyframes(&self) -> usize;
    /// Landmarks held.
    fn num_landmarks(&self) -> usize;
    /// The keyframe `id`, if it is still in the map.
    fn keyframe(&self, id: KeyFrameId) -> Option<&KeyFrame>;
    /// Every keyframe, in slot order.
    fn keyframes(&self) -> impl Iterator<Item = (KeyFrameId, &KeyFrame)> + '_;
    /// Every landmark, in slot order.
    fn landmarks(&self) -> impl Iterator<Item = (LandmarkId, &Landmark)> + '_;
    /// Hands every keyframe to `places` to be remembered, oldest first, as when it leaves the map
    /// (they stay in the map): what saving a map does with the active keyframes.
    fn remember_all_in(&self, places: &mut impl Places);
}

/// A back end adjusting a map of type `M` in bounded steps.
pub trait Adjuster<M> {
    /// Tells the back end of a new keyframe (see [`Backend::keyframe_added`]).
    fn keyframe_added(&mut self, kf: KeyFrameId, seq: u32);

    /// Tells the back end a loop closure moved the map (see [`Backend::map_moved`]).
    fn map_moved(&mut self);

    /// At most about `work_quota` units of work on `map` (see [`Backend::step`]).
    ///
    /// # Errors
    /// As [`Backend::step`].
    fn step(
        &mut self,
        map: &mut M,
        cam: &PinholeCamera,
        work_quota: u32,
    ) -> Result<BackendStatus, BackendError>;

    /// The solve under way as a job (see [`Backend::solve_job`]).
    fn solve_job(&mut self) -> Option<SolveJob<'_>>;

    /// Whether a solve is in progress.
    fn is_busy(&self) -> bool;

    /// Running totals.
    fn stats(&self) -> &BackendStats;

    /// The parameters in use.
    fn params(&self) -> &BackendParams;
}

impl<const W: usize, const H: usize, const C: usize, const K: usize, const L: usize>
    Tracker<Map<K, L>> for Frontend<W, H, C>
{
    fn process(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &mut Map<K, L>,
        places: &mut impl Places,
    ) -> Result<FrameResult, FrontendError> {
        Frontend::process_with(self, frame, cam, map, places)
    }

    fn stats(&self) -> FrontendStats {
        Frontend::stats(self)
    }

    fn tracking_camera(&self, cam: &PinholeCamera) -> PinholeCamera {
        Self::tracking_camera(cam)
    }

    fn params(&self) -> &FrontendParams {
        Frontend::params(self)
    }
}

impl<const K: usize, const L: usize> MapAccess for Map<K, L> {
    fn num_keyframes(&self) -> usize {
        Map::num_keyframes(self)
    }

    fn num_landmarks(&self) -> usize {
        Map::num_landmarks(self)
    }

    fn keyframe(&self, id: KeyFrameId) -> Option<&KeyFrame> {
        Map::keyframe(self, id)
    }

    fn keyframes(&self) -> impl Iterator<Item = (KeyFrameId, &KeyFrame)> + '_ {
        Map::keyframes(self)
    }

    fn landmarks(&self) -> impl Iterator<Item = (LandmarkId, &Landmark)> + '_ {
        Map::landmarks(self)
    }

    fn remember_all_in(&self, places: &mut impl Places) {
        let mut oldest_first: heapless::Vec<(u32, KeyFrameId), K> = heapless::Vec::new();
        for (id, k) in Map::keyframes(self) {
            // At most K keyframes: cannot fail.
            let _ = oldest_first.push((k.seq, id));
        }
        oldest_first.sort_unstable_by_key(|&(seq, _)| seq);
        for (_, id) in oldest_first {
            places.remember(self, id);
        }
    }
}

impl<
    const K: usize,
    const L: usize,
    const LW: usize,
    const R: usize,
    const P: usize,
    const O: usize,
> Adjuster<Map<K, L>> for Backend<K, L, LW, R, P, O>
{
    fn keyframe_added(&mut self, kf: KeyFrameId, seq: u32) {
        Backend::keyframe_added(self, kf, seq);
    }

    fn map_moved(&mut self) {
        Backend::map_moved(self);
    }

    fn step(
        &mut self,
        map: &mut Map<K, L>,
        cam: &PinholeCamera,
        work_quota: u32,
    ) -> Result<BackendStatus, BackendError> {
        Backend::step(self, map, cam, work_quota)
    }

    fn solve_job(&mut self) -> Option<SolveJob<'_>> {
        Backend::solve_job(self)
    }

    fn is_busy(&self) -> bool {
        Backend::is_busy(self)
    }

    fn stats(&self) -> &BackendStats {
        Backend::stats(self)
    }

    fn params(&self) -> &BackendParams {
        Backend::params(self)
    }
}

/// `impl ProfileTypes` for a profile of `config`: its front end sized by its resolution, its map
/// and back end by its map capacity.
macro_rules! profile_types {
    ($($profile:ty),*) => {$(
        impl ProfileTypes for $profile {
            type Frontend = Frontend<
                { <$profile as Profile>::RESOLUTION.max_width() },
                { <$profile as Profile>::RESOLUTION.max_height() },
                {
                    tracking_buffer_pixels(
                        <$profile as Profile>::RESOLUTION.max_width(),
                        <$profile as Profile>::RESOLUTION.max_height(),
                    )
                },
            >;
            type Map = Map<
                { <$profile as Profile>::MAP.keyframes },
                { <$profile as Profile>::MAP.landmarks },
            >;
            type Backend = Backend<
                { <$profile as Profile>::MAP.keyframes },
                { <$profile as Profile>::MAP.landmarks },
                { <$profile as Profile>::MAP.landmark_words },
                { <$profile as Profile>::MAP.ba_rigs },
                { <$profile as Profile>::MAP.ba_points },
                { <$profile as Profile>::MAP.ba_observations },
            >;

            const NEW: Slam<Self> = Slam::from_parts(
                Frontend::with_params(SLAM_FRONTEND),
                Map::new(),
                Backend::with_params(BackendParams::DEFAULT),
            );

            fn start(
                frontend: FrontendParams,
                backend: BackendParams,
            ) -> (Self::Frontend, Self::Map, Self::Backend) {
                (Frontend::with_params(frontend), Map::new(), Backend::with_params(backend))
            }
        }
    )*};
}

profile_types!(Qvga, Vga, HostQvga, HostVga);
