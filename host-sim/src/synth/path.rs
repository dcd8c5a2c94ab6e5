//! The camera path: smooth sums of sinusoids, optional high-frequency shake.
//!
//! Time `t` in seconds. With `omega = 2 pi / 10 s` (one slow cycle per default sequence):
//!
//! - position (world, metres): `x = 0.45 sin(w t) + 0.05 sin(3 w t)`,
//!   `y = -2.0 + 0.22 sin(2 w t)`, `z = 1.4 + 0.1 sin(1.5 w t)` (2.7 m of travel in 10 s, at most
//!   0.48 m/s);
//! - yaw (about world `z`, positive turns left): `40 deg sin(1.5 w t)`, or `40 deg sin(4.5 w t)` in
//!   the fast-rotation variant;
//! - pitch (positive looks up): `-8 deg + 7 deg sin(2.5 w t)` (twice as fast in the fast variant);
//! - roll (about the viewing direction): `6 deg sin(1.7 w t)`.
//!
//! The start pose (`t = 0`) is at `(0, -2, 1.4)` looking north (`+y`), 8 degrees down, no roll.
//! Orientation: `R_wc = Rz(yaw) Rx(pitch) Ry(roll) R0`, where `R0` maps the camera axes (x right,
//! y down, z forward) to world (`+x`, `-z`, `+y`). The camera stays at least 0.5 m from every
//! surface and every box.
//!
//! Shake adds, per translation and rotation axis, three sinusoids at 5.3, 7.9 and 11.3 Hz with
//! phases from the seed; `shake = 1` gives up to about 4 mm and 0.4 degrees. It is part of the
//! ground truth.

use core::f64::consts::TAU;

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

use super::rng::SplitMix64;

/// Camera position at `t = 0`, world frame, metres.
pub const START_POSITION_M: [f64; 3] = [0.0, -2.0, 1.4];
/// Camera pitch at `t = 0`, degrees (negative looks down).
pub const START_PITCH_DEG: f64 = -8.0;

/// Frequencies of the shake sinusoids, Hz (below the 15 Hz Nyquist rate of 30 Hz frames).
const SHAKE_HZ: [f64; 3] = [5.3, 7.9, 11.3];
/// Translation shake amplitude per unit `shake`, metres.
const SHAKE_TRANS_M: f64 = 0.004;
/// Rotation shake amplitude per unit `shake`, degrees.
const SHAKE_ROT_DEG: f64 = 0.4;

/// A camera path through the demo room.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct CameraPath {
    fast_rotation: bool,
    shake: f64,
    /// Shake phases (radians) per axis (tx, ty, tz, yaw, pitch, roll) and frequency.
    phases: [[f64; 3]; 6],
}

impl CameraPath {
    /// The path; `seed` only sets the shake phases.
    pub(crate) fn new(fast_rotation: bool, shake: f64, seed: u64) -> Self {
        let mut rng = SplitMix64::keyed(seed, 0x5A4E, 0);
        let phases = [(); 6].map(|()| [(); 3].map(|()| rng.uniform(0.0, TAU)));
        Self { fast_rotation, shake, phases }
    }

    /// Shake offset of axis `k` at time `t`, in units of the amplitude (within `[-1, 1]`).
    fn jitter(&self, k: usize, t: f64) -> f64 {
        if self.shake == 0.0 {
            return 0.0;
        }
        let p = self.phases[k];
        (0..3).map(|i| libm::sin(TAU * SHAKE_HZ[i] * t + p[i])).sum::<f64>() / 3.0
    }

    /// Camera position in the world frame at time `t` seconds, metres.
    pub(crate) fn position(&self, t: f64) -> Vector3<f64> {
        let w = TAU / 10.0;
        let s = self.shake * SHAKE_TRANS_M;
        Vector3::new(
            START_POSITION_M[0]
                + 0.45 * libm::sin(w * t)
                + 0.05 * libm::sin(3.0 * w * t)
                + s * self.jitter(0, t),
            START_POSITION_M[1] + 0.22 * libm::sin(2.0 * w * t) + s * self.jitter(1, t),
            START_POSITION_M[2] + 0.1 * libm::sin(1.5 * w * t) + s * self.jitter(2, t),
        )
    }

