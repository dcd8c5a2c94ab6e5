//! The estimator's pure pieces, the comparison with a stated calibration, the file it writes, and
//! its errors on small folders written to a temporary directory. The estimate on real data is
//! checked in `tests/tests/calibrate_depth_real.rs`.

use std::fs;

use image::{ImageBuffer, Luma};

use super::*;

/// The 7-Scenes registered calibration as `calibration/7scenes-kinect-v1.toml` states it.
const STATED: &str = "fx = 526.3\nfy = 526.3\ncx = 322.7\ncy = 236.0\nwidth = 640\nheight = 480\n\
    depth_scale = 1000.0\n[depth]\nfx = 585.0\nfy = 585.0\ncx = 320.0\ncy = 240.0\n\
    tx = -0.0325\nty = 0.0062\ntz = 0.0\n";
/// 7-Scenes' own calibration: the depth camera's nominal intrinsics.
const NOMINAL: &str = "fx = 585.0\nfy = 585.0\ncx = 320.0\ncy = 240.0\nwidth = 640\nheight = 480\ndepth_scale = 1000.0\n";

fn calibration(text: &str) -> Calibration {
    Calibration::from_toml_str(text, Path::new("test.toml")).unwrap()
}

/// An estimate of `[fx, tx, ty, cx, cy]` (the search's order) for the 7-Scenes sensor.
fn estimate_of(p: Params) -> DepthRegistrationEstimate {
    DepthRegistrationEstimate {
        dir: PathBuf::from("data/7scenes"),
        selection: FrameSelection::default(),
        frames: 40,
        sensor: calibration(NOMINAL),
        colour_f_px: p[0],
        colour_c_px: [p[3], p[4]],
        offset_m: [p[1], p[2]],
        nominal_correlation: 0.0923,
        correlation: 0.4102,
    }
}

#[test]
fn correlation_of_proportional_and_constant_data() {
    let a = [(1.0, 2.0), (2.0, 4.0), (3.0, 6.0)];
    assert!((correlation(a.iter().copied()) - 1.0).abs() < 1e-12);
    let opposite = [(1.0, 3.0), (2.0, 2.0), (3.0, 1.0)];
    assert!((correlation(opposite.iter().copied()) + 1.0).abs() < 1e-12);
    let c = [(1.0, 1.0), (2.0, 1.0)];
    assert_eq!(correlation(c.iter().copied()), 0.0);
}

#[test]
fn bilinear_interpolates_inside_and_clamps_outside() {
    // 2 x 2: 0 1 / 2 3.
    let img = [0.0, 1.0, 2.0, 3.0];
    assert_eq!(bilinear(&img, 2, 2, 0.5, 0.5), 1.5);
    assert_eq!(bilinear(&img, 2, 2, 1.0, 0.0), 1.0);
    assert_eq!(bilinear(&img, 2, 2, -5.0, 9.0), 2.0);
    assert_eq!(bilinear(&img, 2, 2, f64::INFINITY, f64::INFINITY), 3.0);
    assert_eq!(bilinear(&[], 0, 0, 1.0, 1.0), 0.0);
}

#[test]
fn edge_strength_peaks_at_a_step_and_has_mean_one() {
    let (w, h) = (24, 16);
    let gray: Vec<u8> = (0..w * h).map(|i| if i % w < 12 { 40 } else { 200 }).collect();
    let e = edge_strength(&gray, w, h);
    let mean = e.iter().sum::<f64>() / e.len() as f64;
    assert!((mean - 1.0).abs() < 1e-9, "mean {mean}");
    let row = &e[8 * w..9 * w];
    let peak = (0..w).max_by(|&a, &b| row[a].total_cmp(&row[b])).unwrap();
    assert!((11..=12).contains(&peak), "peak at column {peak}: {row:?}");
    assert!(row[2] < 0.01 * row[peak] && row[21] < 0.01 * row[peak]);
    // A flat image has no edges, and no NaN from the division by its mean.
    assert!(edge_strength(&[90; 24 * 16], w, h).iter().all(|&v| v == 0.0));
}

#[test]
fn depth_edges_are_the_near_side_of_a_jump_with_three_others_each() {
    let (w, h) = (40, 30);
    // A near square (1 m) on a far wall (2 m); raw units of 1 mm.
    let near = |x: usize, y: usize| (15..25).contains(&x) && (10..20).contains(&y);
    let depth: Vec<u16> =
        (0..w * h).map(|i| if near(i % w, i / w) { 1000 } else { 2000 }).collect();
    let s = samples(&vec![128; w * h], &depth, w, h, 1000.0, 7);
    let edges: Vec<_> = s.samples.iter().filter(|p| p.3 == 1.0).collect();
    // The square's outline: 4 sides of 10 pixels, corners once.
    assert_eq!(edges.len(), 36);
    for &&(u, v, z, _) in &edges {
        let (x, y) = (u as usize, v as usize);
        assert!(near(x, y) && z == 1.0, "({x}, {y}) at {z} m");
        assert!(x == 15 || x == 24 || y == 10 || y == 19, "({x}, {y}) is inside the square");
    }
    assert_eq!(s.samples.len(), 4 * 36);
    // The same seed draws the same pixels; another seed others.
    let again = samples(&vec![128; w * h], &depth, w, h, 1000.0, 7);
    assert_eq!(again.samples, s.samples);
    let other = samples(&vec![128; w * h], &depth, w, h, 1000.0, 8);
    assert_ne!(other.samples, s.samples);
}

