//! Every analytic Jacobian of the geometry module against central differences, through one
//!
//! Test code only: this file is compiled under #[cfg(test)] (see the `mod` line that includes it).
//! generic routine ([`check`]) at many deterministic random points.
//!
//! SO(3)/SE(3) functions are generic, so their cases run in f64 with tight tolerances (their f32
//! precision is tested against f64 next to the code). The camera is f32: its cases difference the
//! f32 code itself, with power-of-two steps on f32-representable inputs so the step is exact, and
//! tolerances sized for f32 rounding (about 1e-4 of the Jacobian's largest entry).

extern crate std;

use nalgebra::{Isometry3, Point2, Point3, SMatrix, SVector, Vector3, Vector6};

use super::camera::PinholeCamera;
use super::se3::{Pose, se3_exp, se3_left_jacobian, se3_left_jacobian_inv, se3_log};
use super::so3::{so3_exp, so3_left_jacobian, so3_left_jacobian_inv, so3_log};
use super::test_support::{random_rotation_vector, random_twist, random_vector3};
use crate::test_rng::TestRng;

/// A function with an analytic Jacobian, and how to sample and difference it.
trait JacobianCase<const N: usize, const M: usize> {
    /// Shown on failure.
    const NAME: &'static str;
    /// Bound on `max |numeric - analytic| / max |analytic|`.
    const REL_TOL: f64;
    /// Central-difference step for every input coordinate, unless [`Self::step`] says otherwise.
    const STEP: f64;
    /// What stays fixed while the input varies (a camera, a pose, a linearization point).
    type Context;
    /// The `i`-th sample: context and the input at which to differentiate.
    fn sample(rng: &mut TestRng, i: usize) -> (Self::Context, SVector<f64, N>);
    /// The central-difference step at `x`.
    fn step(_ctx: &Self::Context, _x: &SVector<f64, N>) -> f64 {
        Self::STEP
    }
    /// The input as the function sees it (f32 cases round to f32), so the true step is known.
    fn quantize(x: &SVector<f64, N>) -> SVector<f64, N> {
        *x
    }
    /// The function.
    fn value(ctx: &Self::Context, x: &SVector<f64, N>) -> SVector<f64, M>;
    /// Its analytic Jacobian, `M x N`.
    fn analytic(ctx: &Self::Context, x: &SVector<f64, N>) -> SMatrix<f64, M, N>;
}

/// Checks `C`'s analytic Jacobian against central differences at `samples` points; returns the
/// worst relative error seen.
fn check<C: JacobianCase<N, M>, const N: usize, const M: usize>(samples: usize) -> f64 {
    let mut rng = TestRng::new(0x00C0_FFEE);
    let mut worst = 0.0f64;
    for i in 0..samples {
        let (ctx, x0) = C::sample(&mut rng, i);
        let x = C::quantize(&x0);
        let analytic = C::analytic(&ctx, &x);
        let mut numeric = SMatrix::<f64, M, N>::zeros();
        let h = C::step(&ctx, &x);
        for k in 0..N {
            let (mut plus, mut minus) = (x, x);
            plus[k] += h;
            minus[k] -= h;
            let (plus, minus) = (C::quantize(&plus), C::quantize(&minus));
            let diff = C::value(&ctx, &plus) - C::value(&ctx, &minus);
            numeric.set_column(k, &(diff / (plus[k] - minus[k])));
        }
        let scale = analytic.abs().max().max(1e-12);
        let err = (numeric - analytic).abs().max() / scale;
        assert!(
            err <= C::REL_TOL,
            "{}: sample {i} at {x:?}: relative error {err:e}\nanalytic {analytic}numeric {numeric}",
            C::NAME
        );
        worst = worst.max(err);
    }
    std::println!("{}: worst relative error {worst:.2e} over {samples} samples", C::NAME);
    worst
}

fn to_f32<const N: usize>(x: &SVector<f64, N>) -> SVector<f64, N> {
    x.map(|v| f64::from(v as f32))
}

/// The power of two at or below `v > 0`: steps that keep f32 inputs exactly representable.
fn pow2_floor(v: f64) -> f64 {
    f64::from_bits(v.to_bits() & 0xFFF0_0000_0000_0000)
}

fn v3(x: &SVector<f64, 3>) -> Vector3<f64> {
    *x
}

