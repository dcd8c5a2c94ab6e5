#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

extern crate std;

use heapless::Vec;
use nalgebra::{Point3, UnitQuaternion, Vector3};

use super::eigen::smallest_eigenvector;
use super::*;
use crate::geometry::{PinholeCamera, Pose};
use crate::image::{DepthView, ImageView};
use crate::test_rng::TestRng;

/// A QVGA camera.
fn cam() -> PinholeCamera {
    PinholeCamera::new(262.5, 262.5, 159.5, 119.5, 320, 240).unwrap()
}

/// A plane `n . p + d = 0` in the camera's frame.
#[derive(Clone, Copy)]
struct TruePlane {
    n: Vector3<f32>,
    d: f32,
}

/// Depth in millimetres of the nearest of `planes` along each pixel's ray (0 where none is in
/// front), with Gaussian-like noise of `noise_m` metres.
fn render(
    cam: &PinholeCamera,
    planes: &[TruePlane],
    noise_m: f32,
    seed: u64,
) -> std::vec::Vec<u16> {
    let mut rng = TestRng::new(seed);
    let mut depth = std::vec![0u16; cam.width() * cam.height()];
    for y in 0..cam.height() {
        for x in 0..cam.width() {
            let ray = cam.back_project(x as f32, y as f32, 1.0).coords;
            let z = planes
                .iter()
                .filter_map(|p| {
                    let along = p.n.dot(&ray);
                    let t = -p.d / along;
                    (along != 0.0 && t > 0.0).then_some(t)
                })
                .fold(f32::INFINITY, f32::min);
            if z.is_finite() {
                // The sum of four uniforms: close enough to a Gaussian of that deviation.
                let u: f32 = (0..4).map(|_| rng.unit_f32() - 0.5).sum();
                let z = z + noise_m * u * 3.0_f32.sqrt();
                depth[y * cam.width() + x] = (z * 1000.0).round().clamp(0.0, 65535.0) as u16;
            }
        }
    }
    depth
}

fn detect(cam: &PinholeCamera, depth: &[u16]) -> Vec<Plane, MAX_FRAME_PLANES> {
    let view = DepthView::new(ImageView::packed(depth, cam.width(), cam.height()).unwrap(), 1000.0)
        .unwrap();
    let mut detector = std::boxed::Box::new(PlaneDetector::new());
    let mut planes = Vec::new();
    detector.detect(&view, cam, &PlaneParams::DEFAULT, &mut planes).unwrap();
    planes
}

/// Degrees between two unit normals.
fn angle_deg(a: &Vector3<f32>, b: &Vector3<f32>) -> f32 {
    libm::acosf(a.dot(b).clamp(-1.0, 1.0)).to_degrees()
}

/// A camera 1.2 m above a floor, looking ahead and 30 degrees down, a wall 3 m ahead: camera
/// `y` points down, `z` ahead.
fn floor_and_wall() -> [TruePlane; 2] {
    let pitch = 30.0f32.to_radians();
    // The floor's normal (up) in the camera's frame, the camera 1.2 m above it.
    let up = Vector3::new(0.0, -pitch.cos(), -pitch.sin());
    // The wall faces the camera: its normal is back toward it, horizontal.
    let back = Vector3::new(0.0, pitch.sin(), -pitch.cos());
    [TruePlane { n: up, d: 1.2 }, TruePlane { n: back, d: 3.0 }]
}

#[test]
fn the_floor_and_a_wall_are_found_to_a_fraction_of_a_degree_and_a_millimetre() {
    let cam = cam();
    let truth = floor_and_wall();
    for (noise_m, max_deg, max_m) in [(0.0, 0.1, 0.001), (0.01, 0.5, 0.005)] {
        let planes = detect(&cam, &render(&cam, &truth, noise_m, 7));
        assert_eq!(planes.len(), 2, "noise {noise_m}: {planes:?}");
        for t in &truth {
            let found = planes
                .iter()
                .find(|p| angle_deg(&p.normal(), &t.n) < 5.0)
                .unwrap_or_else(|| panic!("noise {noise_m}: no plane near {:?}", t.n));
            assert!(angle_deg(&found.normal(), &t.n) < max_deg, "{found:?}");
            assert!((found.offset_m - t.d).abs() < max_m, "{found:?} against {}", t.d);
            assert!(found.frame_fraction() > 0.2, "{found:?}");
        }
        assert!(planes.windows(2).all(|w| w[0].cells >= w[1].cells), "largest first");
    }
}

