//! The keys `calibration.toml` may hold: any other is refused with its line and the valid key
//! nearest to it, so that a misspelt key cannot turn off what it sets without a word.

use std::path::Path;

use super::DatasetError;

/// The keys of `calibration.toml` outside any table (TUM's `d0`..`d4` are refused apart, with
/// what to write instead).
const TOP_LEVEL_KEYS: [&str; 14] = [
    "fx",
    "fy",
    "cx",
    "cy",
    "width",
    "height",
    "depth_scale",
    "k1",
    "k2",
    "p1",
    "p2",
    "k3",
    "depth_noise_coeff_per_m",
    "depth",
];

/// The keys of its `[depth]` table.
const DEPTH_TABLE_KEYS: [&str; 7] = ["fx", "fy", "cx", "cy", "tx", "ty", "tz"];

/// Refuses the first key (in file order) that the file format does not define, at the top level
/// or in the `[depth]` table, with its line and the nearest valid key. `text` has been parsed
/// as TOML already.
pub(super) fn check_keys(text: &str, path: &Path) -> Result<(), DatasetError> {
    let document = toml::de::DeTable::parse(text).map_err(|e| DatasetError::CalibrationSyntax {
        path: path.to_owned(),
        message: e.to_string().trim_end().to_owned(),
    })?;
    // (byte offset, key, table) of every unknown key.
    let mut unknown: Vec<(usize, &str, Option<&'static str>)> = Vec::new();
    for (key, value) in document.get_ref() {
        let name: &str = key.get_ref();
        let tum = super::TUM_DISTORTION_KEYS.iter().any(|(k, _)| *k == name);
        if !tum && !TOP_LEVEL_KEYS.contains(&name) {
            unknown.push((key.span().start, name, None));
        }
        if let ("depth", toml::de::DeValue::Table(table)) = (name, value.get_ref()) {
            for (key, _) in table {
                let name: &str = key.get_ref();
                if !DEPTH_TABLE_KEYS.contains(&name) {
                    unknown.push((key.span().start, name, Some("depth")));
                }
            }
        }
    }
    let Some(&(offset, key, table)) = unknown.iter().min_by_key(|(offset, ..)| *offset) else {
        return Ok(());
    };
    let line = 1 + text.bytes().take(offset).filter(|&b| b == b'\n').count();
    let hint = match table {
        Some(_) if TOP_LEVEL_KEYS.contains(&key) => format!(
            "`{key}` is a top-level key: write it above the [depth] line (every key after a \
             [table] line belongs to that table)"
        ),
        Some(_) => key_hint(key, &DEPTH_TABLE_KEYS),
        None if DEPTH_TABLE_KEYS.contains(&key) => {
            format!("`{key}` is a key of the [depth] table: write it below a [depth] line")
        }
        None => key_hint(key, &TOP_LEVEL_KEYS),
    };
    Err(DatasetError::CalibrationUnknownKey {
        path: path.to_owned(),
        line,
        key: key.to_owned(),
        table,
        hint,
    })
}

/// "did you mean `K`?" with the valid key nearest to `key`, or the valid keys when none is near.
fn key_hint(key: &str, valid: &[&str]) -> String {
    match nearest_key(key, valid) {
        Some(near) => format!("did you mean `{near}`?"),
        None => format!("the keys here are {}", valid.join(", ")),
    }
}

/// The key of `valid` that `key` most likely misspells: the nearest by edit distance (case
/// ignored) when at most a third of its letters differ (at least one may), or else the one that
/// shares the longest start with it, of at least three letters (`depth_noise` for
/// `depth_noise_coeff_per_m`).
fn nearest_key<'v>(key: &str, valid: &[&'v str]) -> Option<&'v str> {
    let key = key.to_ascii_lowercase();
    let by_distance = valid
        .iter()
        .map(|v| (edit_distance(&key, v), *v))
        .filter(|(d, v)| *d <= (key.chars().count().max(v.len()) / 3).max(1))
        .min_by_key(|(d, _)| *d);
    if let Some((_, v)) = by_distance {
        return Some(v);
    }
    let shared = |v: &str| key.chars().zip(v.chars()).take_while(|(a, b)| a == b).count();
    valid
        .iter()
        .map(|v| (shared(v), *v))
        .filter(|(n, _)| *n >= 3)
        .max_by_key(|(n, _)| *n)
        .map(|(_, v)| v)
}

/// The optimal-string-alignment distance between `a` and `b`: insertions, deletions,
/// substitutions and swaps of two neighbouring characters, each 1 (`depht` is 1 from `depth`).
fn edit_distance(a: &str, b: &str) -> usize {
    strsim::osa_distance(a, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edit_distance_counts_swaps_as_one() {
        assert_eq!(edit_distance("depht", "depth"), 1);
        assert_eq!(edit_distance("k_1", "k1"), 1);
        assert_eq!(edit_distance("", "fx"), 2);
        assert_eq!(edit_distance("width", "width"), 0);
        assert_eq!(edit_distance("cx", "fy"), 2);
        assert_eq!(nearest_key("heigth", &TOP_LEVEL_KEYS), Some("height"));
        assert_eq!(nearest_key("q", &TOP_LEVEL_KEYS), None);
    }
}
