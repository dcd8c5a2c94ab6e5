//! The built-in synthetic sequence: determinism, exact ground truth, texture, options, frame port.

// Test helpers outside `#[test]` functions may panic too.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use ferroslam_core::frame::FrameSource;
use ferroslam_sim::synth::{
    DEPTH_SCALE, START_POSITION_M, SynthError, SynthFrame, SynthOptions, SyntheticSequence,
    write_pngs,
};

fn small(frames: usize) -> SynthOptions {
    SynthOptions { frames, width: 320, height: 240, ..SynthOptions::default() }
}

/// Outcome of reprojecting the depth of one frame into another.
#[derive(Debug, Default)]
struct Reprojection {
    /// Pixels whose reprojection landed on the same surface and were compared.
    compared: usize,
    /// Pixels hidden in the other frame by a nearer surface.
    occluded: usize,
    /// Pixels whose reprojection lands near a depth discontinuity, a crease or a hole.
    skipped: usize,
    /// Pixels where the other frame sees *farther* than the reprojected point (impossible with
    /// exact ground truth, beyond the tolerance).
    see_through: usize,
    /// Largest absolute depth disagreement among the compared pixels, metres.
    max_err_m: f64,
}

/// Inverse depth (1/m) at the sub-pixel position `(u, v)` of `frame`, from a least-squares plane
/// `1/z = a x + b y + c` through the 6x6 pixels around it; `None` unless all of them have depth and
/// lie on that plane to within the depth quantization (1/z is affine in the pixel coordinates on a
/// plane, so this skips silhouettes, creases and curved surfaces).
fn planar_inverse_depth(frame: &SynthFrame, u: f64, v: f64) -> Option<f64> {
    let (x0, y0) = (u.floor() as usize, v.floor() as usize);
    let (xs, ys) = (x0.checked_sub(2)?, y0.checked_sub(2)?);
    let mut pts = Vec::with_capacity(36);
    for y in ys..ys + 6 {
        for x in xs..xs + 6 {
            pts.push((x as f64 - u, y as f64 - v, 1.0 / frame.depth_m(x, y)?));
        }
    }
    // Normal equations of the fit, solved by Cramer's rule.
    let mut m = [[0.0f64; 3]; 3];
    let mut rhs = [0.0f64; 3];
    for &(dx, dy, q) in &pts {
        let row = [dx, dy, 1.0];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += row[i] * row[j];
            }
            rhs[i] += row[i] * q;
        }
    }
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(&m);
    let solve = |k: usize| {
        let mut mk = m;
        for i in 0..3 {
            mk[i][k] = rhs[i];
        }
        det(&mk) / d
    };
    let (a, b, c) = (solve(0), solve(1), solve(2));
    // Quantization: z is off by at most half a raw unit, 1/z by that over z^2.
    let half_step = 0.5 / f64::from(frame.depth_scale);
    let planar =
        pts.iter().all(|&(dx, dy, q)| (a * dx + b * dy + c - q).abs() <= 1.5 * half_step * q * q);
    planar.then_some(c)
}

/// Takes every third pixel of `fi` with its depth, maps it with `to_j` (pixel and depth in frame
/// i to the camera-frame point in frame j, metres), projects it into `fj` and compares its z with
/// the depth that `fj` shows there (see [`planar_inverse_depth`]).
fn reproject<F>(
    seq: &SyntheticSequence,
    fi: &SynthFrame,
    fj: &SynthFrame,
    to_j: F,
    tol_m: f64,
) -> Reprojection
where
    F: Fn(f64, f64, f64) -> [f64; 3],
{
    let intr = seq.intrinsics();
    let mut r = Reprojection::default();
    for y in (0..intr.height).step_by(3) {
        for x in (0..intr.width).step_by(3) {
            let Some(z) = fi.depth_m(x, y) else { continue };
            let [px, py, pz] = to_j(x as f64, y as f64, z);
            if pz <= 0.0 {
                continue;
            }
            let (u, v) = (intr.fx * px / pz + intr.cx, intr.fy * py / pz + intr.cy);
            if !(u >= 0.0
                && v >= 0.0
                && u <= (intr.width - 1) as f64
                && v <= (intr.height - 1) as f64)
            {
                continue;
            }
            let Some(q_uv) = planar_inverse_depth(fj, u, v) else {
                r.skipped += 1;
                continue;
            };
            let err = 1.0 / q_uv - pz;
            if err < -tol_m {
                r.occluded += 1;
            } else if err > tol_m {
                r.see_through += 1;
            } else {
                r.compared += 1;
                r.max_err_m = r.max_err_m.max(err.abs());
            }
        }
    }
    r
}

