//! Rendering one frame: supersampled gray, pixel-centre depth, sensor effects, row-parallel.
//!
//! Every pixel is a pure function of (options, frame index, pixel position): the noise of a
//! pixel comes from a generator keyed by the seed, the frame and the pixel index. Chunks of rows
//! are handed out to scoped threads from a shared queue, so the output is the same for any thread
//! count. Hole blobs are drawn afterwards on one thread from the frame's own generator.
//!
//! Whatever depends only on the pose, a row or a column (the prepared ray origin, the culling
//! masks of a row, the normalized coordinates of a column) is computed once and reused; it is the
//! same expression evaluated earlier, so the bits are those of a pixel-by-pixel evaluation.

use std::sync::Mutex;

use nalgebra::{Isometry3, Vector3};

use super::noise::NoiseCache;
use super::rng::SplitMix64;
use super::scene::{CastOrigin, Scene};
use super::{FRAME_RATE_HZ, SynthError, SynthFrame, SynthIntrinsics, SyntheticSequence};

/// Rotated-grid 2x2 supersampling offsets, pixels: no two samples share a row or a column, which
/// anti-aliases near-horizontal and near-vertical edges better than an ordered grid.
const SUBSAMPLES: [[f64; 2]; 4] =
    [[0.125, -0.375], [0.375, 0.125], [-0.125, 0.375], [-0.375, -0.125]];
/// Offsets of the rays of a pixel: the supersamples, then the centre (the depth ray).
const RAY_OFFSETS: [[f64; 2]; 5] =
    [SUBSAMPLES[0], SUBSAMPLES[1], SUBSAMPLES[2], SUBSAMPLES[3], [0.0, 0.0]];
/// Index of the centre ray in [`RAY_OFFSETS`].
const CENTRE: usize = 4;
/// Gray level of radiance 1.
const GRAY_GAIN: f64 = 255.0 * 1.15;
/// Stream keys of the frame-level generator streams.
const STREAM_HOLES: u64 = 0x401E;
/// Rows per work item of the render threads: small enough that the threads finish together
/// (rows differ in cost), large enough that taking an item costs nothing.
const ROWS_PER_CHUNK: usize = 4;

/// A camera pose prepared for generating rays.
#[derive(Debug, Clone)]
struct RayFrame {
    /// The camera centre prepared for casting.
    origin: CastOrigin,
    /// Camera axes in the world frame (columns of `R_wc`).
    axes: [Vector3<f64>; 3],
    /// Per scene object, a pixel rectangle `[x0, y0, x1, y1]` outside which no ray of this pose
    /// (with sample offsets below one pixel) can meet the object. Testing only the objects whose
    /// rectangle holds the pixel gives the same hits as testing all, several times faster.
    rects: Vec<[f64; 4]>,
}

impl RayFrame {
    fn new(t_wc: &Isometry3<f64>, scene: &Scene, intr: &SynthIntrinsics) -> Self {
        let r = t_wc.rotation.to_rotation_matrix();
        let m = r.matrix();
        let t_cw = t_wc.inverse();
        let everywhere = [f64::NEG_INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::INFINITY];
        let rects = (0..scene.object_count())
            .map(|k| {
                let Some(corners) = scene.object_corners(k) else { return everywhere };
                let mut rect = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
                for p in corners {
                    // The projection of a convex hull in front of the camera is the hull of the
                    // projected corners; with a corner behind, fall back to testing everywhere.
                    let p_c = t_cw * p;
                    if p_c.z <= 1e-6 {
                        return everywhere;
                    }
                    let [u, v] =
                        [intr.fx * p_c.x / p_c.z + intr.cx, intr.fy * p_c.y / p_c.z + intr.cy];
                    rect = [
                        rect[0].min(u - 1.0),
                        rect[1].min(v - 1.0),
                        rect[2].max(u + 1.0),
                        rect[3].max(v + 1.0),
                    ];
                }
                rect
            })
            .collect();
        Self {
            origin: scene.prepare(&t_wc.translation.vector.into()),
            axes: [m.column(0).into_owned(), m.column(1).into_owned(), m.column(2).into_owned()],
            rects,
        }
    }

