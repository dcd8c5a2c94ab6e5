//! [`ProfileSource`]: the port wrapper that brings any [`FrameSource`] to a processing profile
//! with the core's downsampling, as the firmware brings the sensor's frames.

use ferroslam_core::frame::{FrameSource, RgbdFrame};
use ferroslam_core::image::ImageError;

use crate::frame::{OwnedFrame, halve_frame};

/// A source that halves every frame of `inner` `levels` times with the core's downsampling, as the
/// firmware does with sensor frames: the port wrapper that puts a VGA source at the QVGA profile.
#[derive(Debug)]
pub struct ProfileSource<S> {
    inner: S,
    levels: u8,
    depth_level: u8,
    current: Option<OwnedFrame>,
}

impl<S> ProfileSource<S> {
    /// Wraps `inner`, halving its frames `levels` times and their depth `depth_level` more
    /// times (see [`OwnedFrame::coarsen_depth`]; both 0 = pass frames through unchanged).
    pub fn new(inner: S, levels: u8, depth_level: u8) -> Self {
        Self { inner, levels, depth_level, current: None }
    }

    /// The wrapped source.
    pub fn inner(&self) -> &S {
        &self.inner
    }
}

/// Why a [`ProfileSource`] could not give a frame.
#[derive(Debug, thiserror::Error)]
pub enum ProfileSourceError<E: std::error::Error + 'static> {
    /// The wrapped source failed.
    #[error(transparent)]
    Source(E),
    /// The frame could not be downsampled.
    #[error("downsampling the frame failed: {0}")]
    Image(#[from] ImageError),
}

impl<S> FrameSource for ProfileSource<S>
where
    S: FrameSource,
    S::Error: std::error::Error + 'static,
{
    type Error = ProfileSourceError<S::Error>;

    fn next_frame(&mut self) -> Result<Option<RgbdFrame<'_>>, Self::Error> {
        let frame = self.inner.next_frame().map_err(ProfileSourceError::Source)?;
        let Some(frame) = frame else { return Ok(None) };
        if self.levels == 0 && self.depth_level == 0 {
            return Ok(Some(frame));
        }
        let halved = self.current.insert(halve_frame(&frame, self.levels)?);
        halved.coarsen_depth(self.depth_level)?;
        Ok(Some(halved.view()?))
    }
}
