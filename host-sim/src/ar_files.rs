//! The files of an AR run (`--ar`) in `DIR/ar/`: where each frame drew each object
//! (`pixels.csv`), the overlay frames (`frame_NNNN.png`, one a second) and an animated preview
//! (`preview.gif`, every third frame) a person can open.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use anyhow::{Context, Result};
use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, DynamicImage, Frame};

use crate::run::{ArRun, TrackingRun};

/// Overlay frames written as PNG: one in this many frames (a second at 30 Hz).
const PNG_EVERY: usize = 30;

/// The preview's frame time, milliseconds: every third frame of 30 Hz shown at its pace.
const GIF_FRAME_MS: u32 = 100;

/// Writes `run`'s AR files into `dir/ar/` (nothing without `--ar`, or when no frame showed two
/// planes).
///
/// # Errors
/// A file that cannot be written or encoded.
pub fn write_ar(dir: &Path, run: &TrackingRun) -> Result<()> {
    let Some(ar) = &run.ar else { return Ok(()) };
    let out = dir.join("ar");
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    write_pixels(&out.join("pixels.csv"), ar, run)?;
    for (index, image) in &ar.overlays {
        if (index - ar.frame).is_multiple_of(PNG_EVERY) {
            let path = out.join(format!("frame_{index:04}.png"));
            image.save(&path).with_context(|| format!("writing {}", path.display()))?;
        }
    }
    let path = out.join("preview.gif");
    let file = File::create(&path).with_context(|| format!("creating {}", path.display()))?;
    let mut gif = GifEncoder::new_with_speed(BufWriter::new(file), 10);
    gif.set_repeat(Repeat::Infinite)?;
    for (_, image) in &ar.overlays {
        let rgba = DynamicImage::ImageRgb8(image.clone()).into_rgba8();
        let delay = Delay::from_numer_denom_ms(GIF_FRAME_MS, 1);
        gif.encode_frame(Frame::from_parts(rgba, 0, 0, delay))
            .with_context(|| format!("encoding {}", path.display()))?;
    }
    Ok(())
}

/// `frame,timestamp_s,object,u,v`: every drawing, frames 0-based as played, pixels at the
/// processing resolution (a drawing behind the camera is left out).
fn write_pixels(path: &Path, ar: &ArRun, run: &TrackingRun) -> Result<()> {
    let file = File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut w = BufWriter::new(file);
    writeln!(w, "frame,timestamp_s,object,u,v")?;
    for (j, drawn) in ar.drawn.iter().enumerate() {
        let index = ar.frame + j;
        let t = run.per_frame.get(index).map_or(f64::NAN, |f| f.timestamp_s);
        for (a, uv) in ar.anchors.iter().zip(drawn) {
            if let Some([u, v]) = uv {
                writeln!(w, "{index},{t:.6},{},{u:.3},{v:.3}", a.object)?;
            }
        }
    }
    w.flush().with_context(|| format!("writing {}", path.display()))
}
