//! Plane detection on one depth image by a grid of cells (see the module documentation of
//! `ar`): fit, keep the flat cells, grow regions over neighbouring cells that agree, refit.

use heapless::Vec;
use nalgebra::{Point3, Vector3};

use super::eigen::smallest_eigenvector;
use crate::config::SensorModel;
use crate::geometry::{PinholeCamera, Pose};
use crate::image::DepthView;

/// Cells of the grid, columns and rows, whatever the resolution: 16 x 16 pixels at QVGA, 32 x
/// 32 at VGA (the pixels a remainder leaves at the right and bottom edges are not read). Fixed
/// in cells so that a plane's support, and the detector's cost, mean the same at any resolution.
pub const PLANE_GRID: (usize, usize) = (20, 15);

/// Cells in all.
const CELLS: usize = PLANE_GRID.0 * PLANE_GRID.1;

/// Samples read per cell side (an 8 x 8 lattice spread over the cell; fewer on a cell narrower
/// than that): 64 points fit a plane to a fraction of the depth noise, at a sixteenth of the
/// pixels of a QVGA cell.
const SAMPLES_PER_SIDE: usize = 8;

/// Planes one frame gives at most (the largest, by cells).
pub const MAX_FRAME_PLANES: usize = 8;

/// One frame's planes, largest first ([`PlaneDetector::detect`] fills it).
pub type FramePlanes = Vec<Plane, MAX_FRAME_PLANES>;

/// The detector's thresholds. Distances are in metres, angles in radians; the depth noise is the
/// sensor model's (`sigma_z = k z^2`, `k` = [`SensorModel::depth_noise_coeff_per_m`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlaneParams {
    /// A cell is flat when the RMS distance of its points to their plane is at most this many
    /// depth standard deviations at the cell's mean depth, plus [`Self::flat_floor_m`]. Default 2.
    pub flat_sigmas: f32,
    /// See [`Self::flat_sigmas`]: the depth's quantization (a millimetre) and a margin. Default
    /// 0.002 m.
    pub flat_floor_m: f32,
    /// A cell is fitted when at least this fraction of its samples has a depth in the sensor's
    /// range. Default 0.75.
    pub min_valid_fraction: f32,
    /// A cell is not flat when two neighbouring samples of its lattice differ by more than this
    /// fraction of their depth (an edge: a step of a box's height, or an object before a wall).
    /// Default 0.05, as tracking's depth step; a floor seen at a grazing angle changes by about
    /// 2% between samples at 3 m.
    pub max_relative_step: f32,
    /// A cell joins a neighbouring region when its normal is within this angle of the region's.
    /// Default 10 degrees (a flat cell's normal is good to a few degrees at 3 m).
    pub max_normal_angle_rad: f32,
    /// ... and its centroid is within this many standard deviations of a centroid's depth (`k
    /// z^2 / sqrt(samples)`) of the region's plane, plus [`Self::join_floor_m`]. Default 4.
    pub join_sigmas: f32,
    /// See [`Self::join_sigmas`]. Default 0.003 m (the depth's millimetre quantization and a
    /// margin): a poster is one plane with its wall; a surface that curves away is not.
    pub join_floor_m: f32,
    /// A region is a plane with at least this many cells. Default 6 (2% of the frame).
    pub min_cells: u16,
    /// The sensor's depth noise and range.
    pub sensor: SensorModel,
}

impl PlaneParams {
    /// The defaults, documented per field.
    pub const DEFAULT: Self = Self {
        flat_sigmas: 2.0,
        flat_floor_m: 0.002,
        min_valid_fraction: 0.75,
        max_relative_step: 0.05,
        max_normal_angle_rad: 10.0 * core::f32::consts::PI / 180.0,
        join_sigmas: 4.0,
        join_floor_m: 0.003,
        min_cells: 6,
        sensor: SensorModel::DEFAULT,
    };

