#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! What ends a run (`Slam::drain_backend`): the work under way, then a local BA around each of
//! the newest `BackendParams::settle_keyframes` keyframes. Two systems fed the same demo frames,
//! one settling none, are the same bits until the drain; after it, the one that settles has run
//! exactly that many local BAs more and moved its keyframes, and settling twice the same way
//! gives the same bits.

use ferroslam_core::backend::BackendParams;
use ferroslam_core::frame::FrameSource;
use ferroslam_core::loops::PlaceMemory;
use ferroslam_core::map::RamStore;
use ferroslam_core::system::{DEFAULT_BACKEND_QUOTA, DEFAULT_DRAIN_STEPS, QvgaSlam, SLAM_FRONTEND};
use ferroslam_tests::demo_frames::demo_frames;

const FRAMES: usize = 90;

/// Keyframes settled: fewer than the default 8, as these frames make 7.
const SETTLE: u8 = 4;

/// The demo's first frames through a system settling `settle` keyframes, before its drain.
fn run(settle: u8) -> Box<QvgaSlam> {
    let (mut source, cam, _) = demo_frames((0..FRAMES).collect());
    let backend = BackendParams { settle_keyframes: settle, ..BackendParams::DEFAULT };
    let mut slam = Box::new(QvgaSlam::with_params(SLAM_FRONTEND, backend));
    let mut places = Box::new(PlaceMemory::new(RamStore::<64>::new(), 1));
    while let Some(frame) = source.next_frame().unwrap() {
        slam.step_backend(&cam, DEFAULT_BACKEND_QUOTA).unwrap();
        slam.process_with(&frame, &cam, places.as_mut()).unwrap();
    }
    slam
}

/// Every keyframe's creation number and pose bits.
fn keyframe_bits(slam: &QvgaSlam) -> Vec<(u32, [u32; 7])> {
    let mut out: Vec<_> = slam
        .map()
        .keyframes()
        .map(|(_, k)| {
            let (t, q) = (k.t_wc.translation.vector, k.t_wc.rotation.coords);
            (k.seq, [t.x, t.y, t.z, q.x, q.y, q.z, q.w].map(f32::to_bits))
        })
        .collect();
    out.sort_unstable_by_key(|k| k.0);
    out
}

#[test]
fn a_run_ends_with_a_local_ba_around_each_of_its_newest_keyframes() {
    let (_, cam, _) = demo_frames(vec![0]);
    let mut none = run(0);
    let mut settled = run(SETTLE);
    let mut again = run(SETTLE);
    assert_eq!(keyframe_bits(&none), keyframe_bits(&settled), "the same bits before the drain");
    let keyframes = none.map().num_keyframes();
    assert!(keyframes > usize::from(SETTLE), "the demo made {keyframes} keyframes");
    let before = settled.backend().stats().local_runs;
    assert_eq!(none.backend().stats().local_runs, before);

    none.drain_backend(&cam, DEFAULT_BACKEND_QUOTA, DEFAULT_DRAIN_STEPS).unwrap();
    let steps = settled.drain_backend(&cam, DEFAULT_BACKEND_QUOTA, DEFAULT_DRAIN_STEPS).unwrap();
    again.drain_backend(&cam, DEFAULT_BACKEND_QUOTA, DEFAULT_DRAIN_STEPS).unwrap();

    let extra = settled.backend().stats().local_runs - none.backend().stats().local_runs;
    assert_eq!(extra, u32::from(SETTLE), "one local BA per settled keyframe");
    assert!(
        steps >= 3 * u32::from(SETTLE),
        "each local BA is built, solved and written back: {steps} steps"
    );
    assert!(!settled.backend().is_busy());
    let (a, b) = (keyframe_bits(&none), keyframe_bits(&settled));
    assert_eq!(a.len(), b.len(), "settling adds or removes no keyframe");
    let moved: Vec<u32> = a.iter().zip(&b).filter(|(x, y)| x.1 != y.1).map(|(x, _)| x.0).collect();
    assert!(!moved.is_empty(), "the settling moved keyframes");
    assert_eq!(keyframe_bits(&settled), keyframe_bits(&again), "deterministic");
}
