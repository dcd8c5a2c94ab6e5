//! The constant-velocity motion model: predict the next `t_cw` from the last two.
//!
//! With world-to-camera poses, the motion between frames is `delta = t_cw(k) t_cw(k-1)^-1`
//! (camera `k-1` to camera `k`), and constant velocity predicts `t_cw(k+1) = delta t_cw(k)`.
//! When the frame intervals differ, the motion is scaled on the manifold:
//! `delta^s = exp(s log(delta))` with `s = (t_next - t_k) / (t_k - t_{k-1})`, i.e. the same twist
//! (velocity) held for a different time. With `s == 1` exactly the product is used directly, so an
//! evenly sampled sequence is continued without a log/exp round trip.

use super::PoseError;
use crate::geometry::{Pose, se3_exp, se3_log};

/// `t_cw` at `time_next_s` predicted from `t_cw_prev` at `time_prev_s` and `t_cw_last` at
/// `time_last_s` by constant velocity (see the module documentation). Times in seconds on any
/// clock; only differences matter (taken in f64, so Unix timestamps keep their precision).
///
/// # Errors
/// [`PoseError::TimestampsNotIncreasing`] unless `time_prev_s < time_last_s <= time_next_s`
/// (all finite).
pub fn predict_constant_velocity(
    t_cw_prev: &Pose,
    time_prev_s: f64,
    t_cw_last: &Pose,
    time_last_s: f64,
    time_next_s: f64,
) -> Result<Pose, PoseError> {
    let finite = time_prev_s.is_finite() && time_last_s.is_finite() && time_next_s.is_finite();
    if !finite || time_prev_s >= time_last_s {
        return Err(PoseError::TimestampsNotIncreasing {
            earlier_s: time_prev_s,
            later_s: time_last_s,
        });
    }
    if time_next_s < time_last_s {
        return Err(PoseError::TimestampsNotIncreasing {
            earlier_s: time_last_s,
            later_s: time_next_s,
        });
    }
    let delta = t_cw_last * t_cw_prev.inverse();
    let ratio = (time_next_s - time_last_s) / (time_last_s - time_prev_s);
    if ratio == 1.0 {
        return Ok(delta * t_cw_last);
    }
    // Twists in f32 (the pose precision); the ratio is rounded once. A gap too long for an
    // f32 ratio (over about 3.4e38 frame intervals) extrapolates nothing: the last pose.
    let ratio = ratio as f32;
    if !ratio.is_finite() {
        return Ok(*t_cw_last);
    }
    let scaled = se3_exp(&(se3_log(&delta) * ratio));
    Ok(scaled * t_cw_last)
}

/// The last two tracked poses with their timestamps, for [`predict_constant_velocity`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MotionModel {
    prev: Option<(f64, Pose)>,
    last: Option<(f64, Pose)>,
}

impl MotionModel {
    /// A model with no history (predicts nothing).
    pub const fn new() -> Self {
        Self { prev: None, last: None }
    }

    /// Records the tracked `t_cw` at `timestamp_s` (seconds).
    ///
    /// # Errors
    /// [`PoseError::TimestampsNotIncreasing`] if `timestamp_s` is not finite or not after the last
    /// recorded one; the model is unchanged.
    pub fn update(&mut self, timestamp_s: f64, t_cw: &Pose) -> Result<(), PoseError> {
        let last_s = self.last.map_or(f64::NEG_INFINITY, |(s, _)| s);
        if !timestamp_s.is_finite() || timestamp_s <= last_s {
            return Err(PoseError::TimestampsNotIncreasing {
                earlier_s: last_s,
                later_s: timestamp_s,
            });
        }
        self.prev = self.last;
        self.last = Some((timestamp_s, *t_cw));
        Ok(())
    }

    /// Moves the recorded poses into a world moved by `c` (`T_new_old`): the velocity is kept.
    pub fn move_world(&mut self, c: &Pose) {
        let c_inv = c.inverse();
        for (_, t_cw) in self.prev.iter_mut().chain(self.last.iter_mut()) {
            *t_cw *= c_inv;
        }
    }