    /// Whether every threshold is finite and in range and the sensor model valid.
    pub fn is_valid(&self) -> bool {
        let non_negative = |v: f32| v.is_finite() && v >= 0.0;
        non_negative(self.flat_sigmas)
            && non_negative(self.flat_floor_m)
            && non_negative(self.join_sigmas)
            && non_negative(self.join_floor_m)
            && (0.0..=1.0).contains(&self.min_valid_fraction)
            && non_negative(self.max_relative_step)
            && self.max_normal_angle_rad.is_finite()
            && (0.0..=core::f32::consts::FRAC_PI_2).contains(&self.max_normal_angle_rad)
            && self.min_cells >= 1
            && self.sensor.is_valid()
    }
}

impl Default for PlaneParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Why [`PlaneDetector::detect`] gave no planes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PlaneError {
    /// The depth image is not the camera's size.
    SizeMismatch,
    /// The image is smaller than the grid (a cell needs a pixel).
    TooSmall,
    /// A threshold is out of range ([`PlaneParams::is_valid`]).
    InvalidParams,
}

/// A plane: the points `p` with `normal . p + offset_m = 0`, in the frame of the camera that saw
/// it or, after [`Plane::transformed`], the world's.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Plane {
    /// Unit normal, pointing to the side the camera saw it from.
    pub normal: [f32; 3],
    /// Metres: in the camera's frame, the camera's distance to the plane (positive).
    pub offset_m: f32,
    /// The mean of its points, metres, each cell's weighted by its depth's inverse variance.
    pub centroid: [f32; 3],
    /// RMS distance of its points to it, metres, weighted as the centroid.
    pub rms_m: f32,
    /// Grid cells it covers (its extent: [`Plane::frame_fraction`]).
    pub cells: u16,
    /// Depth samples it was fitted on.
    pub samples: u32,
}

impl Plane {
    /// Its share of the frame it was seen in: cells over the grid's.
    pub fn frame_fraction(&self) -> f32 {
        f32::from(self.cells) / CELLS as f32
    }

    /// The unit normal as a vector.
    pub fn normal(&self) -> Vector3<f32> {
        Vector3::from(self.normal)
    }

    /// Signed distance of `p` to the plane, metres (positive on the side the normal points to).
    pub fn distance(&self, p: &Point3<f32>) -> f32 {
        self.normal().dot(&p.coords) + self.offset_m
    }

    /// This plane, given in the frame of a camera at `t_wc`, in the world frame.
    pub fn transformed(&self, t_wc: &Pose) -> Self {
        let n = t_wc.rotation * self.normal();
        let c = t_wc * Point3::from(self.centroid);
        let offset_m = self.offset_m - n.dot(&t_wc.translation.vector);
        Self { normal: n.into(), offset_m, centroid: c.coords.into(), ..*self }
    }
}

/// Weighted centred moments of a point set: its count, the weights' sum, the weighted mean and
/// scatter (sums of weighted centred products), merged exactly by the parallel-axis rule so a
/// region's fit never loses precision to large coordinates (Chan, Golub and LeVeque's pairwise
/// update). A cell's points share one weight, the inverse of its depth variance (`1 / z^4`,
/// the sensor's `sigma_z = k z^2`): a region's fit leans on its near cells, whose depth is
/// better, not on the far ones a grazing floor is mostly made of.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Moments {
    count: f32,
    weight: f32,
    mean: [f32; 3],
    /// `xx, xy, xz, yy, yz, zz`.
    scatter: [f32; 6],
}

impl Moments {
    const EMPTY: Self = Self { count: 0.0, weight: 0.0, mean: [0.0; 3], scatter: [0.0; 6] };

    /// The moments of `self` and `o` together.
    fn merged(&self, o: &Self) -> Self {
        let weight = self.weight + o.weight;
        if weight <= 0.0 {
            return Self::EMPTY;
        }
        let d = [o.mean[0] - self.mean[0], o.mean[1] - self.mean[1], o.mean[2] - self.mean[2]];
        let w = self.weight * o.weight / weight;
        let f = o.weight / weight;
        let mean = [self.mean[0] + d[0] * f, self.mean[1] + d[1] * f, self.mean[2] + d[2] * f];
        let dd = [d[0] * d[0], d[0] * d[1], d[0] * d[2], d[1] * d[1], d[1] * d[2], d[2] * d[2]];
        let mut scatter = self.scatter;
        for ((s, &os), &p) in scatter.iter_mut().zip(&o.scatter).zip(&dd) {
            *s += os + p * w;
        }
        Self { count: self.count + o.count, weight, mean, scatter }
    }

