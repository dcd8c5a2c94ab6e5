//! The frames file the QEMU board reads its camera from (`frames.fsrs`): the dataset's frames
//! at sensor resolution as raw frame files back to back.

use std::fs;
use std::io::{BufWriter, Write};
use std::path::Path;

use anyhow::{Context, Result, anyhow, bail};
use ferroslam_firmware::frame_file::{FrameHeader, write_frame};
use ferroslam_sim::dataset::Dataset;

/// The largest frames file the QEMU board can read: its length comes from semihosting's
/// `SYS_FLEN`, a 32-bit word on the Cortex-M (about 4,660 frames at 640 x 480).
const MAX_FRAMES_FILE_BYTES: usize = u32::MAX as usize;

/// Whether `frames` frames of `len` bytes each (`size` pixels) fit the QEMU board's frames file
/// ([`MAX_FRAMES_FILE_BYTES`]).
///
/// # Errors
/// When they do not: the error says how many would.
fn check_frames_file(len: usize, frames: usize, size: (usize, usize)) -> Result<()> {
    if len.saturating_mul(frames) <= MAX_FRAMES_FILE_BYTES {
        return Ok(());
    }
    bail!(
        "{frames} frames of {} x {} are more than the QEMU board can read: it reads its frames \
         file through semihosting, whose file length (SYS_FLEN) is 32 bits, so at most {} frames \
         of this size ({len} bytes each) fit; play fewer frames",
        size.0,
        size.1,
        MAX_FRAMES_FILE_BYTES / len.max(1),
    )
}

/// Writes the dataset's frames at sensor resolution as raw frame files back to back; refuses,
/// before writing, more than [`MAX_FRAMES_FILE_BYTES`] (a dataset's frames are all one size).
pub(super) fn write_frames(dataset: &Dataset, path: &Path) -> Result<()> {
    let header_of = |i: usize| -> Result<_> {
        let f = dataset.load_frame(i)?;
        let header = FrameHeader {
            width: u32::try_from(f.width)?,
            height: u32::try_from(f.height)?,
            depth_scale: f.depth_scale,
            timestamp_s: f.timestamp_s,
        };
        Ok((f, header))
    };
    // The first frame, loaded once: it sizes the file, then is written first.
    let mut first = None;
    if !dataset.is_empty() {
        let (f, header) = header_of(0)?;
        let len = header.file_len().map_err(|e| anyhow!("frame 0: {e:?}"))?;
        check_frames_file(len, dataset.len(), (f.width, f.height))?;
        first = Some((f, header));
    }
    let file = fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut w = BufWriter::new(file);
    for i in 0..dataset.len() {
        let (f, header) = match first.take() {
            Some(loaded) => loaded,
            None => header_of(i)?,
        };
        write_frame(&header, &f.gray, &f.depth, |b| w.write_all(b))
            .map_err(|e| anyhow!("frame {i}: {e:?}"))?;
    }
    w.flush().with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    #[test]
    fn a_frames_file_over_what_semihosting_can_size_is_refused() {
        let vga = 32 + 3 * 640 * 480;
        check_frames_file(vga, 4660, (640, 480)).unwrap();
        let e = check_frames_file(vga, 4661, (640, 480)).unwrap_err().to_string();
        assert!(e.contains("at most 4660 frames"), "{e}");
        check_frames_file(0, usize::MAX, (0, 0)).unwrap();
    }
}
