//! The `frames` target: the board's SLAM ([`QvgaSlam`]) on adversarial frames made from the input
//! bytes, run as the firmware's pipeline runs it (the front end on a frame, then the back end for
//! [`DEFAULT_BACKEND_QUOTA`] units and the place memory's pending write); at the end the back end
//! drained, the map remembered and saved, as a save on the board does.
//!
//! Properties: nothing panics, every pose the front end returns is finite, and the saved map is
//! a map file the loader takes.
//!
//! # Input
//!
//! Byte 0: bit 0 set, a place memory of [`PLACE_RECORDS`] records (else none); byte 1: the seed
//! of the scene's texture. Then up to [`MAX_FRAMES`] frames of [`FRAME_BYTES`] bytes each:
//!
//! - byte 0, kind (mod 16): 0-7 the textured plane ([`Kind::Scene`]), 8 noise, 9 saturated,
//!   10 no depth, 11 extreme depth, 12 the previous frame again, 13 another size, 14 sizes that
//!   disagree, 15 depth with holes and spikes;
//! - byte 1: the frame's own random seed (noise, holes, which size);
//! - bytes 2 and 3: camera motion, quarter pixels (i8 each): the texture moves by it;
//! - byte 4, time: 0-199 `(t + 1)` ms after the previous frame, 200-239 `t - 199` s, 240-251 edge
//!   cases (the same time, earlier, NaN, infinities, 1e300, subnormal, 0, the next float,
//!   f64::MAX), 252-255 1/30 s;
//! - byte 5, depth: bits 0-6 the plane's distance (0.4 m + 5 cm steps), bit 7 a slanted plane;
//! - byte 6: brightness offset (i8 / 4);
//! - byte 7: bits 0-2 the depth scale (5000, 1000, 5000, 5000, 1, 65535, f32::MAX,
//!   f32::MIN_POSITIVE); bits 3-4 the depth level (1, 1, 0, 2); bit 5 freezes (or thaws) the
//!   place memory; bit 7 drains the back end after the frame.
//!
//! Cost: about 40 ms an input, at most about 150 (SLAM on up to [`MAX_FRAMES`] QVGA
//! frames); the runner gives this target fewer inputs under `--iterations`
//! (`FRAMES_ITERATION_DIVISOR`).

use ferroslam_core::config::QVGA;
use ferroslam_core::frame::RgbdFrame;
use ferroslam_core::geometry::PinholeCamera;
use ferroslam_core::geometry::Pose;
use ferroslam_core::image::{DepthView, GrayView, ImageError, ImageView};
use ferroslam_core::loops::PlaceMemory;
use ferroslam_core::map::RamStore;
use ferroslam_core::persist::check_map_file;
use ferroslam_core::system::{DEFAULT_BACKEND_QUOTA, MapAccess, QvgaSlam};
use ferroslam_core::tracking::{NoPlaces, Places};
use ferroslam_sim::synth::rng::mix64;

use super::Outcome;
use super::mutate::Rng;
use super::targets::class_of;

/// Frames an input holds at most.
pub const MAX_FRAMES: usize = 10;
/// Bytes of one frame's description.
pub const FRAME_BYTES: usize = 8;
/// Bytes before the first frame.
pub const HEADER_BYTES: usize = 2;
/// Records of the place memory's store (small, so that a few keyframes fill it).
pub const PLACE_RECORDS: usize = 16;
/// Back-end steps the end of an input (and a frame's bit 7) drains at most.
const DRAIN_STEPS: u32 = 200;

/// The board's frame size, pixels.
const WIDTH: usize = 320;
const HEIGHT: usize = 240;
/// The default camera's focal length at that size, pixels (a Kinect's 525 halved).
const FOCAL_PX: f32 = 262.5;

/// What a frame's pixels are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// The textured plane, moved by the camera motion: a scene the tracker can follow.
    Scene,
    /// Gray and depth uniformly random.
    Noise,
    /// Gray all 255 (or all 0), depth the plane's.
    Saturated,
    /// Depth all 0 (no reading).
    NoDepth,
    /// Depth all `u16::MAX` (or alternating with 1).
    ExtremeDepth,
    /// The previous frame's pixels and sizes again.
    Repeat,
    /// A frame of another size, with a camera of that size.
    OtherSize,
    /// Gray, depth and camera of sizes that disagree.
    Mismatch,
    /// The plane with depth holes (0) and spikes (`u16::MAX`, 1).
    Holes,
}

impl Kind {
    fn of(byte: u8) -> Self {
        match byte % 16 {
            0..=7 => Self::Scene,
            8 => Self::Noise,
            9 => Self::Saturated,
            10 => Self::NoDepth,
            11 => Self::ExtremeDepth,
            12 => Self::Repeat,
            13 => Self::OtherSize,
            14 => Self::Mismatch,
            _ => Self::Holes,
        }
    }
}