    /// World direction of the camera ray through normalized coordinates `(xn, yn)`; its
    /// camera-frame z component is 1, so the hit parameter is the z-depth.
    #[inline]
    fn dir(&self, xn: f64, yn: f64) -> Vector3<f64> {
        self.axes[0] * xn + self.axes[1] * yn + self.axes[2]
    }

    /// The cast mask of pixel `(x, y)`: the objects whose rectangle holds it.
    #[cfg(test)]
    fn mask(&self, x: f64, y: f64) -> u32 {
        self.rects
            .iter()
            .enumerate()
            .filter(|(_, r)| x >= r[0] && y >= r[1] && x <= r[2] && y <= r[3])
            .fold(0, |m, (k, _)| m | (1 << k))
    }

    /// The cast masks of row `y`, pixel by pixel (`masks[x]` is the mask of pixel `(x, y)`): the
    /// rectangles that hold the row, tested on `x` only. Cost: width times those rectangles.
    fn row_masks(&self, y: f64, masks: &mut [u32]) {
        masks.fill(0);
        for (k, r) in self.rects.iter().enumerate() {
            if !(y >= r[1] && y <= r[3]) {
                continue;
            }
            for (x, m) in masks.iter_mut().enumerate() {
                let x = x as f64;
                if x >= r[0] && x <= r[2] {
                    *m |= 1 << k;
                }
            }
        }
    }
}

/// Normalized image coordinates of every column and row at each offset of [`RAY_OFFSETS`]:
/// `cols[x][s] = (x + ox_s - cx) / fx`, `rows[y][s] = (y + oy_s - cy) / fy` (the divisions of a
/// pixel's rays, done once per frame).
#[derive(Debug, Clone)]
struct NormalizedCoords {
    cols: Vec<[f64; 5]>,
    rows: Vec<[f64; 5]>,
}

impl NormalizedCoords {
    fn new(intr: &SynthIntrinsics) -> Self {
        let at = |n: usize, axis: usize, c: f64, f: f64| -> Vec<[f64; 5]> {
            (0..n).map(|p| RAY_OFFSETS.map(|o| (p as f64 + o[axis] - c) / f)).collect()
        };
        Self {
            cols: at(intr.width, 0, intr.cx, intr.fx),
            rows: at(intr.height, 1, intr.cy, intr.fy),
        }
    }
}

/// Everything the render threads share.
struct Job<'a> {
    scene: &'a Scene,
    intr: SynthIntrinsics,
    /// The pose at the timestamp (depth and, without blur, gray).
    centre: RayFrame,
    /// Poses averaged for the gray image (one without motion blur).
    exposure: Vec<RayFrame>,
    coords: NormalizedCoords,
    max_range_m: f64,
    /// Depth readings are dropped where `|cos(incidence)|` is below this.
    grazing_cos: f64,
    depth_noise_k: f64,
    gray_noise_sigma: f64,
    seed: u64,
    frame: u64,
}

/// Renders frame `index` into `out` (whose size fields are already set).
pub(crate) fn render_frame(
    seq: &SyntheticSequence,
    index: usize,
    out: &mut SynthFrame,
) -> Result<(), SynthError> {
    let opts = &seq.opts;
    let t = index as f64 / FRAME_RATE_HZ;
    let k = opts.motion_blur_samples;
    let exposure = (0..k)
        .map(|s| {
            let offset = ((s as f64 + 0.5) / k as f64 - 0.5) * opts.exposure_frames / FRAME_RATE_HZ;
            RayFrame::new(&seq.pose_at(t + offset), &seq.scene, &seq.intrinsics)
        })
        .collect();
    let job = Job {
        scene: &seq.scene,
        intr: seq.intrinsics,
        centre: RayFrame::new(&seq.pose_at(t), &seq.scene, &seq.intrinsics),
        exposure,
        coords: NormalizedCoords::new(&seq.intrinsics),
        max_range_m: opts.max_range_m,
        grazing_cos: opts.grazing_limit_deg.map_or(0.0, |g| libm::cos(g.to_radians())),
        depth_noise_k: opts.depth_noise_k,
        gray_noise_sigma: opts.gray_noise_sigma,
        seed: opts.seed,
        frame: index as u64,
    };
    let (w, h) = (opts.width, opts.height);
    out.gray.clear();
    out.gray.resize(w * h, 0);
    out.depth.clear();
    out.depth.resize(w * h, 0);
    let threads = if opts.threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get()).min(8)
    } else {
        opts.threads
    };
    render_parallel(&job, threads.clamp(1, h), &mut out.gray, &mut out.depth)?;
    if opts.hole_fraction > 0.0 {
        punch_holes(
            &mut out.depth,
            w,
            h,
            opts.hole_fraction,
            SplitMix64::keyed(opts.seed, job.frame, STREAM_HOLES),
        );
    }
    Ok(())
}

