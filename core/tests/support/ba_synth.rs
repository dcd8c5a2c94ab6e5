//! Synthetic RGB-D bundle-adjustment problems with known answers: a camera moving sideways past
//! a scene 1-4 m deep, Kinect-like noise at QVGA, a perturbed start. Shared by
//! `tests/bundle_adjustment.rs` and `benches/ba_step.rs` (included with `#[path]`).
#![allow(dead_code)]

use ferroslam_core::geometry::{PinholeCamera, Pose, se3_exp};
use ferroslam_core::optim::{BaError, BundleAdjuster, CameraId, ObservationId, PointId, RigId};
use nalgebra::{Point2, Point3, Translation3, UnitQuaternion, Vector3, Vector6};

use ferroslam_core::config::capacity::{LOCAL_WINDOW_MAX, MAX_KEYFRAMES};

/// The generator of core's unit tests, the same file: integration tests cannot see the library's
/// `#[cfg(test)]` items.
#[path = "../../src/test_rng.rs"]
mod test_rng;
pub use test_rng::TestRng;

/// Points of the stand-alone adjusters the tests and the benchmark use (larger than the back
/// end's, which `config::BOARD_MAP` sizes).
pub const BA_MAX_POINTS: usize = 1536;
/// Observations of the stand-alone adjusters.
pub const BA_MAX_OBSERVATIONS: usize = 8192;
/// Local BA over the capped window: one rig per keyframe (124,328 bytes on a 64-bit host, checked
/// by `sizes_are_as_documented`).
pub type LocalBundleAdjuster =
    BundleAdjuster<LOCAL_WINDOW_MAX, LOCAL_WINDOW_MAX, BA_MAX_POINTS, BA_MAX_OBSERVATIONS>;
/// Segmented global BA: one rig per segment (8 of 4 keyframes), every keyframe of the board's map
/// a camera (99,504 bytes).
pub type SegmentedBundleAdjuster =
    BundleAdjuster<{ MAX_KEYFRAMES / 4 }, MAX_KEYFRAMES, BA_MAX_POINTS, BA_MAX_OBSERVATIONS>;

/// What to generate.
#[derive(Debug, Clone, Copy)]
pub struct SynthConfig {
    pub keyframes: usize,
    pub points: usize,
    /// Keyframes that see each point (around the one it was seeded in).
    pub span: usize,
    /// The first this many keyframes are fixed (at their true pose).
    pub fixed_keyframes: usize,
    /// Fraction of points fixed (at their true position): reference landmarks.
    pub fixed_point_fraction: f64,
    /// Pixel noise, pixels (Gaussian).
    pub pixel_noise_px: f64,
    /// Depth noise `sigma_z = c z^2`, per metre.
    pub depth_noise_coeff: f64,
    /// Fraction of observations with a depth reading.
    pub depth_fraction: f64,
    /// Fraction of observations that are gross outliers (10-30 px off, depth 30% off).
    pub outlier_fraction: f64,
    /// Start perturbation of free keyframes: translation (m) and rotation (rad) sigma.
    pub start_sigma_t_m: f64,
    pub start_sigma_r_rad: f64,
    /// Start perturbation of free points, metres.
    pub start_sigma_p_m: f64,
    pub seed: u64,
}

impl SynthConfig {
    /// A realistic local-BA window: 65 keyframes, 1000 points, ~6000 observations, Kinect-like
    /// noise at QVGA (0.7 px, `sigma_z = 1.4e-3 z^2`, 90% depth), 2 cm / 0.5 deg / 3 cm start
    /// error, 2 fixed keyframes, 10% reference landmarks.
    pub const REALISTIC: Self = Self {
        keyframes: 65,
        points: 1000,
        span: 6,
        fixed_keyframes: 2,
        fixed_point_fraction: 0.1,
        pixel_noise_px: 0.7,
        depth_noise_coeff: 1.4e-3,
        depth_fraction: 0.9,
        outlier_fraction: 0.0,
        start_sigma_t_m: 0.02,
        start_sigma_r_rad: 0.0087,
        start_sigma_p_m: 0.03,
        seed: 7,
    };

