//! Estimating how an unregistered depth camera sits beside the colour camera, from the images
//! alone: the colour camera's intrinsics and the depth camera's offset, which
//! [`super::registration`] then applies as each frame is loaded (a calibration file with a
//! `[depth]` table, see [`Calibration`]). `ferroslam-sim calibrate-depth` runs it;
//! `calibration/7scenes-kinect-v1.toml` came from it.
//!
//! Input: a TUM-layout folder whose calibration states the depth camera's own intrinsics and no
//! `[depth]` table (the raw output of a Kinect v1, as Microsoft 7-Scenes ships it). No ground truth
//! is read. Deterministic: the same frames give the same estimate, bit for bit.
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
//! gain, and halves the steps when none helps, until the focal step is below 0.1 px.
//!
//! Cost: each frame is decoded at VGA and gets an edge map, then each round of the search scores
//! ten candidates over all the samples; about 15 s for 40 frames of 7-Scenes in a release build.

use std::fmt;
use std::path::{Path, PathBuf};

use ferroslam_core::config::VGA;

use super::{Calibration, Dataset, DatasetError, DatasetOptions, Distortion};

/// A depth pixel is an edge when a 4-neighbour is farther by more than this fraction of its depth.
pub const JUMP_FRACTION: f64 = 0.08;
/// Pixels kept from the image border (the neighbour test and the blur need them).
const BORDER: usize = 4;
/// Non-edge pixels sampled per edge pixel.
const NON_EDGE_PER_EDGE: usize = 3;
/// [`DepthRegistrationEstimate::compare`]: most a colour intrinsic (fx, cx, cy) may differ from a
/// stated one, pixels. The estimate over three disjoint subsets of 7-Scenes spans 0.2-0.3 px per
/// value, and differs from `calibration/7scenes-kinect-v1.toml` (the first implementation's
/// rounded values) by up to 0.4 px; this allows that and the search's last step (fx 0.08 px), and
/// catches any change that moves the estimate by more.
pub const CHECK_PIXELS: f64 = 0.5;
/// [`DepthRegistrationEstimate::compare`]: most a depth offset (tx, ty) may differ from a stated
/// one, metres. The subsets span 0.6-0.8 mm and differ from the file by up to 1.0 mm (0.26 VGA px
/// of registration error at 2 m); this allows that with the same margin as [`CHECK_PIXELS`].
pub const CHECK_METRES: f64 = 0.0015;

/// Why the estimate could not be made or does not match a stated calibration.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CalibrateDepthError {
    /// The dataset path is not a folder.
    #[error("{} is not a dataset folder (rgb.txt, depth.txt, calibration.toml)", dir.display())]
    NotAFolder {
        /// The path given.
        dir: PathBuf,
    },
    /// The folder has no `calibration.toml` to state the depth camera's intrinsics.
    #[error(
        "{} has no calibration.toml: the estimate needs one stating the depth camera's intrinsics \
         (fx, fy, cx, cy), width, height and depth_scale",
        dir.display()
    )]
    NoCalibration {
        /// The dataset folder.
        dir: PathBuf,
    },
    /// The folder, its calibration or a frame could not be read.
    #[error("{source}")]
    Dataset {
        /// What the loader said (it names the file).
        #[from]
        source: DatasetError,
    },
    /// The folder's calibration already has a `[depth]` table: its depth is registered as it is
    /// loaded, so the depth camera's own intrinsics are not what the frames show.
    #[error(
        "{}: its calibration already registers depth to colour (a [depth] table); the estimate \
         needs the depth camera's own intrinsics, without one",
        dir.display()
    )]
    AlreadyRegistered {
        /// The dataset folder.
        dir: PathBuf,
    },
    /// The folder's calibration has a lens distortion: the method takes both cameras as pinhole.
    #[error(
        "{}: its calibration has a lens distortion; the estimate takes both cameras as pinhole",
        dir.display()
    )]
    LensDistortion {
        /// The dataset folder.
        dir: PathBuf,
    },
    /// A frame step of 0.
    #[error("the frame step must be at least 1")]
    ZeroStep,
    /// The first frame asked for is past the last one.
    #[error("{}: no frame from index {start} on ({len} frames associated)", dir.display())]
    NoFrames {
        /// The dataset folder.
        dir: PathBuf,
        /// The first frame asked for.
        start: usize,
        /// Frames the folder has.
        len: usize,
    },
    /// A loaded frame whose image lengths disagree with its size.
    #[error(
        "{}: frame {index} is {width}x{height} pixels but has {gray} gray and {depth} depth samples",
        dir.display()
    )]
    FrameSize {
        /// The dataset folder.
        dir: PathBuf,
        /// The frame's index.
        index: usize,
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
        /// Gray samples.
        gray: usize,
        /// Depth samples.
        depth: usize,
    },
    /// No depth edge in any frame used: nothing to align.
    #[error(
        "{}: no depth edges in the {frames} frames used (from {start} every {step})",
        dir.display()
    )]
    NoDepthEdges {
        /// The dataset folder.
        dir: PathBuf,
        /// Frames read.
        frames: usize,
        /// The first frame.
        start: usize,
        /// The step between frames.
        step: usize,
    },
    /// A calibration to compare with has no depth offset.
    #[error("{} has no [depth] table to compare the depth offset with", file.display())]
    NoDepthTable {
        /// The calibration file.
        file: PathBuf,
    },
    /// A stated calibration differs from the estimate by more than the tolerances.
    #[error("{} does not match the estimate from the images: {}", file.display(), off.join("; "))]
    Mismatch {
        /// The calibration file.
        file: PathBuf,
        /// Each value that is off: `cy differs by 0.6000 (tolerance 0.5)`.
        off: Vec<String>,
    },
}

