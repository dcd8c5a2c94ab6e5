//! `cargo xtask calibrate-depth`: estimates how an unregistered depth camera sits beside the
//! colour camera, from the images alone, and prints a calibration file with a `[depth]` table
//! (the format `ferroslam-sim replay --calibration` reads; see host-sim's `dataset::registration`).
//!
//! ```text
//! cargo xtask calibrate-depth [--dataset DIR] [--start N] [--step N] [--check FILE]
//! ```
//!
//! - `--dataset`: a TUM-layout folder whose `calibration.toml` holds the depth camera's
//!   intrinsics (default: 7-Scenes, which ships its depth camera's nominal ones).
//! - `--start`, `--step`: frames `start, start + step, ...` are used (default 0 and 25: 40 frames
//!   of 7-Scenes).
//! - `--check FILE`: instead of printing a calibration, compares the estimate with `FILE`'s
//!   colour intrinsics and depth offset and fails when one differs by more than
//!   [`CHECK_PIXELS`] or [`CHECK_METRES`]. `cargo xtask ci` checks
//!   [`crate::ci::SEVEN_SCENES_CALIBRATION`] so, which proves the file still follows from the
//!   images by this method (loader, registration and estimator unchanged in effect).
//!
//! Method. A depth edge (a pixel on the near side of a depth jump of more than
//! [`JUMP_FRACTION`]) is an object's outline, and the colour image has an edge there too. For a
//! candidate colour focal length `f` (square pixels), principal point `(cx, cy)` and offset
//! `(tx, ty)` of the depth camera (metres, no rotation, `tz = 0`), every sampled depth pixel is
//! back-projected with the depth intrinsics, moved by the offset and projected into the colour
//! image, where the colour edge strength (Sobel magnitude of the image blurred with a Gaussian of
//! sigma 1 px, divided by its mean) is read bilinearly. The score is the correlation, averaged
//! over the frames, between that strength and "is a depth edge" over the depth edges and three
//! times as many other valid depth pixels (drawn with a fixed seed): it is high when depth
//! outlines land on colour outlines. A coordinate search from the nominal values (the depth
//! camera's own intrinsics, no offset) tries a step up and down in each parameter, keeps any
//! gain, and halves the steps when none helps, until the focal step is below 0.1 px. No ground
//! truth is read. Deterministic.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use ferroslam_core::config::VGA;
use ferroslam_sim::dataset::{Calibration, Dataset, DatasetOptions};

use crate::ci::{SEVEN_SCENES, root};

/// A depth pixel is an edge when a 4-neighbour is farther by more than this fraction of its depth.
const JUMP_FRACTION: f64 = 0.08;
/// Pixels kept from the image border (the neighbour test and the blur need them).
const BORDER: usize = 4;
/// Non-edge pixels sampled per edge pixel.
const NON_EDGE_PER_EDGE: usize = 3;
/// `--check`: most a colour intrinsic (fx, cx, cy) may differ from the file's, pixels. The
/// estimate over three disjoint subsets of 7-Scenes spans 0.2-0.3 px per value, and differs from
/// the file (the first implementation's rounded values) by up to 0.4 px; this allows that and
/// the search's last step (fx 0.08 px), and catches any change that moves the estimate by more.
pub const CHECK_PIXELS: f64 = 0.5;
/// `--check`: most a depth offset (tx, ty) may differ from the file's, metres. The subsets span
/// 0.6-0.8 mm and differ from the file by up to 1.0 mm (0.26 VGA px of registration error at
/// 2 m); this allows that with the same margin as [`CHECK_PIXELS`].
pub const CHECK_METRES: f64 = 0.0015;

/// Options of `calibrate-depth`.
#[derive(Debug, Clone)]
struct Options {
    dataset: PathBuf,
    start: usize,
    step: usize,
    /// `--check FILE`.
    check: Option<PathBuf>,
}

impl Default for Options {
    /// 7-Scenes, frames 0, 25, 50, ..., printing the estimate.
    fn default() -> Self {
        Self { dataset: root().join(SEVEN_SCENES), start: 0, step: 25, check: None }
    }
}

/// One frame's samples: the colour edge map and the sampled depth pixels.
struct FrameSamples {
    width: usize,
    height: usize,
    /// Colour edge strength, row-major, mean 1.
    edges: Vec<f64>,
    /// `(u, v, z_m, is_depth_edge)` of each sampled depth pixel.
    samples: Vec<(f64, f64, f64, f64)>,
}

/// The parameters searched: colour focal length (px), depth offset x and y (m), colour
/// principal point x and y (px).
type Params = [f64; 5];

