//! The matrix-free reduced camera system against a dense f64 reference: gradient,
//! preconditioner blocks and the Schur product, in segmented (rig) mode with offsets, Huber
//! weights, fixed rigs and points, and observations with and without depth.
//!
//! Test code only: this file is compiled under #[cfg(test)] (see the `mod` line that includes it).

extern crate std;

use nalgebra::{
    Matrix3, Point2, Point3, SMatrix, SVector, Translation3, UnitQuaternion, Vector3, Vector6,
};

use super::linalg::{PoseMatrix, sym6_index};
use super::observation_passes::DIAG_FLOOR;
use super::solver_state::Phase;
use super::{BaParams, BaStatus, BundleAdjuster, CameraId};
use crate::geometry::{PinholeCamera, Pose, se3_adjoint};

const RIGS: usize = 4;
const N: usize = 6 * RIGS;
type Ba = BundleAdjuster<RIGS, 8, 32, 256>;

fn camera() -> PinholeCamera {
    PinholeCamera::new(262.5, 262.5, 159.75, 119.75, 320, 240).unwrap()
}

fn pose(t: [f32; 3], r: [f32; 3]) -> Pose {
    Pose::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_scaled_axis(Vector3::new(r[0], r[1], r[2])),
    )
}

/// Four rigs (rig 0 fixed); rigs 1 and 3 carry two cameras each, one at an offset. Twenty
/// points (point 0 fixed), seen by every camera with a per-point observation order grouped by
/// rig, every other one with depth, a few far outside the Huber threshold.
fn build(ba: &mut Ba) -> [CameraId; 6] {
    let cam = camera();
    let rig_poses = [
        pose([0.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
        pose([-0.1, 0.02, 0.01], [0.01, -0.03, 0.0]),
        pose([-0.2, -0.01, 0.03], [-0.02, 0.05, 0.01]),
        pose([-0.3, 0.0, -0.02], [0.0, 0.08, -0.02]),
    ];
    let rigs: std::vec::Vec<_> =
        rig_poses.iter().enumerate().map(|(i, t)| ba.add_rig(t, i == 0).unwrap()).collect();
    let identity = Pose::identity();
    let cams = [
        ba.add_camera(rigs[0], &identity).unwrap(),
        ba.add_camera(rigs[1], &identity).unwrap(),
        ba.add_camera(rigs[1], &pose([0.05, 0.0, 0.01], [0.0, 0.04, 0.0])).unwrap(),
        ba.add_camera(rigs[2], &identity).unwrap(),
        ba.add_camera(rigs[3], &pose([-0.03, 0.01, 0.0], [0.02, 0.0, 0.01])).unwrap(),
        ba.add_camera(rigs[3], &pose([0.04, -0.02, 0.02], [0.0, -0.05, 0.02])).unwrap(),
    ];
    for i in 0..20u16 {
        let f = f32::from(i);
        let p_true = Point3::new(-0.6 + 0.07 * f, 0.3 * (f * 0.7).sin(), 1.5 + 0.1 * f);
        let p_start = p_true + Vector3::new(0.01, -0.02, 0.015) * (f * 1.3).cos();
        let id = ba.add_point(&p_start, i == 0).unwrap();
        for (k, &c) in cams.iter().enumerate() {
            let t_cw = ba.camera_pose(c).unwrap();
            let p_c = t_cw * p_true;
            let uv = cam.project(&p_c).unwrap();
            let off = if (usize::from(i) + k) % 11 == 0 { 8.0 } else { 0.3 * (f + k as f32).sin() };
            let depth = (usize::from(i) + k).is_multiple_of(2).then_some(p_c.z * 1.01);
            ba.add_observation(id, c, Point2::new(uv.x + off, uv.y - 0.5 * off), depth).unwrap();
        }
    }
    cams
}

/// Steps one unit at a time until `stop` holds for the phase.
fn run_until(ba: &mut Ba, stop: impl Fn(Phase) -> bool) {
    for _ in 0..1_000_000 {
        if stop(ba.state.phase) {
            return;
        }
        ba.step(1).unwrap();
    }
    panic!("phase not reached");
}

struct Dense {
    s: SMatrix<f64, N, N>,
    b: SVector<f64, N>,
}

/// The damped, reduced system built densely in f64 from the solver's own linearization point.
fn dense(ba: &Ba) -> Dense {
    let lambda = f64::from(ba.state.lambda);
    let p = &ba.problem;
    let mut hss = SMatrix::<f64, N, N>::zeros();
    let mut gs = SVector::<f64, N>::zeros();
    let mut schur = SMatrix::<f64, N, N>::zeros();
    let mut schur_b = SVector::<f64, N>::zeros();
    for l in 0..usize::from(p.n_points) {
        let (start, end) = p.obs_range(l);
        let mut hll = Matrix3::<f64>::zeros();
        let mut gl = Vector3::<f64>::zeros();
        let mut hsl = SMatrix::<f64, N, 3>::zeros();
        for o in &p.obs[start..end] {
            let c = usize::from(o.camera);
            let rig = p.rig_of(c);
            let cam = &ba.work.cam_pose[ba.state.lin_slot][c];
            let t = ba.state.model.terms(cam, &p.point[l], o).unwrap();
            let ad = se3_adjoint(&p.cam_offset[c].to_pose()).cast::<f64>();
            for row in t.rows() {
                let a = Vector3::from(row.a).cast::<f64>();
                let pc = Vector3::from(t.p_c).cast::<f64>();
                let jc = Vector6::new(a.x, a.y, a.z, 0.0, 0.0, 0.0)
                    + Vector6::from_iterator(
                        [0.0, 0.0, 0.0].into_iter().chain(pc.cross(&a).iter().copied()),
                    );
                let js = ad.transpose() * jc;
                let jl = Vector3::from(PoseMatrix::rotate_back(cam, &row.a)).cast::<f64>();
                let (w, e) = (f64::from(row.w), f64::from(row.e));
                if !p.rig_fixed[rig] {
                    let mut big = SVector::<f64, N>::zeros();
                    big.fixed_rows_mut::<6>(6 * rig).copy_from(&js);
                    hss += big * big.transpose() * w;
                    gs += big * (w * e);
                    hsl += big * jl.transpose() * w;
                }
                hll += jl * jl.transpose() * w;
                gl += jl * (w * e);
            }
        }
        if p.point_fixed[l] {
            continue;
        }
        let floor = hll.diagonal().max() * f64::from(DIAG_FLOOR);
        let mut damped = hll;
        for k in 0..3 {
            damped[(k, k)] += lambda * (hll[(k, k)] + floor);
        }
        let inv = damped.try_inverse().unwrap();
        schur += hsl * inv * hsl.transpose();
        schur_b += hsl * inv * gl;
    }
    let mut s = hss - schur;
    for r in 0..RIGS {
        let block = hss.fixed_view::<6, 6>(6 * r, 6 * r).diagonal();
        let floor = block.max() * f64::from(DIAG_FLOOR);
        for k in 0..6 {
            s[(6 * r + k, 6 * r + k)] += lambda * (block[k] + floor);
        }
    }
    Dense { s, b: gs - schur_b }
}

fn rel(a: f64, b: f64, scale: f64) -> f64 {
    (a - b).abs() / scale
}

/// The test problem started with `lambda_init` 1e-2 and run until its first PCG begins (the
/// reduced system assembled, nothing solved yet).
fn at_first_pcg_start() -> std::boxed::Box<Ba> {
    let mut ba = std::boxed::Box::new(Ba::new());
    build(&mut ba);
    let params = BaParams { lambda_init: 1e-2, ..BaParams::DEFAULT };
    ba.start(&camera(), &params).unwrap();
    run_until(&mut ba, |ph| ph == Phase::PcgStart(0));
    ba
}

#[test]
fn reduced_system_matches_dense_reference() {
    let mut ba = at_first_pcg_start();
    let d = dense(&ba);
    assert!(!ba.work.rig_active[0] && (1..RIGS).all(|r| ba.work.rig_active[r]));
    // Gradient (held in rig_r before PCG starts) and preconditioner blocks L L^T.
    let scale_b = d.b.amax();
    let scale_s = d.s.amax();
    for r in 1..RIGS {
        for i in 0..6 {
            let got = f64::from(ba.work.rig_r[r][i]);
            assert!(rel(got, d.b[6 * r + i], scale_b) < 1e-4, "b rig {r} {i}");
            for j in 0..=i {
                let l = &ba.work.rig_precond[r];
                let llt: f64 = (0..=j)
                    .map(|k| f64::from(l[sym6_index(i, k)]) * f64::from(l[sym6_index(j, k)]))
                    .sum();
                let want = d.s[(6 * r + i, 6 * r + j)];
                assert!(rel(llt, want, scale_s) < 1e-4, "precond rig {r} ({i},{j})");
            }
        }
    }
    // The matrix-free product against S p.
    let mut p = SVector::<f64, N>::zeros();
    for r in 1..RIGS {
        for k in 0..6 {
            let v = ((r * 6 + k) as f32 * 0.37).sin() * if k < 3 { 0.01 } else { 0.003 };
            ba.work.rig_p[r][k] = v;
            p[6 * r + k] = f64::from(v);
        }
    }
    ba.state.phase = Phase::ProductMap(0);
    run_until(&mut ba, |ph| matches!(ph, Phase::Update(0) | Phase::TrialRigs(_)));
    let sp = d.s * p;
    let scale = sp.amax();
    for r in 1..RIGS {
        for k in 0..6 {
            let got = f64::from(ba.work.rig_q[r][k]);
            assert!(
                rel(got, sp[6 * r + k], scale) < 1e-4,
                "S p rig {r} {k}: {got} {}",
                sp[6 * r + k]
            );
        }
    }
}

#[test]
fn pcg_solves_the_reduced_system() {
    let mut ba = std::boxed::Box::new(Ba::new());
    build(&mut ba);
    let params = BaParams {
        lambda_init: 1e-2,
        pcg_max_iterations: 200,
        pcg_relative_tolerance: 1e-6,
        ..BaParams::DEFAULT
    };
    ba.start(&camera(), &params).unwrap();
    run_until(&mut ba, |ph| ph == Phase::PcgStart(0));
    let d = dense(&ba);
    run_until(&mut ba, |ph| matches!(ph, Phase::TrialRigs(_)));
    // The preconditioned system is well conditioned here (eigenvalues 0.26 to 1.5): a few
    // iterations reach the tolerance, far fewer than the 18 unknowns.
    assert!(ba.state.pcg.iteration < 18, "{} iterations", ba.state.pcg.iteration);
    assert!(ba.state.pcg_last_ratio <= 1e-6);
    let sub = d.s.fixed_view::<18, 18>(6, 6).into_owned();
    let x = sub.try_inverse().unwrap() * (-d.b.fixed_rows::<18>(6));
    for r in 1..RIGS {
        for k in 0..6 {
            let got = f64::from(ba.work.rig_x[r][k]);
            assert!((got - x[6 * (r - 1) + k]).abs() < 1e-4 * x.amax(), "x rig {r} {k}");
        }
    }
}

#[test]
fn product_is_the_dense_matrix_column_by_column() {
    let mut ba = at_first_pcg_start();
    let d = dense(&ba);
    let mut m = SMatrix::<f64, 18, 18>::zeros();
    for col in 0..18 {
        for r in 0..RIGS {
            ba.work.rig_p[r] = [0.0; 6];
        }
        ba.work.rig_p[1 + col / 6][col % 6] = 1.0;
        ba.state.phase = Phase::ProductMap(0);
        run_until(&mut ba, |ph| matches!(ph, Phase::Update(0) | Phase::TrialRigs(_)));
        for row in 0..18 {
            m[(row, col)] = f64::from(ba.work.rig_q[1 + row / 6][row % 6]);
        }
    }
    let sub = d.s.fixed_view::<18, 18>(6, 6).into_owned();
    // Symmetric and equal to the dense S to f32 precision.
    assert!((m - m.transpose()).amax() < 1e-6 * sub.amax());
    assert!((m - sub).amax() < 1e-6 * sub.amax());
}

/// Steps `ba` one unit at a time to the end of its solve, checking at every state that a step of
/// one unit fewer than `units_before_finish` leaves the solve running; returns the phase the solve
/// ended from and whether a step of exactly the bound finished it somewhere.
fn check_bound_to_the_end(ba: &mut Ba) -> (Phase, bool) {
    let mut tight = false;
    for state in 0.. {
        let bound = ba.units_before_finish();
        assert!(bound >= 1, "state {state}: a running solve needs at least one unit");
        let quota = u32::try_from(bound).unwrap();
        let mut probe = ba.clone();
        let status = probe.step(quota - 1).unwrap();
        assert_eq!(status, BaStatus::Running, "state {state}, {:?}", ba.state.phase);
        if let BaStatus::Finished(_) = probe.step(1).unwrap() {
            tight = true;
        }
        let phase = ba.state.phase;
        if let BaStatus::Finished(_) = ba.step(1).unwrap() {
            assert_eq!(ba.units_before_finish(), 0, "finished");
            return (phase, tight);
        }
    }
    unreachable!()
}

/// `units_before_finish` is a promise the host's parallel back end relies on: from every state
/// of a solve, a step of one unit fewer than the bound leaves the solve running. The bound is also
/// reached (a step of exactly the bound finishes the solve somewhere), and solves ending at each
/// of the decision, the applied step and the reduction are checked.
#[test]
fn no_step_short_of_the_bound_finishes_the_solve() {
    let solve = |params: &BaParams, before_start: fn(&mut Ba)| {
        let mut ba = Ba::new();
        build(&mut ba);
        before_start(&mut ba);
        assert_eq!(ba.units_before_finish(), 0, "not started");
        ba.start(&camera(), params).unwrap();
        ba
    };
    let mut ends = std::vec::Vec::new();
    for n in [1, 3, 10] {
        let params = BaParams { max_iterations: n, ..BaParams::DEFAULT };
        ends.push(check_bound_to_the_end(&mut solve(&params, |_| {})));
    }
    // A trial rejected on the last iteration ends the solve at the decision: run to the first
    // trial, make the current cost unbeatable, and allow a single iteration.
    let mut ba = solve(&BaParams { max_iterations: 1, ..BaParams::DEFAULT }, |_| {});
    run_until(&mut ba, |p| p == Phase::TrialRigs(0));
    ba.state.cost = 0.0;
    ends.push(check_bound_to_the_end(&mut ba));
    // Every rig and point fixed: nothing to optimize, found at the reduction.
    let mut ba = Ba::new();
    let rig = ba.add_rig(&Pose::identity(), true).unwrap();
    let c = ba.add_camera(rig, &Pose::identity()).unwrap();
    let p = ba.add_point(&Point3::new(0.1, 0.0, 2.0), true).unwrap();
    ba.add_observation(p, c, Point2::new(173.0, 119.75), Some(2.0)).unwrap();
    ba.start(&camera(), &BaParams::DEFAULT).unwrap();
    ends.push(check_bound_to_the_end(&mut ba));
    assert!(ends.iter().all(|&(_, tight)| tight), "the bound is reached in every solve: {ends:?}");
    let ended = |f: fn(Phase) -> bool| ends.iter().any(|&(p, _)| f(p));
    assert!(ended(|p| matches!(p, Phase::ApplyRigs(_))), "{ends:?}");
    assert!(ended(|p| p == Phase::Decide), "{ends:?}");
    assert!(ended(|p| matches!(p, Phase::ReduceRigs(_) | Phase::ReduceCams(_))), "{ends:?}");
}