/// Which frames the estimate reads: `start`, `start + step`, ... to the end.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameSelection {
    /// The first frame (an index among the associated frames).
    pub start: usize,
    /// Frames between two used ones; at least 1.
    pub step: usize,
}

impl Default for FrameSelection {
    /// Frames 0, 25, 50, ...: 40 frames of 7-Scenes.
    fn default() -> Self {
        Self { start: 0, step: 25 }
    }
}

/// The parameters searched: colour focal length (px), depth offset x and y (m), colour
/// principal point x and y (px).
type Params = [f64; 5];

/// What the images say: the colour camera's intrinsics and the depth camera's offset, beside the
/// folder's own (depth camera) calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthRegistrationEstimate {
    /// The dataset folder.
    pub dir: PathBuf,
    /// The frames asked for.
    pub selection: FrameSelection,
    /// The frames read.
    pub frames: usize,
    /// The folder's calibration: the depth camera's intrinsics, the image size, the depth scale.
    pub sensor: Calibration,
    /// The colour camera's focal length, pixels (square pixels: fx = fy).
    pub colour_f_px: f64,
    /// The colour camera's principal point, pixels.
    pub colour_c_px: [f64; 2],
    /// The depth camera's offset `(tx, ty)`, metres, colour camera axes (`p_colour = p_depth +
    /// t`; `tz` is taken as 0).
    pub offset_m: [f64; 2],
    /// The edge correlation with the nominal values (the depth intrinsics for colour, no offset).
    pub nominal_correlation: f64,
    /// The edge correlation with the estimate.
    pub correlation: f64,
}