    /// Forgets the history (after tracking loss: the velocity is no longer known).
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// The predicted `t_cw` at `timestamp_s`: `None` without history, the last pose with one
    /// (zero velocity), constant velocity with two.
    ///
    /// # Errors
    /// [`PoseError::TimestampsNotIncreasing`] if `timestamp_s` is before the last update or not
    /// finite.
    pub fn predict(&self, timestamp_s: f64) -> Result<Option<Pose>, PoseError> {
        match (self.prev, self.last) {
            (Some((t0, p0)), Some((t1, p1))) => {
                predict_constant_velocity(&p0, t0, &p1, t1, timestamp_s).map(Some)
            }
            (None, Some((t1, p1))) => {
                if timestamp_s.is_finite() && timestamp_s >= t1 {
                    Ok(Some(p1))
                } else {
                    Err(PoseError::TimestampsNotIncreasing { earlier_s: t1, later_s: timestamp_s })
                }
            }
            _ => Ok(None),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3, Vector6};

    fn start() -> Pose {
        Pose::from_parts(
            Translation3::new(0.2, -0.1, 1.5),
            UnitQuaternion::from_scaled_axis(Vector3::new(0.1, -0.2, 0.05)),
        )
    }

    fn max_diff(a: &Pose, b: &Pose) -> (f32, f32) {
        let dt = (a.translation.vector - b.translation.vector).amax();
        (dt, a.rotation.angle_to(&b.rotation))
    }

    #[test]
    fn a_gap_beyond_an_f32_ratio_predicts_the_last_pose() {
        // Frames at 30 Hz, then one at 1e300 s (found by `cargo xtask fuzz`): the ratio of
        // intervals is beyond f32, and the prediction is the last pose, finite.
        let delta = se3_exp(&Vector6::new(0.01, 0.0, 0.0, 0.0, 0.01, 0.0));
        let (p0, p1) = (start(), delta * start());
        let predicted = predict_constant_velocity(&p0, 0.0, &p1, 1.0 / 30.0, 1e300).unwrap();
        assert_eq!(predicted, p1);
    }

    #[test]
    fn even_steps_continue_the_sequence_exactly() {
        let delta = se3_exp(&Vector6::new(0.01, 0.002, -0.005, 0.003, -0.01, 0.004));
        let mut model = MotionModel::new();
        assert_eq!(model.predict(0.0), Ok(None));
        let mut t_cw = start();
        let mut poses = [t_cw; 12];
        for p in poses.iter_mut() {
            *p = t_cw;
            t_cw = delta * t_cw;
        }
        for (k, p) in poses.iter().enumerate() {
            let time = 0.5 * k as f64; // exact in binary, so dt ratios are exactly 1
            if k >= 2 {
                let predicted = model.predict(time).unwrap().unwrap();
                let (dt, dr) = max_diff(&predicted, p);
                assert!(dt < 4.0 * f32::EPSILON && dr < 1e-6, "k {k}: {dt} m, {dr} rad");
            }
            model.update(time, p).unwrap();
        }
    }

    #[test]
    fn uneven_steps_scale_the_twist() {
        let xi = Vector6::new(0.3, -0.1, 0.2, 0.05, 0.2, -0.1); // per second
        let at = |s: f32| se3_exp(&(xi * s)) * start();
        let times = [10.0_f64, 10.033, 10.1, 10.117, 10.25];
        for w in times.windows(3) {
            let predicted =
                predict_constant_velocity(&at(0.0), w[0], &at((w[1] - w[0]) as f32), w[1], w[2])
                    .unwrap();
            let truth = at((w[2] - w[0]) as f32);
            let (dt, dr) = max_diff(&predicted, &truth);
            assert!(dt < 2e-6 && dr < 2e-6, "{w:?}: {dt} m, {dr} rad");
        }
        // Same time as the last pose: no motion.
        let p = predict_constant_velocity(&at(0.0), 1.0, &at(0.1), 1.1, 1.1).unwrap();
        assert!(max_diff(&p, &at(0.1)).0 < 1e-6);
    }

    #[test]
    fn bad_timestamps_are_errors() {
        let p = start();
        for (a, b, c) in [(1.0, 1.0, 2.0), (2.0, 1.0, 3.0), (0.0, 1.0, 0.5), (0.0, f64::NAN, 2.0)] {
            let r = predict_constant_velocity(&p, a, &p, b, c);
            assert!(matches!(r, Err(PoseError::TimestampsNotIncreasing { .. })), "{a} {b} {c}");
        }
        let mut model = MotionModel::new();
        model.update(1.0, &p).unwrap();
        assert_eq!(model.predict(1.5), Ok(Some(p)));
        assert!(model.predict(0.5).is_err());
        assert!(model.update(1.0, &p).is_err());
        assert!(model.update(f64::NAN, &p).is_err());
        model.reset();
        assert_eq!(model.predict(2.0), Ok(None));
    }
}
