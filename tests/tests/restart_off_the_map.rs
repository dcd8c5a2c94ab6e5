#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! A map restarted off the known one is brought back by a loop (issue 47): the demo's room played
//! `0-299,150-299` (the camera carried back 150 frames, timestamps continuing at 30 Hz), as
//! `replay --frames` plays it. After the jump tracking fails and restarts at the prediction, a new
//! map off the remembered one; a keyframe of it then verifies in a place remembered from before the
//! restart, and the loop's correction moves the new map onto the old. Before the loop the poses
//! are far off the ground truth, after it they are back on it.

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
    // what became of it.
    let (mut errors, mut outcomes, mut loops) = (Vec::new(), Vec::new(), Vec::new());
    while let Some(frame) = source.next_frame().unwrap() {
        slam.step_backend(&cam, DEFAULT_BACKEND_QUOTA).unwrap();
        let r = slam.process_with(&frame, &cam, places.as_mut()).unwrap();
        let i = errors.len();
        let t = truth[i].translation.vector;
        errors.push((r.t_wc.translation.vector - t).norm());
        outcomes.push(r.outcome());
        if r.loop_closure.is_some() {
            loops.push(i);
        }
    }
    let restart = (300..outcomes.len())
        .find(|&i| outcomes[i] == FrameOutcome::Reinitialized)
        .expect("tracking restarts after the jump, off the map (the case under test)");
    let &closed = loops.first().expect("a loop closes after the restart");
    assert!(closed > restart && closed < restart + 60, "loop at {closed}, restart at {restart}");
    assert_eq!(loops.len(), 1, "one loop brings the map back: {loops:?}");
    let before = errors[restart..closed].iter().copied().fold(0.0, f32::max);
    let after = errors[closed..].iter().copied().fold(0.0, f32::max);
    assert!(before > 0.10, "the restarted map was off: {before} m at most");
    assert!(after < 0.05, "after the loop the poses are back on the ground truth: {after} m");
    assert_eq!(places.loop_stats().accepted, 1);
}