/// Runs `calibrate-depth` with the command-line `args` (after the subcommand).
///
/// # Errors
/// Bad arguments, an unreadable dataset, or frames without depth edges.
pub fn run(args: &[String]) -> Result<()> {
    estimate(&parse_args(args)?)
}

/// `calibrate-depth --check file` with the other options at their defaults (what `cargo xtask
/// ci` runs).
///
/// # Errors
/// As [`run`], and an estimate outside the tolerances of `file`'s values.
pub fn check_file(file: PathBuf) -> Result<()> {
    estimate(&Options { check: Some(file), ..Options::default() })
}

/// Estimates the calibration of `opts.dataset`, then prints it or checks it against
/// `opts.check`.
fn estimate(opts: &Options) -> Result<()> {
    let vga = DatasetOptions { profile: VGA, ..DatasetOptions::default() };
    let dataset = Dataset::open(&opts.dataset, &vga)?;
    let c = *dataset.sensor_calibration();
    if c.depth.is_some() {
        bail!("{}: its calibration already registers depth", opts.dataset.display());
    }
    let depth = [f64::from(c.fx), f64::from(c.fy), f64::from(c.cx), f64::from(c.cy)];
    let mut frames = Vec::new();
    for i in (opts.start..dataset.len()).step_by(opts.step.max(1)) {
        let f = dataset.load_frame(i)?;
        frames.push(samples(&f.gray, &f.depth, f.width, f.height, f64::from(f.depth_scale), i));
    }
    if frames.iter().all(|f| f.samples.is_empty()) {
        bail!("no depth edges in the frames used");
    }
    let score = |p: &Params| mean_correlation(&frames, &depth, p);
    let nominal: Params = [depth[0], 0.0, 0.0, depth[2], depth[3]];
    let start_score = score(&nominal);
    let (p, best) = search(nominal, start_score, score);
    if let Some(file) = &opts.check {
        return check(file, &p);
    }
    eprintln!(
        "{} frames (from {} every {}): edge correlation {start_score:.4} with the nominal values, \
         {best:.4} estimated",
        frames.len(),
        opts.start,
        opts.step
    );
    println!(
        "# Estimated by `cargo xtask calibrate-depth --dataset {} --start {} --step {}`\n\
         # (edge correlation {start_score:.3} -> {best:.3}).\n\
         fx = {:.1}\nfy = {:.1}\ncx = {:.1}\ncy = {:.1}\nwidth = {}\nheight = {}\n\
         depth_scale = {}\n\n[depth]\nfx = {}\nfy = {}\ncx = {}\ncy = {}\n\
         tx = {:.4}\nty = {:.4}\ntz = 0.0",
        opts.dataset.display(),
        opts.start,
        opts.step,
        p[0],
        p[0],
        p[3],
        p[4],
        c.width,
        c.height,
        c.depth_scale,
        c.fx,
        c.fy,
        c.cx,
        c.cy,
        p[1],
        p[2],
    );
    Ok(())
}

/// `--check`: the estimate `p` against `file`'s values, each within its tolerance.
fn check(file: &std::path::Path, p: &Params) -> Result<()> {
    let c = Calibration::load(file)?;
    let d = c.depth.with_context(|| format!("{} has no [depth] table", file.display()))?;
    let values = [
        ("fx", p[0], f64::from(c.fx), CHECK_PIXELS),
        ("cx", p[3], f64::from(c.cx), CHECK_PIXELS),
        ("cy", p[4], f64::from(c.cy), CHECK_PIXELS),
        ("tx", p[1], f64::from(d.t_m[0]), CHECK_METRES),
        ("ty", p[2], f64::from(d.t_m[1]), CHECK_METRES),
    ];
    let mut off = Vec::new();
    for (name, estimated, stated, tolerance) in values {
        let diff = estimated - stated;
        eprintln!("{name}: estimated {estimated:.5}, {} states {stated:.5}", file.display());
        // NaN is off too.
        if diff.is_nan() || diff.abs() > tolerance {
            off.push(format!("{name} differs by {diff:.4} (tolerance {tolerance})"));
        }
    }
    if !off.is_empty() {
        bail!("{} does not match the estimate from the images: {}", file.display(), off.join("; "));
    }
    eprintln!("{}: every value within tolerance of the estimate", file.display());
    Ok(())
}

