//! A `sensor_msgs/msg/CameraInfo` as a [`Calibration`], and a calibration as one.

use std::path::{Path, PathBuf};

use super::error::McapError;
use super::messages::{CameraInfoMsg, Stamp};
use crate::dataset::{Calibration, DatasetError, Distortion};

/// Raw depth units per metre of the frames of a recording calibrated by its CameraInfo alone:
/// millimetres, the unit of `16UC1` depth (REP 118), which keeps it as it is; `32FC1` metres
/// are brought to it (1 mm steps up to 65.5 m).
pub const CAMERA_INFO_DEPTH_SCALE: f32 = 1000.0;

/// The calibration `info` (on `topic` of the file `path`) gives: `K`'s focal lengths and
/// principal point, the size, a `plumb_bob` distortion (OpenCV's k1, k2, p1, p2, k3; fewer
/// coefficients are zeros), and a depth scale of [`CAMERA_INFO_DEPTH_SCALE`]. Any model whose
/// coefficients are all zero is no distortion.
///
/// # Errors
/// [`McapError::CameraInfo`] for another distortion model with coefficients, or a `plumb_bob`
/// with more than five; the calibration's own checks ([`Calibration::validate`]) naming
/// `FILE:TOPIC`.
pub fn calibration(
    path: &Path,
    topic: &str,
    info: &CameraInfoMsg,
) -> Result<Calibration, DatasetError> {
    let bad = |reason: String| McapError::CameraInfo {
        path: path.to_owned(),
        topic: topic.to_owned(),
        reason,
    };
    let distortion = if info.d.iter().all(|&c| c == 0.0) {
        Distortion::NONE
    } else if info.distortion_model == "plumb_bob" && info.d.len() <= 5 {
        let mut d = [0.0f32; 5];
        d.iter_mut().zip(&info.d).for_each(|(slot, &c)| *slot = c as f32);
        let [k1, k2, p1, p2, k3] = d;
        Distortion { k1, k2, p1, p2, k3 }
    } else {
        let (model, n) = (&info.distortion_model, info.d.len());
        return Err(bad(format!(
            "distortion model {model:?} with {n} coefficients: only plumb_bob (k1, k2, p1, p2, \
             k3) is read; give --calibration FILE"
        ))
        .into());
    };
    let k = &info.k;
    let calibration = Calibration {
        fx: k[0] as f32,
        fy: k[4] as f32,
        cx: k[2] as f32,
        cy: k[5] as f32,
        width: info.width,
        height: info.height,
        depth_scale: CAMERA_INFO_DEPTH_SCALE,
        depth: None,
        distortion,
        depth_noise_coeff_per_m: None,
    };
    calibration.validate(&PathBuf::from(format!("{}:{topic}", path.display())))?;
    Ok(calibration)
}

/// The CameraInfo of `calibration` (the colour camera: `K`, size, `plumb_bob` distortion).
pub fn camera_info(calibration: &Calibration, stamp: Stamp) -> CameraInfoMsg {
    let c = calibration;
    let d = c.distortion;
    CameraInfoMsg {
        stamp,
        height: c.height,
        width: c.width,
        distortion_model: "plumb_bob".to_owned(),
        d: [d.k1, d.k2, d.p1, d.p2, d.k3].map(f64::from).to_vec(),
        k: [c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0].map(f64::from),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_info_round_trips_the_intrinsics_and_distortion() {
        let mut c = Calibration::preset("tum1").unwrap();
        c.depth_scale = CAMERA_INFO_DEPTH_SCALE;
        let info = camera_info(&c, Stamp { sec: 1, nanosec: 0 });
        assert_eq!(calibration(Path::new("a.mcap"), "/info", &info).unwrap(), c);
    }

    #[test]
    fn other_models_are_refused_by_name() {
        let c = Calibration::preset("tum1").unwrap();
        let mut info = camera_info(&c, Stamp { sec: 1, nanosec: 0 });
        info.distortion_model = "equidistant".into();
        let err = calibration(Path::new("a.mcap"), "/info", &info).unwrap_err();
        assert!(err.to_string().contains("\"equidistant\" with 5 coefficients"), "{err}");
        // All zeros is no distortion, whatever the model.
        info.d = vec![0.0; 4];
        assert!(calibration(Path::new("a.mcap"), "/info", &info).unwrap().distortion.is_none());
    }
}