/// Renders the frame on `threads` threads (the calling one and scoped ones), each taking the next
/// chunk of [`ROWS_PER_CHUNK`] rows from a shared queue until none is left.
fn render_parallel(
    job: &Job<'_>,
    threads: usize,
    gray: &mut [u8],
    depth: &mut [u16],
) -> Result<(), SynthError> {
    let chunk = ROWS_PER_CHUNK * job.intr.width;
    let queue = Mutex::new(gray.chunks_mut(chunk).zip(depth.chunks_mut(chunk)).enumerate());
    // Renders chunks until the queue is empty; `false` if the queue's lock was poisoned (a
    // worker panicked while taking a chunk).
    let work = || {
        let mut scratch = Scratch::new(job);
        loop {
            let Ok(mut items) = queue.lock() else { return false };
            let next = items.next();
            drop(items);
            let Some((c, (g, d))) = next else { return true };
            render_rows(job, c * ROWS_PER_CHUNK, g, d, &mut scratch);
        }
    };
    std::thread::scope(|s| {
        let mut handles = Vec::with_capacity(threads);
        let mut spawn_failed = false;
        for _ in 1..threads {
            match std::thread::Builder::new().spawn_scoped(s, work) {
                Ok(handle) => handles.push(handle),
                Err(_) => spawn_failed = true,
            }
        }
        let mut ok = work();
        // Join every thread (a scope panics on a panicked thread left unjoined).
        for handle in handles {
            ok &= handle.join().unwrap_or(false);
        }
        if ok && !spawn_failed { Ok(()) } else { Err(SynthError::RenderThread) }
    })
}

/// A render thread's scratch: the cast masks of the row being rendered, one per pixel for each
/// exposure pose (pose-major) and for the centre pose, and its value-noise cache.
struct Scratch {
    exposure_masks: Vec<u32>,
    centre_masks: Vec<u32>,
    noise: NoiseCache,
}

impl Scratch {
    fn new(job: &Job<'_>) -> Self {
        let w = job.intr.width;
        Self {
            exposure_masks: vec![0; w * job.exposure.len()],
            centre_masks: vec![0; w],
            noise: NoiseCache::new(),
        }
    }

    /// Fills the masks of row `y`.
    fn fill_masks(&mut self, job: &Job<'_>, y: usize) {
        let w = job.intr.width;
        for (pose, masks) in job.exposure.iter().zip(self.exposure_masks.chunks_mut(w)) {
            pose.row_masks(y as f64, masks);
        }
        job.centre.row_masks(y as f64, &mut self.centre_masks);
    }
}

