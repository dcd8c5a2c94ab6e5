#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::convert::Infallible;

use super::*;

/// Frames of 16 x 8 pixels, 30 Hz, frame `i`'s gray all `i` and depth all `1000 + i`.
struct Frames {
    next: usize,
    count: usize,
    current: Option<OwnedFrame>,
}

impl FrameSource for Frames {
    type Error = Infallible;

    fn next_frame(&mut self) -> Result<Option<RgbdFrame<'_>>, Infallible> {
        if self.next == self.count {
            return Ok(None);
        }
        let i = self.next;
        self.next += 1;
        let frame = OwnedFrame {
            timestamp_s: i as f64 / 30.0,
            width: 16,
            height: 8,
            gray: vec![i as u8; 128],
            depth: vec![1000 + i as u16; 128],
            depth_level: 0,
            depth_scale: 1000.0,
        };
        Ok(Some(self.current.insert(frame).view().unwrap()))
    }
}

fn frames(count: usize) -> Frames {
    Frames { next: 0, count, current: None }
}

/// Everything `source` gives, copied.
fn drain<S: FrameSource>(source: &mut S) -> Vec<OwnedFrame>
where
    S::Error: std::fmt::Debug,
{
    let mut out = Vec::new();
    while let Some(f) = source.next_frame().unwrap() {
        out.push(halve_frame(&f, 0).unwrap());
    }
    out
}

fn plan(fault: FrameFault, rate: f64, span: Range<usize>) -> FaultPlan {
    FaultPlan { fault, rate, span, seed: 7 }
}

fn faulty(fault: FrameFault, rate: f64, span: Range<usize>) -> FaultySource<Frames> {
    let foreign = vec![OwnedFrame {
        timestamp_s: 99.0,
        width: 16,
        height: 8,
        gray: vec![200; 128],
        depth: vec![7; 128],
        depth_level: 0,
        depth_scale: 1000.0,
    }];
    FaultySource::new(frames(10), plan(fault, rate, span), foreign)
}

#[test]
fn a_zero_rate_passes_every_frame_through_unchanged() {
    for fault in FrameFault::ALL {
        let mut s = faulty(fault, 0.0, 0..10);
        assert_eq!(drain(&mut s), drain(&mut frames(10)), "{fault:?}");
        assert!(s.injected().is_empty());
    }
}

#[test]
fn each_fault_does_what_it_says() {
    let gray0 = |f: &OwnedFrame| f.gray[0];
    // Frames 2 and 3 hit (rate 1 over 2..4; Duplicate and Reorder take frame 3 as the next one).
    let out = drain(&mut faulty(FrameFault::Drop, 1.0, 2..4));
    assert_eq!(out.iter().map(gray0).collect::<Vec<_>>(), [0, 1, 4, 5, 6, 7, 8, 9]);

    let out = drain(&mut faulty(FrameFault::Duplicate, 1.0, 2..3));
    assert_eq!(out.iter().map(gray0).collect::<Vec<_>>(), [0, 1, 2, 2, 3, 4, 5, 6, 7, 8, 9]);
    let stamps: Vec<f64> = out.iter().map(|f| f.timestamp_s).collect();
    assert!(stamps.windows(2).all(|w| w[0] < w[1]), "a duplicate keeps time increasing");

    let out = drain(&mut faulty(FrameFault::Reorder, 1.0, 2..3));
    assert_eq!(out.iter().map(gray0).collect::<Vec<_>>(), [0, 1, 3, 2, 4, 5, 6, 7, 8, 9]);
    assert!(out[3].timestamp_s < out[2].timestamp_s, "the late frame goes back in time");

    let out = drain(&mut faulty(FrameFault::RepeatTimestamp, 1.0, 5..6));
    assert_eq!(out[5].timestamp_s, out[4].timestamp_s);
    assert_eq!(gray0(&out[5]), 5);

    let out = drain(&mut faulty(FrameFault::Black, 1.0, 5..6));
    assert!(out[5].gray.iter().all(|&g| g == 0));
    assert_eq!(out[5].depth, vec![1005; 128], "a black frame keeps its depth");

    let out = drain(&mut faulty(FrameFault::Saturated, 1.0, 5..6));
    assert!(out[5].gray.iter().all(|&g| g == 255) && out[5].depth.iter().all(|&d| d == 0));

    let out = drain(&mut faulty(FrameFault::OtherScene, 1.0, 5..6));
    assert_eq!((gray0(&out[5]), out[5].depth[0]), (200, 7));
    assert_eq!(out[5].timestamp_s, 5.0 / 30.0, "a foreign frame keeps this frame's time");

    let out = drain(&mut faulty(FrameFault::CorruptRows, 1.0, 5..6));
    let changed = (0..8).filter(|y| out[5].gray[y * 16..(y + 1) * 16] != [5; 16]).count();
    assert!((1..=1).contains(&changed), "one row of 8 (an eighth) torn: {changed}");
    for (i, f) in out.iter().enumerate().filter(|(i, _)| *i != 5) {
        assert_eq!(gray0(f), i as u8, "only the hit frame changes");
    }
}

#[test]
fn faults_fall_in_the_span_at_about_the_rate_and_repeat_with_the_seed() {
    let run = |seed| {
        let p = FaultPlan { fault: FrameFault::Black, rate: 0.1, span: 100..900, seed };
        let mut s = FaultySource::new(frames(1000), p, Vec::new());
        drain(&mut s);
        s.injected().iter().map(|i| i.input_index).collect::<Vec<_>>()
    };
    let hits = run(3);
    assert_eq!(hits, run(3), "the same seed hits the same frames");
    assert_ne!(hits, run(4));
    assert!(hits.iter().all(|i| (100..900).contains(i)));
    assert!((50..110).contains(&hits.len()), "about 10% of 800 frames: {}", hits.len());
}

#[test]
fn other_scene_without_foreign_frames_injects_nothing() {
    let mut s = FaultySource::new(frames(10), plan(FrameFault::OtherScene, 1.0, 0..10), vec![]);
    assert_eq!(drain(&mut s), drain(&mut frames(10)));
    assert!(s.injected().is_empty(), "nothing said injected that was not");
}
