//! The built-in synthetic RGB-D sequence (`ferroslam-sim demo`): a textured room ray-cast in code,
//! with exact ground truth.
//!
//! # Scene
//! A 6 m x 7 m x 2.8 m room (world frame: metres, `z` up, floor at `z = 0`, interior from
//! [`ROOM_MIN`] to [`ROOM_MAX`]): brick walls north and south, plaster west, tiles east, a plank
//! floor and a panelled ceiling; fourteen posters (random shapes, letter-like text at three sizes, a
//! calibration checkerboard, logos, landscape prints); six boxes at different depths, four of them
//! rotated about the vertical axis, and a checkered ball, so that the camera sees parallax and
//! occlusion. All textures have structure (mortar lines, grout, planks, slats, grain) plus
//! multi-octave value noise. Shading is Lambertian under one fixed directional light plus ambient,
//! so a surface point has the same brightness from every viewpoint. The layout never depends on
//! options or seed.
//!
//! # Frames
//! - Gray: 8 bits, 2x2 rotated-grid supersampling per pixel (anti-aliased edges).
//! - Depth: 16 bits, `raw / depth_scale` metres (`depth_scale` = 5000 as in TUM), the z-depth along
//!   the optical axis of the surface seen through the pixel *centre* (never a blend across an edge);
//!   0 = no reading (beyond [`SynthOptions::max_range_m`], or a simulated hole).
//! - Time: frame `i` is at `i / 30` seconds ([`FRAME_RATE_HZ`]).
//!
//! # Camera
//! Pinhole without distortion, camera frame x right, y down, z forward, pixel centres at integer
//! coordinates (pixel `(0, 0)` is centred at `(0.0, 0.0)`). At 640 x 480: `fx = fy = 525`,
//! `cx = 319.5`, `cy = 239.5`; at other sizes the focal length scales with the width (same
//! horizontal field of view) and the principal point stays at the image centre
//! ([`SynthIntrinsics::for_size`]).
//!
//! # Path
//! 10 s by default (300 frames): the camera starts at `(0, -2, 1.4)` looking north, 8 degrees down,
//! translates about 2.7 m along smooth sums of sinusoids and sweeps its yaw over +-40 degrees with
//! some pitch (-15 to -1 degrees) and roll (+-6 degrees); see [`SyntheticSequence::pose_at`]. It
//! never gets closer than 0.5 m to any surface; longer sequences continue the same motion.
//!
//! # Determinism
//! All randomness comes from one SplitMix64 generator keyed by the seed, the frame and the pixel, and
//! every transcendental function goes through `libm`, so the output is bit-identical across runs,
//! machines and thread counts.

mod face;
mod noise;
mod path;
mod poster;
mod render;
pub mod rng;
mod scene;
mod source;
mod texture;
mod tum_folder;

use std::path::PathBuf;

use ferroslam_core::image::ImageError;
use nalgebra::{Isometry3, Point3, Vector3};

use crate::trajectory::{StampedPose, Trajectory};

pub use path::{START_PITCH_DEG, START_POSITION_M};
pub use scene::{ROOM_MAX, ROOM_MIN};
pub use source::{SynthSource, write_pngs};
pub use tum_folder::write_tum_folder;

/// Frame rate of the synthetic sequence, Hz.
pub const FRAME_RATE_HZ: f64 = 30.0;
/// Raw depth units per metre (as in the TUM RGB-D benchmark).
pub const DEPTH_SCALE: f64 = 5000.0;

