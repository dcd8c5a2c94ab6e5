//! Image decoding: colour to 8-bit gray, 16-bit depth.
//!
//! Gray conversion uses ITU-R BT.601 luma in OpenCV's fixed point,
//! `Y = (4899 R + 9617 G + 1868 B + 8192) >> 14` (OpenCV's `COLOR_RGB2GRAY`, which the TUM tools and
//! most SLAM systems use on these recordings), bit-exact and independent of the image crate's own
//! conversion. Alpha is dropped (not composited). 16-bit samples are reduced to 8 bits by
//! `(v * 255 + 32767) / 65535` (rounding to nearest) after the luma sum. The file format is found
//! from the content, not the extension.
//!
//! The same decoding runs on a file (`decode_gray`, `decode_depth`: what the dataset loader
//! calls) or on a file's bytes already in memory ([`gray_from_bytes`], [`depth_from_bytes`]: what
//! `cargo xtask fuzz` feeds mutated images to).

use std::io::{BufRead, Cursor, Seek};
use std::path::Path;

use image::{DynamicImage, ImageFormat, ImageReader};

use super::DatasetError;

/// Opens and decodes an image, recognising its format from its content.
fn decode(path: &Path) -> Result<(DynamicImage, Option<ImageFormat>), DatasetError> {
    let io = |source| DatasetError::Io { path: path.to_owned(), source };
    decode_from(ImageReader::open(path).map_err(io)?, path)
}

/// Decodes the image `reader` reads, recognising its format from its content; `path` names it in
/// errors.
fn decode_from<R: BufRead + Seek>(
    reader: ImageReader<R>,
    path: &Path,
) -> Result<(DynamicImage, Option<ImageFormat>), DatasetError> {
    let io = |source| DatasetError::Io { path: path.to_owned(), source };
    let reader = reader.with_guessed_format().map_err(io)?;
    let format = reader.format();
    let image =
        reader.decode().map_err(|source| DatasetError::Decode { path: path.to_owned(), source })?;
    Ok((image, format))
}

/// `8-bit RGB JPEG`-style description of a decoded image, for error messages.
fn describe(image: &DynamicImage, format: Option<ImageFormat>) -> String {
    let color = match image {
        DynamicImage::ImageLuma8(_) => "8-bit gray",
        DynamicImage::ImageLumaA8(_) => "8-bit gray+alpha",
        DynamicImage::ImageRgb8(_) => "8-bit RGB",
        DynamicImage::ImageRgba8(_) => "8-bit RGBA",
        DynamicImage::ImageLuma16(_) => "16-bit gray",
        DynamicImage::ImageLumaA16(_) => "16-bit gray+alpha",
        DynamicImage::ImageRgb16(_) => "16-bit RGB",
        DynamicImage::ImageRgba16(_) => "16-bit RGBA",
        DynamicImage::ImageRgb32F(_) => "32-bit float RGB",
        DynamicImage::ImageRgba32F(_) => "32-bit float RGBA",
        _ => "an unknown pixel format",
    };
    let container = format.map_or("image".to_owned(), |f| format!("{f:?}").to_uppercase());
    format!("{color} {container}")
}

/// Errors unless `(width, height)` is `expected`, in pixels.
fn check_size(
    path: &Path,
    (width, height): (u32, u32),
    expected: (u32, u32),
) -> Result<(), DatasetError> {
    if (width, height) != expected {
        return Err(DatasetError::ImageSize {
            path: path.to_owned(),
            width,
            height,
            expected_width: expected.0,
            expected_height: expected.1,
        });
    }
    Ok(())
}

/// BT.601 luma in OpenCV's 14-bit fixed point, on samples of any width up to 16 bits.
fn luma(r: u32, g: u32, b: u32) -> u32 {
    (4899 * r + 9617 * g + 1868 * b + 8192) >> 14
}

/// A 16-bit sample reduced to 8 bits, rounding to nearest.
fn to_u8(v: u32) -> u8 {
    ((v * 255 + 32767) / 65535) as u8
}

/// Converts RGB(A) samples with `step` channels per pixel to gray with `f` mapping luma to 8 bits.
pub(crate) fn rgb_to_gray<T: Copy + Into<u32>>(
    s: &[T],
    step: usize,
    f: impl Fn(u32) -> u8,
) -> Vec<u8> {
    s.chunks_exact(step)
        .map(|p| match p {
            [r, g, b, ..] => f(luma((*r).into(), (*g).into(), (*b).into())),
            _ => 0,
        })
        .collect()
}

/// Decodes a colour (or gray) image to 8-bit gray, checking its size against `expected`.
///
/// # Errors
/// [`DatasetError::Io`], [`DatasetError::Decode`], [`DatasetError::ImageSize`] or
/// [`DatasetError::ColorFormat`], each naming `path`.
pub(crate) fn decode_gray(path: &Path, expected: (u32, u32)) -> Result<Vec<u8>, DatasetError> {
    let (image, format) = decode(path)?;
    to_gray(image, format, path, expected)
}

/// Decodes an image file's bytes `bytes` to 8-bit gray as the dataset loader decodes a colour
/// image file, checking its size against `expected` (pixels); `path` only names it in errors.
///
/// # Errors
/// As the loader's: [`DatasetError::Decode`], [`DatasetError::ImageSize`] or
/// [`DatasetError::ColorFormat`].
pub fn gray_from_bytes(
    bytes: &[u8],
    path: &Path,
    expected: (u32, u32),
) -> Result<Vec<u8>, DatasetError> {
    let (image, format) = decode_from(ImageReader::new(Cursor::new(bytes)), path)?;
    to_gray(image, format, path, expected)
}