    /// These moments with every point's weight multiplied by `by`.
    fn weighted(&self, by: f32) -> Self {
        Self { weight: self.weight * by, scatter: self.scatter.map(|s| s * by), ..*self }
    }

    /// The plane through the points: normal toward the camera (the origin), offset, weighted
    /// RMS distance.
    fn fit(&self) -> Option<([f32; 3], f32, f32)> {
        if self.count < 3.0 || self.weight <= 0.0 {
            return None;
        }
        let s = self.scatter;
        let (normal, values) =
            smallest_eigenvector([[s[0], s[1], s[2]], [s[1], s[3], s[4]], [s[2], s[4], s[5]]])?;
        let m = self.mean;
        let along = normal[0] * m[0] + normal[1] * m[1] + normal[2] * m[2];
        let normal = if along > 0.0 { normal.map(|c| -c) } else { normal };
        let offset = along.abs();
        let rms = ferroslam_fpu::sqrtf(values[0].max(0.0) / self.weight);
        Some((normal, offset, rms))
    }
}

/// One cell of the grid after its fit.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Cell {
    moments: Moments,
    /// The fitted normal (toward the camera); meaningful when the cell is flat.
    normal: [f32; 3],
}

impl Cell {
    const EMPTY: Self = Self { moments: Moments::EMPTY, normal: [0.0; 3] };
}

/// One bit per cell of the grid (kept apart from [`Cell`], whose two flags padded it by 4 bytes:
/// 1.2 KB of the detector).
#[derive(Debug, Clone, Copy)]
struct CellBits([u32; CELLS.div_ceil(32)]);

impl CellBits {
    const NONE: Self = Self([0; CELLS.div_ceil(32)]);

    fn has(&self, i: usize) -> bool {
        self.0.get(i / 32).is_some_and(|w| w & (1 << (i % 32)) != 0)
    }

    fn set(&mut self, i: usize) {
        if let Some(w) = self.0.get_mut(i / 32) {
            *w |= 1 << (i % 32);
        }
    }
}

/// Plane detection on depth images (see the module documentation of `ar`): the grid's cells
/// and the region growing's queue, reused from frame to frame: 18,080 bytes
/// (`memory-budget.md`); place it in a `static` or a box, not on the stack.
///
/// Cost per frame: 64 depth samples interpolated and back-projected per cell, two passes over
/// them (the mean, then the centred scatter), one 3 x 3 eigen-decomposition per cell and one
/// per cell a region takes.
#[derive(Debug, Clone)]
pub struct PlaneDetector {
    cells: [Cell; CELLS],
    /// The cells flat within the depth noise (a region may start or grow from them).
    flat: CellBits,
    /// The cells a region took.
    taken: CellBits,
    /// Cell indices, by ascending RMS (the region growing's seeds, flattest first), then the
    /// growing's queue.
    order: [u16; CELLS],
    queue: [u16; CELLS],
}

impl Default for PlaneDetector {
    fn default() -> Self {
        Self::new()
    }
}

impl PlaneDetector {
    /// An idle detector (`const`, for a `static`).
    pub const fn new() -> Self {
        Self {
            cells: [Cell::EMPTY; CELLS],
            flat: CellBits::NONE,
            taken: CellBits::NONE,
            order: [0; CELLS],
            queue: [0; CELLS],
        }
    }

