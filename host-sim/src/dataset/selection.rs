//! Playing a recording in another order: `--frames A-B,C-D,...` picks ranges of its frames, each
//! forwards or backwards (`0-999,998-0` goes out and back; `0-700,100-999` carries the camera
//! back to a place it has seen), so that loops, revisits and jumps can be made from any recording.
//!
//! The frames played get new timestamps that keep increasing: within a range each step takes the
//! recording's own interval between the two frames (backwards too), and the step into a new range
//! takes the recording's median interval, as a camera would jump between two frames. The ground
//! truth follows its frames: each played frame gets the pose the recording's ground truth has at
//! the frame's own time (the nearest within the association limit), stamped with the new time.

use std::fmt;
use std::str::FromStr;

use crate::trajectory::{StampedPose, Trajectory};

/// One range of frame indices, inclusive at both ends; `first > last` runs backwards.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameRange {
    /// The first frame played (index among the recording's associated frames, from 0).
    pub first: usize,
    /// The last frame played.
    pub last: usize,
}

impl FrameRange {
    /// The indices of the range, in play order.
    fn indices(self) -> Box<dyn Iterator<Item = usize>> {
        if self.first <= self.last {
            Box::new(self.first..=self.last)
        } else {
            Box::new((self.last..=self.first).rev())
        }
    }
}

/// The ranges of `--frames`, in play order (at least one).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FrameSelection(Vec<FrameRange>);

/// Why a `--frames` value was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SelectionError {
    /// The text is not ranges `A-B` (or single frames `A`) separated by commas.
    #[error(
        "`{text}` is not a list of frame ranges: expected A-B[,C-D...] (frame indices from 0; a \
         range may run backwards, e.g. 0-999,998-0)"
    )]
    Syntax {
        /// The text given.
        text: String,
    },
    /// A range names a frame the recording does not have.
    #[error(
        "frame range {first}-{last} is outside the recording's {frames} frames (0-{max})",
        max = frames.saturating_sub(1)
    )]
    OutOfRange {
        /// The range's first frame.
        first: usize,
        /// The range's last frame.
        last: usize,
        /// Frames the recording has.
        frames: usize,
    },
}

impl FromStr for FrameSelection {
    type Err = SelectionError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let syntax = || SelectionError::Syntax { text: text.to_owned() };
        let index = |s: &str| s.trim().parse::<usize>().map_err(|_| syntax());
        let ranges = text
            .split(',')
            .map(|part| match part.split_once('-') {
                Some((a, b)) => Ok(FrameRange { first: index(a)?, last: index(b)? }),
                None => index(part).map(|i| FrameRange { first: i, last: i }),
            })
            .collect::<Result<Vec<_>, _>>()?;
        if ranges.is_empty() {
            return Err(syntax());
        }
        Ok(Self(ranges))
    }
}

impl fmt::Display for FrameSelection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, r) in self.0.iter().enumerate() {
            let sep = if i == 0 { "" } else { "," };
            write!(f, "{sep}{}-{}", r.first, r.last)?;
        }
        Ok(())
    }
}

impl FrameSelection {
    /// The ranges, in play order.
    pub fn ranges(&self) -> &[FrameRange] {
        &self.0
    }

    /// The frame indices to play, in order, for a recording of `frames` frames.
    ///
    /// # Errors
    /// [`SelectionError::OutOfRange`] when a range names a frame past the last.
    pub fn indices(&self, frames: usize) -> Result<Vec<usize>, SelectionError> {
        let mut out = Vec::new();
        for &r in &self.0 {
            if r.first.max(r.last) >= frames {
                return Err(SelectionError::OutOfRange { first: r.first, last: r.last, frames });
            }
            out.extend(r.indices());
        }
        Ok(out)
    }
}

/// New timestamps for the frames `order` (indices into `times_s`, the recording's frame times in
/// seconds, increasing) that keep increasing: consecutive frames of the recording (either way)
/// keep their interval, a jump takes the median interval. The first frame keeps its time.
pub fn renumbered_times(times_s: &[f64], order: &[usize]) -> Vec<f64> {
    let median = median_interval(times_s);
    let mut out = Vec::with_capacity(order.len());
    let mut previous: Option<(usize, f64)> = None;
    for &i in order {
        let t = times_s.get(i).copied().unwrap_or(0.0);
        let new = match previous {
            None => t,
            Some((j, t_prev)) => {
                let step = match (times_s.get(j), i.abs_diff(j)) {
                    (Some(&tj), 1) => (t - tj).abs(),
                    _ => median,
                };
                // A recording whose two frames share a time still plays forwards.
                t_prev + if step > 0.0 { step } else { median }
            }
        };
        out.push(new);
        previous = Some((i, new));
    }
    out
}

