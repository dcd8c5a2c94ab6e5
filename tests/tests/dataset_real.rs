//! The dataset loader on real data: `../shared/datasets/7scenes-redkitchen-1000` (Kinect v1,
//! 640x480, JPEG colour, 16-bit PNG depth in millimetres, 1000 frames). The data is only read.

// The helpers below are test code too (clippy only exempts `#[test]` functions themselves).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::time::Instant;

use ferroslam_core::config::{QVGA, Resolution, VGA};
use ferroslam_core::frame::FrameSource;
use ferroslam_sim::dataset::{Dataset, DatasetOptions, OwnedFrame};
use ferroslam_tests::shared_dataset;

fn dir() -> PathBuf {
    let dir = shared_dataset("7scenes-redkitchen-1000");
    assert!(dir.join("rgb.txt").is_file(), "real dataset not found at {}", dir.display());
    dir
}

fn open(profile: Resolution, max_frames: Option<usize>) -> Dataset {
    let opts = DatasetOptions { profile, max_frames, ..DatasetOptions::default() };
    Dataset::open(&dir(), &opts).unwrap()
}

#[test]
fn opens_with_all_frames_associated() {
    let ds = open(VGA, None);
    assert_eq!(ds.len(), 1000);
    assert!(ds.skipped().is_empty(), "{:?}", ds.skipped().first());
    assert!(ds.frames().iter().all(|f| f.rgb_timestamp_s == f.depth_timestamp_s));
    assert!(ds.frames()[999].rgb_path.ends_with("rgb/frame-000999.color.jpg"));
    assert!(ds.frames()[999].depth_path.ends_with("depth/frame-000999.depth.png"));
    let c = ds.calibration();
    assert_eq!((c.fx, c.fy, c.cx, c.cy), (585.0, 585.0, 320.0, 240.0));
    assert_eq!((c.width, c.height, c.depth_scale), (640, 480, 1000.0));
    let gt = ds.groundtruth().unwrap();
    assert_eq!(gt.len(), 1000);
    assert_eq!(gt[0].timestamp_s, 0.0);
    // The path is about 7.4 m long (README); the summed ground-truth steps must agree.
    let length: f64 = gt
        .windows(2)
        .map(|w| (w[1].t_wc.translation.vector - w[0].t_wc.translation.vector).norm())
        .sum();
    assert!((6.0..9.0).contains(&length), "path length {length} m");
}

/// Fraction of valid depth samples, median valid depth in metres, gray mean.
fn stats(f: &OwnedFrame) -> (f64, f32, f64) {
    let mut valid: Vec<u16> = f.depth.iter().copied().filter(|&d| d != 0).collect();
    valid.sort_unstable();
    let fraction = valid.len() as f64 / f.depth.len() as f64;
    let median_m = f32::from(valid[valid.len() / 2]) / f.depth_scale;
    let mean = f.gray.iter().map(|&g| f64::from(g)).sum::<f64>() / f.gray.len() as f64;
    (fraction, median_m, mean)
}

#[test]
fn frame_0_at_vga_is_plausible() {
    let ds = open(VGA, Some(1));
    let f = ds.load_frame(0).unwrap();
    assert_eq!((f.width, f.height, f.gray.len(), f.depth.len()), (640, 480, 640 * 480, 640 * 480));
    assert_eq!((f.timestamp_s, f.depth_scale), (0.0, 1000.0));
    let (fraction, median_m, mean) = stats(&f);
    // A kitchen seen from ~1-3 m: most pixels have a reading; a real, non-flat image.
    assert!(fraction > 0.6, "valid depth fraction {fraction}");
    assert!((0.5..4.0).contains(&median_m), "median depth {median_m} m");
    assert!((40.0..220.0).contains(&mean), "gray mean {mean}");
    let spread = f.gray.iter().max().unwrap() - f.gray.iter().min().unwrap();
    assert!(spread > 100, "gray range {spread}");
    let view = f.view().unwrap();
    assert_eq!(view.gray.size(), (640, 480));
    assert!(view.depth.depth_m(320, 240).is_none_or(|d| (0.3..5.0).contains(&d)));
}