/// Reprojection of frame `i` into frame `j` with the sequence's own ground truth.
fn reproject_gt(seq: &SyntheticSequence, i: usize, j: usize, tol_m: f64) -> Reprojection {
    let (fi, fj) = (seq.render(i).unwrap(), seq.render(j).unwrap());
    let t_ji = seq.ground_truth(j).unwrap().t_wc.inverse() * seq.ground_truth(i).unwrap().t_wc;
    let intr = seq.intrinsics();
    let to_j = |x, y, z| {
        let p = t_ji * intr.back_project(x, y, z);
        [p.x, p.y, p.z]
    };
    reproject(seq, &fi, &fj, to_j, tol_m)
}

/// Depth quantization (one raw unit) plus a small margin for rounding in the transforms.
const TOL_M: f64 = 1.0 / DEPTH_SCALE + 5e-5;

fn assert_exact(r: &Reprojection, what: &str) {
    let total = r.compared + r.occluded + r.skipped + r.see_through;
    assert_eq!(r.see_through, 0, "{what}: a surface seen behind a reprojected point: {r:?}");
    assert!(r.max_err_m <= TOL_M, "{what}: {r:?}");
    assert!(r.compared * 10 >= total * 6, "{what}: too few comparable pixels: {r:?}");
}

#[test]
fn ground_truth_is_exact_by_reprojection() {
    let seq = SyntheticSequence::new(SynthOptions::default()).unwrap();
    for (i, j) in [(0, 1), (0, 12), (40, 55), (100, 130), (200, 290), (299, 250)] {
        let r = reproject_gt(&seq, i, j, TOL_M);
        assert_exact(&r, &format!("frames {i} -> {j}"));
    }
}

#[test]
fn ground_truth_is_exact_with_shake_and_fast_rotation() {
    let opts = SynthOptions { shake: 2.0, fast_rotation: true, seed: 5, ..SynthOptions::default() };
    let seq = SyntheticSequence::new(opts).unwrap();
    for (i, j) in [(10, 13), (77, 80), (150, 152)] {
        let r = reproject_gt(&seq, i, j, TOL_M);
        assert_exact(&r, &format!("shaken frames {i} -> {j}"));
    }
}

#[test]
fn reprojection_detects_a_wrong_pose() {
    // Negative control: the same check with the pose of the *next* frame (about 1 cm and 1 degree
    // off) must fail, so passing above means something.
    let seq = SyntheticSequence::new(SynthOptions::default()).unwrap();
    let (fi, fj) = (seq.render(40).unwrap(), seq.render(55).unwrap());
    let wrong = seq.ground_truth(56).unwrap().t_wc.inverse() * seq.ground_truth(40).unwrap().t_wc;
    let intr = seq.intrinsics();
    let to_j = |x, y, z| {
        let p = wrong * intr.back_project(x, y, z);
        [p.x, p.y, p.z]
    };
    let r = reproject(&seq, &fi, &fj, to_j, TOL_M);
    assert!(
        r.see_through > 1000 && r.compared * 10 < (r.compared + r.see_through + r.occluded),
        "{r:?}"
    );
}

/// Fraction of pixels whose central-difference gradient magnitude exceeds `threshold` gray
/// levels, and fraction of 32x32 blocks whose standard deviation exceeds `min_std`.
fn texture_stats(f: &SynthFrame, threshold: f64, min_std: f64) -> (f64, f64) {
    let (w, h) = (f.width, f.height);
    let g = |x: usize, y: usize| f64::from(f.gray[y * w + x]);
    let mut strong = 0usize;
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let (gx, gy) = (g(x + 1, y) - g(x - 1, y), g(x, y + 1) - g(x, y - 1));
            if (gx * gx + gy * gy).sqrt() > threshold {
                strong += 1;
            }
        }
    }
    let (mut textured, mut blocks) = (0usize, 0usize);
    for by in (0..h - 31).step_by(32) {
        for bx in (0..w - 31).step_by(32) {
            let vals: Vec<f64> = (by..by + 32)
                .flat_map(|y| (bx..bx + 32).map(move |x| (x, y)))
                .map(|(x, y)| g(x, y))
                .collect();
            let mean = vals.iter().sum::<f64>() / vals.len() as f64;
            let var = vals.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / vals.len() as f64;
            blocks += 1;
            if var.sqrt() > min_std {
                textured += 1;
            }
        }
    }
    (strong as f64 / ((w - 2) * (h - 2)) as f64, textured as f64 / blocks as f64)
}

