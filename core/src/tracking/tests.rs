//! The front end on a small ray-cast scene with known poses, and on bad frames.
//!
//! Test code only: compiled under #[cfg(test)] from `frontend.rs`.

extern crate std;
use std::boxed::Box;
use std::vec::Vec;

use nalgebra::{Translation3, UnitQuaternion, Vector3};

use super::keyframe_rule::{KeyframeDecision, decide_keyframe};
use super::*;
use crate::frame::RgbdFrame;
use crate::geometry::{PinholeCamera, Pose};
use crate::image::{DepthView, GrayView, ImageView};

const W: usize = 320;
const H: usize = 240;
const DEPTH_SCALE: f32 = 5000.0;

fn camera() -> PinholeCamera {
    PinholeCamera::new(262.5, 262.5, 159.5, 119.5, W, H).unwrap()
}

fn hash(i: i32, j: i32, k: u32) -> f32 {
    let mut h = (i as u32).wrapping_mul(0x9E37_79B9) ^ (j as u32).wrapping_mul(0x85EB_CA6B) ^ k;
    h ^= h >> 15;
    h = h.wrapping_mul(0x2C1B_3C6D);
    h ^= h >> 12;
    (h & 0xFFFF) as f32 / 65535.0
}

/// Gray level of the wall at world `(x, y)`: jittered Gaussian blobs of random contrast on a
/// lattice of 8 cm, over a smooth gradient.
fn texture(x: f32, y: f32) -> f32 {
    const S: f32 = 0.08;
    let (ci, cj) = (libm::floorf(x / S) as i32, libm::floorf(y / S) as i32);
    let mut g = 128.0 + 20.0 * libm::sinf(1.3 * x + 0.7 * y);
    for i in ci - 1..=ci + 1 {
        for j in cj - 1..=cj + 1 {
            let bx = (i as f32 + 0.2 + 0.6 * hash(i, j, 1)) * S;
            let by = (j as f32 + 0.2 + 0.6 * hash(i, j, 2)) * S;
            let amp = 160.0 * (hash(i, j, 3) - 0.5);
            let sigma = 0.012 + 0.01 * hash(i, j, 4);
            let r2 = (x - bx) * (x - bx) + (y - by) * (y - by);
            g += amp * libm::expf(-r2 / (2.0 * sigma * sigma));
        }
    }
    g.clamp(0.0, 255.0)
}

/// Renders the wall `z_w = 2 + 0.1 x_w` seen from `t_wc`: gray and raw depth (scale 5000).
fn render(t_wc: &Pose) -> (Vec<u8>, Vec<u16>) {
    let cam = camera();
    let (mut gray, mut depth) = (vec_of(0u8), vec_of(0u16));
    let o = t_wc.translation.vector;
    for v in 0..H {
        for u in 0..W {
            let d_c = cam.back_project(u as f32, v as f32, 1.0).coords;
            let d = t_wc.rotation * d_c;
            // Plane n.p = 2 with n = (-0.1, 0, 1).
            let n = Vector3::new(-0.1, 0.0, 1.0);
            let t = (2.0 - n.dot(&o)) / n.dot(&d);
            let hit = o + d * t;
            gray[v * W + u] = texture(hit.x, hit.y) as u8;
            depth[v * W + u] = (t * DEPTH_SCALE) as u16; // depth along the optical axis (d_c.z = 1)
        }
    }
    (gray, depth)
}

fn vec_of<T: Copy>(x: T) -> Vec<T> {
    std::vec![x; W * H]
}

fn frame<'a>(t: f64, gray: &'a [u8], depth: &'a [u16]) -> RgbdFrame<'a> {
    RgbdFrame {
        timestamp_s: t,
        gray: GrayView::packed(gray, W, H).unwrap(),
        depth: DepthView::new(ImageView::packed(depth, W, H).unwrap(), DEPTH_SCALE).unwrap(),
    }
}

fn pose_at(k: usize) -> Pose {
    let s = k as f32;
    Pose::from_parts(
        Translation3::new(0.01 * s, -0.004 * s, 0.006 * s),
        UnitQuaternion::from_scaled_axis(Vector3::new(0.002 * s, -0.004 * s, 0.003 * s)),
    )
}

/// A map small enough for tests yet larger than one keyframe's needs.
type TestMap = crate::map::Map<16, 2048>;

fn new_map() -> Box<TestMap> {
    Box::default()
}