    /// A small problem: 10 keyframes, 150 points.
    pub const SMALL: Self = Self { keyframes: 10, points: 150, span: 5, ..Self::REALISTIC };
}

/// One generated observation.
#[derive(Debug, Clone, Copy)]
pub struct SynthObs {
    pub keyframe: usize,
    pub uv: Point2<f32>,
    pub depth_m: Option<f32>,
    pub outlier: bool,
}

/// A generated problem: truth, start and observations (grouped by point).
pub struct Synth {
    pub camera: PinholeCamera,
    pub true_t_cw: Vec<Pose>,
    pub start_t_cw: Vec<Pose>,
    pub fixed_keyframe: Vec<bool>,
    pub true_p_w: Vec<Point3<f32>>,
    pub start_p_w: Vec<Point3<f32>>,
    pub fixed_point: Vec<bool>,
    pub obs: Vec<Vec<SynthObs>>,
}

/// The ids of a filled problem: camera of each keyframe, each point, each observation in the
/// order added (with its outlier flag).
pub struct Filled {
    pub cams: Vec<CameraId>,
    pub points: Vec<PointId>,
    pub obs: Vec<ObservationId>,
    pub outlier: Vec<bool>,
}

/// Kinect intrinsics halved: QVGA.
pub fn qvga_camera() -> PinholeCamera {
    PinholeCamera::new(262.5, 262.5, 159.75, 119.75, 320, 240).expect("valid intrinsics")
}

/// Camera-to-world pose of keyframe `k`: moving along x by 5 cm per keyframe, a little up and
/// down and back and forth, yawing and pitching a few degrees.
fn true_t_wc(k: usize) -> Pose {
    let kf = k as f32;
    let c = Vector3::new(0.05 * kf, 0.02 * (kf / 5.0).sin(), 0.03 * (kf / 7.0).cos());
    let r =
        UnitQuaternion::from_euler_angles(0.05 * (kf / 6.0).sin(), 0.15 * (kf / 10.0).sin(), 0.0);
    Pose::from_parts(Translation3::from(c), r)
}

/// `exp(xi) t` with `xi` Gaussian (sigma_t on rho, sigma_r on phi).
pub fn perturb(rng: &mut TestRng, t: &Pose, sigma_t: f64, sigma_r: f64) -> Pose {
    let mut g = |s: f64| (s * rng.normal()) as f32;
    let xi = Vector6::new(g(sigma_t), g(sigma_t), g(sigma_t), g(sigma_r), g(sigma_r), g(sigma_r));
    se3_exp(&xi) * t
}

impl Synth {
    pub fn generate(cfg: &SynthConfig) -> Self {
        let camera = qvga_camera();
        let mut rng = TestRng::new(cfg.seed);
        let true_t_cw: Vec<Pose> = (0..cfg.keyframes).map(|k| true_t_wc(k).inverse()).collect();
        let fixed_keyframe: Vec<bool> =
            (0..cfg.keyframes).map(|k| k < cfg.fixed_keyframes).collect();
        let start_t_cw = true_t_cw
            .iter()
            .zip(&fixed_keyframe)
            .map(|(t, &f)| {
                if f {
                    *t
                } else {
                    perturb(&mut rng, t, cfg.start_sigma_t_m, cfg.start_sigma_r_rad)
                }
            })
            .collect();
        let mut s = Self {
            camera,
            true_t_cw,
            start_t_cw,
            fixed_keyframe,
            true_p_w: Vec::new(),
            start_p_w: Vec::new(),
            fixed_point: Vec::new(),
            obs: Vec::new(),
        };
        for i in 0..cfg.points {
            s.add_point(cfg, &mut rng, i);
        }
        s
    }

