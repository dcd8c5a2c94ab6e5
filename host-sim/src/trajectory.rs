//! Stamped camera trajectories and the TUM trajectory file format.
//!
//! A trajectory is a list of [`StampedPose`]s: a timestamp in seconds and the pose `t_wc` (camera to
//! world; translation in metres). The same type holds estimates written by `replay` and ground truth
//! read from a dataset.
//!
//! # File format (TUM RGB-D benchmark)
//!
//! One pose per line, `timestamp tx ty tz qx qy qz qw`, fields separated by whitespace, with
//! `(tx, ty, tz)` the camera centre in the world frame (metres) and `(qx, qy, qz, qw)` the rotation
//! camera to world as a quaternion (Hamilton, scalar last).
//!
//! Reading rules ([`Trajectory::parse_tum`]):
//! - a line whose first non-blank character is `#` is a comment; blank lines are skipped;
//! - every other line must hold exactly 8 finite numbers;
//! - the quaternion is normalized; a quaternion of norm below [`MIN_QUATERNION_NORM`] (zero) or with
//!   a NaN is an error (the TUM tools silently skip such lines, evo silently reads them as identity);
//! - timestamps must be **strictly increasing**. evo neither sorts nor rejects unsorted or repeated
//!   timestamps (it falls back to a linear search when matching); we reject them, naming the line, so
//!   that association is always evo's binary-search path and a pose is never silently shadowed by
//!   another one with the same timestamp.
//!
//! Errors name the file, the 1-based line number and the line's text.
//!
//! Writing rules ([`Trajectory::to_tum_string`]): no header, one line per pose,
//! `{timestamp:.6} {tx:.7} {ty:.7} {tz:.7} {qx:.7} {qy:.7} {qz:.7} {qw:.7}` with `\n` line ends,
//! and the quaternion sign chosen so that `qw >= 0` (q and -q are the same rotation). The text
//! depends only on the poses, so the same trajectory always gives the same bytes (and hash).

use std::fmt;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

/// A quaternion whose norm is below this is treated as "no rotation given" and rejected.
pub const MIN_QUATERNION_NORM: f64 = 1e-6;

/// One pose of a trajectory: when, and where the camera was.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StampedPose {
    /// Timestamp in seconds (the dataset's clock, e.g. Unix time for TUM sequences).
    pub timestamp_s: f64,
    /// Camera-to-world pose: maps points from the camera frame to the world frame; its translation
    /// is the camera centre in the world, in metres.
    pub t_wc: Isometry3<f64>,
}

impl StampedPose {
    /// A pose from a timestamp (s), a camera centre in the world (m) and a camera-to-world quaternion
    /// given as `(qx, qy, qz, qw)`. The quaternion is normalized (however large its components);
    /// `None` if it is (near) zero, or if any value is not finite.
    pub fn from_tum_values(timestamp_s: f64, t_m: [f64; 3], q_xyzw: [f64; 4]) -> Option<Self> {
        if !timestamp_s.is_finite() || t_m.iter().chain(q_xyzw.iter()).any(|v| !v.is_finite()) {
            return None;
        }
        let [qx, qy, qz, qw] = q_xyzw;
        let q = Quaternion::new(qw, qx, qy, qz);
        // Components near f64's limit overflow the norm, which would normalize the quaternion to
        // zero: scale those down by the largest first (any other is normalized as it is).
        let q = if q.norm().is_finite() { q } else { q / q.coords.amax() };
        if q.norm() < MIN_QUATERNION_NORM {
            return None;
        }
        let rotation = UnitQuaternion::new_normalize(q);
        let translation = Translation3::new(t_m[0], t_m[1], t_m[2]);
        Some(Self { timestamp_s, t_wc: Isometry3::from_parts(translation, rotation) })
    }
}

/// A time-ordered list of camera poses.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trajectory {
    /// The poses, by strictly increasing timestamp (the reader guarantees it; code that builds a
    /// trajectory by hand should keep it, see [`Trajectory::check_increasing`]).
    pub poses: Vec<StampedPose>,
}