/// A front end and its map after frames `0..frames` of [`pose_at`], each tracked.
fn tracked_through(frames: usize) -> (Box<QvgaFrontend>, Box<TestMap>) {
    let cam = camera();
    let mut fe: Box<QvgaFrontend> = Box::default();
    let mut map = new_map();
    for k in 0..frames {
        let (g, d) = render(&pose_at(k));
        assert!(fe.process(&frame(k as f64 / 30.0, &g, &d), &cam, &mut map).unwrap().tracked);
    }
    (fe, map)
}

#[test]
fn tracks_a_known_motion_to_a_centimetre() {
    let cam = camera();
    let mut fe: Box<QvgaFrontend> = Box::default();
    let mut map = new_map();
    let mut last_err = f32::INFINITY;
    for k in 0..12 {
        let truth = pose_at(k);
        let (g, d) = render(&truth);
        let r = fe.process(&frame(k as f64 / 30.0, &g, &d), &cam, &mut map).unwrap();
        assert!(r.tracked, "frame {k}: {r:?}");
        assert_eq!(r.state, FrontendState::Tracking);
        if k > 0 {
            assert!(r.inliers >= 30, "frame {k}: {r:?}");
            // A smooth motion: the start pose is the prediction's or the guides', never a
            // recovery's.
            assert!(
                matches!(r.guide_stage, GuideStage::None | GuideStage::MotionModel),
                "frame {k}: {:?}",
                r.guide_stage
            );
        }
        // What the frame ran: the first is a keyframe with no tracking; later ones run at least
        // one final stage, and detect features exactly when they make a keyframe.
        let w = r.work;
        if k == 0 {
            assert_eq!((w.final_stages, w.guide_runs), (0, 0), "{w:?}");
        } else {
            assert!(w.final_stages >= 1, "frame {k}: {w:?}");
            // A smooth motion needs no rotation from the small images.
            assert!(!w.rotation_estimated, "frame {k}: {w:?}");
        }
        assert_eq!(w.detected, r.keyframe.is_some(), "frame {k}: {w:?}");
        // The first frame defines the world; the truth starts at the identity too.
        last_err = (r.t_wc.translation.vector - truth.translation.vector).norm();
        let rot_err = (r.t_wc.rotation.inverse() * truth.rotation).angle();
        assert!(last_err < 0.01, "frame {k}: translation error {last_err} m, {r:?}");
        assert!(rot_err < 0.01, "frame {k}: rotation error {rot_err} rad");
    }
    assert!(last_err < 0.01);
    let stats = fe.stats();
    assert_eq!((stats.frames, stats.tracked_frames, stats.lost_frames), (12, 12, 0));
    assert!(stats.keyframes >= 1);
    assert_eq!(map.num_keyframes(), stats.keyframes as usize);
}

#[test]
fn landmarks_outlive_their_keyframe_and_the_map_stays_bounded() {
    let cam = camera();
    // A keyframe every 10 cm, two keyframes at most: the oldest is retired, tracked landmarks
    // survive it.
    let params = FrontendParams { keyframe_max_translation_m: 0.1, ..FrontendParams::DEFAULT };
    let mut fe: Box<QvgaFrontend> = Box::new(QvgaFrontend::with_params(params));
    let mut map: Box<crate::map::Map<2, 600>> = Box::default();
    let (g, d) = render(&pose_at(0));
    let r = fe.process(&frame(0.0, &g, &d), &cam, &mut map).unwrap();
    let first_kf = r.keyframe.unwrap();
    let first_ids: Vec<_> = fe.local_map().items().iter().map(|t| t.id).collect();
    let mut made = 0;
    for k in 1..40 {
        let (g, d) = render(&pose_at(k));
        let r = fe.process(&frame(k as f64 / 30.0, &g, &d), &cam, &mut map).unwrap();
        assert!(r.tracked, "frame {k}: {r:?}");
        made += usize::from(r.keyframe.is_some());
        assert!(map.num_keyframes() <= 2 && map.num_landmarks() <= 600);
    }
    assert!(made >= 2, "the motion needs new keyframes ({made})");
    assert!(map.keyframe(first_kf).is_none(), "the first keyframe was retired");
    let still = fe.local_map().items().iter().filter(|t| first_ids.contains(&t.id)).count();
    assert!(still > 0, "landmarks of the retired keyframe are still tracked");
    for t in fe.local_map().items() {
        assert!(map.landmark(t.id).is_some(), "every tracked landmark is in the map");
    }
}