fn uv64(uv: Point2<f32>) -> SVector<f64, 2> {
    uv.coords.cast()
}

/// A camera with random intrinsics around a VGA sensor's.
fn random_camera(rng: &mut TestRng) -> PinholeCamera {
    let f = rng.uniform(200.0, 800.0);
    let fy = f * rng.uniform(0.95, 1.05);
    let (cx, cy) = (rng.uniform(300.0, 340.0), rng.uniform(220.0, 260.0));
    PinholeCamera::new(f as f32, fy as f32, cx as f32, cy as f32, 640, 480).unwrap()
}

/// A camera-frame point in a 100-degree-wide frustum, 0.3 to 6 m deep.
fn random_point_in_view(rng: &mut TestRng) -> Vector3<f64> {
    let z = rng.uniform(0.3, 6.0);
    Vector3::new(z * rng.uniform(-0.6, 0.6), z * rng.uniform(-0.6, 0.6), z)
}

struct ProjectWrtPoint;
impl JacobianCase<3, 2> for ProjectWrtPoint {
    const NAME: &'static str = "d(uv)/d(p_c)";
    const REL_TOL: f64 = 1e-3;
    const STEP: f64 = 1.0 / 1024.0;
    type Context = PinholeCamera;
    fn sample(rng: &mut TestRng, _: usize) -> (PinholeCamera, SVector<f64, 3>) {
        (random_camera(rng), random_point_in_view(rng))
    }
    /// About depth / 256: curvature and f32 rounding of uv both scale with the depth.
    fn step(_: &PinholeCamera, x: &SVector<f64, 3>) -> f64 {
        pow2_floor(x.z / 256.0)
    }
    fn quantize(x: &SVector<f64, 3>) -> SVector<f64, 3> {
        to_f32(x)
    }
    fn value(cam: &PinholeCamera, x: &SVector<f64, 3>) -> SVector<f64, 2> {
        uv64(cam.project(&Point3::from(x.cast())).unwrap())
    }
    fn analytic(cam: &PinholeCamera, x: &SVector<f64, 3>) -> SMatrix<f64, 2, 3> {
        cam.project_with_jacobian(&Point3::from(x.cast())).unwrap().1.cast()
    }
}

struct BackProjectWrtUvDepth;
impl JacobianCase<3, 3> for BackProjectWrtUvDepth {
    const NAME: &'static str = "d(p_c)/d(u, v, depth)";
    const REL_TOL: f64 = 1e-3;
    // Linear in u, v and bilinear with depth: central differences are exact, so a long step
    // only shrinks the rounding noise.
    const STEP: f64 = 1.0 / 16.0;
    type Context = PinholeCamera;
    fn sample(rng: &mut TestRng, _: usize) -> (PinholeCamera, SVector<f64, 3>) {
        let cam = random_camera(rng);
        let x = SVector::from([
            rng.uniform(0.0, 639.0),
            rng.uniform(0.0, 479.0),
            rng.uniform(0.3, 6.0),
        ]);
        (cam, x)
    }
    fn quantize(x: &SVector<f64, 3>) -> SVector<f64, 3> {
        to_f32(x)
    }
    fn value(cam: &PinholeCamera, x: &SVector<f64, 3>) -> SVector<f64, 3> {
        cam.back_project(x.x as f32, x.y as f32, x.z as f32).coords.cast()
    }
    fn analytic(cam: &PinholeCamera, x: &SVector<f64, 3>) -> SMatrix<f64, 3, 3> {
        cam.back_project_with_jacobian(x.x as f32, x.y as f32, x.z as f32).1.cast()
    }
}

/// A camera, a world-to-camera pose and a world point the pose sees.
type WorldScene = (PinholeCamera, Isometry3<f64>, Point3<f32>);

fn random_scene(rng: &mut TestRng, i: usize) -> WorldScene {
    let cam = random_camera(rng);
    let t_cw = se3_exp(&random_twist(rng, i));
    let p_w = t_cw.inverse() * Point3::from(random_point_in_view(rng));
    (cam, t_cw, p_w.cast())
}

