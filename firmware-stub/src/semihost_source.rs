//! Recorded frames read from a host file through semihosting, as a
//! [`FrameSource`]: the QEMU board's camera. Only built for the Cortex-M target.
//!
//! The file is a sequence of raw frame files ([`frame_file`](crate::frame_file)), one after the
//! other. Each frame is streamed as a sensor would send it: the gray plane two rows at a time,
//! then the depth plane two rows at a time, each row pair halved into the [`HalfFrame`] store at
//! once. The full-resolution frame is never held: the board's RAM is sized for the QVGA store.

use core::fmt;

use ferroslam_core::frame::{FrameSource, RgbdFrame};
use ferroslam_core::image::ImageError;

use crate::frame_file::{FrameFileError, FrameHeader, HEADER_LEN, decode_depth_le};
use crate::semihosting::{HostFile, Mode, SemihostingError};
use crate::stream::{HalfFrame, MAX_SENSOR_HEIGHT, MAX_SENSOR_WIDTH};

/// Why a recorded frame could not be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
#[non_exhaustive]
pub enum SourceError {
    /// A semihosting call failed.
    Semihosting(SemihostingError),
    /// The frame header is invalid, or the file ends inside a frame.
    Frame(FrameFileError),
    /// The frame is larger than VGA or smaller than 2x2.
    Image(ImageError),
}

impl SourceError {
    /// A number naming the variant, for a fault message's detail.
    pub fn code(&self) -> u32 {
        match self {
            Self::Semihosting(_) => 1,
            Self::Frame(_) => 2,
            Self::Image(_) => 3,
        }
    }
}

impl fmt::Display for SourceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Semihosting(e) => write!(f, "semihosting: {e}"),
            Self::Frame(e) => write!(f, "frame file: {e}"),
            Self::Image(e) => write!(f, "frame size: {e}"),
        }
    }
}

impl core::error::Error for SourceError {}

impl From<SemihostingError> for SourceError {
    fn from(e: SemihostingError) -> Self {
        Self::Semihosting(e)
    }
}
impl From<FrameFileError> for SourceError {
    fn from(e: FrameFileError) -> Self {
        Self::Frame(e)
    }
}
impl From<ImageError> for SourceError {
    fn from(e: ImageError) -> Self {
        Self::Image(e)
    }
}

/// Frames of a host file, streamed into a [`HalfFrame`].
#[derive(Debug)]
pub struct SemihostFrames<'b> {
    file: HostFile,
    file_len: usize,
    offset: usize,
    store: &'b mut HalfFrame,
    /// Two full-resolution rows of bytes (gray: 2 x width; depth: 4 x width).
    rows: [u8; 4 * MAX_SENSOR_WIDTH],
    /// Two depth rows decoded.
    depth_rows: [u16; 2 * MAX_SENSOR_WIDTH],
}

impl<'b> SemihostFrames<'b> {
    /// Opens the host file at `path`, filling `store` frame by frame.
    ///
    /// # Errors
    /// The semihosting errors of opening the file or reading its length.
    pub fn open(path: &str, store: &'b mut HalfFrame) -> Result<Self, SourceError> {
        let file = HostFile::open(path, Mode::Read)?;
        let file_len = file.len()?;
        let (rows, depth_rows) = ([0; 4 * MAX_SENSOR_WIDTH], [0; 2 * MAX_SENSOR_WIDTH]);
        Ok(Self { file, file_len, offset: 0, store, rows, depth_rows })
    }

    /// Reads exactly `n` bytes into the row buffer.
    fn read_rows(&mut self, n: usize) -> Result<(), SourceError> {
        let buf = self.rows.get_mut(..n).ok_or(ImageError::ZeroSize)?;
        self.file.read_exact(buf)?;
        self.offset += n;
        Ok(())
    }

    /// Streams one frame's planes into the store and returns its header.
    fn stream_frame(&mut self) -> Result<FrameHeader, SourceError> {
        let mut head = [0u8; HEADER_LEN];
        self.file.read_exact(&mut head)?;
        self.offset += HEADER_LEN;
        let header = FrameHeader::decode(&head)?;
        let remaining = self.file_len.saturating_sub(self.offset) + HEADER_LEN;
        let expected = header.file_len()?;
        if remaining < expected {
            return Err(FrameFileError::LengthMismatch { expected, got: remaining }.into());
        }
        let (w, h) = (header.width as usize, header.height as usize);
        if w > MAX_SENSOR_WIDTH || h > MAX_SENSOR_HEIGHT {
            return Err(ImageError::SizeMismatch {
                expected: (MAX_SENSOR_WIDTH, MAX_SENSOR_HEIGHT),
                got: (w, h),
            }
            .into());
        }
        self.store.start(w, h)?;
        for row in 0..h / 2 {
            self.read_rows(2 * w)?;
            let (top, rest) = self.rows.split_at(w);
            self.store.put_gray_rows(row, top, rest.get(..w).unwrap_or_default())?;
        }
        if h % 2 == 1 {
            self.read_rows(w)?; // the last odd row is dropped by the halving
        }
        for row in 0..h / 2 {
            self.read_rows(4 * w)?;
            let bytes = self.rows.get(..4 * w).unwrap_or_default();
            let samples = self.depth_rows.get_mut(..2 * w).unwrap_or_default();
            decode_depth_le(bytes, samples)?;
            let (top, bottom) = samples.split_at(w);
            self.store.put_depth_rows(row, top, bottom)?;
        }
        if h % 2 == 1 {
            self.read_rows(2 * w)?;
        }
        Ok(header)
    }
}

impl FrameSource for SemihostFrames<'_> {
    type Error = SourceError;

    /// The next frame of the file, `Ok(None)` at its end. After an error the file position is
    /// unknown, so the source ends there.
    fn next_frame(&mut self) -> Result<Option<RgbdFrame<'_>>, Self::Error> {
        if self.offset >= self.file_len {
            return Ok(None);
        }
        let header = match self.stream_frame() {
            Ok(h) => h,
            Err(e) => {
                self.offset = self.file_len;
                return Err(e);
            }
        };
        Ok(Some(self.store.frame(header.timestamp_s, header.depth_scale)?))
    }
}