/// The coordinate search of the module documentation, from `p` scoring `best`.
fn search(mut p: Params, mut best: f64, score: impl Fn(&Params) -> f64) -> (Params, f64) {
    let mut steps: Params = [20.0, 0.02, 0.02, 8.0, 8.0];
    while steps[0] >= 0.1 {
        let mut improved = false;
        for k in 0..p.len() {
            for sign in [1.0, -1.0] {
                let mut q = p;
                q[k] += sign * steps[k];
                let s = score(&q);
                if s > best {
                    (best, p, improved) = (s, q, true);
                }
            }
        }
        if !improved {
            steps = steps.map(|s| s / 2.0);
        }
    }
    (p, best)
}

/// The correlation of the module documentation, averaged over the frames that have samples.
fn mean_correlation(frames: &[FrameSamples], depth: &[f64; 4], p: &Params) -> f64 {
    let [dfx, dfy, dcx, dcy] = *depth;
    let [f, tx, ty, cx, cy] = *p;
    let (mut sum, mut n) = (0.0, 0usize);
    for fr in frames.iter().filter(|fr| !fr.samples.is_empty()) {
        let pairs = fr.samples.iter().map(|&(u, v, z, e)| {
            let x = (u - dcx) * z / dfx + tx;
            let y = (v - dcy) * z / dfy + ty;
            (bilinear(&fr.edges, fr.width, fr.height, cx + f * x / z, cy + f * y / z), e)
        });
        sum += correlation(pairs);
        n += 1;
    }
    sum / n.max(1) as f64
}

/// Pearson correlation of the pairs (0 when either side is constant).
fn correlation(pairs: impl Iterator<Item = (f64, f64)> + Clone) -> f64 {
    let (mut n, mut sa, mut sb) = (0.0, 0.0, 0.0);
    for (a, b) in pairs.clone() {
        (n, sa, sb) = (n + 1.0, sa + a, sb + b);
    }
    let (ma, mb) = (sa / n, sb / n);
    let (mut cab, mut caa, mut cbb) = (0.0, 0.0, 0.0);
    for (a, b) in pairs {
        let (da, db) = (a - ma, b - mb);
        (cab, caa, cbb) = (cab + da * db, caa + da * da, cbb + db * db);
    }
    if caa > 0.0 && cbb > 0.0 { cab / (caa * cbb).sqrt() } else { 0.0 }
}

/// `img` at `(x, y)`, bilinearly, with coordinates clamped to the image.
fn bilinear(img: &[f64], w: usize, h: usize, x: f64, y: f64) -> f64 {
    let x = x.clamp(0.0, (w - 1) as f64);
    let y = y.clamp(0.0, (h - 1) as f64);
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (ax, ay) = (x - x0 as f64, y - y0 as f64);
    let at = |xx: usize, yy: usize| img.get(yy * w + xx).copied().unwrap_or(0.0);
    let top = at(x0, y0) * (1.0 - ax) + at(x1, y0) * ax;
    let bottom = at(x0, y1) * (1.0 - ax) + at(x1, y1) * ax;
    top * (1.0 - ay) + bottom * ay
}

/// The colour edge map and the depth samples of one frame (`seed` picks the non-edge pixels).
fn samples(
    gray: &[u8],
    depth: &[u16],
    w: usize,
    h: usize,
    scale: f64,
    seed: usize,
) -> FrameSamples {
    let edges = edge_strength(gray, w, h);
    let z = |x: usize, y: usize| f64::from(depth[y * w + x]) / scale;
    let (mut edge, mut other) = (Vec::new(), Vec::new());
    for y in BORDER..h.saturating_sub(BORDER) {
        for x in BORDER..w.saturating_sub(BORDER) {
            let d = z(x, y);
            if d <= 0.0 {
                continue;
            }
            let neighbours = [z(x - 1, y), z(x + 1, y), z(x, y - 1), z(x, y + 1)];
            let jump = neighbours.iter().any(|&n| n > 0.0 && (n - d) / d > JUMP_FRACTION);
            (if jump { &mut edge } else { &mut other }).push((x as f64, y as f64, d));
        }
    }
    // A fixed-seed xorshift draw of the non-edge pixels (partial Fisher-Yates).
    let mut state = 0x9E37_79B9_7F4A_7C15u64 ^ (seed as u64).wrapping_mul(0x2545_F491_4F6C_DD1D);
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let take = (edge.len() * NON_EDGE_PER_EDGE).min(other.len());
    for i in 0..take {
        let j = i + (next() % (other.len() - i) as u64) as usize;
        other.swap(i, j);
    }
    let samples = edge
        .iter()
        .map(|&(u, v, d)| (u, v, d, 1.0))
        .chain(other.iter().take(take).map(|&(u, v, d)| (u, v, d, 0.0)))
        .collect();
    FrameSamples { width: w, height: h, edges, samples }
}

