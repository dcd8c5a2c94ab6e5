//! Feeding your own frames to the core, start to end: a TUM-layout RGB-D folder read with the
//! `image` crate (stand-in for your camera driver), each frame brought to the reference board's
//! QVGA profile with the core's own downsampling, tracked by [`QvgaSlam`] with the back end
//! stepped by a fixed quota after every frame (the firmware's schedule, so the same bits), and
//! every pose printed on stdout as a TUM trajectory line (`timestamp tx ty tz qx qy qz qw`, the
//! camera-to-world pose, metres, the world being the first keyframe's camera).
//!
//! ```sh
//! cargo run --release -p ferroslam-core --example track_your_frames -- [DIR] [MAX_FRAMES] > traj.txt
//! ```
//!
//! `DIR` defaults to the 7-Scenes recording in `../shared/datasets/`; its `calibration.toml` gives
//! the intrinsics and depth scale (top-level `fx`, `fy`, `cx`, `cy`, `width`, `height`,
//! `depth_scale`; the simulator's `replay` reads the rest of that file: distortion, depth
//! registration). `ferroslam-sim eval DIR/groundtruth.txt traj.txt` then gives the ATE.

use std::error::Error;
use std::path::{Path, PathBuf};

use ferroslam_core::config::QVGA;
use ferroslam_core::frame::RgbdFrame;
use ferroslam_core::geometry::PinholeCamera;
use ferroslam_core::image::{
    DepthView, GrayView, GrayViewMut, ImageView, ImageViewMut, downsample_depth_2x,
    downsample_gray_2x,
};
use ferroslam_core::system::{DEFAULT_BACKEND_QUOTA, DEFAULT_DRAIN_STEPS, QvgaSlam};

/// Colour and depth images further apart than this are not one frame, seconds (TUM's rule).
const MAX_DT_S: f64 = 0.02;

fn main() -> Result<(), Box<dyn Error>> {
    let mut args = std::env::args().skip(1);
    let dir = args.next().map_or_else(default_dir, PathBuf::from);
    let max_frames = args.next().map(|n| n.parse::<usize>()).transpose()?.unwrap_or(usize::MAX);
    let calibration = Calibration::read(&dir.join("calibration.toml"))?;
    // The sensor's camera halved once: the camera of the QVGA frames the core sees.
    let sensor = PinholeCamera::new(
        calibration.fx,
        calibration.fy,
        calibration.cx,
        calibration.cy,
        calibration.width,
        calibration.height,
    )?;
    let cam = sensor.downscaled_2x()?;
    // About a megabyte: on the heap here; the firmware keeps it in a `static`.
    let mut slam: Box<QvgaSlam> = Box::default();
    let frames = associate(&read_list(&dir, "rgb.txt")?, &read_list(&dir, "depth.txt")?);
    let (mut tracked, mut lost) = (0, 0);
    for (timestamp_s, rgb, depth) in frames.into_iter().take(max_frames) {
        // Your camera's buffers: 8-bit gray and 16-bit depth at the sensor's resolution.
        let gray = image::open(&rgb)?.to_luma8();
        let depth = image::open(&depth)?.to_luma16();
        let (w, h) = (gray.width() as usize, gray.height() as usize);
        if (w, h) != (calibration.width, calibration.height)
            || depth.dimensions() != gray.dimensions()
        {
            return Err(format!("{}: not {w}x{h} like the calibration", rgb.display()).into());
        }
        // The board's profile: gray halved once, depth halved twice (`QVGA.depth_level`).
        let mut gray_qvga = vec![0u8; (w / 2) * (h / 2)];
        downsample_gray_2x(
            &GrayView::packed(gray.as_raw(), w, h)?,
            &mut GrayViewMut::packed(&mut gray_qvga, w / 2, h / 2)?,
        )?;
        let mut depth_half = vec![0u16; (w / 2) * (h / 2)];
        downsample_depth_2x(
            &ImageView::packed(depth.as_raw(), w, h)?,
            &mut ImageViewMut::packed(&mut depth_half, w / 2, h / 2)?,
        )?;
        let mut depth_quarter = vec![0u16; (w / 4) * (h / 4)];
        downsample_depth_2x(
            &ImageView::packed(&depth_half, w / 2, h / 2)?,
            &mut ImageViewMut::packed(&mut depth_quarter, w / 4, h / 4)?,
        )?;
        let frame = RgbdFrame {
            timestamp_s,
            gray: GrayView::packed(&gray_qvga, w / 2, h / 2)?,
            depth: DepthView::with_level(
                ImageView::packed(&depth_quarter, w / 4, h / 4)?,
                calibration.depth_scale,
                QVGA.depth_level,
            )?,
        };
        // The back end's step for the frame before, then this frame's tracking.
        slam.step_backend(&cam, DEFAULT_BACKEND_QUOTA)?;
        let result = slam.process(&frame, &cam)?;
        if result.tracked {
            tracked += 1;
        } else {
            lost += 1;
        }
        let (t, q) = (result.t_wc.translation.vector, result.t_wc.rotation.coords);
        println!(
            "{timestamp_s:.6} {:.6} {:.6} {:.6} {:.6} {:.6} {:.6} {:.6}",
            t.x, t.y, t.z, q.x, q.y, q.z, q.w
        );
    }
    slam.drain_backend(&cam, DEFAULT_BACKEND_QUOTA, DEFAULT_DRAIN_STEPS)?;
    let keyframes = slam.map().keyframes().count();
    eprintln!("{tracked} frames tracked, {lost} not; {keyframes} keyframes in the map at the end");
    Ok(())
}