#[test]
fn texture_has_structure_everywhere() {
    let seq = SyntheticSequence::new(SynthOptions::default()).unwrap();
    for i in [0, 60, 120, 180, 240, 299] {
        let f = seq.render(i).unwrap();
        let (strong, textured) = texture_stats(&f, 24.0, 4.0);
        assert!(strong > 0.15, "frame {i}: only {strong:.3} of the pixels have a strong gradient");
        assert!(textured > 0.9, "frame {i}: only {textured:.3} of 32x32 blocks are textured");
        // Exposure: neither dark nor saturated.
        let mean = f.gray.iter().map(|&g| f64::from(g)).sum::<f64>() / f.gray.len() as f64;
        let clipped = f.gray.iter().filter(|&&g| g == 0 || g == 255).count();
        assert!((70.0..180.0).contains(&mean), "frame {i}: mean gray {mean}");
        assert!(clipped * 100 < f.gray.len(), "frame {i}: {clipped} clipped pixels");
    }
}

#[test]
fn depth_is_dense_and_in_range_by_default() {
    let seq = SyntheticSequence::new(small(300)).unwrap();
    for i in [0, 150, 299] {
        let f = seq.render(i).unwrap();
        assert_eq!(f.depth_scale, 5000.0);
        assert!(f.depth.iter().all(|&d| d > 0), "frame {i} has holes without hole options");
        let (lo, hi) = f.depth.iter().fold((u16::MAX, 0), |(lo, hi), &d| (lo.min(d), hi.max(d)));
        // The camera keeps 0.5 m from everything; the far corners of the room are within 8 m.
        assert!(lo >= 2500 && hi <= 40_000, "frame {i}: depth {lo}..{hi} raw");
    }
}

#[test]
fn frames_are_bit_identical_across_runs_and_thread_counts() {
    let noisy = SynthOptions {
        depth_noise_k: 0.002,
        gray_noise_sigma: 2.0,
        hole_fraction: 0.05,
        grazing_limit_deg: Some(75.0),
        shake: 1.0,
        motion_blur_samples: 2,
        seed: 11,
        ..small(40)
    };
    for base in [small(40), noisy] {
        let reference = SyntheticSequence::new(SynthOptions { threads: 1, ..base.clone() })
            .unwrap()
            .render(33)
            .unwrap();
        for threads in [1, 2, 3, 7] {
            let seq = SyntheticSequence::new(SynthOptions { threads, ..base.clone() }).unwrap();
            for _ in 0..2 {
                let f = seq.render(33).unwrap();
                assert!(f == reference, "{threads} threads gave different bytes");
            }
        }
    }
}

#[test]
fn intrinsics_are_as_documented() {
    let vga = SyntheticSequence::new(SynthOptions::default()).unwrap().intrinsics();
    assert_eq!((vga.fx, vga.fy, vga.cx, vga.cy), (525.0, 525.0, 319.5, 239.5));
    assert_eq!((vga.width, vga.height, vga.depth_scale), (640, 480, 5000.0));
    let qvga = SyntheticSequence::new(small(1)).unwrap().intrinsics();
    assert_eq!((qvga.fx, qvga.fy, qvga.cx, qvga.cy), (262.5, 262.5, 159.5, 119.5));
    assert_eq!((qvga.width, qvga.height), (320, 240));
}

