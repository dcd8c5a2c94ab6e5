//! Image messages' pixels as the frames' gray and depth samples.
//!
//! Colour (`rgb8`, `bgr8`, `mono8`) becomes 8-bit gray with the folder loader's BT.601 luma, so an
//! `rgb8` message gives the same gray as the PNG or JPEG it was decoded from. Depth becomes raw
//! samples of `depth_scale` units per metre (the calibration's): `16UC1` is millimetres (REP 118),
//! `32FC1` metres, and a sample is `round(metres * depth_scale)`; NaN, infinite, zero or negative
//! metres, and values past the 16-bit range, are no reading (0). `16UC1` at a depth scale of 1000
//! is copied as it is.

use super::messages::ImageMsg;
use crate::dataset::decode::rgb_to_gray;

/// The colour encodings read, as errors list them.
pub const COLOUR_ENCODINGS: &str = "rgb8, bgr8, mono8";
/// The depth encodings read, as errors list them.
pub const DEPTH_ENCODINGS: &str = "16UC1 (millimetres), 32FC1 (metres)";

/// What a pixel encoding is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// 8-bit red, green, blue.
    Rgb8,
    /// 8-bit blue, green, red.
    Bgr8,
    /// 8-bit gray.
    Mono8,
    /// 16-bit unsigned depth, millimetres.
    Depth16Mm,
    /// 32-bit float depth, metres.
    Depth32M,
}

impl Encoding {
    /// The encoding named `name` (ROS's `sensor_msgs/image_encodings` names), if it is read.
    pub fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "rgb8" => Self::Rgb8,
            "bgr8" => Self::Bgr8,
            "mono8" => Self::Mono8,
            "16UC1" => Self::Depth16Mm,
            "32FC1" => Self::Depth32M,
            _ => return None,
        })
    }

    /// Whether it is a depth encoding.
    pub fn is_depth(self) -> bool {
        matches!(self, Self::Depth16Mm | Self::Depth32M)
    }

    /// Bytes per pixel.
    fn pixel_bytes(self) -> usize {
        match self {
            Self::Rgb8 | Self::Bgr8 => 3,
            Self::Mono8 => 1,
            Self::Depth16Mm => 2,
            Self::Depth32M => 4,
        }
    }
}

/// Why an image message's pixels cannot be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum PixelError {
    /// The encoding is not one this reader converts (or not of the stream it is read for).
    #[error(
        "encoding {encoding:?} is not supported; colour: {COLOUR_ENCODINGS}; depth: {DEPTH_ENCODINGS}"
    )]
    Encoding {
        /// The message's encoding.
        encoding: String,
    },
    /// `step` is shorter than a row, or the data shorter than `step * height`.
    #[error(
        "{width}x{height} {encoding} needs rows of {row} bytes; step is {step}, data {len} bytes"
    )]
    Layout {
        /// Columns.
        width: u32,
        /// Rows.
        height: u32,
        /// The encoding.
        encoding: String,
        /// Bytes a row's pixels take.
        row: usize,
        /// The message's step.
        step: u32,
        /// The message's data length.
        len: usize,
    },
}

/// The rows of `msg`'s pixels (each `width * pixel_bytes` long, padding dropped).
fn rows<'a>(
    msg: &ImageMsg<'a>,
    encoding: Encoding,
) -> Result<impl Iterator<Item = &'a [u8]>, PixelError> {
    let row = msg.width as usize * encoding.pixel_bytes();
    let step = msg.step as usize;
    let height = msg.height as usize;
    if step < row || msg.data.len() < step.saturating_mul(height) {
        return Err(PixelError::Layout {
            width: msg.width,
            height: msg.height,
            encoding: msg.encoding.to_owned(),
            row,
            step: msg.step,
            len: msg.data.len(),
        });
    }
    let data = msg.data;
    // A step of 0 only passes the check for an empty row; `max(1)` keeps `chunks` defined.
    Ok(data.chunks(step.max(1)).take(height).map(move |r| r.get(..row).unwrap_or(r)))
}

/// The encoding of `msg`, if it is read and of the right kind (`depth` or colour).
fn encoding_of(msg: &ImageMsg<'_>, depth: bool) -> Result<Encoding, PixelError> {
    match Encoding::parse(msg.encoding) {
        Some(e) if e.is_depth() == depth => Ok(e),
        _ => Err(PixelError::Encoding { encoding: msg.encoding.to_owned() }),
    }
}

/// `msg`'s pixels as 8-bit gray, row-major without padding.
///
/// # Errors
/// [`PixelError::Encoding`] for a depth or unknown encoding, [`PixelError::Layout`] for a step or
/// data too short.
pub fn gray(msg: &ImageMsg<'_>) -> Result<Vec<u8>, PixelError> {
    let encoding = encoding_of(msg, false)?;
    let mut out = Vec::with_capacity(msg.width as usize * msg.height as usize);
    for row in rows(msg, encoding)? {
        match encoding {
            Encoding::Rgb8 => out.extend(rgb_to_gray(row, 3, |v| v as u8)),
            Encoding::Bgr8 => {
                let rgb: Vec<u8> = row.chunks_exact(3).flat_map(|p| [p[2], p[1], p[0]]).collect();
                out.extend(rgb_to_gray(&rgb, 3, |v| v as u8));
            }
            _ => out.extend_from_slice(row),
        }
    }
    Ok(out)
}

