#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The planes SLAM finds as it runs, as the board has them (issue 49, `system::OnlinePlanes`):
//! on the demo's 300 frames at the board's profile, every room face covering more than a tenth
//! of a checked frame is among the world's planes, its normal within 2 degrees and its offset
//! within 2 cm of the room's (the online poses' drift included), and the planes were looked for
//! once per keyframe at most (on the frames the front end tracked most cheaply). Objects placed on
//! those planes as the board places them (`Slam::command`, the commands its serial link receives)
//! stand where the pixel's ray meets the room, within the planes' own 2 cm (the placing frame's
//! online pose included).

use ferroslam_core::ar::{AnchorCommand, AnchorError, MapPlane};
use ferroslam_core::frame::FrameSource;
use ferroslam_core::system::{DEFAULT_BACKEND_QUOTA, QvgaSlam};
use ferroslam_sim::synth::{SynthOptions, SyntheticSequence};
use ferroslam_tests::demo_frames::{demo_frames, place_objects};
use nalgebra::Vector3;

/// The frames whose visible faces are checked: every 25th from the 30th.
const CHECKED: [usize; 11] = [30, 55, 80, 105, 130, 155, 180, 205, 230, 255, 280];
const MIN_FRACTION: f64 = 0.10;
const MAX_NORMAL_DEG: f64 = 2.0;
const MAX_OFFSET_M: f64 = 0.02;
/// The frame objects are placed in, and their pixels (the floor, a wall).
const PLACE_FRAME: usize = 150;
const PLACE_PIXELS: [(f32, f32); 2] = [(80.0, 200.0), (160.0, 60.0)];

#[test]
fn the_planes_found_as_slam_runs_hold_the_rooms_faces() {
    let sequence = SyntheticSequence::new(SynthOptions::default()).unwrap();
    let (mut source, cam, truth) = demo_frames((0..300).collect());
    let mut slam: Box<QvgaSlam> = Box::default();
    let mut keyframes = 0;
    // Where the placed objects belong: the true point under each pixel of its placing frame.
    let mut placed = Vec::new();
    let mut index = 0;
    while let Some(frame) = source.next_frame().unwrap() {
        slam.step_backend(&cam, DEFAULT_BACKEND_QUOTA).unwrap();
        let r = slam.process(&frame, &cam).unwrap();
        keyframes += usize::from(r.keyframe.is_some());
        if index == PLACE_FRAME {
            placed = place_objects(&mut slam, (&frame, &cam, &r), &truth[index], &PLACE_PIXELS);
            let outside = AnchorCommand::Place { object: 9, pixel: [-5.0, 10.0], scale: 1.0 };
            assert_eq!(slam.command(&outside, &frame, &cam, &r), Err(AnchorError::OutsideImage));
            let unknown = AnchorCommand::Scale { object: 9, scale: 2.0 };
            assert_eq!(slam.command(&unknown, &frame, &cam, &r), Err(AnchorError::UnknownObject));
        }
        index += 1;
    }
    let anchors = slam.anchors();
    assert_eq!(anchors.len(), PLACE_PIXELS.len());
    for (a, truth_w) in anchors.iter().zip(&placed) {
        let error_m = (nalgebra::Point3::from(a.p_w) - truth_w).norm();
        let off = f64::from(error_m);
        assert!(off <= MAX_OFFSET_M, "object {} stands {:.1} mm off", a.object, off * 1e3);
        eprintln!("object {} placed {:.1} mm from where it belongs", a.object, error_m * 1e3);
    }
    let online = slam.planes();
    let planes = online.map().planes();
    let detections = online.detections() as usize;
    assert!(
        (1..=keyframes).contains(&detections),
        "{detections} detections, {keyframes} keyframes"
    );
    let max_depth_m = f64::from(ferroslam_core::config::SensorModel::DEFAULT.depth_max_m);
    let (mut checked, mut worst_deg, mut worst_m) = (0, 0.0f64, 0.0f64);
    for &index in &CHECKED {
        let t_wc = truth[index].cast::<f64>();
        for face in sequence.visible_planes(index, 4, max_depth_m) {
            if face.fraction <= MIN_FRACTION {
                continue;
            }
            // The face in the world (the first camera's frame).
            let n_w = t_wc.rotation * face.normal_c;
            let offset_w = face.offset_m - n_w.dot(&t_wc.translation.vector);
            let (deg, off) = planes
                .iter()
                .map(|m: &MapPlane| {
                    let n = Vector3::from(m.plane.normal).cast::<f64>();
                    let deg = n.dot(&n_w).clamp(-1.0, 1.0).acos().to_degrees();
                    (deg, (f64::from(m.plane.offset_m) - offset_w).abs())
                })
                .filter(|&(deg, _)| deg < 10.0)
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap_or_else(|| panic!("frame {index}: {} not among {planes:?}", face.name));
            assert!(
                deg <= MAX_NORMAL_DEG && off <= MAX_OFFSET_M,
                "frame {index}: {} found {deg:.2} degrees and {:.1} mm off",
                face.name,
                off * 1e3
            );
            checked += 1;
            (worst_deg, worst_m) = (worst_deg.max(deg), worst_m.max(off));
        }
    }
    eprintln!(
        "{} planes from {detections} detections ({keyframes} keyframes, {} in the map); {checked} \
         faces checked, worst {worst_deg:.2} degrees, {:.1} mm; fingerprint {:#010x}",
        planes.len(),
        slam.map().num_keyframes(),
        worst_m * 1e3,
        online.fingerprint()
    );
    assert!(checked >= 12, "{checked} faces checked");
}
