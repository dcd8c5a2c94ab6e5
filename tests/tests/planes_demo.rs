#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! Plane detection on the demo's room (issue 49's first bar): on frames spread over the default
//! demo at the board's resolution, every planar face covering more than 10% of the frame (the
//! renderer's ground truth: walls, floor, boxes' faces) is found by the core's
//! `ar::PlaneDetector` on the frame's depth, its normal within 1 degree and its offset within
//! 1 cm.

use ferroslam_core::ar::{FramePlanes, Plane, PlaneDetector, PlaneParams};
use ferroslam_core::frame::FrameSource;
use ferroslam_sim::synth::{SynthOptions, SyntheticSequence, VisiblePlane};
use ferroslam_tests::demo_frames::demo_frames;

/// The frames checked: every 10th of the demo's 300 (three a second of its path).
const FRAMES: [usize; 30] = {
    let mut frames = [0; 30];
    let mut i = 0;
    while i < 30 {
        frames[i] = 10 * i;
        i += 1;
    }
    frames
};

/// Issue 49's bars on the demo.
const MIN_FRACTION: f64 = 0.10;
const MAX_NORMAL_DEG: f64 = 1.0;
const MAX_OFFSET_M: f64 = 0.01;

/// Degrees between a detected plane's normal and a true one.
fn angle_deg(p: &Plane, t: &VisiblePlane) -> f64 {
    let n = p.normal().cast::<f64>();
    n.dot(&t.normal_c).clamp(-1.0, 1.0).acos().to_degrees()
}

#[test]
fn every_plane_over_a_tenth_of_a_demo_frame_is_found_within_a_degree_and_a_centimetre() {
    let sequence = SyntheticSequence::new(SynthOptions::default()).unwrap();
    let (mut source, cam, _) = demo_frames(FRAMES.to_vec());
    let mut detector = Box::new(PlaneDetector::new());
    let mut planes = FramePlanes::new();
    let (mut checked, mut worst_deg, mut worst_m) = (0, 0.0f64, 0.0f64);
    // What the sensor reads: the detector ignores depth beyond it.
    let max_depth_m = f64::from(PlaneParams::DEFAULT.sensor.depth_max_m);
    for &index in &FRAMES {
        let frame = source.next_frame().unwrap().expect("a demo frame");
        detector.detect(&frame.depth, &cam, &PlaneParams::DEFAULT, &mut planes).unwrap();
        for truth in sequence
            .visible_planes(index, 4, max_depth_m)
            .iter()
            .filter(|t| t.fraction > MIN_FRACTION)
        {
            let found = planes
                .iter()
                .filter(|p| angle_deg(p, truth) < 10.0)
                .min_by(|a, b| {
                    let off = |p: &Plane| (f64::from(p.offset_m) - truth.offset_m).abs();
                    off(a).total_cmp(&off(b))
                })
                .unwrap_or_else(|| panic!("frame {index}: {truth:?} not found among {planes:?}"));
            let (deg, off) =
                (angle_deg(found, truth), (f64::from(found.offset_m) - truth.offset_m).abs());
            eprintln!(
                "frame {index:3}: {:<14} {:4.1}% of the frame: normal {deg:.3} deg, offset {:.1} mm \
                 off ({:.1}% detected)",
                truth.name,
                100.0 * truth.fraction,
                1000.0 * off,
                100.0 * found.frame_fraction()
            );
            assert!(deg <= MAX_NORMAL_DEG, "frame {index}: {truth:?}: {found:?}");
            assert!(off <= MAX_OFFSET_M, "frame {index}: {truth:?}: {found:?}");
            checked += 1;
            worst_deg = worst_deg.max(deg);
            worst_m = worst_m.max(off);
        }
    }
    eprintln!(
        "{checked} planes checked: worst normal {worst_deg:.3} deg, offset {:.1} mm",
        worst_m * 1e3
    );
    assert!(checked >= FRAMES.len(), "at least a plane a frame: {checked}");
}