/// `msg`'s depth as raw samples of `depth_scale` units per metre (see the module doc).
///
/// # Errors
/// [`PixelError::Encoding`] for a colour or unknown encoding, [`PixelError::Layout`] for a step or
/// data too short.
pub fn depth(msg: &ImageMsg<'_>, depth_scale: f32) -> Result<Vec<u16>, PixelError> {
    let encoding = encoding_of(msg, true)?;
    let big = msg.is_bigendian;
    let scale = f64::from(depth_scale);
    let mut out = Vec::with_capacity(msg.width as usize * msg.height as usize);
    for row in rows(msg, encoding)? {
        match encoding {
            Encoding::Depth16Mm => {
                let mm = row.chunks_exact(2).map(|b| {
                    let b = [b[0], b[1]];
                    if big { u16::from_be_bytes(b) } else { u16::from_le_bytes(b) }
                });
                if depth_scale == 1000.0 {
                    out.extend(mm);
                } else {
                    out.extend(mm.map(|v| raw_depth(f64::from(v) / 1000.0, scale)));
                }
            }
            _ => out.extend(row.chunks_exact(4).map(|b| {
                let b = [b[0], b[1], b[2], b[3]];
                let m = if big { f32::from_be_bytes(b) } else { f32::from_le_bytes(b) };
                raw_depth(f64::from(m), scale)
            })),
        }
    }
    Ok(out)
}

/// `depth_m` metres as a raw sample of `scale` units per metre; 0 (no reading) when it is not a
/// positive finite depth within the 16-bit range.
fn raw_depth(depth_m: f64, scale: f64) -> u16 {
    let raw = (depth_m * scale).round();
    if raw.is_finite() && raw > 0.0 && raw <= f64::from(u16::MAX) { raw as u16 } else { 0 }
}

/// A raw sample of `depth_scale` units per metre as `32FC1` metres: NaN for no reading (REP 118).
/// [`depth`] gives the same sample back at the same scale (an `f32` keeps 24 bits; a sample has
/// 16).
pub fn metres_of(raw: u16, depth_scale: f32) -> f32 {
    if raw == 0 { f32::NAN } else { (f64::from(raw) / f64::from(depth_scale)) as f32 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::mcap::messages::Stamp;

    fn msg<'a>(encoding: &'a str, width: u32, step: u32, data: &'a [u8]) -> ImageMsg<'a> {
        let height = (data.len() / step.max(1) as usize) as u32;
        let stamp = Stamp { sec: 0, nanosec: 0 };
        ImageMsg { stamp, height, width, encoding, is_bigendian: false, step, data }
    }

    #[test]
    fn colour_encodings_give_the_loaders_gray() {
        let rgb = [255, 0, 0, 0, 255, 0];
        assert_eq!(gray(&msg("rgb8", 2, 6, &rgb)).unwrap(), vec![76, 150]);
        let bgr = [0, 0, 255, 0, 255, 0];
        assert_eq!(gray(&msg("bgr8", 2, 6, &bgr)).unwrap(), vec![76, 150]);
        // Row padding (step 4 for 3 pixels) is dropped.
        let mono = [1, 2, 3, 0, 4, 5, 6, 0];
        assert_eq!(gray(&msg("mono8", 3, 4, &mono)).unwrap(), vec![1, 2, 3, 4, 5, 6]);
    }

    #[test]
    fn depth_encodings_and_invalid_samples() {
        let mm: Vec<u8> = [1000u16, 0, 65535].iter().flat_map(|v| v.to_le_bytes()).collect();
        assert_eq!(depth(&msg("16UC1", 3, 6, &mm), 1000.0).unwrap(), vec![1000, 0, 65535]);
        assert_eq!(depth(&msg("16UC1", 3, 6, &mm), 5000.0).unwrap(), vec![5000, 0, 0]);
        let m: Vec<u8> = [1.5f32, f32::NAN, f32::INFINITY, -1.0, 0.0, 20.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        assert_eq!(depth(&msg("32FC1", 6, 24, &m), 5000.0).unwrap(), vec![7500, 0, 0, 0, 0, 0]);
        let mut be = msg("32FC1", 1, 4, &[0x3f, 0xc0, 0, 0]);
        be.is_bigendian = true;
        assert_eq!(depth(&be, 1000.0).unwrap(), vec![1500]);
    }

    #[test]
    fn metres_give_every_raw_sample_back() {
        for scale in [5000.0f32, 1000.0, 5208.0, 1.0] {
            for raw in 1..=u16::MAX {
                let m = metres_of(raw, scale);
                assert_eq!(raw_depth(f64::from(m), f64::from(scale)), raw, "{raw} at {scale}");
            }
        }
        assert!(metres_of(0, 5000.0).is_nan());
    }

    #[test]
    fn wrong_kinds_and_layouts_are_errors() {
        let err = gray(&msg("16UC1", 1, 2, &[0, 0])).unwrap_err();
        assert!(err.to_string().contains("rgb8, bgr8, mono8"), "{err}");
        let err = depth(&msg("bayer_rggb8", 1, 1, &[0]), 1000.0).map(|_| ()).unwrap_err();
        assert_eq!(err, PixelError::Encoding { encoding: "bayer_rggb8".into() });
        let mut short = msg("rgb8", 2, 6, &[0; 6]);
        short.height = 2;
        assert!(matches!(gray(&short), Err(PixelError::Layout { .. })));
        assert!(matches!(gray(&msg("rgb8", 2, 3, &[0; 6])), Err(PixelError::Layout { .. })));
    }
}