#[test]
fn timestamps_and_ground_truth() {
    let seq = SyntheticSequence::new(small(300)).unwrap();
    assert_eq!(seq.len(), 300);
    let all = seq.ground_truth_all();
    assert_eq!(all.poses.len(), 300);
    for (i, p) in all.poses.iter().enumerate() {
        assert_eq!(p.timestamp_s, i as f64 / 30.0);
        assert_eq!(Some(*p), seq.ground_truth(i));
    }
    assert!(seq.ground_truth(300).is_none());
    let t0 = all.poses[0].t_wc.translation.vector;
    assert_eq!([t0.x, t0.y, t0.z], START_POSITION_M);
    // About 2.7 m of travel, yaw sweeping through +-40 degrees.
    let length: f64 = all
        .poses
        .windows(2)
        .map(|w| (w[1].t_wc.translation.vector - w[0].t_wc.translation.vector).norm())
        .sum();
    assert!((2.5..3.0).contains(&length), "path length {length}");
    let headings: Vec<f64> = all
        .poses
        .iter()
        .map(|p| {
            // Heading of the optical axis (third column of R_wc), positive to the left of north.
            let r = p.t_wc.rotation.to_rotation_matrix();
            (-r[(0, 2)]).atan2(r[(1, 2)]).to_degrees()
        })
        .collect();
    let (lo, hi) = headings.iter().fold((0.0f64, 0.0f64), |(lo, hi), &h| (lo.min(h), hi.max(h)));
    assert!(lo < -35.0 && hi > 35.0, "heading range {lo}..{hi}");
    let f = seq.render(299).unwrap();
    assert_eq!(f.timestamp_s, 299.0 / 30.0);
}

#[test]
#[ignore = "timing: renders SYNTH_BENCH_FRAMES (default 300) default frames; run in release"]
fn render_speed() {
    let n: usize =
        std::env::var("SYNTH_BENCH_FRAMES").ok().and_then(|s| s.parse().ok()).unwrap_or(300);
    let threads: usize =
        std::env::var("SYNTH_BENCH_THREADS").ok().and_then(|s| s.parse().ok()).unwrap_or(2);
    let seq =
        SyntheticSequence::new(SynthOptions { frames: n, threads, ..SynthOptions::default() })
            .unwrap();
    let t = std::time::Instant::now();
    let mut sum = 0u64;
    for i in 0..n {
        let f = seq.render(i).unwrap();
        sum += f.gray.iter().map(|&g| u64::from(g)).sum::<u64>();
    }
    eprintln!("{n} frames in {:?} ({threads} threads), checksum {sum}", t.elapsed());
}

#[test]
fn holes_remove_depth_only() {
    let clean = SyntheticSequence::new(small(10)).unwrap().render(5).unwrap();
    let opts = SynthOptions { hole_fraction: 0.1, seed: 3, ..small(10) };
    let holed = SyntheticSequence::new(opts).unwrap().render(5).unwrap();
    assert_eq!(holed.gray, clean.gray);
    let zeros = holed.depth.iter().filter(|&&d| d == 0).count() as f64 / holed.depth.len() as f64;
    assert!((0.1..0.12).contains(&zeros), "hole fraction {zeros}");
    // Outside the holes the depth is untouched.
    assert!(holed.depth.iter().zip(&clean.depth).all(|(&h, &c)| h == 0 || h == c));
    // Holes move from frame to frame.
    let other = SyntheticSequence::new(SynthOptions { hole_fraction: 0.1, seed: 3, ..small(10) })
        .unwrap()
        .render(6)
        .unwrap();
    let same = holed.depth.iter().zip(&other.depth).filter(|&(&a, &b)| (a == 0) && (b == 0)).count()
        as f64;
    assert!(same / holed.depth.len() as f64 > 0.0 && same / (holed.depth.len() as f64) < 0.05);
}

#[test]
fn grazing_limit_removes_oblique_surfaces() {
    let clean = SyntheticSequence::new(small(10)).unwrap().render(0).unwrap();
    let opts = SynthOptions { grazing_limit_deg: Some(70.0), ..small(10) };
    let f = SyntheticSequence::new(opts).unwrap().render(0).unwrap();
    assert_eq!(f.gray, clean.gray);
    let zeros = f.depth.iter().filter(|&&d| d == 0).count();
    assert!(zeros > 0 && zeros < f.depth.len() / 2, "{zeros} grazing holes");
    // The far floor is seen at grazing incidence, the wall straight ahead is not.
    let (w, h) = (f.width, f.height);
    assert!(f.depth[(h / 2 + 20) * w + w / 2] == 0 || f.depth[(h / 2 + 30) * w + w / 2] == 0);
    assert!(f.depth[(h / 4) * w + w / 2] != 0);
}