    /// Seeds point `i` in keyframe `i mod K` and observes it from the `span` keyframes around.
    fn add_point(&mut self, cfg: &SynthConfig, rng: &mut TestRng, i: usize) {
        let k_count = cfg.keyframes;
        let anchor = i % k_count;
        let (u, v) = (rng.uniform(10.0, 310.0) as f32, rng.uniform(10.0, 230.0) as f32);
        let depth = rng.uniform(1.0, 4.0) as f32;
        let p_c = self.camera.back_project(u, v, depth);
        let p_w = self.true_t_cw[anchor].inverse() * p_c;
        let first = anchor.saturating_sub(cfg.span / 2).min(k_count.saturating_sub(cfg.span));
        let mut obs = Vec::new();
        for k in first..(first + cfg.span).min(k_count) {
            let p_k = self.true_t_cw[k] * p_w;
            let Some(uv) = self.camera.project(&p_k) else { continue };
            if !self.camera.in_image(&uv, 2.0) {
                continue;
            }
            let outlier = rng.unit() < cfg.outlier_fraction;
            let mut uv_m = Point2::new(
                uv.x + (cfg.pixel_noise_px * rng.normal()) as f32,
                uv.y + (cfg.pixel_noise_px * rng.normal()) as f32,
            );
            let has_depth = rng.unit() < cfg.depth_fraction;
            let z = f64::from(p_k.z);
            let mut depth_m = (z + cfg.depth_noise_coeff * z * z * rng.normal()) as f32;
            if outlier {
                let sign = |r: &mut TestRng| if r.unit() < 0.5 { -1.0 } else { 1.0 };
                // Wrong matches elsewhere in the image.
                uv_m.x = (uv_m.x + sign(rng) * rng.uniform(10.0, 30.0) as f32).clamp(0.0, 319.0);
                uv_m.y = (uv_m.y + sign(rng) * rng.uniform(10.0, 30.0) as f32).clamp(0.0, 239.0);
                depth_m *= 1.3;
            }
            obs.push(SynthObs {
                keyframe: k,
                uv: uv_m,
                depth_m: has_depth.then_some(depth_m),
                outlier,
            });
        }
        let fixed = rng.unit() < cfg.fixed_point_fraction;
        let start = if fixed {
            p_w
        } else {
            let s = cfg.start_sigma_p_m;
            p_w + Vector3::new(
                (s * rng.normal()) as f32,
                (s * rng.normal()) as f32,
                (s * rng.normal()) as f32,
            )
        };
        self.true_p_w.push(p_w);
        self.start_p_w.push(start);
        self.fixed_point.push(fixed);
        self.obs.push(obs);
    }

    pub fn observation_count(&self) -> usize {
        self.obs.iter().map(Vec::len).sum()
    }

    /// Fills `ba` as local BA (a rig per keyframe) from the start values.
    pub fn fill_local<const R: usize, const C: usize, const P: usize, const O: usize>(
        &self,
        ba: &mut BundleAdjuster<R, C, P, O>,
    ) -> Result<Filled, BaError> {
        ba.clear();
        let mut cams = Vec::new();
        for (t, &fixed) in self.start_t_cw.iter().zip(&self.fixed_keyframe) {
            cams.push(ba.add_keyframe(t, fixed)?);
        }
        self.fill_points(ba, cams, |_, obs| obs.to_vec())
    }

    /// Adds the points and their observations, with `cams[k]` the camera of keyframe `k`;
    /// `order` gives the order in which a point's observations are added.
    pub fn fill_points<const R: usize, const C: usize, const P: usize, const O: usize>(
        &self,
        ba: &mut BundleAdjuster<R, C, P, O>,
        cams: Vec<CameraId>,
        order: impl Fn(usize, &[SynthObs]) -> Vec<SynthObs>,
    ) -> Result<Filled, BaError> {
        let (mut points, mut obs, mut outlier) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..self.true_p_w.len() {
            let id = ba.add_point(&self.start_p_w[i], self.fixed_point[i])?;
            for o in order(i, &self.obs[i]) {
                obs.push(ba.add_observation(id, cams[o.keyframe], o.uv, o.depth_m)?);
                outlier.push(o.outlier);
            }
            points.push(id);
        }
        Ok(Filled { cams, points, obs, outlier })
    }