#[test]
fn parallel_surfaces_a_box_height_apart_stay_two_planes() {
    let cam = cam();
    // A floor seen from straight above 2 m up, and a box top 0.3 m above it filling the middle.
    let floor = TruePlane { n: Vector3::new(0.0, 0.0, -1.0), d: 2.0 };
    let mut depth = render(&cam, &[floor], 0.0, 1);
    for y in 60..180 {
        for x in 80..240 {
            depth[y * cam.width() + x] = 1700;
        }
    }
    let planes = detect(&cam, &depth);
    let mut offsets: std::vec::Vec<f32> = planes.iter().map(|p| p.offset_m).collect();
    offsets.sort_by(f32::total_cmp);
    assert_eq!(offsets.len(), 2, "{planes:?}");
    assert!((offsets[0] - 1.7).abs() < 0.002 && (offsets[1] - 2.0).abs() < 0.002, "{offsets:?}");
}

#[test]
fn no_depth_no_curved_surface_no_planes_and_bad_input_is_an_error() {
    let cam = cam();
    assert!(detect(&cam, &std::vec![0u16; 320 * 240]).is_empty(), "no depth");
    // A ball of radius 0.25 m centred 0.8 m ahead (its nearest point 0.55 m away): a patch of it
    // three cells wide is 5 mm from flat.
    let mut sphere = std::vec![0u16; 320 * 240];
    for y in 0..240 {
        for x in 0..320 {
            let r = cam.back_project(x as f32, y as f32, 1.0).coords.normalize();
            // Nearest root of |t r - c|^2 = R^2 with c = (0, 0, 0.8).
            let b = 0.8 * r.z;
            let disc = b * b - (0.64 - 0.0625);
            if disc >= 0.0 {
                sphere[y * 320 + x] = ((b - disc.sqrt()) * r.z * 1000.0).round() as u16;
            }
        }
    }
    let planes = detect(&cam, &sphere);
    assert!(planes.iter().all(|p| p.frame_fraction() < 0.05), "{planes:?}");
    let depth = std::vec![1000u16; 160 * 120];
    let view = DepthView::new(ImageView::packed(&depth, 160, 120).unwrap(), 1000.0).unwrap();
    let mut detector = std::boxed::Box::new(PlaneDetector::new());
    let mut planes = Vec::new();
    let r = detector.detect(&view, &cam, &PlaneParams::DEFAULT, &mut planes);
    assert_eq!(r, Err(PlaneError::SizeMismatch));
    let tiny = PinholeCamera::new(10.0, 10.0, 4.5, 4.5, 10, 10).unwrap();
    let view = DepthView::new(ImageView::packed(&depth[..100], 10, 10).unwrap(), 1000.0).unwrap();
    let r = detector.detect(&view, &tiny, &PlaneParams::DEFAULT, &mut planes);
    assert_eq!(r, Err(PlaneError::TooSmall));
    let bad = PlaneParams { max_normal_angle_rad: f32::NAN, ..PlaneParams::DEFAULT };
    let view = DepthView::new(ImageView::packed(&depth, 160, 120).unwrap(), 1000.0).unwrap();
    assert_eq!(detector.detect(&view, &cam, &bad, &mut planes), Err(PlaneError::InvalidParams));
    assert!(planes.is_empty());
}

#[test]
fn a_plane_moved_into_the_world_holds_the_world_points() {
    let plane = Plane {
        normal: [0.0, -0.6, -0.8],
        offset_m: 2.0,
        centroid: [0.1, 1.2, 1.6],
        rms_m: 0.001,
        cells: 30,
        samples: 1920,
    };
    let t_wc = Pose::from_parts(
        nalgebra::Translation3::new(0.5, -0.2, 1.0),
        UnitQuaternion::from_euler_angles(0.1, -0.3, 0.7),
    );
    let world = plane.transformed(&t_wc);
    // Points on the camera-frame plane are on the world plane once moved.
    let n = plane.normal();
    let a = n.cross(&Vector3::x()).normalize();
    let b = n.cross(&a);
    for (u, v) in [(0.0, 0.0), (1.0, 0.0), (-0.5, 2.0)] {
        let p = Point3::from(-plane.offset_m * n + a * u + b * v);
        assert!(plane.distance(&p).abs() < 1e-5);
        assert!(world.distance(&(t_wc * p)).abs() < 1e-5);
    }
    assert!((world.normal().norm() - 1.0).abs() < 1e-6);
}

