//! Listed images that are not replayed: which list they are in, why, and how that is said.

use std::fmt;
use std::path::{Path, PathBuf};

use super::lists::ListEntry;

/// Which list of a dataset folder an image is listed in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stream {
    /// `rgb.txt`: the colour images, one per frame.
    Rgb,
    /// `depth.txt`: the depth images.
    Depth,
}

impl Stream {
    /// The other stream: the one an image of this one is associated with.
    pub fn other(self) -> Self {
        match self {
            Self::Rgb => Self::Depth,
            Self::Depth => Self::Rgb,
        }
    }

    /// What an image of the stream is called in messages: `colour` or `depth`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Rgb => "colour",
            Self::Depth => "depth",
        }
    }
}

/// Why a listed image is not replayed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SkipReason {
    /// The image file does not exist (or is not a regular file).
    Missing,
    /// No image of the other stream lies within the association limit (or the nearest ones were
    /// taken by closer frames).
    Unassociated,
}

/// A listed image that is not replayed, and why; `Display` gives a one-line warning
/// (`LIST:LINE: PATH does not exist`, or `LIST:LINE: PATH (t = T s): WHY`).
#[derive(Debug, Clone, PartialEq)]
pub struct SkippedFrame {
    /// The list naming it (`.../rgb.txt` or `.../depth.txt`).
    pub list: PathBuf,
    /// Which list that is: a skipped colour image is a skipped frame.
    pub stream: Stream,
    /// 1-based line in that list.
    pub line: usize,
    /// Its timestamp, in seconds.
    pub timestamp_s: f64,
    /// The image path.
    pub path: PathBuf,
    /// Why it is skipped.
    pub reason: SkipReason,
    /// The association limit it was measured against, seconds
    /// ([`super::DatasetOptions::max_dt_s`]).
    pub max_dt_s: f64,
    /// For an unassociated image: the nearest image of the other stream within the limit that
    /// is listed but does not exist (the partner it lost), if there is one.
    pub missing_partner: Option<PathBuf>,
}

impl SkippedFrame {
    /// Why it is skipped, in words and without its place: `file missing`, or `no depth image
    /// within 0.02 s` (with the missing partner, if any).
    pub fn why(&self) -> String {
        match self.reason {
            SkipReason::Missing => "file missing".to_owned(),
            SkipReason::Unassociated => {
                let other = self.stream.other().name();
                let mut why = format!("no {other} image within {} s", self.max_dt_s);
                if let Some(partner) = &self.missing_partner {
                    why.push_str(&format!(" ({} is listed but does not exist)", partner.display()));
                }
                why
            }
        }
    }
}

impl fmt::Display for SkippedFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (list, line, path) = (self.list.display(), self.line, self.path.display());
        match self.reason {
            SkipReason::Missing => write!(f, "{list}:{line}: {path} does not exist"),
            SkipReason::Unassociated => {
                write!(f, "{list}:{line}: {path} (t = {} s): {}", self.timestamp_s, self.why())
            }
        }
    }
}

/// A [`SkippedFrame`] for `entry` of `list`, without a missing partner.
pub(super) fn skip(
    (list, stream): (&Path, Stream),
    entry: &ListEntry,
    reason: SkipReason,
    max_dt_s: f64,
) -> SkippedFrame {
    SkippedFrame {
        list: list.to_owned(),
        stream,
        line: entry.line,
        timestamp_s: entry.timestamp_s,
        path: entry.path.clone(),
        reason,
        max_dt_s,
        missing_partner: None,
    }
}

/// The entries whose image is a file; the others go to `skipped`.
pub(super) fn keep_present(
    list: (&Path, Stream),
    entries: Vec<ListEntry>,
    max_dt_s: f64,
    skipped: &mut Vec<SkippedFrame>,
) -> Vec<ListEntry> {
    let (present, missing): (Vec<_>, Vec<_>) = entries.into_iter().partition(|e| e.path.is_file());
    skipped.extend(missing.iter().map(|e| skip(list, e, SkipReason::Missing, max_dt_s)));
    present
}

/// The image of `stream` nearest to `timestamp_s`, closer than `max_dt_s`, among the missing
/// ones of `skipped`.
pub(super) fn nearest_missing(
    skipped: &[SkippedFrame],
    stream: Stream,
    timestamp_s: f64,
    max_dt_s: f64,
) -> Option<PathBuf> {
    skipped
        .iter()
        .filter(|s| s.stream == stream && s.reason == SkipReason::Missing)
        .map(|s| ((s.timestamp_s - timestamp_s).abs(), s))
        .filter(|(dt, _)| *dt < max_dt_s)
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, s)| s.path.clone())
}
