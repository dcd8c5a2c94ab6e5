//! The eigenvectors of a symmetric 3 x 3 matrix by cyclic Jacobi rotations: f32 arithmetic and
//! square roots only (`ferroslam_fpu::sqrtf`), so the host and the board give the same bits. A
//! plane's normal is the eigenvector of its points' scatter with the smallest eigenvalue.

/// Sweeps over the three off-diagonal entries at most: Jacobi converges quadratically, and a
/// 3 x 3 scatter is diagonal to f32 precision after four or five.
const SWEEPS: usize = 8;

/// The eigenvalues of the symmetric matrix `a` (row-major, only its symmetric part read) in
/// ascending order, and the unit eigenvector of the smallest. `None` when an entry is not finite.
/// Cost: at most [`SWEEPS`] x 3 rotations of about 60 operations each.
pub(super) fn smallest_eigenvector(a: [[f32; 3]; 3]) -> Option<([f32; 3], [f32; 3])> {
    if a.iter().flatten().any(|v| !v.is_finite()) {
        return None;
    }
    let mut a = a;
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..SWEEPS {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        let diag = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if off <= f32::EPSILON * f32::EPSILON * diag {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            rotate(&mut a, &mut v, p, q);
        }
    }
    let mut order = [0, 1, 2];
    order.sort_unstable_by(|&i, &j| a[i][i].total_cmp(&a[j][j]).then(i.cmp(&j)));
    let values = order.map(|i| a[i][i]);
    let k = order[0];
    let e = [v[0][k], v[1][k], v[2][k]];
    let norm = ferroslam_fpu::sqrtf(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
    if norm.is_nan() || norm <= 0.0 {
        return None;
    }
    Some((e.map(|c| c / norm), values))
}

/// One Jacobi rotation zeroing `a[p][q]` (`a <- J^T a J`, `v <- v J`), as Numerical Recipes'
/// `jacobi`: `t = sgn(theta) / (|theta| + sqrt(theta^2 + 1))`, `theta = (a_qq - a_pp) / 2 a_pq`.
fn rotate(a: &mut [[f32; 3]; 3], v: &mut [[f32; 3]; 3], p: usize, q: usize) {
    let apq = a[p][q];
    if apq == 0.0 {
        return;
    }
    let theta = (a[q][q] - a[p][p]) / (2.0 * apq);
    // A huge theta squares to infinity: t is then 0 to f32 precision, nothing to rotate.
    let t = theta.signum() / (theta.abs() + ferroslam_fpu::sqrtf(theta * theta + 1.0));
    if !t.is_finite() || t == 0.0 {
        return;
    }
    let c = 1.0 / ferroslam_fpu::sqrtf(t * t + 1.0);
    let s = t * c;
    for row in a.iter_mut() {
        let (kp, kq) = (row[p], row[q]);
        row[p] = c * kp - s * kq;
        row[q] = s * kp + c * kq;
    }
    // p < q: row p is in the first half of the split, row q opens the second.
    let (first, second) = a.split_at_mut(q);
    if let (Some(row_p), Some(row_q)) = (first.get_mut(p), second.first_mut()) {
        for (pk, qk) in row_p.iter_mut().zip(row_q.iter_mut()) {
            let (x, y) = (*pk, *qk);
            *pk = c * x - s * y;
            *qk = s * x + c * y;
        }
    }
    for row in v.iter_mut() {
        let (kp, kq) = (row[p], row[q]);
        row[p] = c * kp - s * kq;
        row[q] = s * kp + c * kq;
    }
}