/// Estimates the registration of the folder `dir`'s depth to its colour from the frames
/// `selection` names (see the module documentation), at the sensor's resolution.
///
/// # Errors
/// [`CalibrateDepthError::NotAFolder`], [`CalibrateDepthError::NoCalibration`],
/// [`CalibrateDepthError::Dataset`] (the loader's error:
/// lists, calibration, an image), [`CalibrateDepthError::AlreadyRegistered`],
/// [`CalibrateDepthError::LensDistortion`], [`CalibrateDepthError::ZeroStep`],
/// [`CalibrateDepthError::NoFrames`], [`CalibrateDepthError::NoDepthEdges`].
pub fn estimate(
    dir: &Path,
    selection: FrameSelection,
) -> Result<DepthRegistrationEstimate, CalibrateDepthError> {
    if !dir.is_dir() {
        return Err(CalibrateDepthError::NotAFolder { dir: dir.to_owned() });
    }
    // Not a TUM preset the folder's name implies: those are for sensors that register depth.
    if !dir.join("calibration.toml").is_file() {
        return Err(CalibrateDepthError::NoCalibration { dir: dir.to_owned() });
    }
    if selection.step == 0 {
        return Err(CalibrateDepthError::ZeroStep);
    }
    let vga = DatasetOptions { profile: VGA, ..DatasetOptions::default() };
    let dataset = Dataset::open(dir, &vga)?;
    let sensor = *dataset.sensor_calibration();
    if sensor.depth.is_some() {
        return Err(CalibrateDepthError::AlreadyRegistered { dir: dir.to_owned() });
    }
    if sensor.distortion != Distortion::NONE {
        return Err(CalibrateDepthError::LensDistortion { dir: dir.to_owned() });
    }
    let FrameSelection { start, step } = selection;
    if start >= dataset.len() {
        let len = dataset.len();
        return Err(CalibrateDepthError::NoFrames { dir: dir.to_owned(), start, len });
    }
    let mut frames = Vec::new();
    for i in (start..dataset.len()).step_by(step) {
        let f = dataset.load_frame(i)?;
        if f.gray.len() != f.width * f.height || f.depth.len() != f.width * f.height {
            return Err(CalibrateDepthError::FrameSize {
                dir: dir.to_owned(),
                index: i,
                width: f.width,
                height: f.height,
                gray: f.gray.len(),
                depth: f.depth.len(),
            });
        }
        frames.push(samples(&f.gray, &f.depth, f.width, f.height, f64::from(f.depth_scale), i));
    }
    if frames.iter().all(|f| f.samples.is_empty()) {
        let frames = frames.len();
        return Err(CalibrateDepthError::NoDepthEdges { dir: dir.to_owned(), frames, start, step });
    }
    let depth = [sensor.fx, sensor.fy, sensor.cx, sensor.cy].map(f64::from);
    let score = |p: &Params| mean_correlation(&frames, &depth, p);
    let nominal: Params = [depth[0], 0.0, 0.0, depth[2], depth[3]];
    let nominal_correlation = score(&nominal);
    let (p, correlation) = search(nominal, nominal_correlation, score);
    Ok(DepthRegistrationEstimate {
        dir: dir.to_owned(),
        selection,
        frames: frames.len(),
        sensor,
        colour_f_px: p[0],
        colour_c_px: [p[3], p[4]],
        offset_m: [p[1], p[2]],
        nominal_correlation,
        correlation,
    })
}

/// One value of a [`CalibrationCheck`].
#[derive(Debug, Clone, PartialEq)]
pub struct CheckedValue {
    /// The calibration key: `fx`, `cx`, `cy`, `tx` or `ty`.
    pub key: &'static str,
    /// The estimate.
    pub estimated: f64,
    /// What the calibration states.
    pub stated: f64,
    /// Most the two may differ: [`CHECK_PIXELS`] or [`CHECK_METRES`].
    pub tolerance: f64,
}

impl CheckedValue {
    /// Whether the estimate and the stated value differ by at most the tolerance (a NaN does not).
    pub fn within(&self) -> bool {
        (self.estimated - self.stated).abs() <= self.tolerance
    }
}

/// An estimate compared with a stated calibration, value by value. Displayed as one line per
/// value: `fx: estimated 525.93750, FILE states 526.29999`.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationCheck {
    /// The calibration file compared with.
    pub file: PathBuf,
    /// fx, cx, cy, tx, ty.
    pub values: Vec<CheckedValue>,
}

impl CalibrationCheck {
    /// Ok when every value is within its tolerance.
    ///
    /// # Errors
    /// [`CalibrateDepthError::Mismatch`] naming each value that is off.
    pub fn ensure(&self) -> Result<(), CalibrateDepthError> {
        let off: Vec<String> = self
            .values
            .iter()
            .filter(|v| !v.within())
            .map(|v| {
                let diff = v.estimated - v.stated;
                format!("{} differs by {diff:.4} (tolerance {})", v.key, v.tolerance)
            })
            .collect();
        if off.is_empty() {
            Ok(())
        } else {
            Err(CalibrateDepthError::Mismatch { file: self.file.clone(), off })
        }
    }
}

impl fmt::Display for CalibrationCheck {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for v in &self.values {
            writeln!(
                f,
                "{}: estimated {:.5}, {} states {:.5}",
                v.key,
                v.estimated,
                self.file.display(),
                v.stated
            )?;
        }
        Ok(())
    }
}