/// What is wrong with one line of a TUM trajectory file.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum LineProblem {
    /// The line does not hold exactly 8 fields.
    FieldCount {
        /// How many whitespace-separated fields it holds.
        found: usize,
    },
    /// A field is not a number.
    NotANumber {
        /// 1-based field index (1 = timestamp).
        field: usize,
    },
    /// A value is NaN or infinite.
    NotFinite,
    /// The quaternion's norm is below [`MIN_QUATERNION_NORM`].
    ZeroQuaternion,
    /// The timestamp is not greater than the previous pose's.
    TimestampNotIncreasing {
        /// The previous pose's timestamp, in seconds.
        previous_s: f64,
    },
}

impl fmt::Display for LineProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::FieldCount { found } => {
                write!(f, "expected 8 fields `timestamp tx ty tz qx qy qz qw`, found {found}")
            }
            Self::NotANumber { field } => write!(f, "field {field} is not a number"),
            Self::NotFinite => write!(f, "a value is NaN or infinite"),
            Self::ZeroQuaternion => write!(f, "the quaternion is zero"),
            Self::TimestampNotIncreasing { previous_s } => write!(
                f,
                "timestamp is not greater than the previous one ({previous_s}); timestamps must be \
                 strictly increasing"
            ),
        }
    }
}

/// Reading or writing a trajectory failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TrajectoryError {
    /// The file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A line of a TUM file is malformed.
    #[error("{}:{line}: {problem}: `{text}`", path.display())]
    Line {
        /// The file (or the name given to [`Trajectory::parse_tum`]).
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// The line's text, without its line end.
        text: String,
        /// What is wrong with it.
        problem: LineProblem,
    },
}

impl Trajectory {
    /// A trajectory from poses (not checked; see [`Trajectory::check_increasing`]).
    pub fn new(poses: Vec<StampedPose>) -> Self {
        Self { poses }
    }

    /// Number of poses.
    pub fn len(&self) -> usize {
        self.poses.len()
    }

    /// Whether there are no poses.
    pub fn is_empty(&self) -> bool {
        self.poses.is_empty()
    }

    /// The timestamps in seconds, in order.
    pub fn timestamps_s(&self) -> Vec<f64> {
        self.poses.iter().map(|p| p.timestamp_s).collect()
    }

    /// `Err(i)` with the index of the first pose whose timestamp is not finite or not greater than
    /// the one before it; `Ok(())` if the timestamps are finite and strictly increasing.
    pub fn check_increasing(&self) -> Result<(), usize> {
        let mut previous = f64::NEG_INFINITY;
        for (i, pose) in self.poses.iter().enumerate() {
            if !pose.timestamp_s.is_finite() || pose.timestamp_s <= previous {
                return Err(i);
            }
            previous = pose.timestamp_s;
        }
        Ok(())
    }

    /// Reads a TUM trajectory file (rules in the [module docs](self)).
    pub fn read_tum(path: &Path) -> Result<Self, TrajectoryError> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| TrajectoryError::Io { path: path.to_path_buf(), source })?;
        Self::parse_tum(&text, path)
    }

    /// Parses the text of a TUM trajectory file; `path` is only used to name errors. An empty text
    /// (or one of comments only) gives an empty trajectory.
    pub fn parse_tum(text: &str, path: &Path) -> Result<Self, TrajectoryError> {
        let mut poses: Vec<StampedPose> = Vec::new();
        for (index, raw) in text.lines().enumerate() {
            let trimmed = raw.trim();
            if trimmed.is_empty() || trimmed.starts_with('#') {
                continue;
            }
            let line_error = |problem| TrajectoryError::Line {
                path: path.to_path_buf(),
                line: index + 1,
                text: raw.to_string(),
                problem,
            };
            let pose = parse_tum_line(trimmed).map_err(line_error)?;
            if let Some(previous) = poses.last()
                && pose.timestamp_s <= previous.timestamp_s
            {
                return Err(line_error(LineProblem::TimestampNotIncreasing {
                    previous_s: previous.timestamp_s,
                }));
            }
            poses.push(pose);
        }
        Ok(Self { poses })
    }

    /// The values of each pose line of a TUM trajectory file's text as written, `[t, tx, ty, tz,
    /// qx, qy, qz, qw]` (the quaternion not normalized: what [`StampedPose::from_tum_values`]
    /// takes), after checking the text as [`Trajectory::parse_tum`] does.
    ///
    /// # Errors
    /// As [`Trajectory::parse_tum`].
    pub fn parse_tum_values(text: &str, path: &Path) -> Result<Vec<[f64; 8]>, TrajectoryError> {
        Self::parse_tum(text, path)?;
        Ok(text
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty() && !l.starts_with('#'))
            .filter_map(|l| tum_line_values(l).ok())
            .collect())
    }

    /// The trajectory as TUM text (format in the [module docs](self)); deterministic.
    pub fn to_tum_string(&self) -> String {
        let mut out = String::with_capacity(self.poses.len() * 96);
        for pose in &self.poses {
            out.push_str(&format_tum_line(pose));
            out.push('\n');
        }
        out
    }

    /// Writes the trajectory as a TUM file (see [`Trajectory::to_tum_string`]).
    pub fn write_tum(&self, path: &Path) -> Result<(), TrajectoryError> {
        std::fs::write(path, self.to_tum_string())
            .map_err(|source| TrajectoryError::Io { path: path.to_path_buf(), source })
    }
}