#[test]
fn the_smallest_eigenvector_of_a_rotated_diagonal_matrix() {
    let r = UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1).to_rotation_matrix();
    let d = nalgebra::Matrix3::from_diagonal(&Vector3::new(4.0, 1e-4, 2.0));
    let m = r.matrix() * d * r.matrix().transpose();
    let a = [0, 1, 2].map(|i| [0, 1, 2].map(|j| m[(i, j)]));
    let (e, values) = smallest_eigenvector(a).unwrap();
    let expected = r.matrix().column(1).into_owned();
    assert!(Vector3::from(e).dot(&expected).abs() > 1.0 - 1e-6, "{e:?}");
    assert!((values[0] - 1e-4).abs() < 1e-5 && (values[2] - 4.0).abs() < 1e-5, "{values:?}");
    assert!(smallest_eigenvector([[f32::NAN, 0.0, 0.0], [0.0; 3], [0.0; 3]]).is_none());
}

/// A world plane `n . p + d = 0` through `centroid` with `samples` samples.
fn world_plane(normal: [f32; 3], centroid: [f32; 3], samples: u32) -> Plane {
    let n = Vector3::from(normal).normalize();
    Plane {
        normal: n.into(),
        offset_m: -n.dot(&Vector3::from(centroid)),
        centroid,
        rms_m: 0.002,
        cells: 20,
        samples,
    }
}

#[test]
fn the_same_surface_seen_twice_is_one_plane_and_a_box_top_another() {
    let p = PlaneMergeParams::DEFAULT;
    let mut map = PlaneMap::new();
    let floor = world_plane([0.0, 0.0, 1.0], [0.0, 0.0, 0.0], 1000);
    assert_eq!(map.observe(&floor, &p), Observed::Added(0));
    // The floor again, a metre away, a centimetre high and tilted half a degree.
    let tilt = 0.5f32.to_radians();
    let again = world_plane([libm::sinf(tilt), 0.0, libm::cosf(tilt)], [1.0, 0.5, 0.01], 1000);
    assert_eq!(map.observe(&again, &p), Observed::Merged(0));
    // A box top 0.3 m up, and a wall: planes of their own.
    assert_eq!(
        map.observe(&world_plane([0.0, 0.0, 1.0], [0.5, 0.5, 0.3], 500), &p),
        Observed::Added(1)
    );
    assert_eq!(
        map.observe(&world_plane([1.0, 0.0, 0.0], [-3.0, 0.0, 1.0], 800), &p),
        Observed::Added(2)
    );
    let kept = map.planes()[0];
    assert_eq!(kept.observations, 2);
    assert_eq!(kept.plane.samples, 2000);
    // The centroids' mean, on the merged plane, the normals' mean a quarter degree off vertical.
    assert_eq!(kept.plane.centroid, [0.5, 0.25, 0.005]);
    assert!(kept.plane.distance(&Point3::from(kept.plane.centroid)).abs() < 1e-6, "{kept:?}");
    let off = libm::acosf(kept.plane.normal[2]).to_degrees();
    assert!((off - 0.25).abs() < 0.01, "{kept:?}");
    assert!((kept.plane.normal().norm() - 1.0).abs() < 1e-6);
    // The same normal facing the other way (a plane's back) is another surface.
    let under = world_plane([0.0, 0.0, -1.0], [0.0, 0.0, 0.0], 100);
    assert_eq!(map.observe(&under, &p), Observed::Added(3));
}