/// `image` (in container `format`, from `path`) as 8-bit gray, checked to be `expected` pixels.
fn to_gray(
    image: DynamicImage,
    format: Option<ImageFormat>,
    path: &Path,
    expected: (u32, u32),
) -> Result<Vec<u8>, DatasetError> {
    check_size(path, (image.width(), image.height()), expected)?;
    let u8_id = |v: u32| v as u8;
    let gray = match image {
        DynamicImage::ImageLuma8(b) => b.into_raw(),
        DynamicImage::ImageLumaA8(b) => b.into_raw().chunks_exact(2).map(|p| p[0]).collect(),
        DynamicImage::ImageRgb8(b) => rgb_to_gray(b.as_raw(), 3, u8_id),
        DynamicImage::ImageRgba8(b) => rgb_to_gray(b.as_raw(), 4, u8_id),
        DynamicImage::ImageLuma16(b) => b.as_raw().iter().map(|&v| to_u8(v.into())).collect(),
        DynamicImage::ImageLumaA16(b) => {
            b.as_raw().chunks_exact(2).map(|p| to_u8(p[0].into())).collect()
        }
        DynamicImage::ImageRgb16(b) => rgb_to_gray(b.as_raw(), 3, to_u8),
        DynamicImage::ImageRgba16(b) => rgb_to_gray(b.as_raw(), 4, to_u8),
        other => {
            let found = describe(&other, format);
            return Err(DatasetError::ColorFormat { path: path.to_owned(), found });
        }
    };
    Ok(gray)
}

/// A colour image's pixels as an 8-bit image message holds them (`convert --mcap`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum ColourPixels {
    /// 8-bit red, green, blue, row-major (an RGB or RGBA image, alpha dropped).
    Rgb8(Vec<u8>),
    /// 8-bit gray: a gray image, or the loader's gray of any other (16-bit) image.
    Mono8(Vec<u8>),
}

/// Decodes a colour image as 8-bit pixels from which the loader's gray follows exactly: RGB(A)
/// 8-bit as RGB, 8-bit gray as it is, anything else as the gray [`decode_gray`] gives.
///
/// # Errors
/// As [`decode_gray`].
pub(crate) fn decode_colour(
    path: &Path,
    expected: (u32, u32),
) -> Result<ColourPixels, DatasetError> {
    let (image, format) = decode(path)?;
    check_size(path, (image.width(), image.height()), expected)?;
    Ok(match image {
        DynamicImage::ImageRgb8(b) => ColourPixels::Rgb8(b.into_raw()),
        DynamicImage::ImageRgba8(b) => ColourPixels::Rgb8(
            b.as_raw().chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect(),
        ),
        other => ColourPixels::Mono8(to_gray(other, format, path, expected)?),
    })
}

/// Decodes a 16-bit gray PNG depth image, checking its size against `expected`.
///
/// # Errors
/// [`DatasetError::Io`], [`DatasetError::Decode`], [`DatasetError::DepthFormat`] (any other pixel
/// format or container, e.g. an 8-bit or colour PNG) or [`DatasetError::ImageSize`], each naming
/// `path`.
pub(crate) fn decode_depth(path: &Path, expected: (u32, u32)) -> Result<Vec<u16>, DatasetError> {
    let (image, format) = decode(path)?;
    to_depth(image, format, path, expected)
}

/// Decodes an image file's bytes `bytes` as the dataset loader decodes a depth image file (a
/// 16-bit gray PNG), checking its size against `expected` (pixels); `path` only names it in
/// errors.
///
/// # Errors
/// As the loader's: [`DatasetError::Decode`], [`DatasetError::DepthFormat`] or
/// [`DatasetError::ImageSize`].
pub fn depth_from_bytes(
    bytes: &[u8],
    path: &Path,
    expected: (u32, u32),
) -> Result<Vec<u16>, DatasetError> {
    let (image, format) = decode_from(ImageReader::new(Cursor::new(bytes)), path)?;
    to_depth(image, format, path, expected)
}

/// `image` (in container `format`, from `path`) as 16-bit depth samples, if it is a 16-bit gray
/// PNG of `expected` pixels.
fn to_depth(
    image: DynamicImage,
    format: Option<ImageFormat>,
    path: &Path,
    expected: (u32, u32),
) -> Result<Vec<u16>, DatasetError> {
    match image {
        DynamicImage::ImageLuma16(b) if format == Some(ImageFormat::Png) => {
            check_size(path, b.dimensions(), expected)?;
            Ok(b.into_raw())
        }
        other => Err(DatasetError::DepthFormat {
            path: path.to_owned(),
            found: describe(&other, format),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn luma_matches_opencv_fixed_point() {
        assert_eq!(luma(255, 255, 255), 255);
        assert_eq!(luma(0, 0, 0), 0);
        // cv::cvtColor(RGB2GRAY) of pure red, green, blue: 76, 150, 29.
        assert_eq!((luma(255, 0, 0), luma(0, 255, 0), luma(0, 0, 255)), (76, 150, 29));
        assert_eq!(luma(65535, 65535, 65535), 65535);
        assert_eq!((to_u8(65535), to_u8(0), to_u8(257 * 100)), (255, 0, 100));
    }
}