#[test]
fn frame_0_at_qvga_is_the_halved_vga_frame() {
    let full = open(VGA, Some(1)).load_frame(0).unwrap();
    // The board keeps the depth one level coarser than the gray image; the halving rule is
    // checked on the depth at the gray image's resolution (level 0).
    let board = open(QVGA, Some(1)).load_frame(0).unwrap();
    assert_eq!((board.depth_level, board.depth_size()), (1, (160, 120)));
    let opts = DatasetOptions {
        profile: QVGA,
        max_frames: Some(1),
        depth_level: Some(0),
        ..DatasetOptions::default()
    };
    let ds = Dataset::open(&dir(), &opts).unwrap();
    let c = ds.calibration();
    assert_eq!((c.fx, c.fy, c.width, c.height), (292.5, 292.5, 320, 240));
    // Pixel centres: the VGA centre 320 maps to (320 + 0.5) / 2 - 0.5.
    assert_eq!((c.cx, c.cy), (159.75, 119.75));
    assert_eq!(ds.sensor_calibration().fx, 585.0);
    let half = ds.load_frame(0).unwrap();
    assert_eq!(
        (half.width, half.height, half.gray.len(), half.depth.len()),
        (320, 240, 76800, 76800)
    );
    for y in 0..240 {
        for x in 0..320 {
            let block =
                [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(dx, dy)| (2 * y + dy) * 640 + 2 * x + dx);
            let sum: u32 = block.iter().map(|&i| u32::from(full.gray[i])).sum();
            assert_eq!(u32::from(half.gray[y * 320 + x]), (sum + 2) / 4, "gray at ({x}, {y})");
            // Depth is never averaged across surfaces: the mean of the middle two samples of
            // four on one surface (within 1/32 of each other), else a real sample of the block,
            // or 0 when it has none.
            let d = half.depth[y * 320 + x];
            let mut samples = block.map(|i| full.depth[i]);
            samples.sort_unstable();
            if samples.iter().all(|&s| s == 0) {
                assert_eq!(d, 0);
            } else if samples[0] != 0
                && u32::from(samples[2] - samples[1]) * 32 <= u32::from(samples[1])
            {
                let mean = (u32::from(samples[1]) + u32::from(samples[2])) / 2;
                assert_eq!(u32::from(d), mean, "depth at ({x}, {y})");
            } else {
                assert!(d != 0 && samples.contains(&d), "depth at ({x}, {y})");
            }
        }
    }
    let (fraction, median_m, _) = stats(&half);
    assert!(fraction > 0.6 && (0.5..4.0).contains(&median_m));
}

#[test]
fn reader_streams_the_same_bytes_as_load_frame() {
    let ds = open(QVGA, Some(100));
    let expected: Vec<OwnedFrame> = (0..100).map(|i| ds.load_frame(i).unwrap()).collect();
    let mut reader = ds.into_reader(4);
    for (i, want) in expected.iter().enumerate() {
        let got = reader.next_frame().unwrap().unwrap_or_else(|| panic!("ended at {i}"));
        assert_eq!(got.timestamp_s, want.timestamp_s);
        assert_eq!(got.gray.size(), (want.width, want.height));
        assert!(got.gray.rows().flatten().eq(want.gray.iter()), "gray of frame {i}");
        assert!(got.depth.raw().rows().flatten().eq(want.depth.iter()), "depth of frame {i}");
        assert_eq!(got.depth.depth_scale(), 1000.0);
    }
    assert!(reader.next_frame().unwrap().is_none());
}

#[test]
fn reader_streams_all_1000_frames_in_order() {
    let mut reader = open(VGA, None).into_reader(8);
    let start = Instant::now();
    let (mut n, mut last_t) = (0usize, f64::NEG_INFINITY);
    while let Some(frame) = reader.next_frame().unwrap() {
        assert!(frame.timestamp_s > last_t);
        last_t = frame.timestamp_s;
        n += 1;
    }
    // Reported, not asserted (timing belongs in benchmarks).
    eprintln!("decoded {n} VGA frames through the reader in {:.2?}", start.elapsed());
    assert_eq!(n, 1000);
}