/// Sobel gradient magnitude of `gray` blurred by a Gaussian of sigma 1 px (radius 4, borders
/// clamped), divided by its mean.
fn edge_strength(gray: &[u8], w: usize, h: usize) -> Vec<f64> {
    let kernel: Vec<f64> = (-4i32..=4).map(|i| (-f64::from(i * i) / 2.0).exp()).collect();
    let norm: f64 = kernel.iter().sum();
    let clamp = |i: isize, n: usize| i.clamp(0, n as isize - 1) as usize;
    let blur = |src: &dyn Fn(usize, usize) -> f64, horizontal: bool| -> Vec<f64> {
        let mut out = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut s = 0.0;
                for (k, kv) in kernel.iter().enumerate() {
                    let o = k as isize - 4;
                    s += kv
                        * if horizontal {
                            src(clamp(x as isize + o, w), y)
                        } else {
                            src(x, clamp(y as isize + o, h))
                        };
                }
                out[y * w + x] = s / norm;
            }
        }
        out
    };
    let first = blur(&|x, y| f64::from(gray[y * w + x]), true);
    let g = blur(&|x, y| first[y * w + x], false);
    let at = |x: isize, y: isize| g[clamp(y, h) * w + clamp(x, w)];
    let mut mag = vec![0.0; w * h];
    for y in 0..h as isize {
        for x in 0..w as isize {
            let gx = (at(x + 1, y - 1) + 2.0 * at(x + 1, y) + at(x + 1, y + 1))
                - (at(x - 1, y - 1) + 2.0 * at(x - 1, y) + at(x - 1, y + 1));
            let gy = (at(x - 1, y + 1) + 2.0 * at(x, y + 1) + at(x + 1, y + 1))
                - (at(x - 1, y - 1) + 2.0 * at(x, y - 1) + at(x + 1, y - 1));
            mag[y as usize * w + x as usize] = gx.hypot(gy);
        }
    }
    let mean = mag.iter().sum::<f64>() / mag.len().max(1) as f64;
    if mean > 0.0 {
        mag.iter_mut().for_each(|m| *m /= mean);
    }
    mag
}

fn parse_args(args: &[String]) -> Result<Options> {
    let mut opts = Options::default();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = || it.next().with_context(|| format!("{a} needs a value"));
        match a.as_str() {
            "--dataset" => opts.dataset = PathBuf::from(value()?),
            "--start" => opts.start = value()?.parse().context("--start: a frame index")?,
            "--step" => opts.step = value()?.parse().context("--step: a frame count")?,
            "--check" => opts.check = Some(PathBuf::from(value()?)),
            other => bail!(
                "unknown argument {other}; usage: cargo xtask calibrate-depth [--dataset DIR] \
                 [--start N] [--step N] [--check FILE]"
            ),
        }
    }
    if opts.step == 0 {
        bail!("--step must be at least 1");
    }
    Ok(opts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn correlation_of_proportional_and_constant_data() {
        let a = [(1.0, 2.0), (2.0, 4.0), (3.0, 6.0)];
        assert!((correlation(a.iter().copied()) - 1.0).abs() < 1e-12);
        let c = [(1.0, 1.0), (2.0, 1.0)];
        assert_eq!(correlation(c.iter().copied()), 0.0);
    }

    #[test]
    fn check_passes_within_tolerance_and_names_what_is_off() {
        let file = root().join(crate::ci::SEVEN_SCENES_CALIBRATION);
        // fx, tx, ty, cx, cy as the file states them, then each nudged.
        let stated: Params = [526.3, -0.0325, 0.0062, 322.7, 236.0];
        check(&file, &stated).unwrap();
        let mut near = stated;
        near[0] += 0.9 * CHECK_PIXELS;
        near[2] -= 0.9 * CHECK_METRES;
        check(&file, &near).unwrap();
        let mut far = stated;
        far[4] += 1.1 * CHECK_PIXELS;
        far[1] += 1.1 * CHECK_METRES;
        let e = check(&file, &far).unwrap_err().to_string();
        assert!(e.contains("cy differs") && e.contains("tx differs"), "{e}");
        assert!(!e.contains("fx") && !e.contains("ty"), "{e}");
        let nan: Params = [f64::NAN, -0.0325, 0.0062, 322.7, 236.0];
        assert!(check(&file, &nan).unwrap_err().to_string().contains("fx differs"));
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
}