#[test]
fn black_frames_and_missing_depth_never_panic() {
    let cam = camera();
    let mut fe: Box<QvgaFrontend> = Box::default();
    let mut map = new_map();
    let (black, no_depth) = (vec_of(0u8), vec_of(0u16));
    let r = fe.process(&frame(0.0, &black, &no_depth), &cam, &mut map).unwrap();
    assert_eq!((r.state, r.tracked), (FrontendState::Initializing, false));
    assert_eq!(r.outcome(), FrameOutcome::Initializing);
    let (g, d) = render(&pose_at(0));
    let r = fe.process(&frame(0.1, &g, &no_depth), &cam, &mut map).unwrap();
    assert_eq!(r.state, FrontendState::Initializing, "no depth: no keyframe");
    assert_eq!(map.num_keyframes(), 0, "a failed keyframe leaves nothing in the map");
    let r = fe.process(&frame(0.2, &g, &d), &cam, &mut map).unwrap();
    assert!(r.keyframe.is_some() && r.tracked);
    // A black frame while tracking: lost, pose held (the prediction), never a jump.
    let r = fe.process(&frame(0.3, &black, &d), &cam, &mut map).unwrap();
    assert_eq!((r.state, r.tracked), (FrontendState::Lost, false));
    assert_eq!(r.outcome(), FrameOutcome::Lost);
    assert!(r.t_wc.translation.vector.norm() < 1e-6);
    // Saturated white: lost again; the second loss in a row restarts from a keyframe, which a
    // flat image cannot give, so it stays lost.
    let white = vec_of(255u8);
    let r = fe.process(&frame(0.35, &white, &d), &cam, &mut map).unwrap();
    assert_eq!((r.state, r.tracked), (FrontendState::Lost, false));
    // All-invalid depth: matching works on the image, pixel-only residuals; must not panic.
    let r = fe.process(&frame(0.4, &g, &no_depth), &cam, &mut map).unwrap();
    assert!(r.state != FrontendState::Initializing);
    // The same frame again (new timestamp) tracks at the same pose.
    let r = fe.process(&frame(0.5, &g, &d), &cam, &mut map).unwrap();
    assert!(r.state == FrontendState::Tracking, "{r:?}");
    assert!(r.t_wc.translation.vector.norm() < 0.005, "{r:?}");
    assert!(fe.stats().lost_frames >= 1);
    // Every frame has one outcome: 2 before the first keyframe, 1 tracked (the first keyframe),
    // 3 lost (black, white, no depth), 1 restarted from a keyframe (the last); they add up.
    let st = fe.stats();
    let tally = (st.initializing_frames, st.tracked_frames, st.lost_frames, st.reinitializations);
    assert_eq!(tally, (2, 1, 3, 1), "{st:?}");
    assert_eq!(st.relocalizations, 0, "no place memory: nothing relocalizes");
    assert_eq!(
        st.tracked_frames
            + st.reinitializations
            + st.relocalizations
            + st.lost_frames
            + st.initializing_frames,
        7
    );
}

#[test]
fn a_frame_from_another_scene_is_lost_not_a_jump() {
    let cam = camera();
    let (mut fe, mut map) = tracked_through(3);
    // Noise unrelated to the wall, with a plausible depth.
    let noise: Vec<u8> = (0..W * H).map(|i| (hash(i as i32, 7, 9) * 255.0) as u8).collect();
    let (_, d) = render(&pose_at(3));
    let before = fe.process(&frame(3.0 / 30.0, &noise, &d), &cam, &mut map).unwrap();
    assert_eq!((before.state, before.tracked), (FrontendState::Lost, false));
    let predicted = pose_at(3).translation.vector;
    assert!((before.t_wc.translation.vector - predicted).norm() < 0.01, "held at the prediction");
    // Back to the scene: tracked again.
    let (g, d) = render(&pose_at(4));
    let r = fe.process(&frame(4.0 / 30.0, &g, &d), &cam, &mut map).unwrap();
    assert!(r.tracked, "{r:?}");
}