/// One pose as a TUM line without line end: `{t:.6} {tx:.7} {ty:.7} {tz:.7} {qx:.7} {qy:.7} {qz:.7}
/// {qw:.7}`, with the quaternion sign chosen so that `qw >= 0` and no negative zeros (`-0.0000000`
/// is written `0.0000000`).
pub fn format_tum_line(pose: &StampedPose) -> String {
    let t = pose.t_wc.translation.vector;
    let q = pose.t_wc.rotation.quaternion();
    let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
    let mut line = fixed(pose.timestamp_s, 6);
    for v in [t.x, t.y, t.z, sign * q.i, sign * q.j, sign * q.k, sign * q.w] {
        line.push(' ');
        line.push_str(&fixed(v, 7));
    }
    line
}

/// `v` with `decimals` digits after the point, a value that rounds to zero written without sign.
fn fixed(v: f64, decimals: usize) -> String {
    let text = format!("{v:.decimals$}");
    match text.strip_prefix('-') {
        Some(rest) if rest.bytes().all(|b| b == b'0' || b == b'.') => rest.to_string(),
        _ => text,
    }
}

/// Parses one non-comment, non-blank TUM line.
fn parse_tum_line(line: &str) -> Result<StampedPose, LineProblem> {
    let [t, tx, ty, tz, qx, qy, qz, qw] = tum_line_values(line)?;
    StampedPose::from_tum_values(t, [tx, ty, tz], [qx, qy, qz, qw])
        .ok_or(LineProblem::ZeroQuaternion)
}

