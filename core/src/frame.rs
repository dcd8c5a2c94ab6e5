//! An RGB-D frame as the core sees it, the port every frame producer implements
//! ([`FrameSource`]), and the port every consumer of the core's output implements
//! ([`TelemetrySink`]).

use crate::image::{DepthView, GrayView};
use crate::wire::Message;

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

/// A consumer of the pipeline's output: the firmware's serial link (postcard + COBS + CRC over a
/// UART), a host writer (trajectory files, a capture file), a test recorder.
///
/// One required method, in the style of embedded-hal: each implementation has its own error type.
/// Messages are [`wire`](crate::wire) messages, so every sink sees exactly what the serial link
/// would carry.
pub trait TelemetrySink {
    /// What can go wrong sending a message (a UART error, a full disk).
    type Error: core::fmt::Debug;

    /// Sends one message, whole or not at all as far as the sink can tell (a link that fails
    /// mid-frame leaves a partial frame, which the receiver's decoder drops and counts).
    ///
    /// # Errors
    /// The implementation's error; the caller may go on with the next message.
    fn send(&mut self, message: &Message) -> Result<(), Self::Error>;
}

impl<T: TelemetrySink + ?Sized> TelemetrySink for &mut T {
    type Error = T::Error;

    fn send(&mut self, message: &Message) -> Result<(), Self::Error> {
        (**self).send(message)
    }
}