#[test]
fn weak_attempts_that_agree_stop_the_attempts() {
    let cam = camera();
    let (mut fe, mut map) = tracked_through(4);
    // The right 60% of the image covered by a flat gray card: every start pose finds the same
    // few landmarks left, weak against the frames before; more attempts would find no more.
    let truth = pose_at(4);
    let (mut g, d) = render(&truth);
    for row in g.chunks_mut(W) {
        row[W * 2 / 5..].fill(128);
    }
    let r = fe.process(&frame(4.0 / 30.0, &g, &d), &cam, &mut map).unwrap();
    assert!(r.tracked, "{r:?}");
    // The prediction's final stage is weak, the guides' agrees with it and is weaker: those two
    // and the prediction's rerun, not every attempt (five final stages, three guide runs).
    assert_eq!((r.work.final_stages, r.work.guide_runs), (3, 1), "{r:?}");
    assert_eq!(r.guide_stage, GuideStage::None, "the prediction's pose won: {r:?}");
    assert!(!r.work.rotation_estimated, "{r:?}");
    let err = (r.t_wc.translation.vector - truth.translation.vector).norm();
    assert!(err < 0.01, "translation error {err} m, {r:?}");
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let cam = camera();
    let mut fe: Box<QvgaFrontend> = Box::default();
    let mut map = new_map();
    let (g, d) = render(&pose_at(0));
    fe.process(&frame(1.0, &g, &d), &cam, &mut map).unwrap();
    let e = fe.process(&frame(1.0, &g, &d), &cam, &mut map).unwrap_err();
    assert!(matches!(e, FrontendError::TimestampNotIncreasing { .. }));
    let e = fe.process(&frame(f64::NAN, &g, &d), &cam, &mut map).unwrap_err();
    assert!(matches!(e, FrontendError::TimestampNotIncreasing { .. }));
    let small = PinholeCamera::new(100.0, 100.0, 50.0, 50.0, 100, 100).unwrap();
    let e = fe.process(&frame(2.0, &g, &d), &small, &mut map).unwrap_err();
    let sizes = ((W, H), (W, H), (100, 100), (W, H));
    assert!(
        matches!(e, FrontendError::SizeMismatch { gray, depth, camera, capacity }
            if (gray, depth, camera, capacity) == sizes),
        "{e:?}"
    );
    assert_eq!(
        std::format!("{e}"),
        "gray image 320x240, depth covering 320x240, camera 100x100: the three must have one \
         size, at most the 320x240 that the front end holds"
    );
    // A map the caller cleared: the front end starts over instead of following dead ids.
    map.clear();
    let r = fe.process(&frame(3.0, &g, &d), &cam, &mut map).unwrap();
    assert!(r.keyframe.is_some() && r.reinitialized, "{r:?}");
}

#[test]
fn defaults_match_the_building_blocks_and_sizes_are_bounded() {
    let p = FrontendParams::DEFAULT;
    let hessian = crate::features::HessianParams { threshold: 30.0, ..Default::default() };
    assert_eq!(p.hessian, hessian);
    let m = crate::matching::MatchParams::DEFAULT;
    assert_eq!(
        p.matching,
        crate::matching::MatchParams { half_size: 4, forward_backward_max_px: None, ..m }
    );
    let (guide, fine) = (crate::matching::TrackParams::GUIDE, crate::matching::TrackParams::FINE);
    assert_eq!((p.guide, p.track), (guide, fine));
    assert_eq!(p.guide_wide, crate::matching::TrackParams::GUIDE_WIDE);
    assert_eq!(p.pose, crate::pose::PoseParams::default());
    assert!(p.is_valid());
    let sensor = crate::config::SensorModel::DEFAULT;
    assert_eq!(p.with_sensor(sensor), p, "the default sensor model is the default");
    let quiet = crate::config::SensorModel { depth_noise_coeff_per_m: 2.0e-4, ..sensor };
    let q = p.with_sensor(quiet);
    assert_eq!(q.sensor(), &quiet, "the sensor model reaches the pose estimator");
    assert_eq!(crate::pose::PoseParams { sensor, ..q.pose }, p.pose);
    let qvga = core::mem::size_of::<QvgaFrontend>();
    let vga = core::mem::size_of::<VgaFrontend>();
    std::println!("QvgaFrontend {qvga} bytes, VgaFrontend {vga} bytes");
    // The local map dominates: 256 templates of 16 x 16 pixels with their anchors.
    assert!(qvga < 240_000, "{qvga}");
}

