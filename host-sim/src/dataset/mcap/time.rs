//! Header stamps and seconds.
//!
//! A stamp is read as the decimal `sec.nnnnnnnnn` parsed as an `f64`: the correctly rounded value,
//! the same `f64` a TUM list gives for the same time written with up to nine decimals. A folder's
//! time written with more decimals than a stamp holds (`0.03333333333333333`, the demo's index / 30)
//! would come back different, so `convert` carries those times exactly in a metadata record
//! ([`EXACT_TIMES_METADATA`]: `sec.nnnnnnnnn` -> the time as the folder wrote it), and a reader
//! takes a stamp's time from there when it is listed.

use std::collections::{BTreeMap, HashMap};

use super::messages::Stamp;

/// Name of the metadata record holding times finer than a nanosecond, exactly.
pub const EXACT_TIMES_METADATA: &str = "ferroslam.exact_times";

/// The stamp of `t_s` seconds: its shortest decimal, cut to whole nanoseconds (rounded);
/// `None` for a time that is negative, not finite, or past `i32::MAX` seconds (2038).
pub fn stamp_of(t_s: f64) -> Option<Stamp> {
    if !(t_s.is_finite() && t_s >= 0.0 && t_s < f64::from(i32::MAX)) {
        return None;
    }
    let text = format!("{t_s}");
    let (whole, fraction) = text.split_once('.').unwrap_or((&text, ""));
    let mut sec: i32 = whole.parse().ok()?;
    let mut nanosec = if fraction.len() <= 9 {
        format!("{fraction:0<9}").parse().ok()?
    } else {
        ((t_s - t_s.floor()) * 1e9).round() as u32
    };
    if nanosec >= 1_000_000_000 {
        sec = sec.checked_add(1)?;
        nanosec -= 1_000_000_000;
    }
    Some(Stamp { sec, nanosec })
}

/// `stamp` as `sec.nnnnnnnnn`.
pub fn stamp_text(stamp: Stamp) -> String {
    format!("{}.{:09}", stamp.sec, stamp.nanosec)
}

/// The seconds a stamp stands for: the decimal `sec.nnnnnnnnn` correctly rounded to `f64`.
pub fn seconds_of(stamp: Stamp) -> f64 {
    // Always a valid float literal; the fallback is never taken.
    stamp_text(stamp).parse().unwrap_or(f64::from(stamp.sec) + f64::from(stamp.nanosec) * 1e-9)
}

/// Times finer than a nanosecond, by stamp: what [`EXACT_TIMES_METADATA`] holds.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ExactTimes {
    by_stamp: HashMap<Stamp, f64>,
}

impl ExactTimes {
    /// Reads the metadata record's map; entries that do not parse are left out (the stamp's
    /// own time is used for them).
    pub fn from_metadata(map: &BTreeMap<String, String>) -> Self {
        let by_stamp = map
            .iter()
            .filter_map(|(key, value)| {
                let (sec, nanosec) = key.split_once('.')?;
                let stamp = Stamp { sec: sec.parse().ok()?, nanosec: nanosec.parse().ok()? };
                Some((stamp, value.parse().ok()?))
            })
            .collect();
        Self { by_stamp }
    }

    /// The record's map: each stamp as `sec.nnnnnnnnn`, its time as the shortest decimal that
    /// reads back as the same `f64`.
    pub fn to_metadata(&self) -> BTreeMap<String, String> {
        self.by_stamp.iter().map(|(s, t)| (stamp_text(*s), format!("{t}"))).collect()
    }

    /// Whether there is nothing to carry.
    pub fn is_empty(&self) -> bool {
        self.by_stamp.is_empty()
    }

    /// The stamp for `t_s`, remembering `t_s` when the stamp alone does not give it back;
    /// `None` when `t_s` has no stamp ([`stamp_of`]) or another time finer than a nanosecond
    /// already has the same stamp.
    pub fn stamp(&mut self, t_s: f64) -> Option<Stamp> {
        let stamp = stamp_of(t_s)?;
        if seconds_of(stamp) == t_s {
            return Some(stamp);
        }
        match self.by_stamp.insert(stamp, t_s) {
            Some(other) if other != t_s => None,
            _ => Some(stamp),
        }
    }

    /// The time `stamp` stands for.
    pub fn seconds(&self, stamp: Stamp) -> f64 {
        self.by_stamp.get(&stamp).copied().unwrap_or_else(|| seconds_of(stamp))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_with_up_to_nine_decimals_come_back_exactly() {
        for text in ["0.000000", "0.033333", "1305031102.175304", "5.5", "7", "0.000000001"] {
            let t: f64 = text.parse().unwrap();
            let stamp = stamp_of(t).unwrap();
            assert_eq!(seconds_of(stamp).to_bits(), t.to_bits(), "{text}");
        }
        assert_eq!(
            stamp_of(1305031102.175304),
            Some(Stamp { sec: 1305031102, nanosec: 175304000 })
        );
        assert_eq!(stamp_of(-1.0), None);
        assert_eq!(stamp_of(f64::NAN), None);
        assert_eq!(stamp_of(3e9), None);
    }

    #[test]
    fn finer_times_are_carried_and_read_back() {
        let mut exact = ExactTimes::default();
        let times: Vec<f64> = (0..300).map(|i| i as f64 / 30.0).collect();
        let stamps: Vec<Stamp> = times.iter().map(|&t| exact.stamp(t).unwrap()).collect();
        assert!(!exact.is_empty());
        let read = ExactTimes::from_metadata(&exact.to_metadata());
        for (t, s) in times.iter().zip(&stamps) {
            assert_eq!(read.seconds(*s).to_bits(), t.to_bits());
        }
        // Two times within a nanosecond cannot both be carried.
        assert!(exact.stamp(0.1 + 1e-12).is_some());
        assert!(exact.stamp(0.1 + 2e-12).is_none());
    }
}
