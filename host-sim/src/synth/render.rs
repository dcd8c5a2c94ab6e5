//! Rendering one frame: supersampled gray, pixel-centre depth, sensor effects, row-parallel.
//!
//! Every pixel is a pure function of (options, frame index, pixel position): the noise of a
//! pixel comes from a generator keyed by the seed, the frame and the pixel index. Bands of rows are
//! rendered on scoped threads, so the output is the same for any thread count. Hole blobs are drawn
//! afterwards on one thread from the frame's own generator.

use nalgebra::{Isometry3, Point3, Vector3};

use super::rng::SplitMix64;
use super::scene::Scene;
use super::{FRAME_RATE_HZ, SynthError, SynthFrame, SynthIntrinsics, SyntheticSequence};

/// Rotated-grid 2x2 supersampling offsets, pixels: no two samples share a row or a column, which
/// anti-aliases near-horizontal and near-vertical edges better than an ordered grid.
const SUBSAMPLES: [[f64; 2]; 4] =
    [[0.125, -0.375], [0.375, 0.125], [-0.125, 0.375], [-0.375, -0.125]];
/// Gray level of radiance 1.
const GRAY_GAIN: f64 = 255.0 * 1.15;
/// Stream keys of the frame-level generator streams.
const STREAM_HOLES: u64 = 0x401E;

/// A camera pose prepared for generating rays.
#[derive(Debug, Clone)]
struct RayFrame {
    origin: Point3<f64>,
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
        let origin = Point3::from(t_wc.translation.vector);
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
            origin,
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
    #[inline]
    fn mask(&self, x: f64, y: f64) -> u32 {
        self.rects
            .iter()
            .enumerate()
            .filter(|(_, r)| x >= r[0] && y >= r[1] && x <= r[2] && y <= r[3])
            .fold(0, |m, (k, _)| m | (1 << k))
    }
}

/// Everything a band of rows needs.
struct Job<'a> {
    scene: &'a Scene,
    intr: SynthIntrinsics,
    /// The pose at the timestamp (depth and, without blur, gray).
    centre: RayFrame,
    /// Poses averaged for the gray image (one without motion blur).
    exposure: Vec<RayFrame>,
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

/// Splits the rows into `threads` bands; the calling thread renders the first band and scoped
/// threads the others.
fn render_parallel(
    job: &Job<'_>,
    threads: usize,
    gray: &mut [u8],
    depth: &mut [u16],
) -> Result<(), SynthError> {
    let rows_per_band = job.intr.height.div_ceil(threads);
    let band = rows_per_band * job.intr.width;
    std::thread::scope(|s| {
        let mut bands = gray.chunks_mut(band).zip(depth.chunks_mut(band)).enumerate();
        let first = bands.next();
        let mut handles = Vec::with_capacity(threads);
        let mut spawn_failed = false;
        for (b, (g, d)) in bands {
            let y0 = b * rows_per_band;
            match std::thread::Builder::new().spawn_scoped(s, move || render_rows(job, y0, g, d)) {
                Ok(handle) => handles.push(handle),
                Err(_) => spawn_failed = true,
            }
        }
        if let Some((_, (g, d))) = first {
            render_rows(job, 0, g, d);
        }
        // Join every thread (a scope panics on a panicked thread left unjoined).
        let mut joined = true;
        for handle in handles {
            joined &= handle.join().is_ok();
        }
        if joined && !spawn_failed { Ok(()) } else { Err(SynthError::RenderThread) }
    })
}

/// Renders the rows starting at `y0` into a band of the gray and depth buffers.
fn render_rows(job: &Job<'_>, y0: usize, gray: &mut [u8], depth: &mut [u16]) {
    let w = job.intr.width;
    for (r, (g_row, d_row)) in gray.chunks_mut(w).zip(depth.chunks_mut(w)).enumerate() {
        let y = y0 + r;
        for (x, (g, d)) in g_row.iter_mut().zip(d_row.iter_mut()).enumerate() {
            let mut rng = SplitMix64::keyed(job.seed, job.frame, (y * w + x) as u64);
            // Always draw both so that enabling one noise does not change the other.
            let (n_depth, n_gray) = if job.depth_noise_k > 0.0 || job.gray_noise_sigma > 0.0 {
                (rng.gaussian(), rng.gaussian())
            } else {
                (0.0, 0.0)
            };
            let radiance = pixel_radiance(job, x as f64, y as f64);
            let level = radiance * GRAY_GAIN + job.gray_noise_sigma * n_gray;
            // Round half up (the level is non-negative after the clamp).
            *g = (level.clamp(0.0, 255.0) + 0.5) as u8;
            *d = pixel_depth(job, x as f64, y as f64, n_depth);
        }
    }
}

/// Mean radiance over the supersamples (and the exposure's poses) of pixel `(x, y)`.
#[inline]
fn pixel_radiance(job: &Job<'_>, x: f64, y: f64) -> f64 {
    let i = &job.intr;
    let mut sum = 0.0;
    for pose in &job.exposure {
        let mask = pose.mask(x, y);
        for [ox, oy] in SUBSAMPLES {
            let dir = pose.dir((x + ox - i.cx) / i.fx, (y + oy - i.cy) / i.fy);
            if let Some(hit) = job.scene.cast(&pose.origin, &dir, mask) {
                sum += job.scene.radiance(&hit);
            }
        }
    }
    sum / (SUBSAMPLES.len() * job.exposure.len()) as f64
}

/// Raw depth of pixel `(x, y)`: the z-depth of the surface through the pixel centre, with noise
/// `noise` (a standard normal sample) scaled by `k z^2`; 0 beyond range or at grazing incidence.
#[inline]
fn pixel_depth(job: &Job<'_>, x: f64, y: f64, noise: f64) -> u16 {
    let i = &job.intr;
    let dir = job.centre.dir((x - i.cx) / i.fx, (y - i.cy) / i.fy);
    let Some(hit) = job.scene.cast(&job.centre.origin, &dir, job.centre.mask(x, y)) else {
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
    ((z * i.depth_scale).clamp(1.0, f64::from(u16::MAX)) + 0.5) as u16
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
    use super::*;
    use crate::synth::SynthOptions;

    /// The screen-rectangle culling never changes a hit.
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
            let mut culled = 0;
            for y in 0..intr.height {
                for x in 0..intr.width {
                    let (xf, yf) = (x as f64, y as f64);
                    let mask = frame.mask(xf, yf);
                    culled += (mask != (1 << seq.scene.object_count()) - 1) as usize;
                    for [ox, oy] in SUBSAMPLES.iter().copied().chain([[0.0, 0.0]]) {
                        let dir =
                            frame.dir((xf + ox - intr.cx) / intr.fx, (yf + oy - intr.cy) / intr.fy);
                        let a = seq.scene.cast(&frame.origin, &dir, mask);
                        let b = seq.scene.cast(&frame.origin, &dir, u32::MAX);
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