#[test]
fn a_full_plane_map_keeps_the_best_supported_planes() {
    let p = PlaneMergeParams::DEFAULT;
    let mut map = PlaneMap::new();
    for i in 0..MAX_MAP_PLANES {
        // Parallel planes 10 cm apart, samples 100, 200, ...
        let plane = world_plane([0.0, 0.0, 1.0], [0.0, 0.0, 0.1 * i as f32], 100 * (i as u32 + 1));
        assert_eq!(map.observe(&plane, &p), Observed::Added(i));
    }
    let weak = world_plane([0.0, 1.0, 0.0], [0.0, 5.0, 0.0], 50);
    assert_eq!(map.observe(&weak, &p), Observed::Dropped);
    assert_eq!(map.dropped(), 1);
    let strong = world_plane([0.0, 1.0, 0.0], [0.0, 5.0, 0.0], 150);
    assert_eq!(map.observe(&strong, &p), Observed::Added(0), "in place of the 100-sample plane");
    assert_eq!(map.planes().len(), MAX_MAP_PLANES);
    assert_eq!(map.planes()[0].plane.samples, 150);
}

#[test]
fn a_loop_moves_the_restarted_tracks_planes_onto_the_remembered_ones() {
    let p = PlaneMergeParams::DEFAULT;
    let mut map = PlaneMap::new();
    let floor = world_plane([0.0, 0.0, 1.0], [0.0, 0.0, 0.0], 1000);
    let wall = world_plane([1.0, 0.0, 0.0], [-2.0, 0.0, 1.0], 800);
    assert_eq!(map.observe(&floor, &p), Observed::Added(0));
    assert_eq!(map.observe(&wall, &p), Observed::Added(1));
    // Tracking restarts in a world 0.5 m up and turned 10 degrees about z: the floor seen from
    // there is a plane of its own, and so is a box top the first track never saw.
    map.restart_track();
    let t_old_new = Pose::from_parts(
        nalgebra::Translation3::new(0.0, 0.0, 0.5),
        UnitQuaternion::from_euler_angles(0.0, 0.0, 10f32.to_radians()),
    );
    let box_top = world_plane([0.0, 0.0, 1.0], [0.6, 0.2, 0.3], 300);
    let restarted_floor = floor.transformed(&t_old_new.inverse());
    assert_eq!(map.observe(&restarted_floor, &p), Observed::Added(2));
    assert_eq!(map.observe(&box_top.transformed(&t_old_new.inverse()), &p), Observed::Added(3));
    assert_eq!(map.planes()[2].track, 1);
    // The loop's correction: the floor joins the remembered floor, the box top stays a plane
    // and lands where it is; the first track's planes do not move.
    map.correct(&t_old_new, &p);
    let kept = map.planes();
    assert_eq!(kept.len(), 3, "{kept:?}");
    assert_eq!((kept[0].observations, kept[0].plane.samples, kept[0].track), (2, 2000, 0));
    assert!(kept[0].plane.offset_m.abs() < 1e-5 && kept[0].plane.normal[2] > 0.99999);
    assert_eq!(kept[1].plane, wall);
    let moved = kept[2];
    assert_eq!(moved.track, 1);
    assert!((moved.plane.offset_m + 0.3).abs() < 1e-5, "{moved:?}");
    let c = moved.plane.centroid;
    assert!((c[0] - 0.6).abs() < 1e-5 && (c[1] - 0.2).abs() < 1e-5, "{moved:?}");
    // A plane observed after the loop is still the restarted track's.
    assert_eq!(
        map.observe(&world_plane([0.0, 1.0, 0.0], [0.0, 3.0, 1.0], 100), &p),
        Observed::Added(3)
    );
    assert_eq!(map.planes()[3].track, 1);
}

