#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! A map saved by one run and loaded by the next (issue 48, first part): the demo's room, frames
//! 0-99 mapped and saved through `PlaceMemory::save`; a second system, switched on with nothing
//! but that file, plays frames 60-119 (it starts where the first run has been and goes on
//! beyond). Its first frames relocalize in the loaded map, and its poses are in the first run's
//! world frame (the ground truth's first camera), not a new one.
//!
//! The map carries the world's planes and the objects placed on them (issue 49): two objects
//! placed in frame 50 of the first run are, in the second, the same bits, and its poses draw them
//! where the true camera sees the true points under their placing pixels. A third system
//! localizes in the same file (`--localize`) and draws them within the demo's AR bars.

use ferroslam_core::frame::FrameSource;
use ferroslam_core::loops::PlaceMemory;
use ferroslam_core::map::RamStore;
use ferroslam_core::system::{DEFAULT_BACKEND_QUOTA, MapAccess, QvgaSlam};
use ferroslam_core::tracking::{FrameOutcome, Places};
use ferroslam_tests::demo_frames::{demo_frames, place_objects};

type Memory = PlaceMemory<RamStore<64>>;

/// The frame of the first run objects are placed in, and their pixels (the floor, a wall).
const PLACE_FRAME: usize = 50;
const PLACE_PIXELS: [(f32, f32); 2] = [(80.0, 200.0), (160.0, 60.0)];

/// A frame's outcome, its position error against the ground truth (world: frame 0's camera),
/// and the pixel error of each placed object drawn from its pose.
type Played = (FrameOutcome, f32, Vec<f32>);

/// Plays frames `first..first + frames` of the demo through `slam` with `places`, placing the
/// objects at [`PLACE_FRAME`] when it comes (their true points pushed to `placed`); returns
/// what [`Played`] says of each frame.
fn play(
    slam: &mut QvgaSlam,
    places: &mut Memory,
    first: usize,
    frames: usize,
    placed: &mut Vec<nalgebra::Point3<f32>>,
) -> Vec<Played> {
    let (mut source, cam, truth) = demo_frames((first..first + frames).collect());
    let mut out = Vec::new();
    while let Some(frame) = source.next_frame().unwrap() {
        let (index, t_true) = (first + out.len(), truth[out.len()]);
        slam.step_backend(&cam, DEFAULT_BACKEND_QUOTA).unwrap();
        let r = slam.process_with(&frame, &cam, places).unwrap();
        if index == PLACE_FRAME {
            placed.extend(place_objects(slam, (&frame, &cam, &r), &t_true, &PLACE_PIXELS));
        }
        let drawn = slam.anchors().iter().zip(placed.iter()).filter_map(|(a, p)| {
            let true_px = t_true.inverse_transform_point(p);
            let at = cam.project(&true_px)?;
            let [u, v] = a.pixel(&r.t_wc, &cam)?;
            Some((nalgebra::Vector2::new(u, v) - at.coords).norm())
        });
        let drawn = drawn.collect();
        let t = t_true.translation.vector;
        out.push((r.outcome(), (r.t_wc.translation.vector - t).norm(), drawn));
    }
    out
}