/// Renders the rows starting at `y0` into a chunk of the gray and depth buffers.
fn render_rows(
    job: &Job<'_>,
    y0: usize,
    gray: &mut [u8],
    depth: &mut [u16],
    scratch: &mut Scratch,
) {
    let w = job.intr.width;
    for (r, (g_row, d_row)) in gray.chunks_mut(w).zip(depth.chunks_mut(w)).enumerate() {
        let y = y0 + r;
        scratch.fill_masks(job, y);
        let yn = &job.coords.rows[y];
        for (x, (g, d)) in g_row.iter_mut().zip(d_row.iter_mut()).enumerate() {
            // Always draw both so that enabling one noise does not change the other.
            let (n_depth, n_gray) = if job.depth_noise_k > 0.0 || job.gray_noise_sigma > 0.0 {
                let mut rng = SplitMix64::keyed(job.seed, job.frame, (y * w + x) as u64);
                (rng.gaussian(), rng.gaussian())
            } else {
                (0.0, 0.0)
            };
            let xn = &job.coords.cols[x];
            let radiance =
                pixel_radiance(job, xn, yn, &scratch.exposure_masks[x..], &mut scratch.noise);
            let level = radiance * GRAY_GAIN + job.gray_noise_sigma * n_gray;
            // Round half up (the level is non-negative after the clamp).
            *g = (level.clamp(0.0, 255.0) + 0.5) as u8;
            *d = pixel_depth(job, xn[CENTRE], yn[CENTRE], scratch.centre_masks[x], n_depth);
        }
    }
}

/// Mean radiance over the supersamples (and the exposure's poses) of a pixel: `xn`, `yn` are its
/// column's and row's normalized coordinates, `masks[s * width]` its cast mask under pose `s`.
#[inline]
fn pixel_radiance(
    job: &Job<'_>,
    xn: &[f64; 5],
    yn: &[f64; 5],
    masks: &[u32],
    noise: &mut NoiseCache,
) -> f64 {
    let mut sum = 0.0;
    let masks = masks.iter().step_by(job.intr.width);
    for (pose, &mask) in job.exposure.iter().zip(masks) {
        for s in 0..SUBSAMPLES.len() {
            let dir = pose.dir(xn[s], yn[s]);
            if let Some(hit) = job.scene.cast_from(&pose.origin, &dir, mask) {
                sum += job.scene.radiance(&hit, noise);
            }
        }
    }
    sum / (SUBSAMPLES.len() * job.exposure.len()) as f64
}

/// Raw depth of the pixel whose centre ray has normalized coordinates `(xn, yn)` and cast mask
/// `mask`: the z-depth of the surface it meets, with noise `noise` (a standard normal sample)
/// scaled by `k z^2`; 0 beyond range or at grazing incidence.
#[inline]
fn pixel_depth(job: &Job<'_>, xn: f64, yn: f64, mask: u32, noise: f64) -> u16 {
    let dir = job.centre.dir(xn, yn);
    let Some(hit) = job.scene.cast_from(&job.centre.origin, &dir, mask) else {
        return 0;
    };
    let z = hit.t;
    if !(z > 0.0 && z <= job.max_range_m) {
        return 0;
    }
    if job.grazing_cos > 0.0 && hit.normal.dot(&dir).abs() < job.grazing_cos * dir.norm() {
        return 0;
    }
    let z = z + job.depth_noise_k * z * z * noise;
    ((z * job.intr.depth_scale).clamp(1.0, f64::from(u16::MAX)) + 0.5) as u16
}