    /// The planes of `depth` (seen by `cam`, the same size), largest first, into `planes`
    /// (cleared first; at most [`MAX_FRAME_PLANES`]), in the camera's frame.
    ///
    /// # Errors
    /// [`PlaneError`]: nothing is detected then (`planes` is left empty).
    pub fn detect(
        &mut self,
        depth: &DepthView<'_>,
        cam: &PinholeCamera,
        params: &PlaneParams,
        planes: &mut FramePlanes,
    ) -> Result<(), PlaneError> {
        planes.clear();
        if !params.is_valid() {
            return Err(PlaneError::InvalidParams);
        }
        if depth.size() != (cam.width(), cam.height()) {
            return Err(PlaneError::SizeMismatch);
        }
        if cam.width() < PLANE_GRID.0 || cam.height() < PLANE_GRID.1 {
            return Err(PlaneError::TooSmall);
        }
        self.fit_cells(depth, cam, params);
        let mut regions: Vec<(Moments, u16), MAX_FRAME_PLANES> = Vec::new();
        for k in 0..CELLS {
            let seed = usize::from(self.order[k]);
            if !self.flat.has(seed) || self.taken.has(seed) {
                continue;
            }
            let (moments, cells) = self.grow(seed, params);
            if cells < params.min_cells {
                continue;
            }
            // Largest first: a region that does not fit takes the place of the smallest.
            if regions.is_full() {
                match regions.iter().enumerate().min_by_key(|(_, r)| r.1) {
                    Some((i, r)) if r.1 < cells => {
                        regions[i] = (moments, cells);
                    }
                    _ => {}
                }
            } else {
                let _ = regions.push((moments, cells));
            }
        }
        // Largest first; equal sizes keep their seeds' order (an insertion sort: stable).
        for i in 1..regions.len() {
            let mut j = i;
            while j > 0 && regions[j - 1].1 < regions[j].1 {
                regions.swap(j - 1, j);
                j -= 1;
            }
        }
        for (moments, cells) in &regions {
            let Some((normal, offset_m, rms_m)) = moments.fit() else { continue };
            let plane = Plane {
                normal,
                offset_m,
                centroid: moments.mean,
                rms_m,
                cells: *cells,
                // At most 64 samples a cell, 300 cells: exact.
                samples: moments.count as u32,
            };
            let _ = planes.push(plane);
        }
        Ok(())
    }

    /// Fits every cell and orders them flattest first.
    fn fit_cells(&mut self, depth: &DepthView<'_>, cam: &PinholeCamera, params: &PlaneParams) {
        let (cw, ch) = (cam.width() / PLANE_GRID.0, cam.height() / PLANE_GRID.1);
        let (sx, sy) = (SAMPLES_PER_SIDE.min(cw), SAMPLES_PER_SIDE.min(ch));
        let k = params.sensor.depth_noise_coeff_per_m;
        let (zmin, zmax) = (params.sensor.depth_min_m, params.sensor.depth_max_m);
        let mut rms = [f32::INFINITY; CELLS];
        (self.flat, self.taken) = (CellBits::NONE, CellBits::NONE);
        for (i, cell) in self.cells.iter_mut().enumerate() {
            *cell = Cell::EMPTY;
            let (x0, y0) = ((i % PLANE_GRID.0) * cw, (i / PLANE_GRID.0) * ch);
            // The cell's lattice: pixel centres spread evenly over it, row by row.
            let mut points = [None::<Point3<f32>>; SAMPLES_PER_SIDE * SAMPLES_PER_SIDE];
            for (j, p) in points.iter_mut().enumerate().take(sx * sy) {
                let (a, b) = (j % sx, j / sx);
                let (x, y) = (x0 + (2 * a + 1) * cw / (2 * sx), y0 + (2 * b + 1) * ch / (2 * sy));
                // Interpolated at the pixel's centre: the depth may be coarser than the image
                // (the board's), and its pixel's own centre is then up to half a pixel away.
                let (u, v) = (x as f32, y as f32);
                *p = depth
                    .depth_at(u, v, params.max_relative_step)
                    .filter(|z| (zmin..=zmax).contains(z))
                    .map(|z| cam.back_project(u, v, z));
            }
            let points = &points[..sx * sy];
            let valid = points.iter().flatten().count();
            // Counts are at most 64: exact in f32.
            if (valid as f32) < params.min_valid_fraction * points.len() as f32 || valid < 3 {
                continue;
            }
            if has_step(points, sx, params.max_relative_step) {
                continue;
            }
            let n = valid as f32;
            let mut sum = [0.0f32; 3];
            for p in points.iter().flatten() {
                sum = [sum[0] + p.x, sum[1] + p.y, sum[2] + p.z];
            }
            let mean = sum.map(|s| s / n);
            let mut scatter = [0.0f32; 6];
            for p in points.iter().flatten() {
                let d = [p.x - mean[0], p.y - mean[1], p.z - mean[2]];
                let products =
                    [d[0] * d[0], d[0] * d[1], d[0] * d[2], d[1] * d[1], d[1] * d[2], d[2] * d[2]];
                for (s, q) in scatter.iter_mut().zip(products) {
                    *s += q;
                }
            }
            let unweighted = Moments { count: n, weight: n, mean, scatter };
            let Some((normal, _, cell_rms)) = unweighted.fit() else { continue };
            // In metres: z is at least the sensor's minimum depth, so the weight is finite.
            let z2 = mean[2] * mean[2];
            cell.moments = unweighted.weighted(1.0 / (z2 * z2));
            let z = mean[2];
            cell.normal = normal;
            if cell_rms <= params.flat_sigmas * k * z * z + params.flat_floor_m {
                self.flat.set(i);
            }
            if let Some(r) = rms.get_mut(i) {
                *r = cell_rms;
            }
        }
        for (i, o) in self.order.iter_mut().enumerate() {
            // At most 300 cells: the index fits.
            *o = i as u16;
        }
        let key = |i: u16| rms.get(usize::from(i)).copied().unwrap_or(f32::INFINITY);
        self.order.sort_unstable_by(|&a, &b| key(a).total_cmp(&key(b)).then(a.cmp(&b)));
    }