#[test]
fn a_saved_map_is_where_the_next_run_starts() {
    let mut slam: Box<QvgaSlam> = Box::default();
    let mut places: Box<Memory> = Box::new(PlaceMemory::new(RamStore::new(), 1));
    let mut placed = Vec::new();
    let first = play(&mut slam, &mut places, 0, 100, &mut placed);
    assert!(first.iter().all(|(o, _, _)| *o != FrameOutcome::Lost));
    // Save: the remembered keyframes and those still in the map, then the planes and anchors.
    slam.map().remember_all_in(places.as_mut());
    let mut file = Vec::new();
    places
        .save(Some(&slam.world()), |b: &[u8]| -> Result<(), ()> {
            file.extend_from_slice(b);
            Ok(())
        })
        .unwrap();
    let saved_planes = slam.planes().map().planes().to_vec();
    let saved_anchors: Vec<_> = slam.anchors().iter().copied().collect();
    assert!(!saved_planes.is_empty(), "the first run found planes");
    assert_eq!(saved_anchors.len(), PLACE_PIXELS.len());
    // Switched on again: a new system and a place memory with nothing but the file.
    let (mut slam, mut places) = switched_on(&file, false);
    let planes: Vec<_> = slam.planes().map().planes().iter().map(|m| m.plane).collect();
    assert_eq!(planes, saved_planes.iter().map(|m| m.plane).collect::<Vec<_>>());
    let second = play(&mut slam, &mut places, 60, 60, &mut placed);
    let start = relocalized_start(&second);
    let worst = second[start..].iter().map(|(_, e, _)| *e).fold(0.0, f32::max);
    assert!(worst < 0.05, "in the first run's world frame: {worst} m at most off");
    // The objects: where the first run left them, drawn where they belong.
    let anchors: Vec<_> = slam.anchors().iter().copied().collect();
    assert_eq!(anchors, saved_anchors, "the loaded anchors, bit for bit, not moved");
    let (median, p95) = median_p95(&second[start..]);
    let (median_first, p95_first) = median_p95(&first[PLACE_FRAME..]);
    eprintln!(
        "{} planes and {} objects saved; objects drawn from where they belong: {median:.2} px \
         median, {p95:.2} px p95 after the load ({median_first:.2} / {p95_first:.2} px in the \
         run that placed them)",
        saved_planes.len(),
        saved_anchors.len()
    );
    // The demo's AR bar for the median (issue 49). Its p95 (3 px) is not held by a run that
    // extends the map: its poses come from one relocalization and drift to 1.7 cm by its last
    // frames (docs/decisions.md, "Planes and anchors saved with the map").
    assert!(median <= 1.0, "median {median} px (p95 {p95} px)");
    // Localizing in the same file (`--localize`): the run is held on the map by its points, and
    // the objects are drawn within both of the demo's AR bars (median 1 px, p95 3 px).
    let (mut slam, mut places) = switched_on(&file, true);
    let localized = play(&mut slam, &mut places, 60, 60, &mut placed);
    let (median, p95) = median_p95(&localized[relocalized_start(&localized)..]);
    eprintln!("localizing in the loaded map: {median:.2} px median, {p95:.2} px p95");
    assert!(median <= 1.0 && p95 <= 3.0, "median {median} px, p95 {p95} px");
}

/// A new system and a place memory holding nothing but the map `file` (frozen when `localize`,
/// as `replay --localize`), the file's planes and anchors restored.
fn switched_on(file: &[u8], localize: bool) -> (Box<QvgaSlam>, Box<Memory>) {
    let mut slam: Box<QvgaSlam> = Box::default();
    let mut places: Box<Memory> = Box::new(PlaceMemory::new(RamStore::new(), 1));
    let world = places.load(file).unwrap().expect("the file holds planes and anchors");
    assert!(places.holds_places());
    places.freeze(localize);
    slam.restore_world(&world);
    (slam, places)
}

/// The first frame of a run in a loaded map that has a pose: within its first 5 frames, and
/// relocalized in the map.
fn relocalized_start(frames: &[Played]) -> usize {
    let start = frames
        .iter()
        .position(|(o, _, _)| *o != FrameOutcome::Initializing)
        .expect("the run starts");
    assert!(start < 5, "it starts within 5 frames: at {start}");
    assert_eq!(frames[start].0, FrameOutcome::Relocalized, "by relocalizing in the loaded map");
    start
}

/// The median and p95 pixel error of the objects drawn in `frames`, each of which draws every
/// object.
fn median_p95(frames: &[Played]) -> (f32, f32) {
    let mut errors: Vec<f32> = frames.iter().flat_map(|(_, _, d)| d.clone()).collect();
    assert_eq!(errors.len(), frames.len() * PLACE_PIXELS.len(), "drawn every frame");
    errors.sort_by(f32::total_cmp);
    (errors[errors.len() / 2], errors[errors.len() * 95 / 100])
}