#[test]
fn an_anchor_stands_where_the_pixel_ray_meets_the_plane_under_it() {
    let cam = cam();
    let truth = floor_and_wall();
    let depth = render(&cam, &truth, 0.0, 3);
    let view = DepthView::new(ImageView::packed(&depth, 320, 240).unwrap(), 1000.0).unwrap();
    let planes = detect(&cam, &depth);
    let t_wc = Pose::from_parts(
        nalgebra::Translation3::new(1.0, 2.0, 0.5),
        UnitQuaternion::from_euler_angles(0.0, 0.4, 0.0),
    );
    // A pixel low in the image sees the floor, one high up the wall.
    for ((u, v), plane) in [((160.0, 220.0), truth[0]), ((160.0, 40.0), truth[1])] {
        let a = Anchor::place(7, 2.0, (u, v), &view, &cam, &t_wc, &planes).unwrap();
        assert_eq!((a.object, a.scale), (7, 2.0));
        // On the true plane, in the camera's frame, to a millimetre; its up is the plane's normal.
        let p_c = t_wc.inverse_transform_point(&Point3::from(a.p_w));
        assert!((plane.n.dot(&p_c.coords) + plane.d).abs() < 0.001, "{a:?}");
        let up_c = t_wc.rotation.inverse() * Vector3::from(a.up_w);
        assert!(angle_deg(&up_c, &plane.n) < 0.1, "{a:?}");
        // Drawn back at its pixel.
        let [du, dv] = a.pixel(&t_wc, &cam).unwrap();
        assert!((du - u).abs() < 1e-2 && (dv - v).abs() < 1e-2, "({du}, {dv})");
    }
    let err = |uv, scale, planes: &[Plane]| Anchor::place(0, scale, uv, &view, &cam, &t_wc, planes);
    assert_eq!(err((-1.0, 5.0), 1.0, &planes), Err(AnchorError::OutsideImage));
    assert_eq!(err((f32::NAN, 5.0), 1.0, &planes), Err(AnchorError::OutsideImage));
    assert_eq!(err((160.0, 220.0), 0.0, &planes), Err(AnchorError::InvalidScale));
    assert_eq!(err((160.0, 220.0), 1.0, &[]), Err(AnchorError::NoPlane));
    let holes = std::vec![0u16; 320 * 240];
    let empty = DepthView::new(ImageView::packed(&holes, 320, 240).unwrap(), 1000.0).unwrap();
    assert_eq!(
        Anchor::place(0, 1.0, (160.0, 220.0), &empty, &cam, &t_wc, &planes),
        Err(AnchorError::NoDepth)
    );
}

/// A scene placed against keyframe `k` at `t_wk`, the frame seen from the keyframe itself.
fn placing_frame<'a>(
    view: &'a DepthView<'a>,
    cam: &'a PinholeCamera,
    t_wc: &'a Pose,
    planes: &'a [Plane],
    k: crate::map::KeyFrameId,
) -> PlacingFrame<'a> {
    PlacingFrame { depth: view, cam, t_wc, planes, reference: Some(k) }
}

#[test]
fn anchors_are_placed_scaled_moved_and_removed_by_commands() {
    let cam = cam();
    let depth = render(&cam, &floor_and_wall(), 0.0, 5);
    let view = DepthView::new(ImageView::packed(&depth, 320, 240).unwrap(), 1000.0).unwrap();
    let planes = detect(&cam, &depth);
    let t_wc = Pose::identity();
    let mut keyframes = crate::map::Arena::<(), 2>::new();
    let k = crate::map::KeyFrameId(keyframes.insert(()).unwrap());
    let frame = placing_frame(&view, &cam, &t_wc, &planes, k);
    let mut anchors = Anchors::new();
    let place = |object, pixel| AnchorCommand::Place { object, pixel, scale: 1.0 };
    let floor = anchors.apply(&place(3, [160.0, 220.0]), Some(&frame)).unwrap();
    anchors.apply(&place(9, [160.0, 40.0]), Some(&frame)).unwrap();
    assert_eq!(anchors.iter().map(|a| a.object).collect::<std::vec::Vec<_>>(), [3, 9]);
    // A scale changes the scale only.
    let scaled = anchors.apply(&AnchorCommand::Scale { object: 3, scale: 2.5 }, None).unwrap();
    assert_eq!((scaled.p_w, scaled.scale), (floor.p_w, 2.5));
    // Placing an object again moves it; the order of first placement is kept.
    let moved = anchors.apply(&place(3, [100.0, 200.0]), Some(&frame)).unwrap();
    assert_ne!(moved.p_w, floor.p_w);
    assert_eq!(anchors.get(3), Some(&moved));
    assert_eq!(anchors.iter().map(|a| a.object).collect::<std::vec::Vec<_>>(), [3, 9]);
    // Errors change nothing.
    let before = anchors.clone();
    let bad = [
        (anchors.apply(&place(4, [160.0, 220.0]), None), AnchorError::NotTracked),
        (anchors.apply(&place(3, [-5.0, 0.0]), Some(&frame)), AnchorError::OutsideImage),
        (anchors.scale(3, f32::NAN), AnchorError::InvalidScale),
        (anchors.scale(5, 2.0), AnchorError::UnknownObject),
        (anchors.remove(5), AnchorError::UnknownObject),
    ];
    for (result, error) in bad {
        assert_eq!(result, Err(error));
    }
    assert_eq!(
        anchors.iter().collect::<std::vec::Vec<_>>(),
        before.iter().collect::<std::vec::Vec<_>>()
    );
    assert_eq!(anchors.remove(3).unwrap().object, 3);
    assert_eq!(anchors.iter().map(|a| a.object).collect::<std::vec::Vec<_>>(), [9]);
    // Full: the slots hold other objects; a placed object may still move.
    for object in 10..10 + crate::config::capacity::MAX_ANCHORS as u16 - 1 {
        anchors.apply(&place(object, [160.0, 220.0]), Some(&frame)).unwrap();
    }
    assert_eq!(anchors.apply(&place(99, [160.0, 220.0]), Some(&frame)), Err(AnchorError::Full));
    assert!(anchors.apply(&place(9, [150.0, 210.0]), Some(&frame)).is_ok());
}