#[test]
fn the_search_finds_the_peak_of_a_smooth_score() {
    let target: Params = [526.0, -0.03, 0.006, 322.5, 236.0];
    let scale: Params = [10.0, 0.01, 0.01, 5.0, 5.0];
    let score = |p: &Params| {
        -p.iter().zip(target).zip(scale).map(|((a, b), s)| ((a - b) / s).powi(2)).sum::<f64>()
    };
    let start: Params = [585.0, 0.0, 0.0, 320.0, 240.0];
    let (p, _) = search(start, score(&start), score);
    for ((a, b), s) in p.iter().zip(target).zip(scale) {
        assert!((a - b).abs() < 0.02 * s, "{p:?}");
    }
}

#[test]
fn compare_passes_within_tolerance_and_names_what_is_off() {
    let file = Path::new("calibration/7scenes-kinect-v1.toml");
    let stated = calibration(STATED);
    // fx, tx, ty, cx, cy as the file states them, then each nudged.
    let exact: Params = [526.3, -0.0325, 0.0062, 322.7, 236.0];
    estimate_of(exact).compare(&stated, file).unwrap().ensure().unwrap();
    let mut near = exact;
    near[0] += 0.9 * CHECK_PIXELS;
    near[2] -= 0.9 * CHECK_METRES;
    estimate_of(near).compare(&stated, file).unwrap().ensure().unwrap();
    let mut far = exact;
    far[4] += 1.1 * CHECK_PIXELS;
    far[1] += 1.1 * CHECK_METRES;
    let e = estimate_of(far).compare(&stated, file).unwrap().ensure().unwrap_err().to_string();
    assert!(e.contains("cy differs") && e.contains("tx differs"), "{e}");
    assert!(!e.contains("fx") && !e.contains("ty"), "{e}");
    assert!(e.starts_with("calibration/7scenes-kinect-v1.toml does not match"), "{e}");
    let nan: Params = [f64::NAN, -0.0325, 0.0062, 322.7, 236.0];
    let e = estimate_of(nan).compare(&stated, file).unwrap().ensure().unwrap_err();
    assert!(e.to_string().contains("fx differs"), "{e}");
    // The listing, one line per value.
    let listing = estimate_of(exact).compare(&stated, file).unwrap().to_string();
    assert_eq!(listing.lines().count(), 5);
    assert!(listing.starts_with("fx: estimated 526.30000, calibration/7scenes-kinect-v1.toml"));
    // A calibration without a depth camera has no offset to compare.
    let e = estimate_of(exact).compare(&calibration(NOMINAL), file).unwrap_err();
    assert!(matches!(e, CalibrateDepthError::NoDepthTable { .. }), "{e}");
}

#[test]
fn the_file_written_loads_with_the_estimate_and_the_sensor_depth_camera() {
    let e = estimate_of([525.9375, -0.03172, 0.00719, 322.5, 235.75]);
    let text = e.to_toml();
    assert!(text.starts_with(
        "# Estimated from the images by `ferroslam-sim calibrate-depth data/7scenes --start 0 \
         --step 25`\n# (edge correlation 0.092 -> 0.410).\n"
    ));
    let c = calibration(&text);
    assert_eq!((c.fx, c.fy, c.cx, c.cy), (525.9, 525.9, 322.5, 235.8));
    assert_eq!((c.width, c.height, c.depth_scale), (640, 480, 1000.0));
    let d = c.depth.unwrap();
    assert_eq!((d.fx, d.fy, d.cx, d.cy), (585.0, 585.0, 320.0, 240.0));
    assert_eq!(d.t_m, [-0.0317, 0.0072, 0.0]);
    // What it writes passes its own check.
    e.compare(&c, Path::new("out.toml")).unwrap().ensure().unwrap();
    let summary = e.to_string();
    assert!(summary.contains("40 frames (from 0 every 25)"), "{summary}");
    assert!(summary.contains("tx = -31.72 mm, ty = 7.19 mm"), "{summary}");
}

