//! The box filters of the Fast-Hessian detector and the per-sample math shared by the strip
//! detector and the tests' full-frame reference: det(H) at a sample, the sign of the Laplacian,
//! and the 3D quadratic refinement of a 3x3x3 response cube.

/// Filter sizes (side length in pixels) of each octave's four layers (SURF's first two octaves).
pub const OCTAVE_FILTER_SIZES: [[usize; 4]; 2] = [[9, 15, 21, 27], [15, 27, 39, 51]];

/// Sampling step of each octave, in pixels: responses are evaluated at `x, y` multiples of it.
pub const OCTAVE_STEPS: [usize; 2] = [1, 2];

/// Half size of the largest filter of all octaves.
const MAX_HALF: usize = (OCTAVE_FILTER_SIZES[1][3] - 1) / 2;

/// Integral-image rows held by the rolling buffer: the largest filter spans `2*MAX_HALF + 1` rows
/// and its box sums need the row above it too.
pub const INTEGRAL_RING_ROWS: usize = 2 * MAX_HALF + 2;

/// One octave's geometry, so that run-time code iterates octaves instead of indexing tables.
#[derive(Debug, Clone, Copy)]
pub(super) struct Octave {
    /// 0 for the first octave, 1 for the second.
    pub index: usize,
    /// Sampling step, in pixels.
    pub step: usize,
    /// Filter sizes of the four layers, in pixels.
    pub sizes: [usize; 4],
}

impl Octave {
    const fn of(index: usize) -> Self {
        Self { index, step: OCTAVE_STEPS[index], sizes: OCTAVE_FILTER_SIZES[index] }
    }

    /// Half size `(size - 1) / 2` of the octave's largest filter: samples closer than `half + 1`
    /// pixels to the border have no response in this octave.
    pub(super) const fn half(&self) -> usize {
        (self.sizes[3] - 1) / 2
    }

    /// First sample coordinate (a multiple of the step) where the largest filter fits:
    /// `coord - half - 1 >= 0`, so box sums never read before the first integral row or column.
    pub(super) const fn first_sample(&self) -> usize {
        (self.half() + 1).div_ceil(self.step) * self.step
    }

    /// Difference of filter size between adjacent layers, in pixels.
    pub(super) const fn size_step(&self) -> usize {
        self.sizes[1] - self.sizes[0]
    }
}

/// The octaves, first to last.
pub(super) const OCTAVES: [Octave; 2] = [Octave::of(0), Octave::of(1)];

/// Rows of an integral image: `row(y)[x]` is the sum of pixels `(0..=x, 0..=y)` (mod 2^32).
pub(super) trait IntegralRows {
    /// Integral row `y`; empty (reads as zero) if not held.
    fn row(&self, y: usize) -> &[u32];
}

/// Sum of the pixels in rows `top+1..=bot` (given as their bounding integral rows) and columns
/// `c0..=c1`. Requires `c0 >= 1`; exact because the true sum is below 2^31.
fn box_sum(top: &[u32], bot: &[u32], c0: usize, c1: usize) -> i32 {
    let at = |r: &[u32], c: usize| r.get(c).copied().unwrap_or(0);
    let before = c0.saturating_sub(1);
    let s = at(bot, c1)
        .wrapping_sub(at(top, c1))
        .wrapping_sub(at(bot, before))
        .wrapping_add(at(top, before));
    s as i32
}