#[test]
fn a_loop_correction_moves_the_anchors_of_the_active_map_only() {
    let cam = cam();
    let depth = render(&cam, &floor_and_wall(), 0.0, 6);
    let view = DepthView::new(ImageView::packed(&depth, 320, 240).unwrap(), 1000.0).unwrap();
    let planes = detect(&cam, &depth);
    let t_wc = Pose::from_parts(
        nalgebra::Translation3::new(0.5, -0.2, 1.0),
        UnitQuaternion::from_euler_angles(0.1, -0.3, 0.2),
    );
    let mut keyframes = crate::map::Arena::<(), 2>::new();
    let (active, retired) = (
        crate::map::KeyFrameId(keyframes.insert(()).unwrap()),
        crate::map::KeyFrameId(keyframes.insert(()).unwrap()),
    );
    let mut anchors = Anchors::new();
    let moved = anchors
        .place(1, 1.0, (160.0, 220.0), &placing_frame(&view, &cam, &t_wc, &planes, active))
        .unwrap();
    let kept = anchors
        .place(2, 1.0, (160.0, 40.0), &placing_frame(&view, &cam, &t_wc, &planes, retired))
        .unwrap();
    let correction = Pose::from_parts(
        nalgebra::Translation3::new(0.3, 0.1, -0.05),
        UnitQuaternion::from_euler_angles(0.0, 0.0, 0.2),
    );
    anchors.correct(&correction, |k| k == active);
    let a = anchors.get(1).unwrap();
    let expected = correction * Point3::from(moved.p_w);
    assert!((Point3::from(a.p_w) - expected).norm() < 1e-5, "{a:?}");
    let up = correction.rotation * Vector3::from(moved.up_w);
    assert!((Vector3::from(a.up_w) - up).norm() < 1e-5);
    // Drawn at its pixel from the corrected placing pose, as from the pose before.
    let [u, v] = a.pixel(&(correction * t_wc), &cam).unwrap();
    assert!((u - 160.0).abs() < 1e-2 && (v - 220.0).abs() < 1e-2, "({u}, {v})");
    // The retired keyframe's anchor belongs to the remembered places: it stays.
    assert_eq!(anchors.get(2), Some(&kept));
}

/// A full world: [`MAX_MAP_PLANES`] planes of random orientation and [`MAX_ANCHORS`] anchors.
fn full_world(rng: &mut TestRng) -> (PlaneMap, Anchors) {
    use crate::config::capacity::MAX_ANCHORS;
    let mut unit = || {
        let v =
            Vector3::new(rng.uniform_f32(-1.0, 1.0), rng.uniform_f32(-1.0, 1.0), 1.0).normalize();
        [v.x, v.y, v.z]
    };
    let planes: std::vec::Vec<MapPlane> = (0..MAX_MAP_PLANES as u32)
        .map(|k| {
            let normal = unit();
            MapPlane {
                plane: Plane {
                    normal,
                    offset_m: 0.5 + k as f32 * 0.1,
                    centroid: normal.map(|n| -n * (0.5 + k as f32 * 0.1)),
                    rms_m: 0.002 * k as f32,
                    cells: k as u16 * 3,
                    samples: 1000 + k * 77,
                },
                observations: k as u16 + 1,
                track: 0,
            }
        })
        .collect();
    let anchors: std::vec::Vec<Anchor> = (0..MAX_ANCHORS as u16)
        .map(|object| Anchor {
            object: object * 5,
            p_w: [f32::from(object), -1.0, 2.5],
            up_w: unit(),
            scale: 0.25 * f32::from(object + 1),
        })
        .collect();
    (PlaneMap::restored(&planes), Anchors::restored(&anchors))
}