/// Zeroes elliptic blobs of the depth image until about `fraction` of the pixels are covered.
fn punch_holes(depth: &mut [u16], w: usize, h: usize, fraction: f64, mut rng: SplitMix64) {
    let target = (fraction * (w * h) as f64).ceil() as usize;
    let scale = (w as f64 / 640.0).max(0.05);
    let mut hole = vec![false; w * h];
    let mut covered = 0usize;
    // Enough blobs for any fraction up to 0.9; the cap only guards against a logic error.
    for _ in 0..1_000_000 {
        if covered >= target {
            break;
        }
        let (cx, cy) = (rng.uniform(0.0, w as f64), rng.uniform(0.0, h as f64));
        let (ra, rb) = (rng.uniform(3.0, 18.0) * scale, rng.uniform(3.0, 18.0) * scale);
        let angle = rng.uniform(0.0, core::f64::consts::PI);
        let (c, s) = (libm::cos(angle), libm::sin(angle));
        let r = ra.max(rb);
        let x0 = (cx - r).floor().max(0.0) as usize;
        let x1 = ((cx + r).ceil() as usize).min(w - 1);
        let y0 = (cy - r).floor().max(0.0) as usize;
        let y1 = ((cy + r).ceil() as usize).min(h - 1);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (dx, dy) = (x as f64 - cx, y as f64 - cy);
                let (a, b) = ((c * dx + s * dy) / ra, (-s * dx + c * dy) / rb);
                let k = y * w + x;
                if a * a + b * b <= 1.0 && !hole[k] {
                    hole[k] = true;
                    depth[k] = 0;
                    covered += 1;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Point3;

    use super::*;
    use crate::synth::SynthOptions;

    /// The screen-rectangle culling (per pixel or per row) and the prepared origin never change
    /// a hit; the normalized coordinates are the per-pixel divisions.
    #[test]
    fn culling_gives_the_same_hits_as_testing_everything() {
        let seq = SyntheticSequence::new(SynthOptions {
            width: 160,
            height: 120,
            ..SynthOptions::default()
        })
        .unwrap();
        let intr = seq.intrinsics;
        for t in [0.0, 1.3, 2.9, 4.4, 6.1, 8.8] {
            let frame = RayFrame::new(&seq.pose_at(t), &seq.scene, &intr);
            let coords = NormalizedCoords::new(&intr);
            let mut row_masks = vec![0; intr.width];
            let mut culled = 0;
            for y in 0..intr.height {
                frame.row_masks(y as f64, &mut row_masks);
                for (x, &row_mask) in row_masks.iter().enumerate() {
                    let (xf, yf) = (x as f64, y as f64);
                    let mask = frame.mask(xf, yf);
                    assert_eq!(row_mask, mask, "t {t} pixel ({x}, {y})");
                    culled += (mask != (1 << seq.scene.object_count()) - 1) as usize;
                    for (s, [ox, oy]) in RAY_OFFSETS.into_iter().enumerate() {
                        let (xn, yn) =
                            ((xf + ox - intr.cx) / intr.fx, (yf + oy - intr.cy) / intr.fy);
                        assert_eq!([coords.cols[x][s], coords.rows[y][s]], [xn, yn]);
                        let dir = frame.dir(xn, yn);
                        let a = seq.scene.cast_from(&frame.origin, &dir, mask);
                        let b = seq.scene.cast(frame.origin.origin(), &dir, u32::MAX);
                        assert_eq!(a, b, "t {t} pixel ({x}, {y})");
                    }
                }
            }
            // The culling does cull.
            assert!(culled > intr.width * intr.height / 2);
        }
    }

    #[test]
    fn depth_is_the_z_of_the_centre_ray_hit() {
        let seq = SyntheticSequence::new(SynthOptions {
            width: 64,
            height: 48,
            ..SynthOptions::default()
        })
        .unwrap();
        let f = seq.render(7).unwrap();
        let pose = seq.pose_at(7.0 / FRAME_RATE_HZ);
        let intr = seq.intrinsics;
        for (y, x) in [(0, 0), (10, 20), (47, 63), (24, 31)] {
            let dir = pose.rotation
                * Vector3::new((x as f64 - intr.cx) / intr.fx, (y as f64 - intr.cy) / intr.fy, 1.0);
            let origin = Point3::from(pose.translation.vector);
            let hit = seq.scene.cast(&origin, &dir, u32::MAX).unwrap();
            let p_c = pose.inverse() * (origin + dir * hit.t);
            assert!((p_c.z - hit.t).abs() < 1e-12);
            assert_eq!(f.depth[y * 64 + x], (hit.t * 5000.0).round() as u16);
        }
    }

    #[test]
    fn hole_coverage_reaches_the_fraction() {
        let (w, h) = (200, 100);
        let mut depth = vec![1u16; w * h];
        punch_holes(&mut depth, w, h, 0.3, SplitMix64::new(4));
        let zeros = depth.iter().filter(|&&d| d == 0).count() as f64 / (w * h) as f64;
        assert!((0.3..0.35).contains(&zeros), "{zeros}");
    }
}
