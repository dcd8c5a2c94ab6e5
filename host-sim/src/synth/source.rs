//! The synthetic sequence as a core [`FrameSource`], and PNG export of frames.

use std::path::{Path, PathBuf};

use ferroslam_core::frame::{FrameSource, RgbdFrame};

use super::{DEPTH_SCALE, SynthError, SynthFrame, SyntheticSequence};

/// Renders the frames of a [`SyntheticSequence`] in order through the core's frame port.
///
/// The frame handed out borrows the source's own buffers, which the next call overwrites.
#[derive(Debug, Clone)]
pub struct SynthSource {
    sequence: SyntheticSequence,
    next: usize,
    frame: SynthFrame,
}

impl SynthSource {
    /// A source starting at frame 0.
    pub fn new(sequence: SyntheticSequence) -> Self {
        let frame = SynthFrame::empty(DEPTH_SCALE as f32);
        Self { sequence, next: 0, frame }
    }

    /// A source whose first frame is frame `first` of `sequence` (none at all when `first` is
    /// past the end).
    pub fn starting_at(sequence: SyntheticSequence, first: usize) -> Self {
        Self { next: first, ..Self::new(sequence) }
    }

    /// The sequence being played.
    pub fn sequence(&self) -> &SyntheticSequence {
        &self.sequence
    }

    /// Index of the frame the next call to `next_frame` renders.
    pub fn position(&self) -> usize {
        self.next
    }
}

impl FrameSource for SynthSource {
    type Error = SynthError;

    /// Renders the next frame; `Ok(None)` after the last one. On an error the source moves on to
    /// the following frame.
    fn next_frame(&mut self) -> Result<Option<RgbdFrame<'_>>, SynthError> {
        if self.next >= self.sequence.len() {
            return Ok(None);
        }
        let index = self.next;
        self.next += 1;
        self.sequence.render_into(index, &mut self.frame)?;
        Ok(Some(self.frame.view()?))
    }
}

/// Writes `frame` as `DIR/STEM_gray.png` (8-bit gray) and `DIR/STEM_depth.png` (16-bit, raw units,
/// TUM convention) and returns the two paths. `dir` must exist.
///
/// # Errors
/// [`SynthError::Png`] when a file cannot be encoded or written.
pub fn write_pngs(
    frame: &SynthFrame,
    dir: &Path,
    stem: &str,
) -> Result<(PathBuf, PathBuf), SynthError> {
    let (w, h) = (frame.width as u32, frame.height as u32);
    let gray_path = dir.join(format!("{stem}_gray.png"));
    let depth_path = dir.join(format!("{stem}_depth.png"));
    let png_err = |path: &Path| {
        let path = path.to_path_buf();
        move |source| SynthError::Png { path, source }
    };
    let size_err = |path: &Path| SynthError::Png {
        path: path.to_path_buf(),
        source: image::ImageError::Parameter(image::error::ParameterError::from_kind(
            image::error::ParameterErrorKind::DimensionMismatch,
        )),
    };
    let gray =
        image::GrayImage::from_raw(w, h, frame.gray.clone()).ok_or_else(|| size_err(&gray_path))?;
    gray.save(&gray_path).map_err(png_err(&gray_path))?;
    let depth =
        image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(w, h, frame.depth.clone())
            .ok_or_else(|| size_err(&depth_path))?;
    depth.save(&depth_path).map_err(png_err(&depth_path))?;
    Ok((gray_path, depth_path))
}