    /// Grows a region from the flat cell `seed` over its 4-neighbours (breadth first):
    /// a flat cell not yet taken joins when it agrees with the region's plane, refitted after
    /// each join. Returns the region's moments and cells.
    fn grow(&mut self, seed: usize, params: &PlaneParams) -> (Moments, u16) {
        let cos_max = libm::cosf(params.max_normal_angle_rad);
        let k = params.sensor.depth_noise_coeff_per_m;
        let Some(first) = self.cells.get(seed) else { return (Moments::EMPTY, 0) };
        self.taken.set(seed);
        let mut moments = first.moments;
        let mut plane = (first.normal, -dot(&first.normal, &first.moments.mean));
        let mut cells = 1u16;
        // At most 300 cells: the indices fit.
        self.queue[0] = seed as u16;
        let (mut head, mut tail) = (0usize, 1usize);
        while head < tail {
            let at = usize::from(self.queue[head]);
            head += 1;
            let (col, row) = (at % PLANE_GRID.0, at / PLANE_GRID.0);
            let neighbours = [
                (col > 0).then(|| at - 1),
                (col + 1 < PLANE_GRID.0).then(|| at + 1),
                (row > 0).then(|| at - PLANE_GRID.0),
                (row + 1 < PLANE_GRID.1).then(|| at + PLANE_GRID.0),
            ];
            for j in neighbours.into_iter().flatten() {
                let Some(cell) = self.cells.get(j) else { continue };
                if !self.flat.has(j) || self.taken.has(j) {
                    continue;
                }
                let m = &cell.moments;
                let z = m.mean[2];
                let reach = params.join_sigmas * k * z * z / ferroslam_fpu::sqrtf(m.count)
                    + params.join_floor_m;
                let apart = (dot(&plane.0, &m.mean) + plane.1).abs();
                if dot(&cell.normal, &plane.0) < cos_max || apart > reach {
                    continue;
                }
                self.taken.set(j);
                moments = moments.merged(m);
                if let Some((normal, offset, _)) = moments.fit() {
                    plane = (normal, offset);
                }
                cells += 1;
                if let Some(q) = self.queue.get_mut(tail) {
                    *q = j as u16;
                    tail += 1;
                }
            }
        }
        (moments, cells)
    }
}

/// Whether two samples next to each other on a lattice `width` samples wide (row by row) differ
/// in depth by more than `max_relative` of the nearer.
fn has_step(points: &[Option<Point3<f32>>], width: usize, max_relative: f32) -> bool {
    let apart = |a: &Option<Point3<f32>>, b: &Option<Point3<f32>>| match (a, b) {
        (Some(a), Some(b)) => (a.z - b.z).abs() > max_relative * a.z.min(b.z),
        _ => false,
    };
    let across = points.chunks(width).any(|row| row.windows(2).any(|w| apart(&w[0], &w[1])));
    let down = points.iter().zip(points.iter().skip(width)).any(|(a, b)| apart(a, b));
    across || down
}

/// The dot product of two 3-vectors held as arrays.
pub(super) fn dot(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