#[test]
fn a_keyframe_due_on_a_costly_frame_is_put_off_a_bounded_number_of_times() {
    let p = FrontendParams::DEFAULT;
    let full = KeyframeDecision::Make { octaves: p.hessian.octaves };
    let cheap = KeyframeDecision::Make { octaves: p.costly_keyframe_octaves };
    assert_eq!(decide_keyframe(false, false, 0, &p), KeyframeDecision::None);
    assert_eq!(decide_keyframe(false, true, 2, &p), KeyframeDecision::None);
    assert_eq!(decide_keyframe(true, false, 0, &p), full);
    // A cheap frame makes the keyframe at once, even after put-offs.
    assert_eq!(decide_keyframe(true, false, p.keyframe_max_put_off, &p), full);
    for put_off in 0..p.keyframe_max_put_off {
        assert_eq!(decide_keyframe(true, true, put_off, &p), KeyframeDecision::PutOff);
    }
    // Put-offs used up: made on the costly frame, with fewer octaves.
    assert_eq!(decide_keyframe(true, true, p.keyframe_max_put_off, &p), cheap);
    assert!(p.costly_keyframe_octaves < p.hessian.octaves);
    // 0 makes every keyframe when due.
    let never = FrontendParams { keyframe_max_put_off: 0, ..p };
    assert_eq!(decide_keyframe(true, true, 0, &never), cheap);
    // What makes a frame costly.
    let w = FrontendWork { final_stages: 1, guide_runs: 3, ..FrontendWork::default() };
    assert!(!w.is_costly());
    assert!(FrontendWork { final_stages: 2, ..w }.is_costly());
    assert!(FrontendWork { rotation_estimated: true, ..w }.is_costly());
}

#[test]
fn costly_keyframe_octaves_out_of_range_are_an_error() {
    let cam = camera();
    let (g, d) = render(&pose_at(0));
    for octaves in [0, 9] {
        let params = FrontendParams { costly_keyframe_octaves: octaves, ..FrontendParams::DEFAULT };
        assert!(!params.is_valid());
        let mut fe: Box<QvgaFrontend> = Box::new(QvgaFrontend::with_params(params));
        let mut map = new_map();
        let e = fe.process(&frame(0.0, &g, &d), &cam, &mut map).unwrap_err();
        assert_eq!(e, FrontendError::InvalidParams);
        assert_eq!(map.num_keyframes(), 0, "nothing changes on an error");
    }
}

#[test]
fn without_costly_frames_putting_off_changes_nothing() {
    // The smooth scene never runs a second final stage nor the small-image rotation, so the
    // put-off rule must leave every output bit as it is with the rule off.
    let cam = camera();
    let run = |params: FrontendParams| {
        let mut fe: Box<QvgaFrontend> = Box::new(QvgaFrontend::with_params(params));
        let mut map = new_map();
        let mut out = Vec::new();
        for k in 0..24 {
            let (g, d) = render(&pose_at(k));
            let r = fe.process(&frame(k as f64 / 30.0, &g, &d), &cam, &mut map).unwrap();
            assert!(!r.work.is_costly(), "frame {k}: {:?}", r.work);
            out.push((r.t_wc.to_homogeneous(), r.keyframe, r.inliers));
        }
        (out, fe.stats())
    };
    let (with_rule, stats) = run(FrontendParams::DEFAULT);
    let (without, _) = run(FrontendParams { keyframe_max_put_off: 0, ..FrontendParams::DEFAULT });
    assert_eq!(stats.keyframes_put_off, 0);
    assert!(stats.keyframes >= 2, "the motion makes keyframes ({})", stats.keyframes);
    assert_eq!(with_rule, without);
}

/// The front end tracks a VGA frame on its halved level with the QVGA parameters, and a frame
/// whose width is nearer the reference than its half on the frame itself with scaled ones.
#[test]
fn the_tracking_level_and_camera_follow_the_frame_width() {
    type Vga = crate::tracking::VgaFrontend;
    assert_eq!(
        [(320, 240), (424, 240), (512, 384), (640, 480)].map(|(w, h)| Vga::level_for(w, h)),
        [0, 0, 1, 1]
    );
    assert_eq!(QvgaFrontend::level_for(640, 480), 0, "no room for the halved frame");
    let cam = PinholeCamera::new(525.0, 525.0, 319.5, 239.5, 640, 480).unwrap();
    let level = Vga::tracking_camera(&cam);
    assert_eq!((level.width(), level.height(), level.fx()), (320, 240, 262.5));
    assert_eq!(QvgaFrontend::tracking_camera(&camera()), camera());
    let p = FrontendParams::DEFAULT;
    assert_eq!(p.at_pixel_scale(1.0), p);
    let q = p.at_pixel_scale(1.325);
    assert_eq!((q.guide.search_radius, q.guide_wide.search_radius), (4, 21));
    assert_eq!(q.guide_wide.search_step, 3);
    assert!(q.guide.is_valid() && q.guide_wide.is_valid() && q.track.is_valid() && q.is_valid());
}