/// Options of the synthetic sequence. `Default` gives the clean 640 x 480, 300-frame demo.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthOptions {
    /// Number of frames (30 per second of path).
    pub frames: usize,
    /// Image width in pixels (16 to 8192).
    pub width: usize,
    /// Image height in pixels (16 to 8192).
    pub height: usize,
    /// Depth noise: Gaussian with `sigma = depth_noise_k * z^2` (`k` in 1/m, `z` in m; Kinect v1
    /// is about 0.0015). 0 = exact depth (up to quantization).
    pub depth_noise_k: f64,
    /// Fraction of the pixels (0 to 0.9) whose depth is removed in random elliptic blobs of
    /// 3 to 18 pixels radius (at 640 pixels width), like sensor dropouts.
    pub hole_fraction: f64,
    /// Remove depth where the viewing ray meets the surface at more than this angle from the
    /// normal, degrees (Kinect-like grazing dropouts, e.g. 75). `None` = keep all.
    pub grazing_limit_deg: Option<f64>,
    /// Depth beyond this is no reading, metres (at most 13.1, the largest 16-bit value at 5000/m).
    pub max_range_m: f64,
    /// Gaussian noise added to the gray image, gray levels (0 = none).
    pub gray_noise_sigma: f64,
    /// Motion blur: the gray image averages this many renders spread over the exposure
    /// (1 = no blur). Depth and ground truth stay at the frame's timestamp (the exposure's middle).
    pub motion_blur_samples: usize,
    /// Exposure time as a fraction of the frame interval (0 to 1], used by motion blur.
    pub exposure_frames: f64,
    /// High-frequency shake added to the path (part of the ground truth): 1 = up to about 4 mm and
    /// 0.4 degrees at 5 to 11 Hz; 0 = none; at most 5.
    pub shake: f64,
    /// Sweep yaw three times faster (about 110 degrees per second) and pitch twice as fast.
    pub fast_rotation: bool,
    /// Seed of every random choice (noise, holes, shake phases); the room itself is fixed.
    pub seed: u64,
    /// Render threads; 0 = the machine's parallelism (at most 8). The output never depends on it.
    pub threads: usize,
}

impl Default for SynthOptions {
    fn default() -> Self {
        Self {
            frames: 300,
            width: 640,
            height: 480,
            depth_noise_k: 0.0,
            hole_fraction: 0.0,
            grazing_limit_deg: None,
            max_range_m: 8.0,
            gray_noise_sigma: 0.0,
            motion_blur_samples: 1,
            exposure_frames: 0.5,
            shake: 0.0,
            fast_rotation: false,
            seed: 0,
            threads: 0,
        }
    }
}

/// `Err(InvalidOption)` unless `ok`.
fn require(ok: bool, name: &'static str, reason: &'static str) -> Result<(), SynthError> {
    if ok { Ok(()) } else { Err(SynthError::InvalidOption { name, reason }) }
}

impl SynthOptions {
    /// Checks every option.
    ///
    /// # Errors
    /// [`SynthError::InvalidOption`] naming the first bad option.
    pub fn validate(&self) -> Result<(), SynthError> {
        let in_range = |x: f64, lo: f64, hi: f64| x.is_finite() && x >= lo && x <= hi;
        require((1..=1_000_000).contains(&self.frames), "frames", "must be 1 to 1000000")?;
        require((16..=8192).contains(&self.width), "width", "must be 16 to 8192 pixels")?;
        require((16..=8192).contains(&self.height), "height", "must be 16 to 8192 pixels")?;
        require(
            in_range(self.depth_noise_k, 0.0, 0.1),
            "depth_noise_k",
            "must be finite, 0 to 0.1",
        )?;
        require(
            in_range(self.hole_fraction, 0.0, 0.9),
            "hole_fraction",
            "must be finite, 0 to 0.9",
        )?;
        if let Some(g) = self.grazing_limit_deg {
            require(
                g.is_finite() && g > 0.0 && g <= 90.0,
                "grazing_limit_deg",
                "must be in (0, 90]",
            )?;
        }
        let max_m = f64::from(u16::MAX) / DEPTH_SCALE;
        require(
            self.max_range_m.is_finite() && self.max_range_m > 0.0 && self.max_range_m <= max_m,
            "max_range_m",
            "must be in (0, 13.1] metres",
        )?;
        require(
            in_range(self.gray_noise_sigma, 0.0, 100.0),
            "gray_noise_sigma",
            "must be finite, 0 to 100",
        )?;
        require(
            (1..=64).contains(&self.motion_blur_samples),
            "motion_blur_samples",
            "must be 1 to 64",
        )?;
        require(
            self.exposure_frames.is_finite()
                && self.exposure_frames > 0.0
                && self.exposure_frames <= 1.0,
            "exposure_frames",
            "must be in (0, 1]",
        )?;
        require(in_range(self.shake, 0.0, 5.0), "shake", "must be finite, 0 to 5")?;
        require(self.threads <= 64, "threads", "must be at most 64")
    }
}