/// One frame's description (see the module documentation).
#[derive(Debug, Clone, Copy)]
struct FrameSpec {
    kind: Kind,
    seed: u8,
    motion: [i8; 2],
    time: u8,
    depth: u8,
    brightness: i8,
    extra: u8,
}

impl FrameSpec {
    fn of(b: &[u8]) -> Self {
        let at = |i: usize| b.get(i).copied().unwrap_or(0);
        Self {
            kind: Kind::of(at(0)),
            seed: at(1),
            motion: [at(2) as i8, at(3) as i8],
            time: at(4),
            depth: at(5),
            brightness: at(6) as i8,
            extra: at(7),
        }
    }

    /// Raw depth units per metre.
    fn depth_scale(&self) -> f32 {
        [5000.0, 1000.0, 5000.0, 5000.0, 1.0, 65535.0, f32::MAX, f32::MIN_POSITIVE]
            [usize::from(self.extra & 7)]
    }

    /// Halvings of the depth image against the gray image.
    fn depth_level(&self) -> u8 {
        [QVGA.depth_level, QVGA.depth_level, 0, 2][usize::from((self.extra >> 3) & 3)]
    }

    /// The plane's distance at image column `x` of `width`, metres.
    fn plane_m(&self, x: usize, width: usize) -> f32 {
        let base = 0.4 + f32::from(self.depth & 0x7F) * 0.05;
        if self.depth & 0x80 == 0 {
            base
        } else {
            base * (1.0 + 0.5 * (x as f32 / width.max(1) as f32 - 0.5))
        }
    }

    /// This frame's timestamp after `previous_s` (see the module documentation).
    fn timestamp_s(&self, previous_s: f64) -> f64 {
        match self.time {
            t @ 0..=199 => previous_s + f64::from(t + 1) * 1e-3,
            t @ 200..=239 => previous_s + f64::from(t - 199),
            240 => previous_s,
            241 => previous_s - 1.0,
            242 => f64::NAN,
            243 => f64::INFINITY,
            244 => f64::NEG_INFINITY,
            245 => 1e300,
            246 => -1e300,
            247 => f64::MIN_POSITIVE,
            248 => 0.0,
            249 => previous_s + 1e-12,
            250 => previous_s.next_up(),
            251 => f64::MAX,
            _ => previous_s + 1.0 / 30.0,
        }
    }
}

/// The pixels of one frame, owned.
#[derive(Debug, Clone, Default)]
struct Pixels {
    gray: Vec<u8>,
    size: (usize, usize),
    depth: Vec<u16>,
    depth_size: (usize, usize),
    depth_level: u8,
    depth_scale: f32,
    camera_size: (usize, usize),
}

impl Pixels {
    /// The frame's gray and depth views.
    fn views(&self) -> Result<(GrayView<'_>, DepthView<'_>), ImageError> {
        let gray = ImageView::packed(&self.gray, self.size.0, self.size.1)?;
        let raw = ImageView::packed(&self.depth, self.depth_size.0, self.depth_size.1)?;
        Ok((gray, DepthView::with_level(raw, self.depth_scale, self.depth_level)?))
    }
}