#[test]
fn depth_noise_changes_depth_not_gray() {
    let k = 0.0015;
    let clean = SyntheticSequence::new(small(10)).unwrap().render(3).unwrap();
    let noisy = SyntheticSequence::new(SynthOptions { depth_noise_k: k, seed: 9, ..small(10) })
        .unwrap()
        .render(3)
        .unwrap();
    assert_eq!(noisy.gray, clean.gray);
    assert_ne!(noisy.depth, clean.depth);
    // (noisy - clean) / z^2 is a sample of N(0, k^2), up to quantization.
    let d: Vec<f64> = noisy
        .depth
        .iter()
        .zip(&clean.depth)
        .map(|(&n, &c)| {
            let z = f64::from(c) / 5000.0;
            (f64::from(n) - f64::from(c)) / 5000.0 / (z * z)
        })
        .collect();
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let sigma = (d.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / d.len() as f64).sqrt();
    assert!(mean.abs() < 0.05 * k, "mean {mean}");
    assert!((sigma / k - 1.0).abs() < 0.1, "sigma {sigma} vs k {k}");
}

#[test]
fn gray_noise_changes_gray_not_depth() {
    let clean = SyntheticSequence::new(small(10)).unwrap().render(3).unwrap();
    let noisy = SyntheticSequence::new(SynthOptions { gray_noise_sigma: 3.0, ..small(10) })
        .unwrap()
        .render(3)
        .unwrap();
    assert_eq!(noisy.depth, clean.depth);
    let diff: Vec<f64> =
        noisy.gray.iter().zip(&clean.gray).map(|(&a, &b)| f64::from(a) - f64::from(b)).collect();
    let rms = (diff.iter().map(|d| d * d).sum::<f64>() / diff.len() as f64).sqrt();
    assert!((2.7..3.3).contains(&rms), "gray noise rms {rms}");
}

/// Largest rotation between consecutive frames, degrees, and largest distance from the calm path.
fn path_stats(seq: &SyntheticSequence) -> f64 {
    let gt = seq.ground_truth_all();
    gt.poses
        .windows(2)
        .map(|w| (w[0].t_wc.inverse() * w[1].t_wc).rotation.angle().to_degrees())
        .fold(0.0, f64::max)
}

#[test]
fn shake_perturbs_the_ground_truth_slightly() {
    let calm = SyntheticSequence::new(small(300)).unwrap();
    let shaken =
        SyntheticSequence::new(SynthOptions { shake: 1.0, seed: 1, ..small(300) }).unwrap();
    let again = SyntheticSequence::new(SynthOptions { shake: 1.0, seed: 1, ..small(300) }).unwrap();
    let other = SyntheticSequence::new(SynthOptions { shake: 1.0, seed: 2, ..small(300) }).unwrap();
    assert_eq!(shaken.ground_truth_all(), again.ground_truth_all());
    assert_ne!(shaken.ground_truth_all(), other.ground_truth_all());
    let (mut max_t, mut max_r) = (0.0f64, 0.0f64);
    for i in 0..300 {
        let (a, b) = (calm.ground_truth(i).unwrap().t_wc, shaken.ground_truth(i).unwrap().t_wc);
        let d = a.inverse() * b;
        max_t = max_t.max(d.translation.vector.norm());
        max_r = max_r.max(d.rotation.angle().to_degrees());
    }
    assert!(max_t > 0.002 && max_t < 0.01, "shake translation {max_t} m");
    assert!(max_r > 0.2 && max_r < 1.0, "shake rotation {max_r} deg");
    // High-frequency: the shaken path turns more between frames than the calm one.
    assert!(path_stats(&shaken) > path_stats(&calm));
    // The rendered image follows the shaken pose.
    assert_ne!(shaken.render(17).unwrap().gray, calm.render(17).unwrap().gray);
}

#[test]
fn fast_rotation_turns_faster() {
    let calm = SyntheticSequence::new(small(300)).unwrap();
    let fast = SyntheticSequence::new(SynthOptions { fast_rotation: true, ..small(300) }).unwrap();
    let (slow_deg, fast_deg) = (path_stats(&calm), path_stats(&fast));
    assert!(slow_deg < 2.0 && fast_deg > 2.5 * slow_deg, "{slow_deg} vs {fast_deg} deg per frame");
}

