//! 2x2 linear maps and the fixed affine bank (the paper's "transformation network").
//!
//! A map is `[[a, b], [c, d]]` acting on a column vector `(x, y)` as `(a x + b y, c x + d y)`.
//! Every operation uses single f32 multiplies and adds (never `mul_add`), so host and Cortex-M
//! give the same bits.

/// A 2x2 linear map, row-major: `m[row][col]`.
pub type Mat2 = [[f32; 2]; 2];

/// The identity map.
pub const IDENTITY: Mat2 = [[1.0, 0.0], [0.0, 1.0]];

/// `cos` and `sin` of -10, -5, 0, 5 and 10 degrees, as f32 literals (no run-time trigonometry).
const ROTATIONS_COS_SIN: [(f32, f32); 5] = [
    (0.984_807_7, -0.173_648_18),
    (0.996_194_7, -0.087_155_74),
    (1.0, 0.0),
    (0.996_194_7, 0.087_155_74),
    (0.984_807_7, 0.173_648_18),
];

/// Isotropic-plus-anisotropic scales of the bank: `(sx, sy)`.
const SCALES: [(f32, f32); 3] = [(0.9, 0.9), (1.0, 1.0), (1.1, 1.1)];

/// Shears of the bank (`x += k y`).
const SHEARS: [f32; 3] = [-0.1, 0.0, 0.1];

/// Number of maps in [`AFFINE_BANK`]: 3 scales x 5 rotations x 3 shears.
pub const AFFINE_BANK_LEN: usize = SCALES.len() * ROTATIONS_COS_SIN.len() * SHEARS.len();

/// The transformation network: `A = R(theta) * S(s, s) * Sh(k)` for scales `s` in
/// {0.9, 1.0, 1.1}, in-plane rotations `theta` in {-10, -5, 0, 5, 10} degrees and shears `k` in
/// {-0.1, 0, 0.1}, where `R` is the counter-clockwise rotation in image axes (x right, y down, so
/// it turns clockwise on screen), `S` the diagonal scale and `Sh = [[1, k], [0, 1]]`.
///
/// Ordered scale-major, then rotation, then shear; index 22 (`s = 1`, `theta = 0`, `k = 0`) is the
/// identity. Built at compile time with plain f32 products.
pub const AFFINE_BANK: [Mat2; AFFINE_BANK_LEN] = build_bank();

/// Index of the identity in [`AFFINE_BANK`].
pub const AFFINE_BANK_IDENTITY: usize = 22;

const fn build_bank() -> [Mat2; AFFINE_BANK_LEN] {
    let mut bank = [IDENTITY; AFFINE_BANK_LEN];
    let mut i = 0;
    while i < AFFINE_BANK_LEN {
        let (sx, sy) = SCALES[i / 15];
        let (c, s) = ROTATIONS_COS_SIN[(i / 3) % 5];
        let k = SHEARS[i % 3];
        // R * S = [[c sx, -s sy], [s sx, c sy]]; times [[1, k], [0, 1]].
        let rs = [[c * sx, -s * sy], [s * sx, c * sy]];
        bank[i] = [[rs[0][0], rs[0][0] * k + rs[0][1]], [rs[1][0], rs[1][0] * k + rs[1][1]]];
        i += 1;
    }
    bank
}

/// `a * b`.
pub fn mat_mul(a: &Mat2, b: &Mat2) -> Mat2 {
    [
        [a[0][0] * b[0][0] + a[0][1] * b[1][0], a[0][0] * b[0][1] + a[0][1] * b[1][1]],
        [a[1][0] * b[0][0] + a[1][1] * b[1][0], a[1][0] * b[0][1] + a[1][1] * b[1][1]],
    ]
}

/// `m * (x, y)`.
pub fn mat_apply(m: &Mat2, (x, y): (f32, f32)) -> (f32, f32) {
    (m[0][0] * x + m[0][1] * y, m[1][0] * x + m[1][1] * y)
}

/// The inverse of `m`, or `None` when it is singular, badly conditioned (|det| < 1e-3) or not
/// finite.
pub fn mat_inverse(m: &Mat2) -> Option<Mat2> {
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    if !det.is_finite() || det.abs() < 1e-3 {
        return None;
    }
    let inv = 1.0 / det;
    Some([[m[1][1] * inv, -m[0][1] * inv], [-m[1][0] * inv, m[0][0] * inv]])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bank_identity_and_shape() {
        assert_eq!(AFFINE_BANK[AFFINE_BANK_IDENTITY], IDENTITY);
        // Rotation by +10 deg at scale 1.1, no shear: determinant 1.21.
        let m = AFFINE_BANK[15 * 2 + 3 * 4 + 1];
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        assert!((det - 1.21).abs() < 1e-5);
        assert!((m[1][0] - 1.1 * 0.173_648_18).abs() < 1e-6);
    }

    #[test]
    fn inverse_round_trip() {
        for m in AFFINE_BANK {
            let p = mat_mul(&m, &mat_inverse(&m).unwrap());
            for (r, row) in p.iter().enumerate() {
                for (c, &v) in row.iter().enumerate() {
                    let want = if r == c { 1.0 } else { 0.0 };
                    assert!((v - want).abs() < 1e-5);
                }
            }
        }
        assert!(mat_inverse(&[[1.0, 2.0], [2.0, 4.0]]).is_none());
        assert!(mat_inverse(&[[f32::NAN, 0.0], [0.0, 1.0]]).is_none());
    }
}
