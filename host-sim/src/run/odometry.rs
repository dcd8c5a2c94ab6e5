//! Odometry mode: the front end alone against the board's map (depth fused into the landmarks,
//! no bundle adjustment).

use anyhow::Result;
use ferroslam_core::frame::FrameSource;
use ferroslam_core::geometry::PinholeCamera;
use ferroslam_core::map::BoardMap;
use ferroslam_core::system::Tracker;
use ferroslam_core::tracking::{FrontendState, NoPlaces};

use super::data_path::{Progress, drive};
use super::result::{TrackingRun, frame_figures};
use crate::trajectory::{StampedPose, Trajectory};

/// Runs `source` through the front end `make_frontend` builds (a profile's, boxed: hundreds of
/// KB, never kept on the stack) and the board's map.
///
/// # Errors
/// As [`drive`]; a frame the front end rejects (size or timestamp).
pub(super) fn run<F, S>(
    source: &mut S,
    progress: Progress,
    cam: &PinholeCamera,
    make_frontend: impl FnOnce() -> Box<F>,
) -> Result<TrackingRun>
where
    F: Tracker<BoardMap>,
    S: FrameSource,
    S::Error: std::error::Error + Send + Sync + 'static,
{
    let mut frontend = make_frontend();
    let mut map: Box<BoardMap> = super::boxed(BoardMap::default);
    let (mut camera, mut keyframes, mut per_frame) = (Vec::new(), Vec::new(), Vec::new());
    let data = drive(source, progress, |frame| {
        let r = frontend.process(frame, cam, &mut map, &mut NoPlaces)?;
        per_frame.push(frame_figures(frame.timestamp_s, &r));
        if r.state == FrontendState::Initializing {
            // No pose before the first keyframe, which defines the world frame.
            return Ok(());
        }
        let pose = StampedPose { timestamp_s: frame.timestamp_s, t_wc: r.t_wc.cast::<f64>() };
        camera.push(pose);
        if r.keyframe.is_some() {
            keyframes.push(pose);
        }
        Ok(())
    })?;
    let stats = frontend.stats();
    let camera = Trajectory::new(camera);
    Ok(TrackingRun {
        data,
        online: camera.clone(),
        camera,
        keyframes: Trajectory::new(keyframes),
        per_frame,
        tracked_frames: stats.tracked_frames as usize,
        lost_frames: stats.lost_frames as usize,
        reinitialized_frames: stats.reinitializations as usize,
        relocalized_frames: stats.relocalizations as usize,
        places: None,
        initializing_frames: stats.initializing_frames as usize,
        state_bytes: std::mem::size_of::<F>() + std::mem::size_of::<BoardMap>(),
        backend: None,
        planes: None,
        ar: None,
        map_points: None,
    })
}
#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::OwnedFrame;
    use ferroslam_core::tracking::QvgaFrontend;

    fn frame(width: usize, height: usize, depth_level: u8) -> OwnedFrame {
        let (dw, dh) = (width >> depth_level, height >> depth_level);
        OwnedFrame {
            timestamp_s: 0.0,
            width,
            height,
            gray: vec![0; width * height],
            depth: vec![0; dw * dh],
            depth_level,
            depth_scale: 5000.0,
        }
    }

    fn camera(width: usize, height: usize) -> PinholeCamera {
        let (w, h) = (width as f32, height as f32);
        PinholeCamera::new(w, w, (w - 1.0) / 2.0, (h - 1.0) / 2.0, width, height).unwrap()
    }

    #[test]
    fn frames_that_do_not_fit_the_front_end_name_every_size() {
        // What a replay reports when the front end refuses a frame: the core's error.
        let fits = |f: &OwnedFrame, c: &PinholeCamera| {
            let mut frontend: Box<QvgaFrontend> = Box::default();
            let mut map: Box<BoardMap> = Box::default();
            frontend.process(&f.view().unwrap(), c, &mut map).map(|_| ()).map_err(|e| e.to_string())
        };
        assert!(fits(&frame(320, 240, 1), &camera(320, 240)).is_ok());
        assert!(fits(&frame(160, 120, 0), &camera(160, 120)).is_ok(), "smaller frames fit");
        let e = fits(&frame(640, 480, 1), &camera(640, 480)).unwrap_err().to_string();
        assert_eq!(
            e,
            "gray image 640x480, depth covering 640x480, camera 640x480: the three must have one \
             size, at most the 320x240 that the front end holds"
        );
        // An odd height at depth level 1: the depth covers one row fewer.
        let e = fits(&frame(4, 3, 1), &camera(4, 3)).unwrap_err().to_string();
        assert!(e.starts_with("gray image 4x3, depth covering 4x2, camera 4x3"), "{e}");
        let e = fits(&frame(320, 240, 1), &camera(160, 120)).unwrap_err().to_string();
        assert!(e.contains("camera 160x120"), "{e}");
    }
}
