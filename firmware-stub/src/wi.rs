//! The W(I) check: the paper's total image variation (Eq. 3) of one frame at full and half
//! resolution, and a checksum of the half-resolution depth, computed the same way on the firmware
//! and on the host so that the two results can be compared bit for bit.
//!
//! The firmware reports its result as one text line (see [`WiReport`]'s `Display`), which the host
//! parses back with [`WiReport::parse`].

use core::fmt;

use ferroslam_core::image::{
    GrayView, GrayViewMut, ImageError, ImageView, ImageViewMut, downsample_depth_2x,
    downsample_gray_2x, total_variation,
};

/// The first word of a result line.
pub const RESULT_TAG: &str = "ferroslam-wi";

/// What the W(I) check computes for one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct WiReport {
    /// Full-resolution width in pixels.
    pub width: u32,
    /// Full-resolution height in pixels.
    pub height: u32,
    /// `W(I)` of the full-resolution gray image (VGA for the reference recordings), gray levels.
    pub wi_vga: u64,
    /// `W(I)` of the gray image halved by [`downsample_gray_2x`] (QVGA), gray levels.
    pub wi_qvga: u64,
    /// 64-bit FNV-1a of the depth halved by [`downsample_depth_2x`]: its raw samples row-major,
    /// each as two little-endian bytes.
    pub depth_qvga_fnv1a: u64,
}

/// 64-bit FNV-1a over the samples of `depth`, row by row, each sample as two little-endian bytes
/// (stride padding is not hashed).
pub fn fnv1a_depth(depth: &ImageView<'_, u16>) -> u64 {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    let mut h = OFFSET;
    for row in depth.rows() {
        for &d in row {
            for b in d.to_le_bytes() {
                h = (h ^ u64::from(b)).wrapping_mul(PRIME);
            }
        }
    }
    h
}

/// Runs the W(I) check on one frame: `W(I)` of `gray`, of `gray` halved into `qvga_gray`, and the
/// checksum of `depth` halved into `qvga_depth`. The scratch buffers must hold at least
/// `(width / 2) * (height / 2)` samples; the caller owns them (static on the firmware).
///
/// # Errors
/// [`ImageError::SizeMismatch`] when `gray` and `depth` differ in size, and the view errors of a
/// scratch buffer that is too small or a frame smaller than 2x2.
pub fn compute(
    gray: &GrayView<'_>,
    depth: &ImageView<'_, u16>,
    qvga_gray: &mut [u8],
    qvga_depth: &mut [u16],
) -> Result<WiReport, ImageError> {
    if depth.size() != gray.size() {
        return Err(ImageError::SizeMismatch { expected: gray.size(), got: depth.size() });
    }
    let (w, h) = gray.size();
    let (hw, hh) = (w / 2, h / 2);
    let mut small_gray = GrayViewMut::packed(qvga_gray, hw, hh)?;
    downsample_gray_2x(gray, &mut small_gray)?;
    let mut small_depth = ImageViewMut::packed(qvga_depth, hw, hh)?;
    downsample_depth_2x(depth, &mut small_depth)?;
    let too_big = ImageError::BufferTooSmall { needed: usize::MAX, got: 0 };
    Ok(WiReport {
        width: u32::try_from(w).map_err(|_| too_big)?,
        height: u32::try_from(h).map_err(|_| too_big)?,
        wi_vga: total_variation(gray),
        wi_qvga: total_variation(&small_gray.as_view()),
        depth_qvga_fnv1a: fnv1a_depth(&small_depth.as_view()),
    })
}

/// The result line: `ferroslam-wi v1 width=640 height=480 wi_vga=N wi_qvga=N
/// depth_qvga_fnv1a=0x0123456789abcdef` (one line, decimal except the hash; no newline).
impl fmt::Display for WiReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{RESULT_TAG} v1 width={} height={} wi_vga={} wi_qvga={} depth_qvga_fnv1a={:#018x}",
            self.width, self.height, self.wi_vga, self.wi_qvga, self.depth_qvga_fnv1a
        )
    }
}

impl WiReport {
    /// Parses a line written by `Display` (surrounding whitespace allowed); `None` if it is not
    /// exactly such a line.
    pub fn parse(line: &str) -> Option<Self> {
        let mut words = line.split_whitespace();
        if words.next()? != RESULT_TAG || words.next()? != "v1" {
            return None;
        }
        let mut field = |key: &str| words.next()?.strip_prefix(key)?.strip_prefix('=');
        let width = field("width")?.parse().ok()?;
        let height = field("height")?.parse().ok()?;
        let wi_vga = field("wi_vga")?.parse().ok()?;
        let wi_qvga = field("wi_qvga")?.parse().ok()?;
        let hash = field("depth_qvga_fnv1a")?.strip_prefix("0x")?;
        let depth_qvga_fnv1a = u64::from_str_radix(hash, 16).ok()?;
        if words.next().is_some() {
            return None;
        }
        Some(Self { width, height, wi_vga, wi_qvga, depth_qvga_fnv1a })
    }
}