struct ProjectWrtPose;
impl JacobianCase<6, 2> for ProjectWrtPose {
    const NAME: &'static str = "d(uv)/d(xi), t_cw <- exp(xi) t_cw";
    const REL_TOL: f64 = 1e-3;
    const STEP: f64 = 1e-3;
    type Context = WorldScene;
    fn sample(rng: &mut TestRng, i: usize) -> (WorldScene, SVector<f64, 6>) {
        (random_scene(rng, i), Vector6::zeros())
    }
    fn value((cam, t_cw, p_w): &WorldScene, xi: &SVector<f64, 6>) -> SVector<f64, 2> {
        let perturbed: Pose = (se3_exp(xi) * t_cw).cast();
        uv64(cam.project_world(&perturbed, p_w).unwrap())
    }
    fn analytic((cam, t_cw, p_w): &WorldScene, _: &SVector<f64, 6>) -> SMatrix<f64, 2, 6> {
        let proj = cam.project_world_with_jacobians(&t_cw.cast(), p_w).unwrap();
        proj.d_uv_d_xi.cast()
    }
}

struct ProjectWrtWorldPoint;
impl JacobianCase<3, 2> for ProjectWrtWorldPoint {
    const NAME: &'static str = "d(uv)/d(p_w)";
    const REL_TOL: f64 = 1e-3;
    const STEP: f64 = 1.0 / 1024.0;
    type Context = (PinholeCamera, Pose);
    fn sample(rng: &mut TestRng, i: usize) -> ((PinholeCamera, Pose), SVector<f64, 3>) {
        let (cam, t_cw, p_w) = random_scene(rng, i);
        ((cam, t_cw.cast()), p_w.coords.cast())
    }
    fn step((_, t_cw): &(PinholeCamera, Pose), x: &SVector<f64, 3>) -> f64 {
        pow2_floor((t_cw.cast::<f64>() * Point3::from(*x)).z / 256.0)
    }
    fn quantize(x: &SVector<f64, 3>) -> SVector<f64, 3> {
        to_f32(x)
    }
    fn value((cam, t_cw): &(PinholeCamera, Pose), x: &SVector<f64, 3>) -> SVector<f64, 2> {
        uv64(cam.project_world(t_cw, &Point3::from(x.cast())).unwrap())
    }
    fn analytic((cam, t_cw): &(PinholeCamera, Pose), x: &SVector<f64, 3>) -> SMatrix<f64, 2, 3> {
        let proj = cam.project_world_with_jacobians(t_cw, &Point3::from(x.cast())).unwrap();
        proj.d_uv_d_p_w.cast()
    }
}

/// Rotation vectors away from pi, where a step could wrap the log.
fn rotation_below_pi(rng: &mut TestRng, i: usize) -> Vector3<f64> {
    let phi = random_rotation_vector(rng, i);
    if phi.norm() > 3.1 { phi * (3.1 / phi.norm()) } else { phi }
}

struct So3Exp;
impl JacobianCase<3, 3> for So3Exp {
    const NAME: &'static str = "SO(3) J_l: exp(phi + d) = exp(J_l d) exp(phi)";
    const REL_TOL: f64 = 1e-8;
    const STEP: f64 = 1e-6;
    type Context = Vector3<f64>;
    fn sample(rng: &mut TestRng, i: usize) -> (Vector3<f64>, SVector<f64, 3>) {
        (random_rotation_vector(rng, i), Vector3::zeros())
    }
    fn value(phi: &Vector3<f64>, d: &SVector<f64, 3>) -> SVector<f64, 3> {
        so3_log(&(so3_exp(&(phi + v3(d))) * so3_exp(phi).inverse()))
    }
    fn analytic(phi: &Vector3<f64>, _: &SVector<f64, 3>) -> SMatrix<f64, 3, 3> {
        so3_left_jacobian(phi)
    }
}

struct So3Log;
impl JacobianCase<3, 3> for So3Log {
    const NAME: &'static str = "SO(3) J_l^-1: log(exp(d) exp(phi)) = phi + J_l^-1 d";
    const REL_TOL: f64 = 1e-8;
    const STEP: f64 = 1e-6;
    type Context = Vector3<f64>;
    fn sample(rng: &mut TestRng, i: usize) -> (Vector3<f64>, SVector<f64, 3>) {
        (rotation_below_pi(rng, i), Vector3::zeros())
    }
    fn value(phi: &Vector3<f64>, d: &SVector<f64, 3>) -> SVector<f64, 3> {
        so3_log(&(so3_exp(&v3(d)) * so3_exp(phi)))
    }
    fn analytic(phi: &Vector3<f64>, _: &SVector<f64, 3>) -> SMatrix<f64, 3, 3> {
        so3_left_jacobian_inv(phi)
    }
}