    /// RMS camera-centre error (m) and RMS rotation error (rad) over the free keyframes.
    pub fn pose_rmse(&self, t_cw: impl Fn(usize) -> Pose) -> (f64, f64) {
        let (mut st, mut sr, mut n) = (0.0, 0.0, 0usize);
        for k in (0..self.true_t_cw.len()).filter(|&k| !self.fixed_keyframe[k]) {
            let (est, truth) = (t_cw(k).inverse(), self.true_t_cw[k].inverse());
            st += f64::from((est.translation.vector - truth.translation.vector).norm_squared());
            sr += f64::from(est.rotation.angle_to(&truth.rotation)).powi(2);
            n += 1;
        }
        let n = n.max(1) as f64;
        ((st / n).sqrt(), (sr / n).sqrt())
    }

    /// RMS point error (m) over the free points.
    pub fn point_rmse(&self, p_w: impl Fn(usize) -> Point3<f32>) -> f64 {
        let (mut s, mut n) = (0.0, 0usize);
        for i in (0..self.true_p_w.len()).filter(|&i| !self.fixed_point[i]) {
            s += f64::from((p_w(i) - self.true_p_w[i]).norm_squared());
            n += 1;
        }
        (s / n.max(1) as f64).sqrt()
    }
}

/// A segmented problem: keyframes in segments of `seg_len`, one rig per segment (segment 0
/// fixed, the others perturbed by 2 cm / 0.5 deg), each keyframe a camera at its true offset
/// inside its segment.
pub struct Segmented {
    pub synth: Synth,
    pub rigs: Vec<RigId>,
    /// True `t_sw` of each segment (its first keyframe's `t_cw`).
    pub truth: Vec<Pose>,
    pub filled: Filled,
}

/// [`SynthConfig::REALISTIC`] with 30 keyframes and 500 points, no keyframe perturbation (the
/// segments are perturbed instead).
pub const SEGMENT_CFG: SynthConfig = SynthConfig {
    keyframes: 30,
    points: 500,
    fixed_keyframes: 0,
    start_sigma_t_m: 0.0,
    start_sigma_r_rad: 0.0,
    ..SynthConfig::REALISTIC
};

/// Fills `ba` in segmented mode. A point's observations are added in an order that splits each
/// segment's (odd points), exercising the approximate preconditioner.
pub fn segmented<const R: usize, const C: usize, const P: usize, const O: usize>(
    cfg: &SynthConfig,
    seg_len: usize,
    ba: &mut BundleAdjuster<R, C, P, O>,
) -> Result<Segmented, BaError> {
    let synth = Synth::generate(cfg);
    let mut rng = TestRng::new(99);
    ba.clear();
    let (mut truth, mut rigs, mut cams) = (Vec::new(), Vec::new(), Vec::new());
    for seg in 0..cfg.keyframes.div_ceil(seg_len) {
        let t_sw = synth.true_t_cw[seg_len * seg];
        let start = if seg == 0 { t_sw } else { perturb(&mut rng, &t_sw, 0.02, 0.0087) };
        rigs.push(ba.add_rig(&start, seg == 0)?);
        truth.push(t_sw);
    }
    for k in 0..cfg.keyframes {
        let t_cs = synth.true_t_cw[k] * truth[k / seg_len].inverse();
        cams.push(ba.add_camera(rigs[k / seg_len], &t_cs)?);
    }
    let interleave = |i: usize, obs: &[SynthObs]| {
        if i.is_multiple_of(2) {
            return obs.to_vec();
        }
        obs.iter().step_by(2).chain(obs.iter().skip(1).step_by(2)).copied().collect()
    };
    let filled = synth.fill_points(ba, cams, interleave)?;
    Ok(Segmented { synth, rigs, truth, filled })
}

impl Segmented {
    /// RMS rig-centre error (m) over the free rigs, given each rig's current `t_sw`.
    pub fn rig_error(&self, rig_pose: impl Fn(RigId) -> Pose) -> f64 {
        let mut s = 0.0;
        for (rig, t) in self.rigs.iter().zip(&self.truth).skip(1) {
            let est = rig_pose(*rig).inverse();
            s +=
                f64::from((est.translation.vector - t.inverse().translation.vector).norm_squared());
        }
        (s / (self.truth.len() - 1).max(1) as f64).sqrt()
    }
}