/// The texture's value at `(x, y)` (pixels, any real position): two octaves of value noise.
fn texture(seed: u64, x: f32, y: f32) -> f32 {
    let lattice = |ix: i64, iy: i64, salt: u64| {
        let h = mix64(seed ^ salt ^ (ix as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15))
            ^ (iy as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
        f32::from(mix64(h) as u8)
    };
    let octave = |cell: f32, salt: u64| {
        let (u, v) = (x / cell, y / cell);
        let (ix, iy) = (u.floor(), v.floor());
        let (fx, fy) = (u - ix, v - iy);
        let (ix, iy) = (ix as i64, iy as i64);
        let top = lattice(ix, iy, salt) * (1.0 - fx) + lattice(ix + 1, iy, salt) * fx;
        let bottom = lattice(ix, iy + 1, salt) * (1.0 - fx) + lattice(ix + 1, iy + 1, salt) * fx;
        top * (1.0 - fy) + bottom * fy
    };
    0.65 * octave(9.0, 1) + 0.35 * octave(3.0, 2)
}

/// A script's state while its frames are made.
#[derive(Debug)]
struct Scene {
    texture_seed: u64,
    /// The camera's offset over the texture, pixels.
    offset: (f32, f32),
    /// The last finite timestamp given, seconds.
    clock_s: f64,
    pixels: Pixels,
}

impl Scene {
    /// The plane's gray image of `w` x `h` at the current offset, brightened by `spec`.
    fn plane_gray(&self, spec: &FrameSpec, (w, h): (usize, usize)) -> Vec<u8> {
        let (ox, oy) = self.offset;
        let shift = f32::from(spec.brightness) / 4.0;
        let mut gray = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let v = texture(self.texture_seed, x as f32 + ox, y as f32 + oy) + shift;
                gray.push(v.clamp(0.0, 255.0) as u8);
            }
        }
        gray
    }

    /// The plane's depth image for a gray image of `w` x `h` at `level`, in `scale` units.
    fn plane_depth(spec: &FrameSpec, (w, h): (usize, usize), level: u8, scale: f32) -> Vec<u16> {
        let (dw, dh) = ((w >> level).max(1), (h >> level).max(1));
        let mut depth = Vec::with_capacity(dw * dh);
        for _ in 0..dh {
            for x in 0..dw {
                let raw = (spec.plane_m(x, dw) * scale).round();
                depth.push(raw.clamp(0.0, f32::from(u16::MAX)) as u16);
            }
        }
        depth
    }

    /// Makes the pixels of the frame `spec` describes (the previous ones for [`Kind::Repeat`]).
    fn render(&mut self, spec: &FrameSpec) {
        self.offset.0 += f32::from(spec.motion[0]) / 4.0;
        self.offset.1 += f32::from(spec.motion[1]) / 4.0;
        if spec.kind == Kind::Repeat && !self.pixels.gray.is_empty() {
            return;
        }
        let mut rng = Rng::new(u64::from(spec.seed) ^ self.texture_seed.rotate_left(8));
        let mut size = (WIDTH, HEIGHT);
        let mut camera_size = size;
        let mut level = spec.depth_level();
        let scale = spec.depth_scale();
        if spec.kind == Kind::OtherSize {
            let sizes =
                [(160, 120), (318, 238), (322, 242), (2, 2), (16, 12), (640, 480), (4, 240)];
            size = sizes[usize::from(spec.seed) % sizes.len()];
            camera_size = size;
        }
        let mut depth_size = ((size.0 >> level).max(1), (size.1 >> level).max(1));
        if spec.kind == Kind::Mismatch {
            match spec.seed % 3 {
                0 => level = 0,
                1 => camera_size = (2 * WIDTH, 2 * HEIGHT),
                _ => depth_size = (depth_size.0 / 2, depth_size.1 / 2),
            }
        }
        let gray = match spec.kind {
            Kind::Noise => (0..size.0 * size.1).map(|_| rng.byte()).collect(),
            Kind::Saturated => {
                vec![if spec.seed.is_multiple_of(2) { 255 } else { 0 }; size.0 * size.1]
            }
            _ => self.plane_gray(spec, size),
        };
        let plane_size = (depth_size.0 << level, depth_size.1 << level);
        let mut depth = Self::plane_depth(spec, plane_size, level, scale);
        depth.resize(depth_size.0 * depth_size.1, 0);
        match spec.kind {
            Kind::Noise => depth.iter_mut().for_each(|d| *d = rng.next_u64() as u16),
            Kind::NoDepth => depth.fill(0),
            Kind::ExtremeDepth if spec.seed.is_multiple_of(2) => depth.fill(u16::MAX),
            Kind::ExtremeDepth => depth
                .iter_mut()
                .enumerate()
                .for_each(|(i, d)| *d = if i % 2 == 0 { u16::MAX } else { 1 }),
            Kind::Holes => {
                for d in &mut depth {
                    *d = match rng.below(8) {
                        0 | 1 => 0,
                        2 => u16::MAX,
                        3 => 1,
                        _ => *d,
                    };
                }
            }
            _ => {}
        }
        self.pixels = Pixels {
            gray,
            size,
            depth,
            depth_size,
            depth_level: level,
            depth_scale: scale,
            camera_size,
        };
    }
}

/// The camera for frames of `(w, h)`: the board's focal length scaled to the width, the
/// principal point at the centre.
fn camera_for((w, h): (usize, usize)) -> Result<PinholeCamera, String> {
    let f = FOCAL_PX * w as f32 / WIDTH as f32;
    let c = |n: usize| (n as f32 - 1.0) / 2.0;
    PinholeCamera::new(f, f, c(w), c(h), w, h).map_err(|e| format!("no camera of {w}x{h}: {e:?}"))
}