struct Se3Exp;
impl JacobianCase<6, 6> for Se3Exp {
    const NAME: &'static str = "SE(3) J_l: exp(xi + d) = exp(J_l d) exp(xi)";
    const REL_TOL: f64 = 1e-8;
    const STEP: f64 = 1e-6;
    type Context = Vector6<f64>;
    fn sample(rng: &mut TestRng, i: usize) -> (Vector6<f64>, SVector<f64, 6>) {
        (random_twist(rng, i), Vector6::zeros())
    }
    fn value(xi: &Vector6<f64>, d: &SVector<f64, 6>) -> SVector<f64, 6> {
        se3_log(&(se3_exp(&(xi + d)) * se3_exp(xi).inverse()))
    }
    fn analytic(xi: &Vector6<f64>, _: &SVector<f64, 6>) -> SMatrix<f64, 6, 6> {
        se3_left_jacobian(xi)
    }
}

struct Se3Log;
impl JacobianCase<6, 6> for Se3Log {
    const NAME: &'static str = "SE(3) J_l^-1: log(exp(d) exp(xi)) = xi + J_l^-1 d";
    const REL_TOL: f64 = 1e-8;
    const STEP: f64 = 1e-6;
    type Context = Vector6<f64>;
    fn sample(rng: &mut TestRng, i: usize) -> (Vector6<f64>, SVector<f64, 6>) {
        let rho = random_vector3(rng, -2.0, 2.0);
        let phi = rotation_below_pi(rng, i);
        (Vector6::new(rho.x, rho.y, rho.z, phi.x, phi.y, phi.z), Vector6::zeros())
    }
    fn value(xi: &Vector6<f64>, d: &SVector<f64, 6>) -> SVector<f64, 6> {
        se3_log(&(se3_exp(d) * se3_exp(xi)))
    }
    fn analytic(xi: &Vector6<f64>, _: &SVector<f64, 6>) -> SMatrix<f64, 6, 6> {
        se3_left_jacobian_inv(xi)
    }
}

const SAMPLES: usize = 3000;

#[test]
fn projection_wrt_camera_point() {
    check::<ProjectWrtPoint, 3, 2>(SAMPLES);
}

#[test]
fn back_projection_wrt_pixel_and_depth() {
    check::<BackProjectWrtUvDepth, 3, 3>(SAMPLES);
}

#[test]
fn projection_wrt_pose_perturbation() {
    check::<ProjectWrtPose, 6, 2>(SAMPLES);
}

#[test]
fn projection_wrt_world_point() {
    check::<ProjectWrtWorldPoint, 3, 2>(SAMPLES);
}

#[test]
fn so3_exp_left_jacobian() {
    check::<So3Exp, 3, 3>(SAMPLES);
}

#[test]
fn so3_log_inverse_left_jacobian() {
    check::<So3Log, 3, 3>(SAMPLES);
}

#[test]
fn se3_exp_left_jacobian() {
    check::<Se3Exp, 6, 6>(SAMPLES);
}

#[test]
fn se3_log_inverse_left_jacobian() {
    check::<Se3Log, 6, 6>(SAMPLES);
}

/// The checker itself must catch a wrong Jacobian.
struct WrongSign;
impl JacobianCase<3, 3> for WrongSign {
    const NAME: &'static str = "deliberately wrong";
    const REL_TOL: f64 = 1e-3;
    const STEP: f64 = 1e-6;
    type Context = Vector3<f64>;
    fn sample(rng: &mut TestRng, i: usize) -> (Vector3<f64>, SVector<f64, 3>) {
        So3Exp::sample(rng, i)
    }
    fn value(phi: &Vector3<f64>, d: &SVector<f64, 3>) -> SVector<f64, 3> {
        So3Exp::value(phi, d)
    }
    fn analytic(phi: &Vector3<f64>, _: &SVector<f64, 3>) -> SMatrix<f64, 3, 3> {
        so3_left_jacobian(&-phi)
    }
}

#[test]
#[should_panic(expected = "deliberately wrong")]
fn checker_rejects_a_wrong_jacobian() {
    // Sample 0 has phi = 0, where J_l(phi) = J_l(-phi); the others differ.
    check::<WrongSign, 3, 3>(10);
}