/// Formats `value` into `buf` without a heap, returning the written text; `None` if `buf` is too
/// small.
pub fn format_into<'b>(buf: &'b mut [u8], value: &impl fmt::Display) -> Option<&'b str> {
    struct Cursor<'c> {
        buf: &'c mut [u8],
        len: usize,
    }
    impl fmt::Write for Cursor<'_> {
        fn write_str(&mut self, s: &str) -> fmt::Result {
            let end = self.len.checked_add(s.len()).ok_or(fmt::Error)?;
            let dst = self.buf.get_mut(self.len..end).ok_or(fmt::Error)?;
            dst.copy_from_slice(s.as_bytes());
            self.len = end;
            Ok(())
        }
    }
    let mut c = Cursor { buf, len: 0 };
    fmt::write(&mut c, format_args!("{value}")).ok()?;
    let Cursor { buf, len } = c;
    core::str::from_utf8(buf.get(..len)?).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::ToString;

    #[test]
    fn fnv1a_matches_the_reference_vectors() {
        // FNV-1a 64 of the bytes "a\0" (sample 0x0061), and of no bytes (empty not possible for a
        // view, so check the one-sample case against a byte-wise computation).
        let d = [0x0061u16];
        let v = ImageView::packed(&d, 1, 1).unwrap();
        let mut h = 0xcbf2_9ce4_8422_2325u64;
        for b in [0x61u8, 0x00] {
            h = (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
        }
        assert_eq!(fnv1a_depth(&v), h);
        // FNV-1a 64 of "a" is af63dc4c8601ec8c (published test vector); one more byte changes it.
        let mut a = 0xcbf2_9ce4_8422_2325u64;
        a = (a ^ 0x61).wrapping_mul(0x100_0000_01b3);
        assert_eq!(a, 0xaf63_dc4c_8601_ec8c);
    }

    #[test]
    fn compute_on_a_small_frame() {
        // 4x2 frame: gray step edge, depth with an edge block.
        let gray = [0, 0, 255, 255, 0, 0, 255, 255];
        let depth = [1000, 3000, 0, 0, 1000, 3000, 0, 500];
        let g = GrayView::packed(&gray, 4, 2).unwrap();
        let d = ImageView::packed(&depth, 4, 2).unwrap();
        let (mut sg, mut sd) = ([0u8; 2], [0u16; 2]);
        let r = compute(&g, &d, &mut sg, &mut sd).unwrap();
        assert_eq!((r.width, r.height, r.wi_vga), (4, 2, 1020));
        // Halves: gray [0, 255] -> W = 255 + 255; depth [1000, 500].
        assert_eq!(sg, [0, 255]);
        assert_eq!(r.wi_qvga, 510);
        assert_eq!(sd, [1000, 500]);
        assert_eq!(r.depth_qvga_fnv1a, fnv1a_depth(&ImageView::packed(&sd, 2, 1).unwrap()));
        let mut tiny = [0u8; 1];
        assert!(compute(&g, &d, &mut tiny, &mut sd).is_err());
    }

    #[test]
    fn result_line_round_trips() {
        let r = WiReport {
            width: 640,
            height: 480,
            wi_vga: 1_234_567,
            wi_qvga: 89,
            depth_qvga_fnv1a: 0x00ab_cdef_0123_4567,
        };
        let line = r.to_string();
        assert_eq!(
            line,
            "ferroslam-wi v1 width=640 height=480 wi_vga=1234567 wi_qvga=89 \
             depth_qvga_fnv1a=0x00abcdef01234567"
        );
        assert_eq!(WiReport::parse(&line), Some(r));
        assert_eq!(WiReport::parse(&(line.clone() + "\n")), Some(r));
        assert_eq!(WiReport::parse(&(line.clone() + " x=1")), None);
        assert_eq!(WiReport::parse("ferroslam-wi v2 width=1"), None);
        let mut buf = [0u8; 128];
        assert_eq!(format_into(&mut buf, &r), Some(line.as_str()));
        assert_eq!(format_into(&mut [0u8; 10], &r), None);
    }
}