/// The `frames` target (see the module documentation). Counted in frames: processed by the
/// front end, or rejected by it (size, timestamp, depth scale).
pub fn frames(input: &[u8]) -> Result<Outcome, String> {
    let header = input.get(..HEADER_BYTES).unwrap_or(&[]);
    let with_places = header.first().is_some_and(|b| b & 1 == 1);
    let texture_seed = u64::from(header.get(1).copied().unwrap_or(0)) + 1;
    let specs: Vec<FrameSpec> = input
        .get(HEADER_BYTES..)
        .unwrap_or(&[])
        .chunks_exact(FRAME_BYTES)
        .take(MAX_FRAMES)
        .map(FrameSpec::of)
        .collect();
    let scene = Scene { texture_seed, offset: (0.0, 0.0), clock_s: 0.0, pixels: Pixels::default() };
    if with_places {
        let mut places = Box::new(PlaceMemory::new(RamStore::<PLACE_RECORDS>::new(), 1));
        let outcome = run(scene, &specs, places.as_mut())?;
        let saved = super::targets::save(places.as_mut())
            .map_err(|e| format!("the map does not save after these frames: {e}"))?;
        check_map_file(&saved, PLACE_RECORDS)
            .map_err(|e| format!("the map saved after these frames does not load: {e}"))?;
        Ok(outcome)
    } else {
        run(scene, &specs, &mut NoPlaces)
    }
}

/// Runs the frames `specs` describe through a fresh [`QvgaSlam`] with `places`.
fn run(mut scene: Scene, specs: &[FrameSpec], places: &mut impl Freeze) -> Result<Outcome, String> {
    let mut slam: Box<QvgaSlam> = Box::default();
    let board = camera_for((WIDTH, HEIGHT))?;
    let mut frozen = false;
    // Timestamps of the frames the front end processed, for telling a known issue apart.
    let mut processed_s: Vec<f64> = Vec::new();
    let mut outcome = Outcome { accepted: 0, refused: 0, class: String::new() };
    let mut seen = std::collections::BTreeSet::new();
    for (i, spec) in specs.iter().enumerate() {
        scene.render(spec);
        let timestamp_s = spec.timestamp_s(scene.clock_s);
        if timestamp_s.is_finite() {
            scene.clock_s = timestamp_s;
        }
        if spec.extra & 0x20 != 0 {
            frozen = !frozen;
            places.freeze_places(frozen);
        }
        let p = &scene.pixels;
        // A size no camera can have is run with the board's (the frame is refused for it).
        let cam = camera_for(p.camera_size).unwrap_or(board);
        let (gray, depth) = match p.views() {
            Ok(v) => v,
            Err(e) => {
                outcome.refused += 1;
                seen.insert(format!("view {}", class_of(&e)));
                continue;
            }
        };
        let frame = RgbdFrame { timestamp_s, gray, depth };
        match slam.process_with(&frame, &cam, places) {
            Ok(r) => {
                check_pose(&r.t_wc, i)?;
                processed_s.push(timestamp_s);
                outcome.accepted += 1;
                seen.insert(class_of(&r.outcome()));
                // As the pipeline: the back end's step, then the place memory's pending write.
                if slam.step_backend(&cam, DEFAULT_BACKEND_QUOTA).is_err() {
                    seen.insert("backend error".into());
                }
                places.flush();
            }
            Err(e) => {
                outcome.refused += 1;
                seen.insert(class_of(&e));
            }
        }
        if spec.extra & 0x80 != 0
            && slam.drain_backend(&board, DEFAULT_BACKEND_QUOTA, DRAIN_STEPS).is_err()
        {
            seen.insert("backend error".into());
        }
    }
    // A save's first half, as the board does it before the commit.
    if slam.drain_backend(&board, DEFAULT_BACKEND_QUOTA, DRAIN_STEPS).is_err() {
        seen.insert("backend error".into());
    }
    slam.map().remember_all_in(places);
    places.flush();
    outcome.class = seen.into_iter().collect::<Vec<_>>().join(" ");
    if specs.is_empty() {
        outcome.class = "no frame".into();
    }
    Ok(outcome)
}

/// `Ok` when frame `i`'s pose `t_wc` is finite; else the failure.
fn check_pose(t_wc: &Pose, i: usize) -> Result<(), String> {
    let (t, q) = (t_wc.translation.vector, t_wc.rotation.coords);
    if t.iter().chain(q.iter()).all(|v| v.is_finite()) {
        return Ok(());
    }
    Err(format!("frame {i}: a pose that is not finite: {t_wc:?}"))
}

/// Places that can be frozen (localization: nothing remembered) and thawed; none has nothing to
/// freeze.
trait Freeze: Places {
    fn freeze_places(&mut self, frozen: bool);
}

impl Freeze for NoPlaces {
    fn freeze_places(&mut self, _: bool) {}
}

impl<const N: usize> Freeze for PlaceMemory<RamStore<N>> {
    fn freeze_places(&mut self, frozen: bool) {
        self.freeze(frozen);
    }
}