impl DepthRegistrationEstimate {
    /// The estimate compared with `stated` (read from `file`, which names it): its colour fx, cx,
    /// cy and its depth offset tx, ty, each with its tolerance ([`CalibrationCheck::ensure`]
    /// judges).
    ///
    /// # Errors
    /// [`CalibrateDepthError::NoDepthTable`] when `stated` has no depth camera.
    pub fn compare(
        &self,
        stated: &Calibration,
        file: &Path,
    ) -> Result<CalibrationCheck, CalibrateDepthError> {
        let d = stated
            .depth
            .as_ref()
            .ok_or_else(|| CalibrateDepthError::NoDepthTable { file: file.to_owned() })?;
        let value = |key, estimated, stated: f32, tolerance| CheckedValue {
            key,
            estimated,
            stated: f64::from(stated),
            tolerance,
        };
        let values = vec![
            value("fx", self.colour_f_px, stated.fx, CHECK_PIXELS),
            value("cx", self.colour_c_px[0], stated.cx, CHECK_PIXELS),
            value("cy", self.colour_c_px[1], stated.cy, CHECK_PIXELS),
            value("tx", self.offset_m[0], d.t_m[0], CHECK_METRES),
            value("ty", self.offset_m[1], d.t_m[1], CHECK_METRES),
        ];
        Ok(CalibrationCheck { file: file.to_owned(), values })
    }

    /// [`Self::compare`] with the calibration file `file`.
    ///
    /// # Errors
    /// [`CalibrateDepthError::Dataset`] when the file cannot be read or is not a valid
    /// calibration; as [`Self::compare`].
    pub fn compare_file(&self, file: &Path) -> Result<CalibrationCheck, CalibrateDepthError> {
        self.compare(&Calibration::load(file)?, file)
    }

    /// The calibration file: a header naming the folder, the frames and the edge correlation,
    /// the colour intrinsics (0.1 px), the sensor's size and depth scale, and the `[depth]` table
    /// (the folder's depth intrinsics, the offset to 0.1 mm). [`Calibration::load`] reads it.
    pub fn to_toml(&self) -> String {
        let c = &self.sensor;
        let FrameSelection { start, step } = self.selection;
        let (f, [cx, cy], [tx, ty]) = (self.colour_f_px, self.colour_c_px, self.offset_m);
        format!(
            "# Estimated from the images by `ferroslam-sim calibrate-depth {} --start {start} \
             --step {step}`\n\
             # (edge correlation {:.3} -> {:.3}).\n\
             fx = {f:.1}\nfy = {f:.1}\ncx = {cx:.1}\ncy = {cy:.1}\nwidth = {}\nheight = {}\n\
             depth_scale = {}\n\n[depth]\nfx = {}\nfy = {}\ncx = {}\ncy = {}\n\
             tx = {tx:.4}\nty = {ty:.4}\ntz = 0.0\n",
            self.dir.display(),
            self.nominal_correlation,
            self.correlation,
            c.width,
            c.height,
            c.depth_scale,
            c.fx,
            c.fy,
            c.cx,
            c.cy,
        )
    }
}

impl fmt::Display for DepthRegistrationEstimate {
    /// A summary: frames, correlations, the colour intrinsics and the offset.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let FrameSelection { start, step } = self.selection;
        let ([cx, cy], [tx, ty]) = (self.colour_c_px, self.offset_m);
        writeln!(
            f,
            "{} frames (from {start} every {step}): edge correlation {:.4} with the nominal \
             values, {:.4} estimated",
            self.frames, self.nominal_correlation, self.correlation
        )?;
        writeln!(
            f,
            "colour camera: fx = fy = {:.2} px, cx = {cx:.2} px, cy = {cy:.2} px",
            self.colour_f_px
        )?;
        write!(
            f,
            "depth camera: offset tx = {:.2} mm, ty = {:.2} mm (tz = 0) from the colour camera",
            tx * 1000.0,
            ty * 1000.0
        )
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

/// `img` (`w` x `h`, row-major) at `(x, y)`, bilinearly, with coordinates clamped to the image;
/// 0 for an empty image.
fn bilinear(img: &[f64], w: usize, h: usize, x: f64, y: f64) -> f64 {
    if w == 0 || h == 0 {
        return 0.0;
    }
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
/// `gray` and `depth` hold `w * h` samples each.
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

/// Sobel gradient magnitude of `gray` (`w * h` samples) blurred by a Gaussian of sigma 1 px
/// (radius 4, borders clamped), divided by its mean.
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

#[cfg(test)]
mod tests;
