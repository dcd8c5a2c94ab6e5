//! An RGB-D frame as the core sees it, and the port every frame producer implements.

use crate::image::{DepthView, GrayView};

/// One RGB-D frame: gray intensity and depth of the same instant, borrowed from whoever owns the
/// buffers (a camera driver's DMA buffers, a dataset reader, the synthetic renderer).
///
/// The depth image is expected at the gray image's size; a sensor whose depth is not registered to
/// its colour camera (7-Scenes, Kinect v1) gives depth in the depth camera's own pixels, which the
/// pipeline treats as approximately registered.
#[derive(Debug, Clone, Copy)]
pub struct RgbdFrame<'a> {
    /// Capture time in seconds, on the recording's clock (TUM timestamps are Unix seconds).
    pub timestamp_s: f64,
    /// 8-bit gray image.
    pub gray: GrayView<'a>,
    /// Depth image with its scale.
    pub depth: DepthView<'a>,
}

/// A producer of RGB-D frames: a camera, a recorded dataset, a renderer.
///
/// One required method, in the style of embedded-hal: each implementation has its own error type.
/// Frames come in capture order; `Ok(None)` means the source is exhausted (a camera never returns it).
pub trait FrameSource {
    /// What can go wrong reading a frame (a bus error, a missing file, a corrupt image).
    type Error: core::fmt::Debug;

    /// The next frame, borrowed until the next call.
    ///
    /// # Errors
    /// The implementation's error when a frame cannot be produced; the source may be able to go on
    /// with the following frame, as its documentation says.
    fn next_frame(&mut self) -> Result<Option<RgbdFrame<'_>>, Self::Error>;
}
