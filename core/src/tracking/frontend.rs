//! [`Frontend`]: the front end as callers see it. It checks a frame's size, brings the frame to
//! the pyramid level it tracks on ([`crate::config::tracking_level`]: the level nearest the
//! width its pixel parameters are stated for), and hands it to the `FrameTracker` there.
//!
//! On the tracking level the gray image is the frame's halved with the core's downsampling, the
//! depth the frame's own read for the halved image (finer than it: no depth is lost), and the
//! camera the frame's halved. Everything two-dimensional then happens on that level (templates,
//! searches, features, observations), so a VGA frame is tracked with the templates and windows
//! of the reference resolution; the frame's full-resolution depth is read at the tracked points.

use super::FrontendParams;
use super::local_map::BoardLocalMap;
use super::places::{NoPlaces, Places};
use super::result::{FrameResult, FrontendError, FrontendState, FrontendStats, size_mismatch};
use super::tracker::FrameTracker;
use crate::config::{tracking_buffer_pixels, tracking_level};
use crate::frame::RgbdFrame;
use crate::geometry::PinholeCamera;
use crate::image::{GrayView, GrayViewMut, downsample_gray_2x};
use crate::map::Map;

/// The front end at the reference board's QVGA profile (320 x 240): it tracks on the frame.
pub type QvgaFrontend = Frontend<320, 240>;
/// The front end at the VGA profile (640 x 480): it tracks on the frame halved (76,800 bytes).
pub type VgaFrontend = Frontend<640, 480, { tracking_buffer_pixels(640, 480) }>;

/// The front end for frames up to `W` x `H` pixels, with room for `C` pixels of a frame halved
/// to its tracking level (0: it tracks on the frame itself; see the module documentation).
#[derive(Debug, Clone)]
pub struct Frontend<const W: usize, const H: usize, const C: usize = 0> {
    /// The current frame halved, when the front end tracks on level 1.
    halved: [u8; C],
    tracker: FrameTracker<W, H>,
}

impl<const W: usize, const H: usize, const C: usize> Default for Frontend<W, H, C> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const W: usize, const H: usize, const C: usize> Frontend<W, H, C> {
    /// A front end with [`FrontendParams::DEFAULT`] (`const`, so it can initialize a `static`).
    pub const fn new() -> Self {
        Self::with_params(FrontendParams::DEFAULT)
    }

    /// A front end with `params` (checked on every [`Self::process`]), their pixel values stated
    /// for [`REFERENCE_WIDTH_PX`](crate::config::REFERENCE_WIDTH_PX) and scaled to the tracking
    /// level's width.
    pub const fn with_params(params: FrontendParams) -> Self {
        Self { halved: [0; C], tracker: FrameTracker::with_params(params) }
    }

    /// The parameters as given.
    pub fn params(&self) -> &FrontendParams {
        self.tracker.stated_params()
    }

    /// The state after the last frame.
    pub fn state(&self) -> FrontendState {
        self.tracker.state()
    }

    /// Running totals.
    pub fn stats(&self) -> FrontendStats {
        self.tracker.stats()
    }

    /// The landmarks tracked now.
    pub fn local_map(&self) -> &BoardLocalMap {
        self.tracker.local_map()
    }

    /// The pyramid level frames `width` x `height` are tracked on: [`tracking_level`], when the
    /// halved frame fits in `C` and the size halves exactly; else 0.
    pub const fn level_for(width: usize, height: usize) -> u8 {
        let halves =
            width.is_multiple_of(2) && height.is_multiple_of(2) && (width / 2) * (height / 2) <= C;
        if tracking_level(width) == 1 && halves { 1 } else { 0 }
    }

    /// The camera of the tracking level for frames seen by `cam`: the one the map's observations
    /// are in (bundle adjustment needs it). `cam` itself on level 0.
    pub fn tracking_camera(cam: &PinholeCamera) -> PinholeCamera {
        match Self::level_for(cam.width(), cam.height()) {
            0 => *cam,
            _ => cam.downscaled_2x().unwrap_or(*cam),
        }
    }

    /// Processes one frame (see the module documentation of [`crate::tracking`]) against `map`,
    /// which it extends with keyframes and landmarks. `cam` must describe the frame's size.
    ///
    /// # Errors
    /// [`FrontendError::SizeMismatch`], [`FrontendError::TimestampNotIncreasing`] or
    /// [`FrontendError::InvalidParams`]; nothing changes then. A frame that cannot be tracked
    /// (black, no depth) is not an error: it gives [`FrontendState::Lost`] (or stays
    /// [`FrontendState::Initializing`]).
    pub fn process<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &mut Map<K, L>,
    ) -> Result<FrameResult, FrontendError> {
        self.process_with(frame, cam, map, &mut NoPlaces)
    }

    /// As [`Self::process`], with `places` as the place memory: a keyframe leaving `map` is
    /// handed to it, and a frame that cannot be tracked asks it where it is
    /// ([`FrameOutcome::Relocalized`](super::FrameOutcome::Relocalized) when a remembered place
    /// is verified).
    ///
    /// # Errors
    /// As [`Self::process`].
    pub fn process_with<const K: usize, const L: usize>(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        map: &mut Map<K, L>,
        places: &mut impl Places,
    ) -> Result<FrameResult, FrontendError> {
        let (width, height) = frame.gray.size();
        let fits = width <= W && height <= H;
        if !fits
            || frame.depth.size() != (width, height)
            || (cam.width(), cam.height()) != (width, height)
        {
            return Err(size_mismatch::<W, H>(frame, cam));
        }
        if Self::level_for(width, height) == 0 {
            return self.tracker.process(frame, cam, map, places);
        }
        // `level_for` checked that the halved frame fits and halves exactly: none of these fail.
        let mismatch = || size_mismatch::<W, H>(frame, cam);
        let (w, h) = (width / 2, height / 2);
        let buffer = self.halved.get_mut(..w * h).ok_or_else(mismatch)?;
        let mut halved = GrayViewMut::packed(buffer, w, h).map_err(|_| mismatch())?;
        downsample_gray_2x(&frame.gray, &mut halved).map_err(|_| mismatch())?;
        let buffer = self.halved.get(..w * h).ok_or_else(mismatch)?;
        let gray = GrayView::packed(buffer, w, h).map_err(|_| mismatch())?;
        let depth = frame.depth.for_coarser_image(1).ok_or_else(mismatch)?;
        let level_cam = cam.downscaled_2x().map_err(|_| mismatch())?;
        let level = RgbdFrame { timestamp_s: frame.timestamp_s, gray, depth };
        self.tracker.process(&level, &level_cam, map, places)
    }
}