    /// `(yaw, pitch, roll)` in radians at time `t` seconds.
    pub(crate) fn angles(&self, t: f64) -> [f64; 3] {
        let w = TAU / 10.0;
        let (yaw_rate, pitch_rate) = if self.fast_rotation { (4.5, 5.0) } else { (1.5, 2.5) };
        let s = (self.shake * SHAKE_ROT_DEG).to_radians();
        [
            40f64.to_radians() * libm::sin(yaw_rate * w * t) + s * self.jitter(3, t),
            START_PITCH_DEG.to_radians()
                + 7f64.to_radians() * libm::sin(pitch_rate * w * t)
                + s * self.jitter(4, t),
            6f64.to_radians() * libm::sin(1.7 * w * t) + s * self.jitter(5, t),
        ]
    }

    /// `T_wc` (camera to world) at time `t` seconds.
    pub(crate) fn pose(&self, t: f64) -> Isometry3<f64> {
        let [yaw, pitch, roll] = self.angles(t);
        // Camera axes (x right, y down, z forward) in the world when looking north, level.
        let r0 = Rotation3::from_matrix_unchecked(Matrix3::new(
            1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0,
        ));
        let q = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw)
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), pitch)
            * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), roll)
            * UnitQuaternion::from_rotation_matrix(&r0);
        Isometry3::from_parts(Translation3::from(self.position(t)), q)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::scene::Scene;

    #[test]
    fn start_pose_is_as_documented() {
        let p = CameraPath::new(false, 0.0, 1).pose(0.0);
        assert!((p.translation.vector - Vector3::from(START_POSITION_M)).norm() < 1e-12);
        // Optical axis: north, 8 degrees down; camera x axis: east; camera y axis: mostly down.
        let z = p.rotation * Vector3::z();
        let pitch = START_PITCH_DEG.to_radians();
        assert!((z - Vector3::new(0.0, pitch.cos(), pitch.sin())).norm() < 1e-12);
        assert!((p.rotation * Vector3::x() - Vector3::x()).norm() < 1e-12);
        assert!((p.rotation * Vector3::y()).z < -0.9);
    }

    #[test]
    fn path_is_smooth_and_of_expected_extent() {
        let path = CameraPath::new(false, 0.0, 1);
        let (mut length, mut max_yaw, mut max_step_deg) = (0.0, 0.0f64, 0.0f64);
        let mut prev = path.pose(0.0);
        for i in 1..300 {
            let p = path.pose(f64::from(i) / 30.0);
            length += (p.translation.vector - prev.translation.vector).norm();
            max_step_deg =
                max_step_deg.max((prev.rotation.inverse() * p.rotation).angle().to_degrees());
            max_yaw = max_yaw.max(path.angles(f64::from(i) / 30.0)[0].to_degrees().abs());
            prev = p;
        }
        assert!((2.5..3.0).contains(&length), "path length {length} m");
        assert!(max_yaw > 39.0 && max_yaw <= 40.0, "max yaw {max_yaw}");
        assert!(max_step_deg < 2.0, "max rotation per frame {max_step_deg} deg");
    }

    #[test]
    fn camera_keeps_clear_of_everything() {
        let scene = Scene::demo();
        for (fast, shake) in [(false, 0.0), (true, 0.0), (false, 3.0)] {
            let path = CameraPath::new(fast, shake, 9);
            for i in 0..900 {
                let c = scene.clearance(&path.position(f64::from(i) / 30.0));
                assert!(c > 0.5, "frame {i}: clearance {c} m");
            }
        }
    }

    #[test]
    fn shake_is_small_and_seeded() {
        let calm = CameraPath::new(false, 0.0, 1);
        let a = CameraPath::new(false, 1.0, 1);
        let b = CameraPath::new(false, 1.0, 2);
        let t = 1.234;
        let d = (a.position(t) - calm.position(t)).norm();
        assert!(d > 0.0 && d < 0.008);
        assert_ne!(a.pose(t), b.pose(t));
    }
}