/// The 7-Scenes recording beside the repository.
fn default_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/datasets/7scenes-redkitchen-1000")
}

/// The top-level numbers of a `calibration.toml` this example needs.
struct Calibration {
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    width: usize,
    height: usize,
    depth_scale: f32,
}

impl Calibration {
    /// Reads `key = number` lines up to the first `[table]`, ignoring comments and other keys.
    fn read(path: &Path) -> Result<Self, Box<dyn Error>> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("reading {}: {e}", path.display()))?;
        let value = |key: &str| -> Result<f32, Box<dyn Error>> {
            let line = text
                .lines()
                .take_while(|l| !l.trim_start().starts_with('['))
                .filter_map(|l| l.split('#').next()?.split_once('='))
                .find(|(k, _)| k.trim() == key)
                .ok_or_else(|| format!("{}: no `{key}`", path.display()))?;
            Ok(line.1.trim().parse()?)
        };
        Ok(Self {
            fx: value("fx")?,
            fy: value("fy")?,
            cx: value("cx")?,
            cy: value("cy")?,
            width: value("width")? as usize,
            height: value("height")? as usize,
            depth_scale: value("depth_scale")?,
        })
    }
}

/// `(timestamp_s, file)` of every line of a TUM list (`rgb.txt`, `depth.txt`).
fn read_list(dir: &Path, name: &str) -> Result<Vec<(f64, PathBuf)>, Box<dyn Error>> {
    let path = dir.join(name);
    let text =
        std::fs::read_to_string(&path).map_err(|e| format!("reading {}: {e}", path.display()))?;
    let mut list = Vec::new();
    for line in text.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty()) {
        let mut fields = line.split_whitespace();
        let (Some(t), Some(file)) = (fields.next(), fields.next()) else {
            return Err(format!("{}: bad line `{line}`", path.display()).into());
        };
        list.push((t.parse()?, dir.join(file)));
    }
    Ok(list)
}

/// Each colour image with the depth image nearest in time, within [`MAX_DT_S`].
fn associate(rgb: &[(f64, PathBuf)], depth: &[(f64, PathBuf)]) -> Vec<(f64, PathBuf, PathBuf)> {
    rgb.iter()
        .filter_map(|(t, colour)| {
            let nearest =
                depth.iter().min_by(|a, b| (a.0 - t).abs().total_cmp(&(b.0 - t).abs()))?;
            ((nearest.0 - t).abs() <= MAX_DT_S).then(|| (*t, colour.clone(), nearest.1.clone()))
        })
        .collect()
}
