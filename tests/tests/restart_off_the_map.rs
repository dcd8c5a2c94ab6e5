#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! A map restarted off the known one is brought back by a loop (issue 47): the demo's room played
//! `0-299,150-299` (the camera carried back 150 frames, timestamps continuing at 30 Hz), as
//! `replay --frames` plays it. After the jump tracking fails and restarts at the prediction, a new
//! map off the remembered one; a keyframe of it then verifies in a place remembered from before the
//! restart, and the loop's correction moves the new map onto the old. Before the loop the poses
//! are far off the ground truth, after it they are back on it; a virtual object placed in the
//! restarted map comes with it (issue 49), drawn where it belongs after the loop as before.

use ferroslam_core::ar::{Anchors, FramePlanes, PlacingFrame, PlaneDetector, PlaneParams};
use ferroslam_core::frame::FrameSource;
use ferroslam_core::loops::PlaceMemory;
use ferroslam_core::map::RamStore;
use ferroslam_core::system::{DEFAULT_BACKEND_QUOTA, QvgaSlam};
use ferroslam_core::tracking::FrameOutcome;
use ferroslam_tests::demo_frames::demo_frames;

#[test]
fn a_map_restarted_off_the_known_one_is_brought_back_by_a_loop() {
    let (mut source, cam, truth) = demo_frames((0..300).chain(150..300).collect());
    let mut slam: Box<QvgaSlam> = Box::default();
    let mut places = Box::new(PlaceMemory::new(RamStore::<64>::new(), 1));
    // Each frame's position error against the ground truth (the world is the first camera's), and
    // the frames where a loop closed.
    let (mut errors, mut loops) = (Vec::new(), Vec::new());
    // An object placed 5 frames into the restarted map, at a floor pixel; where each later frame
    // draws it against where the true point under that pixel projects.
    let mut anchors = Anchors::new();
    let mut detector = Box::new(PlaneDetector::new());
    let (mut restart, mut placed_truth) = (None, None);
    let mut pixel_errors = Vec::new();
    while let Some(frame) = source.next_frame().unwrap() {
        slam.step_backend(&cam, DEFAULT_BACKEND_QUOTA).unwrap();
        let r = slam.process_with(&frame, &cam, places.as_mut()).unwrap();
        let i = errors.len();
        let t = truth[i].translation.vector;
        errors.push((r.t_wc.translation.vector - t).norm());
        if let Some(closure) = &r.loop_closure {
            loops.push(i);
            anchors.correct(&closure.correction, |k| slam.map().keyframe(k).is_some());
        }
        if restart.is_none() && i >= 300 && r.outcome() == FrameOutcome::Reinitialized {
            restart = Some(i);
        }
        if restart.is_some_and(|k| i == k + 5) {
            let mut planes = FramePlanes::new();
            detector.detect(&frame.depth, &cam, &PlaneParams::DEFAULT, &mut planes).unwrap();
            let reference = r.reference_keyframe;
            let placing = PlacingFrame {
                depth: &frame.depth,
                cam: &cam,
                t_wc: &r.t_wc,
                planes: &planes,
                reference,
            };
            let (u, v) = (80.0, 200.0);
            anchors.place(0, 1.0, (u, v), &placing).unwrap();
            let z = frame.depth.depth_at(u, v, 0.05).unwrap();
            placed_truth = Some(truth[i] * cam.back_project(u, v, z));
        }
        if let (Some(p_w), Some(a)) = (placed_truth, anchors.get(0)) {
            let seen = cam.project(&(truth[i].inverse() * p_w));
            if let (Some(seen), Some([du, dv])) = (seen, a.pixel(&r.t_wc, &cam)) {
                pixel_errors.push((i, (seen - nalgebra::Point2::new(du, dv)).norm()));
            }
        }
    }
    let restart =
        restart.expect("tracking restarts after the jump, off the map (the case under test)");
    let &closed = loops.first().expect("a loop closes after the restart");
    assert!(closed > restart && closed < restart + 60, "loop at {closed}, restart at {restart}");
    assert_eq!(loops.len(), 1, "one loop brings the map back: {loops:?}");
    let before = errors[restart..closed].iter().copied().fold(0.0, f32::max);
    let after = errors[closed..].iter().copied().fold(0.0, f32::max);
    assert!(before > 0.10, "the restarted map was off: {before} m at most");
    assert!(after < 0.05, "after the loop the poses are back on the ground truth: {after} m");
    assert_eq!(places.loop_stats().accepted, 1);
    // The object, drawn before and after the loop: where it belongs both times, to a pixel at the
    // median and 3 pixels at worst (the loop's own residual; without the correction it would be
    // drawn where the restarted map had it, about 140 px off).
    let (mut before, mut after): (Vec<f32>, Vec<f32>) = (Vec::new(), Vec::new());
    for &(i, e) in &pixel_errors {
        if i < closed { before.push(e) } else { after.push(e) }
    }
    assert!(!before.is_empty() && after.len() > 50, "{pixel_errors:?}");
    for errors in [&mut before, &mut after] {
        errors.sort_by(f32::total_cmp);
        let (median, worst) = (errors[errors.len() / 2], errors[errors.len() - 1]);
        assert!(median < 1.0 && worst < 3.0, "median {median} px, worst {worst} px");
    }
}