#[test]
fn motion_blur_softens_gray_and_keeps_depth() {
    let sharp = SyntheticSequence::new(SynthOptions { fast_rotation: true, ..small(60) })
        .unwrap()
        .render(40)
        .unwrap();
    let opts = SynthOptions {
        fast_rotation: true,
        motion_blur_samples: 6,
        exposure_frames: 1.0,
        ..small(60)
    };
    let blurred = SyntheticSequence::new(opts).unwrap().render(40).unwrap();
    assert_eq!(blurred.depth, sharp.depth);
    assert_ne!(blurred.gray, sharp.gray);
    let (strong_sharp, _) = texture_stats(&sharp, 24.0, 4.0);
    let (strong_blur, _) = texture_stats(&blurred, 24.0, 4.0);
    assert!(strong_blur < 0.8 * strong_sharp, "{strong_blur} vs {strong_sharp}");
}

#[test]
fn invalid_options_are_rejected() {
    let cases: [(SynthOptions, &str); 12] = [
        (SynthOptions { frames: 0, ..small(1) }, "frames"),
        (SynthOptions { width: 0, ..small(1) }, "width"),
        (SynthOptions { height: 3, ..small(1) }, "height"),
        (SynthOptions { depth_noise_k: f64::NAN, ..small(1) }, "depth_noise_k"),
        (SynthOptions { hole_fraction: 1.5, ..small(1) }, "hole_fraction"),
        (SynthOptions { grazing_limit_deg: Some(0.0), ..small(1) }, "grazing_limit_deg"),
        (SynthOptions { max_range_m: 20.0, ..small(1) }, "max_range_m"),
        (SynthOptions { gray_noise_sigma: -1.0, ..small(1) }, "gray_noise_sigma"),
        (SynthOptions { motion_blur_samples: 0, ..small(1) }, "motion_blur_samples"),
        (SynthOptions { exposure_frames: f64::INFINITY, ..small(1) }, "exposure_frames"),
        (SynthOptions { shake: f64::NAN, ..small(1) }, "shake"),
        (SynthOptions { threads: 1000, ..small(1) }, "threads"),
    ];
    for (opts, field) in cases {
        match SyntheticSequence::new(opts) {
            Err(SynthError::InvalidOption { name, .. }) => assert_eq!(name, field),
            other => panic!("{field}: expected InvalidOption, got {other:?}"),
        }
    }
}

#[test]
fn rendering_past_the_end_is_an_error() {
    let seq = SyntheticSequence::new(small(2)).unwrap();
    assert!(matches!(seq.render(2), Err(SynthError::FrameOutOfRange { index: 2, len: 2 })));
}

#[test]
fn frame_source_yields_the_frames_in_order() {
    let seq = SyntheticSequence::new(small(3)).unwrap();
    let expected: Vec<SynthFrame> = (0..3).map(|i| seq.render(i).unwrap()).collect();
    let mut source = seq.into_source();
    for e in &expected {
        let frame = source.next_frame().unwrap().unwrap();
        assert_eq!(frame.timestamp_s, e.timestamp_s);
        assert_eq!(frame.gray.size(), (320, 240));
        assert_eq!(frame.depth.size(), (320, 240));
        assert_eq!(frame.depth.depth_scale(), 5000.0);
        assert!(frame.gray.rows().flatten().eq(e.gray.iter()));
        assert!(frame.depth.raw().rows().flatten().eq(e.depth.iter()));
        assert_eq!(frame.depth.depth_m(10, 20), e.depth_m(10, 20).map(|d| d as f32));
    }
    assert!(source.next_frame().unwrap().is_none());
    assert!(source.next_frame().unwrap().is_none());
}

#[test]
fn frames_can_be_saved_as_png() {
    let dir = tempfile::tempdir().unwrap();
    let f = SyntheticSequence::new(small(1)).unwrap().render(0).unwrap();
    let (gray, depth) = write_pngs(&f, dir.path(), "frame0").unwrap();
    for p in [gray, depth] {
        let bytes = std::fs::read(&p).unwrap();
        assert!(bytes.len() > 1000 && bytes.starts_with(b"\x89PNG"), "{}", p.display());
    }
    // The PNG helper also writes the demo's look-at images when asked to.
    if let Ok(out) = std::env::var("SYNTH_PNG_DIR") {
        let seq = SyntheticSequence::new(SynthOptions::default()).unwrap();
        for i in [0, 75, 150, 225] {
            write_pngs(&seq.render(i).unwrap(), std::path::Path::new(&out), &format!("synth_{i}"))
                .unwrap();
        }
    }
}