/// The eight finite numbers of a TUM line, as written (quaternion not normalized).
fn tum_line_values(line: &str) -> Result<[f64; 8], LineProblem> {
    let mut values = [0.0_f64; 8];
    let mut found = 0;
    for (i, field) in line.split_whitespace().enumerate() {
        if let Some(slot) = values.get_mut(i) {
            *slot = field.parse::<f64>().map_err(|_| LineProblem::NotANumber { field: i + 1 })?;
        }
        found = i + 1;
    }
    if found != 8 {
        return Err(LineProblem::FieldCount { found });
    }
    if values.iter().any(|v| !v.is_finite()) {
        return Err(LineProblem::NotFinite);
    }
    Ok(values)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Trajectory, TrajectoryError> {
        Trajectory::parse_tum(text, Path::new("test.txt"))
    }

    #[test]
    fn reads_comments_blank_lines_and_normalizes_quaternions() {
        let text = "# header\n\n  # indented comment\n1.0 1 2 3 0 0 0 2\n2.5\t4 5 6 0 0 1 1\n";
        let traj = parse(text).unwrap();
        assert_eq!(traj.len(), 2);
        assert_eq!(traj.poses[0].timestamp_s, 1.0);
        assert_eq!(traj.poses[0].t_wc.translation.vector.x, 1.0);
        assert!((traj.poses[0].t_wc.rotation.angle()).abs() < 1e-15);
        let angle = traj.poses[1].t_wc.rotation.angle();
        assert!((angle - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert_eq!(traj.timestamps_s(), vec![1.0, 2.5]);
    }

    #[test]
    fn a_quaternion_whose_norm_overflows_is_normalized_not_zeroed() {
        // Found by `cargo xtask fuzz --target trajectory`: `qw = 0.991e308` made the norm
        // infinite and the "normalized" rotation all zeros.
        let traj = parse("0.2 1 2 3 0 0 0 0.991e308\n0.3 0 0 0 1e300 0 0 1e300\n").unwrap();
        let q = traj.poses[0].t_wc.rotation;
        assert_eq!(q.coords, nalgebra::Vector4::new(0.0, 0.0, 0.0, 1.0), "{q:?}");
        let angle = traj.poses[1].t_wc.rotation.angle();
        assert!((angle - std::f64::consts::FRAC_PI_2).abs() < 1e-12, "{angle}");
        assert!((traj.poses[1].t_wc.rotation.norm() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn errors_name_file_line_and_text() {
        let err = parse("# c\n0 0 0 0 0 0 0 1\n1 0 0 0 0 0 1\n").unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("test.txt:3"), "{msg}");
        assert!(msg.contains("`1 0 0 0 0 0 1`"), "{msg}");
        assert!(matches!(
            err,
            TrajectoryError::Line { line: 3, problem: LineProblem::FieldCount { found: 7 }, .. }
        ));
    }

    #[test]
    fn rejects_bad_values() {
        let cases = [
            ("0 0 0 0 0 0 0 0", LineProblem::ZeroQuaternion),
            ("0 0 0 0 nan 0 0 1", LineProblem::NotFinite),
            ("0 inf 0 0 0 0 0 1", LineProblem::NotFinite),
            ("0 0 x 0 0 0 0 1", LineProblem::NotANumber { field: 3 }),
            ("0 0 0 0 0 0 0 1 9", LineProblem::FieldCount { found: 9 }),
        ];
        for (line, expected) in cases {
            match parse(line) {
                Err(TrajectoryError::Line { problem, line: 1, .. }) => {
                    assert_eq!(problem, expected)
                }
                other => panic!("{line}: {other:?}"),
            }
        }
    }

    #[test]
    fn rejects_repeated_or_decreasing_timestamps() {
        for text in ["1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", "2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n"] {
            let err = parse(text).unwrap_err();
            assert!(matches!(
                err,
                TrajectoryError::Line {
                    line: 2,
                    problem: LineProblem::TimestampNotIncreasing { .. },
                    ..
                }
            ));
        }
    }

    #[test]
    fn empty_text_is_an_empty_trajectory() {
        assert!(parse("").unwrap().is_empty());
        assert!(parse("# only\n\n").unwrap().is_empty());
    }

    #[test]
    fn writer_is_fixed_precision_with_positive_qw_and_round_trips() {
        let pose = StampedPose::from_tum_values(
            1305031102.175304,
            [0.1, -2.0, 3.25],
            [0.0, 0.0, -std::f64::consts::FRAC_1_SQRT_2, -std::f64::consts::FRAC_1_SQRT_2],
        )
        .unwrap();
        let traj = Trajectory::new(vec![pose]);
        let text = traj.to_tum_string();
        assert_eq!(
            text,
            "1305031102.175304 0.1000000 -2.0000000 3.2500000 0.0000000 0.0000000 0.7071068 0.7071068\n"
        );
        let back = parse(&text).unwrap();
        assert_eq!(back.poses[0].timestamp_s, 1305031102.175304);
        let d = back.poses[0].t_wc.inverse() * pose.t_wc;
        assert!(d.translation.vector.norm() < 1e-7 && d.rotation.angle() < 1e-6);
        assert_eq!(back.to_tum_string(), text);
        assert_eq!(fixed(-1e-9, 7), "0.0000000");
        assert_eq!(fixed(-1e-3, 2), "0.00");
        assert_eq!(fixed(-0.5, 1), "-0.5");
    }

    #[test]
    fn io_error_names_the_file() {
        let err = Trajectory::read_tum(Path::new("/nonexistent/traj.txt")).unwrap_err();
        assert!(err.to_string().contains("/nonexistent/traj.txt"));
    }

    #[test]
    fn check_increasing_finds_the_first_bad_index() {
        let p = |t| StampedPose::from_tum_values(t, [0.0; 3], [0.0, 0.0, 0.0, 1.0]).unwrap();
        assert_eq!(Trajectory::new(vec![p(0.0), p(1.0)]).check_increasing(), Ok(()));
        assert_eq!(Trajectory::new(vec![p(0.0), p(1.0), p(1.0)]).check_increasing(), Err(2));
    }
}