/// What can go wrong building or rendering the synthetic sequence.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SynthError {
    /// An option is out of its documented range (or NaN).
    #[error("invalid synthetic option `{name}`: {reason}")]
    InvalidOption {
        /// The option's field name in [`SynthOptions`].
        name: &'static str,
        /// What the option must be.
        reason: &'static str,
    },
    /// A frame index past the end of the sequence.
    #[error("frame {index} is out of range (the sequence has {len} frames)")]
    FrameOutOfRange {
        /// The index asked for.
        index: usize,
        /// The number of frames.
        len: usize,
    },
    /// A render worker thread panicked (a bug).
    #[error("a render thread panicked")]
    RenderThread,
    /// The frame buffers could not be viewed as core images (a bug).
    #[error("frame buffers do not form an image: {0}")]
    Image(#[from] ImageError),
    /// A file could not be written.
    #[error("cannot write {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A PNG could not be written.
    #[error("cannot write {path}: {source}")]
    Png {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: image::ImageError,
    },
}

/// The pinhole intrinsics and depth scale of the synthetic camera (no distortion).
///
/// Pixel centres are at integer coordinates; camera frame x right, y down, z forward.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SynthIntrinsics {
    /// Focal length in pixels, x.
    pub fx: f64,
    /// Focal length in pixels, y.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Raw depth units per metre.
    pub depth_scale: f64,
}

impl SynthIntrinsics {
    /// The intrinsics at `width x height`: `fx = fy = 525 * width / 640`,
    /// `cx = (width - 1) / 2`, `cy = (height - 1) / 2` (so 525, 525, 319.5, 239.5 at 640 x 480).
    pub fn for_size(width: usize, height: usize) -> Self {
        let f = 525.0 * width as f64 / 640.0;
        Self {
            fx: f,
            fy: f,
            cx: 0.5 * (width as f64 - 1.0),
            cy: 0.5 * (height as f64 - 1.0),
            width,
            height,
            depth_scale: DEPTH_SCALE,
        }
    }

    /// Pixel coordinates `(u, v)` of a camera-frame point (metres), or `None` behind the camera.
    pub fn project(&self, p_c: &Point3<f64>) -> Option<[f64; 2]> {
        (p_c.z > 0.0)
            .then(|| [self.fx * p_c.x / p_c.z + self.cx, self.fy * p_c.y / p_c.z + self.cy])
    }

    /// The camera-frame point (metres) at pixel `(u, v)` with z-depth `z_m`.
    pub fn back_project(&self, u: f64, v: f64, z_m: f64) -> Point3<f64> {
        Point3::new((u - self.cx) / self.fx * z_m, (v - self.cy) / self.fy * z_m, z_m)
    }
}

/// A planar face of the room seen in a frame ([`SyntheticSequence::visible_planes`]): the points
/// `p` of the camera's frame with `normal_c . p + offset_m = 0`.
#[derive(Debug, Clone, PartialEq)]
pub struct VisiblePlane {
    /// Which face: `floor`, `north wall`, `box 2 face 5`, ...
    pub name: String,
    /// Its share of the frame.
    pub fraction: f64,
    /// Unit normal in the camera's frame, toward the camera.
    pub normal_c: Vector3<f64>,
    /// The camera's distance to the plane, metres.
    pub offset_m: f64,
}

