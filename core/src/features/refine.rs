//! The per-candidate math of the detector, shared by the strip detector and the tests' full-frame
//! reference: the strict 3x3x3 maximum test and the 3D quadratic refinement of a response cube.

/// Responses around a candidate, indexed `[scale][row][column]`, each `-1..=1` around the centre.
pub(super) type Cube = [[[f32; 3]; 3]; 3];

/// Whether the centre of `cube` exceeds `threshold` and is the maximum of its 26 neighbours:
/// strictly greater than those before it in `(scale, row, column)` order, at least equal to those
/// after it. The tie rule keeps exactly one sample of a plateau of equal responses (such as the
/// two samples either side of a symmetric blob centred between them), where a strict test on all
/// sides would drop both.
pub(super) fn is_maximum(cube: &Cube, threshold: f32) -> bool {
    let v = cube[1][1][1];
    !v.is_nan() && v > threshold && cube.iter().enumerate().all(|(s, p)| plane_below(v, p, s))
}

/// Whether every value of `plane`, the 3x3 block of scale index `s` (0 below the centre's layer,
/// 1 its own, 2 above) of a cube centred on `v`, lets `v` be the maximum under the rule of
/// [`is_maximum`]; the block's own centre is skipped when `s == 1`.
pub(super) fn plane_below(v: f32, plane: &[[f32; 3]; 3], s: usize) -> bool {
    plane.iter().enumerate().all(|(r, row)| {
        row.iter().enumerate().all(|(c, &n)| match (s, r, c).cmp(&(1, 1, 1)) {
            core::cmp::Ordering::Less => n < v,
            core::cmp::Ordering::Equal => true,
            core::cmp::Ordering::Greater => n <= v,
        })
    })
}

/// Offsets `(dx, dy, ds)` in samples of the extremum of the 3D quadratic fitted to `cube` by
/// central differences (Brown and Lowe), or `None` when the fit is singular or any offset exceeds
/// one sample (the vertex lies outside the cube: the fit is not to be trusted).
///
/// One sample, as OpenCV's SURF accepts, not Lowe's half sample: the centre is the unique
/// maximum of its cube (see [`is_maximum`]), so no neighbour reports the same extremum, and a
/// vertex past half a sample is what a peak between two samples gives (the scale terms of the
/// fit push a blob centred exactly between two samples about 0.505 samples towards the other).
/// Dropping those would lose the features that fall between samples.
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
    if off.iter().all(|o| o.is_finite() && *o >= -1.0 && *o <= 1.0) { Some(off) } else { None }
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
        assert!(is_maximum(&c, 0.0));
        assert!(refine(&[[[0.0; 3]; 3]; 3]).is_none());
    }

    #[test]
    fn of_two_equal_samples_only_the_first_is_a_maximum() {
        let mut c: Cube = [[[0.0; 3]; 3]; 3];
        c[1][1][1] = 5.0;
        assert!(is_maximum(&c, 1.0));
        assert!(!is_maximum(&c, 5.0));
        // An equal neighbour after the centre (below it, right of it, in the layer above) is
        // allowed; one before it is not.
        for (s, r, k) in [(1, 2, 1), (1, 1, 2), (2, 0, 0)] {
            let mut d = c;
            d[s][r][k] = 5.0;
            assert!(is_maximum(&d, 1.0), "{s} {r} {k}");
            d[s][r][k] = 5.5;
            assert!(!is_maximum(&d, 1.0), "{s} {r} {k}");
        }
        for (s, r, k) in [(1, 0, 1), (1, 1, 0), (0, 2, 2)] {
            let mut d = c;
            d[s][r][k] = 5.0;
            assert!(!is_maximum(&d, 1.0), "{s} {r} {k}");
        }
        c[1][1][1] = f32::NAN;
        assert!(!is_maximum(&c, 1.0));
    }
}