/// The integral rows one filter needs at one image row `y`, fetched once per row.
pub(super) struct Taps<'a> {
    l: usize,
    b: usize,
    inv_area: f32,
    /// Rows `y - l`, `y + l - 1`: the `Dxx` boxes span rows `y-(l-1)..=y+(l-1)`.
    xx: [&'a [u32]; 2],
    /// Rows `y - b - 1`, `y + b`, `y - l/2 - 1`, `y + l/2`: the `Dyy` outer and middle boxes.
    yy: [&'a [u32]; 4],
    /// Rows `y - l - 1`, `y - 1`, `y`, `y + l`: the upper and lower `Dxy` quadrants.
    xy: [&'a [u32]; 4],
}

impl<'a> Taps<'a> {
    /// Taps of the filter of side `size` at image row `y`; requires `y >= size/2 + 1`.
    pub(super) fn new<I: IntegralRows>(ii: &'a I, size: usize, y: usize) -> Self {
        let l = size / 3;
        let b = (size - 1) / 2;
        // Rows above `y` saturate at 0 instead of wrapping; callers keep `y >= b + 1` anyway.
        let up = |d: usize| ii.row(y.saturating_sub(d));
        let down = |d: usize| ii.row(y + d);
        Self {
            l,
            b,
            inv_area: 1.0 / (size * size) as f32,
            xx: [up(l), down(l - 1)],
            yy: [up(b + 1), down(b), up(l / 2 + 1), down(l / 2)],
            xy: [up(l + 1), up(1), down(0), down(l)],
        }
    }

    /// Unnormalized integer `(Dxx, Dyy, Dxy)` at column `x`; requires `x >= b + 1`.
    fn derivatives(&self, x: usize) -> (i32, i32, i32) {
        // Columns left of `x` saturate at 0 instead of wrapping; callers keep `x >= b + 1`. Every
        // box sum is then a true pixel sum (< 2^24), so the i32 arithmetic cannot overflow.
        let (l, b, h) = (self.l, self.b, self.l / 2);
        let left = |d: usize| x.saturating_sub(d);
        let [xt, xb] = self.xx;
        let dxx = box_sum(xt, xb, left(b), x + b) - 3 * box_sum(xt, xb, left(h), x + h);
        let [yt, yb, mt, mb] = self.yy;
        let (c0, c1) = (left(l - 1), x + l - 1);
        let dyy = box_sum(yt, yb, c0, c1) - 3 * box_sum(mt, mb, c0, c1);
        let [r0, r1, r2, r3] = self.xy;
        let dxy = box_sum(r0, r1, left(l), left(1)) + box_sum(r2, r3, x + 1, x + l)
            - box_sum(r0, r1, x + 1, x + l)
            - box_sum(r2, r3, left(l), left(1));
        (dxx, dyy, dxy)
    }

    /// det(H) of the area-normalized filters at column `x`: `Dxx*Dyy - (0.9*Dxy)^2`.
    pub(super) fn response(&self, x: usize) -> f32 {
        let (dxx, dyy, dxy) = self.derivatives(x);
        // Integer magnitudes stay below 2^24, so the conversions are exact.
        let fxx = dxx as f32 * self.inv_area;
        let fyy = dyy as f32 * self.inv_area;
        let wxy = 0.9 * (dxy as f32 * self.inv_area);
        fxx * fyy - wxy * wxy
    }

    /// Whether the trace `Dxx + Dyy` (the Laplacian) at column `x` is `>= 0`.
    pub(super) fn laplacian_positive(&self, x: usize) -> bool {
        let (dxx, dyy, _) = self.derivatives(x);
        dxx + dyy >= 0
    }
}

/// Responses around a candidate, indexed `[scale][row][column]`, each `-1..=1` around the centre.
pub(super) type Cube = [[[f32; 3]; 3]; 3];

/// Whether the centre of `cube` exceeds `threshold` and every one of its 26 neighbours.
pub(super) fn is_strict_maximum(cube: &Cube, threshold: f32) -> bool {
    let v = cube[1][1][1];
    if v.is_nan() || v <= threshold {
        return false;
    }
    let mut neighbours_ge = 0;
    for plane in cube {
        for row in plane {
            for &n in row {
                if n >= v {
                    neighbours_ge += 1;
                }
            }
        }
    }
    // The centre itself is the only value allowed to be >= v.
    neighbours_ge == 1
}

/// Offsets `(dx, dy, ds)` in samples of the extremum of the 3D quadratic fitted to `cube` by
/// central differences (Brown and Lowe), or `None` when the fit is singular or any offset exceeds
/// half a sample (the extremum belongs to a neighbour).
pub(super) fn refine(c: &Cube) -> Option<[f32; 3]> {
    let v = c[1][1][1];
    let gx = (c[1][1][2] - c[1][1][0]) / 2.0;
    let gy = (c[1][2][1] - c[1][0][1]) / 2.0;
    let gs = (c[2][1][1] - c[0][1][1]) / 2.0;
    let hxx = c[1][1][2] + c[1][1][0] - 2.0 * v;
    let hyy = c[1][2][1] + c[1][0][1] - 2.0 * v;
    let hss = c[2][1][1] + c[0][1][1] - 2.0 * v;
    let hxy = (c[1][2][2] - c[1][2][0] - c[1][0][2] + c[1][0][0]) / 4.0;
    let hxs = (c[2][1][2] - c[2][1][0] - c[0][1][2] + c[0][1][0]) / 4.0;
    let hys = (c[2][2][1] - c[2][0][1] - c[0][2][1] + c[0][0][1]) / 4.0;
    let h = [[hxx, hxy, hxs], [hxy, hyy, hys], [hxs, hys, hss]];
    let off = solve3(&h, [-gx, -gy, -gs])?;
    if off.iter().all(|o| o.is_finite() && *o >= -0.5 && *o <= 0.5) { Some(off) } else { None }
}

/// Determinant of a 3x3 matrix, expanded along the first row.
fn det3(m: &[[f32; 3]; 3]) -> f32 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// Solves `m * x = r` by Cramer's rule; `None` if `m` is singular or not finite.
fn solve3(m: &[[f32; 3]; 3], r: [f32; 3]) -> Option<[f32; 3]> {
    let d = det3(m);
    if !d.is_finite() || d == 0.0 {
        return None;
    }
    let mut x = [0.0; 3];
    for (k, xk) in x.iter_mut().enumerate() {
        let mut mk = *m;
        for (row, rv) in mk.iter_mut().zip(r) {
            row[k] = rv;
        }
        *xk = det3(&mk) / d;
    }
    Some(x)
}

/// SURF's sigma of a (possibly fractional) filter size: `1.2 * size / 9`.
pub(super) fn sigma_of_size(size: f32) -> f32 {
    1.2 * size / 9.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ring_holds_the_largest_filter() {
        assert_eq!(INTEGRAL_RING_ROWS, 52);
        assert_eq!(OCTAVES[0].first_sample(), 14);
        assert_eq!(OCTAVES[1].first_sample(), 26);
    }

    #[test]
    fn refine_finds_the_vertex_of_a_quadratic() {
        // f = -(x-0.2)^2 - 2(y+0.1)^2 - (s-0.3)^2 sampled at -1, 0, 1.
        let mut c: Cube = [[[0.0; 3]; 3]; 3];
        for (s, plane) in c.iter_mut().enumerate() {
            for (y, row) in plane.iter_mut().enumerate() {
                for (x, v) in row.iter_mut().enumerate() {
                    let (fx, fy, fs) = (x as f32 - 1.2, y as f32 - 0.9, s as f32 - 1.3);
                    *v = 10.0 - fx * fx - 2.0 * fy * fy - fs * fs;
                }
            }
        }
        let o = refine(&c).unwrap();
        assert!(
            (o[0] - 0.2).abs() < 1e-5 && (o[1] + 0.1).abs() < 1e-5 && (o[2] - 0.3).abs() < 1e-5
        );
        assert!(is_strict_maximum(&c, 0.0));
        assert!(refine(&[[[0.0; 3]; 3]; 3]).is_none());
    }
}