/// One rendered frame (depth scale [`DEPTH_SCALE`], timestamps `index / 30` s).
pub type SynthFrame = crate::frame::OwnedFrame;

/// The synthetic sequence: options, camera, room and path. Frames are rendered on demand.
#[derive(Debug, Clone)]
pub struct SyntheticSequence {
    opts: SynthOptions,
    intrinsics: SynthIntrinsics,
    scene: scene::Scene,
    path: path::CameraPath,
}

impl SyntheticSequence {
    /// A sequence with validated options.
    ///
    /// # Errors
    /// [`SynthError::InvalidOption`] when an option is out of range (see [`SynthOptions`]).
    pub fn new(opts: SynthOptions) -> Result<Self, SynthError> {
        opts.validate()?;
        Ok(Self {
            intrinsics: SynthIntrinsics::for_size(opts.width, opts.height),
            scene: scene::Scene::demo(),
            path: path::CameraPath::new(opts.fast_rotation, opts.shake, opts.seed),
            opts,
        })
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.opts.frames
    }

    /// Always `false`: a sequence has at least one frame.
    pub fn is_empty(&self) -> bool {
        self.opts.frames == 0
    }

    /// The options the sequence was built with.
    pub fn options(&self) -> &SynthOptions {
        &self.opts
    }

    /// Camera intrinsics and depth scale.
    pub fn intrinsics(&self) -> SynthIntrinsics {
        self.intrinsics
    }

    /// Timestamp of frame `index` in seconds, `None` past the end.
    pub fn timestamp(&self, index: usize) -> Option<f64> {
        (index < self.len()).then(|| index as f64 / FRAME_RATE_HZ)
    }

    /// The exact camera-to-world pose at any time `t_s` (seconds) of the continuous path,
    /// including shake. Frame `i` is rendered at `pose_at(i / 30)`.
    ///
    /// With `w = 2 pi / 10 s`: position (world, metres) `x = 0.45 sin(w t) + 0.05 sin(3 w t)`,
    /// `y = -2 + 0.22 sin(2 w t)`, `z = 1.4 + 0.1 sin(1.5 w t)`; yaw (about world `z`, positive
    /// turns left) `40 deg sin(1.5 w t)` (`sin(4.5 w t)` with `fast_rotation`); pitch (positive
    /// looks up) `-8 deg + 7 deg sin(2.5 w t)` (`sin(5 w t)` with `fast_rotation`); roll `6 deg
    /// sin(1.7 w t)`; `R_wc = Rz(yaw) Rx(pitch) Ry(roll) R0`, where `R0` maps the camera axes
    /// (x right, y down, z forward) to world `+x`, `-z`, `+y`. Shake adds three sinusoids at 5.3,
    /// 7.9 and 11.3 Hz with seeded phases per axis.
    pub fn pose_at(&self, t_s: f64) -> Isometry3<f64> {
        self.path.pose(t_s)
    }

    /// Exact ground truth of frame `index` (`T_wc` at its timestamp), `None` past the end.
    pub fn ground_truth(&self, index: usize) -> Option<StampedPose> {
        self.timestamp(index)
            .map(|timestamp_s| StampedPose { timestamp_s, t_wc: self.pose_at(timestamp_s) })
    }

    /// Ground truth of every frame, in order.
    pub fn ground_truth_all(&self) -> Trajectory {
        Trajectory { poses: (0..self.len()).filter_map(|i| self.ground_truth(i)).collect() }
    }

    /// Renders frame `index`.
    ///
    /// # Errors
    /// [`SynthError::FrameOutOfRange`] past the end; [`SynthError::RenderThread`] if a worker
    /// thread panicked.
    pub fn render(&self, index: usize) -> Result<SynthFrame, SynthError> {
        let mut frame = SynthFrame::empty(DEPTH_SCALE as f32);
        self.render_into(index, &mut frame)?;
        Ok(frame)
    }