/// The median interval between consecutive times, seconds; 1/30 s when there are fewer than two
/// times or no positive interval.
fn median_interval(times_s: &[f64]) -> f64 {
    let mut steps: Vec<f64> =
        times_s.windows(2).map(|w| w[1] - w[0]).filter(|d| *d > 0.0).collect();
    if steps.is_empty() {
        return 1.0 / 30.0;
    }
    steps.sort_by(f64::total_cmp);
    steps[steps.len() / 2]
}

/// The ground truth that follows the played frames: for each frame `k` played, the pose of
/// `groundtruth` nearest to its original time `original_s[k]` (within `max_dt_s`), stamped with
/// its new time `played_s[k]`. Frames with no ground truth near them get no pose.
pub fn following_groundtruth(
    groundtruth: &Trajectory,
    original_s: &[f64],
    played_s: &[f64],
    max_dt_s: f64,
) -> Trajectory {
    let poses = &groundtruth.poses;
    let nearest = |t: f64| {
        let i = poses.partition_point(|p| p.timestamp_s < t);
        [i.checked_sub(1), Some(i)]
            .into_iter()
            .flatten()
            .filter_map(|j| poses.get(j))
            .min_by(|a, b| (a.timestamp_s - t).abs().total_cmp(&(b.timestamp_s - t).abs()))
            .filter(|p| (p.timestamp_s - t).abs() <= max_dt_s)
    };
    let followed = original_s
        .iter()
        .zip(played_s)
        .filter_map(|(&t, &t_new)| nearest(t).map(|p| StampedPose { timestamp_s: t_new, ..*p }))
        .collect();
    Trajectory::new(followed)
}

#[cfg(test)]
mod tests {
    use nalgebra::{Isometry3, Vector3};

    use super::*;

    #[test]
    fn ranges_parse_forwards_backwards_and_single_frames() {
        let s: FrameSelection = "0-3, 2-0,7".parse().unwrap();
        assert_eq!(s.indices(8).unwrap(), vec![0, 1, 2, 3, 2, 1, 0, 7]);
        assert_eq!(s.to_string(), "0-3,2-0,7-7");
        for bad in ["", "a-3", "1-", "-4", "1-2-3", "1,,2", "3 4"] {
            assert!(bad.parse::<FrameSelection>().is_err(), "{bad}");
        }
        let e = "0-999,998-0".parse::<FrameSelection>().unwrap().indices(500).unwrap_err();
        assert_eq!(
            e.to_string(),
            "frame range 0-999 is outside the recording's 500 frames (0-499)"
        );
    }

    #[test]
    fn played_times_keep_increasing_with_the_recording_s_intervals() {
        // Frames 0.1 s apart, but for a longer gap between 2 and 3.
        let times = [10.0, 10.1, 10.2, 10.5, 10.6];
        let played = renumbered_times(&times, &[0, 1, 2, 3, 4, 3, 2, 0]);
        let expect = [10.0, 10.1, 10.2, 10.5, 10.6, 10.7, 11.0, 11.1];
        for (p, e) in played.iter().zip(expect) {
            assert!((p - e).abs() < 1e-9, "{played:?}");
        }
        assert!(played.windows(2).all(|w| w[1] > w[0]));
    }

    #[test]
    fn the_ground_truth_follows_its_frames() {
        let pose = |t: f64, x: f64| StampedPose {
            timestamp_s: t,
            t_wc: Isometry3::translation(x, 0.0, 0.0),
        };
        let gt = Trajectory::new(vec![pose(1.0, 0.0), pose(1.01, 1.0), pose(2.0, 2.0)]);
        // Played: frame at 2.0 (x 2), then back at 1.0 (x 0), then one with no ground truth.
        let followed = following_groundtruth(&gt, &[2.0, 1.004, 1.5], &[5.0, 5.1, 5.2], 0.02);
        let got: Vec<(f64, f64)> =
            followed.poses.iter().map(|p| (p.timestamp_s, p.t_wc.translation.x)).collect();
        assert_eq!(got, vec![(5.0, 2.0), (5.1, 0.0)]);
        assert_eq!(followed.poses[1].t_wc.translation.vector, Vector3::zeros());
    }
}