/// A folder of `n` frames `w` x `h`: a flat gray image and `depth(k, x, y)` (raw, 1 mm), with
/// `calibration` as its `calibration.toml` unless `None`.
fn folder(dir: &Path, n: usize, calibration: Option<&str>, depth: impl Fn(usize, u32, u32) -> u16) {
    let (w, h) = (32u32, 24u32);
    fs::create_dir_all(dir.join("rgb")).unwrap();
    fs::create_dir_all(dir.join("depth")).unwrap();
    let (mut rgb, mut dl) = (String::new(), String::new());
    for k in 0..n {
        let t = k as f64 / 30.0;
        rgb += &format!("{t:.6} rgb/{k}.png\n");
        dl += &format!("{t:.6} depth/{k}.png\n");
        ImageBuffer::<Luma<u8>, Vec<u8>>::from_pixel(w, h, Luma([100]))
            .save(dir.join(format!("rgb/{k}.png")))
            .unwrap();
        ImageBuffer::<Luma<u16>, Vec<u16>>::from_fn(w, h, |x, y| Luma([depth(k, x, y)]))
            .save(dir.join(format!("depth/{k}.png")))
            .unwrap();
    }
    fs::write(dir.join("rgb.txt"), rgb).unwrap();
    fs::write(dir.join("depth.txt"), dl).unwrap();
    if let Some(text) = calibration {
        fs::write(dir.join("calibration.toml"), text).unwrap();
    }
}

const SMALL: &str =
    "fx = 30.0\nfy = 30.0\ncx = 16.0\ncy = 12.0\nwidth = 32\nheight = 24\ndepth_scale = 1000.0\n";

#[test]
fn bad_input_gives_an_error_naming_what_is_wrong() {
    let tmp = tempfile::tempdir().unwrap();
    let all = FrameSelection { start: 0, step: 1 };
    let err = |dir: &Path, sel| estimate(dir, sel).unwrap_err();

    let missing = tmp.path().join("absent");
    let e = err(&missing, all);
    assert!(matches!(e, CalibrateDepthError::NotAFolder { .. }), "{e}");
    assert!(e.to_string().contains("absent is not a dataset folder"), "{e}");

    // No calibration.toml.
    let bare = tmp.path().join("bare");
    folder(&bare, 2, None, |_, _, _| 1000);
    let e = err(&bare, all);
    assert!(matches!(e, CalibrateDepthError::NoCalibration { .. }), "{e}");
    assert!(e.to_string().contains("bare has no calibration.toml"), "{e}");
    // Nor does a folder named like a TUM sequence take its sensor's preset.
    let tum = tmp.path().join("rgbd_dataset_freiburg3_office");
    folder(&tum, 2, None, |_, _, _| 1000);
    assert!(matches!(err(&tum, all), CalibrateDepthError::NoCalibration { .. }));

    // A calibration that already registers depth.
    let registered = tmp.path().join("registered");
    let text = format!(
        "{SMALL}[depth]\nfx = 30.0\nfy = 30.0\ncx = 16.0\ncy = 12.0\ntx = 0.01\nty = 0.0\ntz = 0.0\n"
    );
    folder(&registered, 2, Some(&text), |_, _, _| 1000);
    let e = err(&registered, all);
    assert!(matches!(e, CalibrateDepthError::AlreadyRegistered { .. }), "{e}");

    // Flat depth: no edge anywhere.
    let flat = tmp.path().join("flat");
    folder(&flat, 3, Some(SMALL), |_, _, _| 1000);
    let e = err(&flat, all);
    assert!(matches!(e, CalibrateDepthError::NoDepthEdges { frames: 3, .. }), "{e}");
    let e = err(&flat, FrameSelection { start: 3, step: 1 });
    assert!(matches!(e, CalibrateDepthError::NoFrames { start: 3, len: 3, .. }), "{e}");
    assert!(matches!(
        err(&flat, FrameSelection { start: 0, step: 0 }),
        CalibrateDepthError::ZeroStep
    ));

    // A calibration the loader rejects: its error, naming the file and the key.
    let zero = tmp.path().join("zero");
    folder(&zero, 2, Some(&SMALL.replace("fx = 30.0", "fx = 0.0")), |_, _, _| 1000);
    let e = err(&zero, all);
    assert!(matches!(e, CalibrateDepthError::Dataset { .. }), "{e}");
    assert!(e.to_string().contains("calibration.toml") && e.to_string().contains("fx"), "{e}");

    // A listed frame whose depth image is not an image.
    let corrupt = tmp.path().join("corrupt");
    folder(&corrupt, 2, Some(SMALL), |_, _, _| 1000);
    fs::write(corrupt.join("depth/1.png"), b"not a png").unwrap();
    let e = err(&corrupt, all);
    assert!(e.to_string().contains("1.png"), "{e}");
}

#[test]
fn a_small_folder_with_depth_edges_gives_a_finite_estimate() {
    let tmp = tempfile::tempdir().unwrap();
    // A near square on a far wall, moving one pixel a frame.
    folder(tmp.path(), 3, Some(SMALL), |k, x, y| {
        let x0 = 10 + k as u32;
        if (x0..x0 + 8).contains(&x) && (8..16).contains(&y) { 800 } else { 1600 }
    });
    let e = estimate(tmp.path(), FrameSelection { start: 0, step: 1 }).unwrap();
    assert_eq!(e.frames, 3);
    assert!(e.colour_f_px.is_finite() && e.offset_m.iter().all(|v| v.is_finite()));
    // A flat colour image has no edges: nothing moves the estimate from the nominal values.
    assert_eq!((e.colour_f_px, e.colour_c_px, e.offset_m), (30.0, [16.0, 12.0], [0.0, 0.0]));
    assert_eq!(e.correlation, e.nominal_correlation);
}
