//! Compact binary descriptors: what a map landmark keeps of its appearance once its tracking
//! template is gone, so a later keyframe can recognize it (map reuse when the camera comes back).
//!
//! A [`Descriptor`] is 64 intensity comparisons (BRIEF, Calonder et al. 2010) between pairs of
//! 3 x 3 box averages in a 15 x 15 window around the pixel (the boxes smooth the noise the
//! comparisons would otherwise see). The pairs are fixed (a deterministic pattern, denser near the
//! centre). Not rotation or scale invariant: it is compared only between views the geometry has
//! already brought close (predicted pixel within a few pixels, consistent depth), where the
//! in-plane rotation and scale change are small.
//!
//! Cost: 13 x 13 box sums (separable, about 500 additions) and 64 comparisons per descriptor;
//! 8 bytes each.

use crate::image::GrayView;

/// Radius of the comparison points around the centre, pixels (the boxes reach one further).
const POINT_RADIUS: i32 = 6;
/// Side of the box-sum grid: every point where a comparison box can be centred.
const GRID: usize = 2 * POINT_RADIUS as usize + 1;

/// A 64-bit binary descriptor (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Descriptor(pub u64);

impl Descriptor {
    /// The number of differing bits (0..=64).
    pub fn distance(self, other: Self) -> u32 {
        (self.0 ^ other.0).count_ones()
    }

    /// The descriptor of `img` around pixel `(x, y)` (rounded to the nearest pixel); `None` when
    /// the 15 x 15 window leaves the image or a coordinate is not finite.
    pub fn of(img: &GrayView<'_>, x: f32, y: f32) -> Option<Self> {
        let (w, h) = img.size();
        let reach = POINT_RADIUS + 1;
        let (cx, cy) = (libm::roundf(x), libm::roundf(y));
        // NaN fails the comparisons; the casts below only see values inside the image.
        let inside = cx >= reach as f32
            && cy >= reach as f32
            && cx + (reach as f32) < w as f32
            && cy + (reach as f32) < h as f32;
        if !inside {
            return None;
        }
        let (x0, y0) = (cx as usize - reach as usize, cy as usize - reach as usize);
        // Horizontal 3-sums of the 15 window rows, then vertical: `boxes[j][i]` is the 3 x 3 sum
        // centred at window offset `(i - 6, j - 6)` from the centre.
        let mut rows = [[0u16; GRID]; GRID + 2];
        for (j, out) in rows.iter_mut().enumerate() {
            let px = img.row(y0 + j)?.get(x0..x0 + GRID + 2)?;
            for (o, tri) in out.iter_mut().zip(px.windows(3)) {
                if let [a, b, c] = *tri {
                    *o = u16::from(a) + u16::from(b) + u16::from(c);
                }
            }
        }
        let mut boxes = [[0u16; GRID]; GRID];
        for (j, out) in boxes.iter_mut().enumerate() {
            for (i, o) in out.iter_mut().enumerate() {
                *o = rows[j][i] + rows[j + 1][i] + rows[j + 2][i];
            }
        }
        let at = |(dx, dy): (i8, i8)| {
            let (i, j) =
                ((i32::from(dx) + POINT_RADIUS) as usize, (i32::from(dy) + POINT_RADIUS) as usize);
            boxes.get(j).and_then(|r| r.get(i)).copied().unwrap_or(0)
        };
        let mut bits = 0u64;
        for (k, &(a, b)) in PATTERN.iter().enumerate() {
            if at(a) < at(b) {
                bits |= 1 << k;
            }
        }
        Some(Self(bits))
    }
}

/// The 64 comparison pairs: offsets in `[-6, 6]^2` from the centre, drawn once from a fixed
/// linear congruential generator (each coordinate the mean of two uniform draws, so the points
/// gather near the centre, as BRIEF's Gaussian pattern does), at compile time.
const PATTERN: [((i8, i8), (i8, i8)); 64] = pattern();

const fn pattern() -> [((i8, i8), (i8, i8)); 64] {
    let mut out = [((0i8, 0i8), (0i8, 0i8)); 64];
    let mut state: u32 = 0x2545_F491;
    let mut k = 0;
    while k < 64 {
        let mut c = [0i8; 4];
        let mut m = 0;
        while m < 4 {
            // Two draws in 0..=12 averaged, minus 6: -6..=6, triangular.
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let a = (state >> 24) % 13;
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let b = (state >> 24) % 13;
            c[m] = ((a + b) / 2) as i8 - 6;
            m += 1;
        }
        if c[0] == c[2] && c[1] == c[3] {
            // A point compared with itself tells nothing: shift the second one.
            c[2] = if c[2] < 6 { c[2] + 1 } else { c[2] - 1 };
        }
        out[k] = ((c[0], c[1]), (c[2], c[3]));
        k += 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn textured(shift: usize) -> [u8; 64 * 64] {
        let mut img = [0u8; 64 * 64];
        for (k, p) in img.iter_mut().enumerate() {
            let (x, y) = ((k % 64 + shift) as u32, (k / 64) as u32);
            let h = (x.wrapping_mul(0x9E37_79B9) ^ y.wrapping_mul(0x85EB_CA6B))
                .wrapping_mul(0x2C1B_3C6D);
            *p = (h >> 24) as u8;
        }
        img
    }

    #[test]
    fn the_same_place_matches_and_another_does_not() {
        let (a, b) = (textured(0), textured(3));
        let (va, vb) =
            (GrayView::packed(&a, 64, 64).unwrap(), GrayView::packed(&b, 64, 64).unwrap());
        // Image b is image a shifted left by 3 pixels: a's (30, 30) is b's (27, 30).
        let da = Descriptor::of(&va, 30.0, 30.0).unwrap();
        assert_eq!(da.distance(Descriptor::of(&vb, 27.0, 30.0).unwrap()), 0);
        let other = Descriptor::of(&vb, 40.0, 20.0).unwrap();
        assert!(da.distance(other) > 16, "{}", da.distance(other));
        // Sub-pixel positions round to the pixel; the window must fit.
        assert_eq!(Descriptor::of(&va, 30.4, 29.6), Some(da));
        assert_eq!(Descriptor::of(&va, 6.0, 30.0), None);
        assert_eq!(Descriptor::of(&va, 57.0, 30.0), None);
        assert_eq!(Descriptor::of(&va, f32::NAN, 30.0), None);
    }

    #[test]
    fn the_pattern_compares_distinct_points_inside_the_window() {
        for &((ax, ay), (bx, by)) in &PATTERN {
            assert!((ax, ay) != (bx, by));
            for v in [ax, ay, bx, by] {
                assert!((-6..=6).contains(&v));
            }
        }
    }
}