/// The [`WORLD_UNITS`] units of `world`.
fn units(world: &World<'_>) -> [crate::map::RecordBytes; WORLD_UNITS] {
    let mut out = [[0; crate::config::capacity::PLACE_RECORD_BYTES]; WORLD_UNITS];
    for (k, unit) in out.iter_mut().enumerate() {
        world.encode(k, unit);
    }
    out
}

/// `units` taken in order, then checked whole.
fn taken(units: &[crate::map::RecordBytes]) -> Result<SavedWorld, WorldError> {
    let mut saved = SavedWorld::new();
    for unit in units {
        saved.take(unit)?;
    }
    saved.whole()
}

#[test]
fn a_full_world_saves_and_reads_back_to_the_same_bits_and_bytes() {
    let mut rng = TestRng::new(49);
    let (planes, anchors) = full_world(&mut rng);
    let bytes = units(&World { planes: &planes, anchors: &anchors });
    let saved = taken(&bytes).unwrap();
    assert_eq!(saved.planes(), planes.planes());
    assert!(saved.anchors().iter().eq(anchors.iter()));
    // Held again and saved again: the same bytes.
    let (planes_again, anchors_again) = saved.restored();
    assert_eq!(units(&World { planes: &planes_again, anchors: &anchors_again }), bytes);
    // Restored planes are an earlier track than the run's: a loop moves none of them.
    assert_eq!(planes_again.track(), 1);
    // An empty world too.
    let (none, no_anchors) = (PlaneMap::new(), Anchors::new());
    let empty = taken(&units(&World { planes: &none, anchors: &no_anchors })).unwrap();
    assert!(empty.planes().is_empty() && empty.anchors().is_empty());
}

#[test]
fn world_units_that_are_not_as_written_are_refused_with_what_is_wrong() {
    let mut rng = TestRng::new(50);
    let (planes, anchors) = full_world(&mut rng);
    let good = units(&World { planes: &planes, anchors: &anchors });
    // Writes `value` at byte `at` of a unit and seals it again (its checksum made to match).
    let changed = |unit: usize, at: usize, value: &[u8]| {
        let mut bytes = good;
        bytes[unit][at..at + value.len()].copy_from_slice(value);
        crate::map::seal(&mut bytes[unit]);
        bytes
    };
    let mut flipped = good;
    flipped[1][100] ^= 1;
    let cases: [(std::vec::Vec<crate::map::RecordBytes>, WorldError); 10] = [
        (std::vec![good[1], good[0]], WorldError::Order(1)),
        (std::vec![good[0]], WorldError::Incomplete),
        (flipped.to_vec(), WorldError::Checksum),
        (changed(0, 0, b"X").to_vec(), WorldError::NotAWorld),
        (changed(0, 2, &[9]).to_vec(), WorldError::Version(9)),
        (changed(0, 6, &[1]).to_vec(), WorldError::Padding),
        // Unit 0 holding one plane fewer: the 25th's bytes are where nothing is written.
        (changed(0, 4, &[24]).to_vec(), WorldError::Padding),
        // More planes than unit 0 holds.
        (changed(0, 4, &[26]).to_vec(), WorldError::Counts),
        // A plane's normal x made NaN.
        (changed(0, 8, &f32::NAN.to_le_bytes()).to_vec(), WorldError::Plane),
        // Unit 1's first anchor given the object id of its second (5).
        (changed(1, 8 + 7 * 40, &[5]).to_vec(), WorldError::Anchor),
    ];
    for (bytes, wrong) in cases {
        assert_eq!(taken(&bytes).map(|_| ()), Err(wrong));
    }
}
