#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! A map saved by one run and loaded by the next (issue 48, first part): the demo's room, frames
//! 0-99 mapped and saved through `PlaceMemory::save`; a second system, switched on with nothing
//! but that file, plays frames 60-119 (it starts where the first run has been and goes on
//! beyond). Its first frames relocalize in the loaded map, and its poses are in the first run's
//! world frame (the ground truth's first camera), not a new one.

use ferroslam_core::frame::FrameSource;
use ferroslam_core::loops::PlaceMemory;
use ferroslam_core::map::RamStore;
use ferroslam_core::system::{DEFAULT_BACKEND_QUOTA, MapAccess, QvgaSlam};
use ferroslam_core::tracking::{FrameOutcome, Places};
use ferroslam_tests::demo_frames::demo_frames;

type Memory = PlaceMemory<RamStore<64>>;

/// Plays frames `first..first + frames` of the demo through `slam` with `places`; returns each
/// frame's outcome and position error against the ground truth (world: frame 0's camera).
fn play(
    slam: &mut QvgaSlam,
    places: &mut Memory,
    first: usize,
    frames: usize,
) -> Vec<(FrameOutcome, f32)> {
    let (mut source, cam, truth) = demo_frames((first..first + frames).collect());
    let mut out = Vec::new();
    while let Some(frame) = source.next_frame().unwrap() {
        slam.step_backend(&cam, DEFAULT_BACKEND_QUOTA).unwrap();
        let r = slam.process_with(&frame, &cam, places).unwrap();
        let t = truth[out.len()].translation.vector;
        out.push((r.outcome(), (r.t_wc.translation.vector - t).norm()));
    }
    out
}

#[test]
fn a_saved_map_is_where_the_next_run_starts() {
    let mut slam: Box<QvgaSlam> = Box::default();
    let mut places: Box<Memory> = Box::new(PlaceMemory::new(RamStore::new(), 1));
    let first = play(&mut slam, &mut places, 0, 100);
    assert!(first.iter().all(|(o, _)| *o != FrameOutcome::Lost));
    // Save: the remembered keyframes and those still in the map.
    slam.map().remember_all_in(places.as_mut());
    let mut file = Vec::new();
    places
        .save(|b: &[u8]| -> Result<(), ()> {
            file.extend_from_slice(b);
            Ok(())
        })
        .unwrap();
    // Switched on again: a new system and a place memory with nothing but the file.
    let mut slam: Box<QvgaSlam> = Box::default();
    let mut places: Box<Memory> = Box::new(PlaceMemory::new(RamStore::new(), 1));
    places.load(&file).unwrap();
    assert!(places.holds_places());
    let second = play(&mut slam, &mut places, 60, 60);
    let start = second
        .iter()
        .position(|(o, _)| *o != FrameOutcome::Initializing)
        .expect("the second run starts");
    assert!(start < 5, "it starts within 5 frames: at {start}");
    assert_eq!(second[start].0, FrameOutcome::Relocalized, "by relocalizing in the loaded map");
    let worst = second[start..].iter().map(|&(_, e)| e).fold(0.0, f32::max);
    assert!(worst < 0.05, "in the first run's world frame: {worst} m at most off");
}