    /// Renders frame `index` into `frame`, reusing its buffers.
    ///
    /// # Errors
    /// As [`SyntheticSequence::render`].
    pub fn render_into(&self, index: usize, frame: &mut SynthFrame) -> Result<(), SynthError> {
        let timestamp_s =
            self.timestamp(index).ok_or(SynthError::FrameOutOfRange { index, len: self.len() })?;
        frame.timestamp_s = timestamp_s;
        frame.width = self.opts.width;
        frame.height = self.opts.height;
        frame.depth_scale = DEPTH_SCALE as f32;
        render::render_frame(self, index, frame)
    }

    /// The planar faces frame `index` sees within `max_depth_m` (the room's walls, floor and
    /// ceiling, the boxes' faces; not the spheres), largest first: one ray every `step` pixels (at
    /// least 1), each face with the share of those rays that hit it first no deeper than
    /// `max_depth_m` (a sensor's range), and its plane in the camera's frame. The ground truth of
    /// plane detection.
    pub fn visible_planes(&self, index: usize, step: usize, max_depth_m: f64) -> Vec<VisiblePlane> {
        let Some(gt) = self.ground_truth(index) else { return Vec::new() };
        let (t_wc, k, step) = (gt.t_wc, self.intrinsics, step.max(1));
        let r_cw = t_wc.rotation.inverse();
        let origin = Point3::from(t_wc.translation.vector);
        let mut planes: Vec<(face::FaceId, VisiblePlane)> = Vec::new();
        let mut rays = 0usize;
        for y in (0..k.height).step_by(step) {
            for x in (0..k.width).step_by(step) {
                rays += 1;
                let dir_c = k.back_project(x as f64, y as f64, 1.0).coords;
                let Some(hit) = self.scene.cast(&origin, &(t_wc.rotation * dir_c), u32::MAX) else {
                    continue;
                };
                if matches!(hit.face, face::FaceId::Sphere(_)) || hit.t > max_depth_m {
                    continue;
                }
                if let Some((_, p)) = planes.iter_mut().find(|(f, _)| *f == hit.face) {
                    p.fraction += 1.0;
                    continue;
                }
                let normal_c = r_cw * hit.normal;
                let p_c = dir_c * hit.t;
                let name = match hit.face {
                    face::FaceId::Room(f) => {
                        ["west wall", "east wall", "south wall", "north wall", "floor", "ceiling"]
                            .get(usize::from(f))
                            .map_or_else(|| format!("room face {f}"), |n| (*n).to_owned())
                    }
                    face::FaceId::Box { index, face } => format!("box {index} face {face}"),
                    face::FaceId::Sphere(i) => format!("sphere {i}"),
                };
                let plane =
                    VisiblePlane { name, fraction: 1.0, normal_c, offset_m: -normal_c.dot(&p_c) };
                planes.push((hit.face, plane));
            }
        }
        let mut planes: Vec<VisiblePlane> = planes.into_iter().map(|(_, p)| p).collect();
        for p in &mut planes {
            p.fraction /= rays.max(1) as f64;
        }
        planes.sort_by(|a, b| b.fraction.total_cmp(&a.fraction));
        planes
    }

    /// Where the ray of frame `index`'s camera in direction `dir_c` (camera frame) first meets
    /// the room, in the world frame, metres; `None` past the end or for a null direction.
    pub fn cast_ray(&self, index: usize, dir_c: &Vector3<f64>) -> Option<Point3<f64>> {
        let t_wc = self.ground_truth(index)?.t_wc;
        let origin = Point3::from(t_wc.translation.vector);
        let dir = t_wc.rotation * dir_c;
        let hit = self.scene.cast(&origin, &dir, u32::MAX)?;
        Some(origin + dir * hit.t)
    }

    /// A [`ferroslam_core::frame::FrameSource`] that renders the frames in order.
    pub fn into_source(self) -> SynthSource {
        SynthSource::new(self)
    }
}
