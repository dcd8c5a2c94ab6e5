//! TUM image lists: `rgb.txt` and `depth.txt`, one `timestamp path` per data line. (Ground truth
//! is a TUM trajectory file, read by [`crate::trajectory`].)
//!
//! Lines whose first non-blank character is `#` and blank lines are skipped; fields are separated by
//! any run of spaces or tabs; `\r\n` line ends are accepted. Timestamps are seconds on the
//! recording's clock and must strictly increase from one data line to the next (a repeated or
//! earlier timestamp is an error naming the file and both lines).

use std::path::{Path, PathBuf};

use super::DatasetError;

/// The layout of a line of `rgb.txt` / `depth.txt`.
const IMAGE_LINE: &str = "timestamp path";

/// One data line of `rgb.txt` or `depth.txt`.
#[derive(Debug, Clone, PartialEq)]
pub struct ListEntry {
    /// Seconds on the stream's clock.
    pub timestamp_s: f64,
    /// The image path joined to the dataset folder (an absolute path in the list stays as is).
    pub path: PathBuf,
    /// 1-based line number in the list file.
    pub line: usize,
}

/// Reads a whole text file, naming it on failure.
pub(crate) fn read_text(path: &Path) -> Result<String, DatasetError> {
    std::fs::read_to_string(path)
        .map_err(|source| DatasetError::Io { path: path.to_owned(), source })
}

/// The data lines of `text` with their 1-based numbers: comments and blank lines dropped.
fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines().enumerate().map(|(i, l)| (i + 1, l)).filter(|(_, l)| {
        let t = l.trim_start();
        !t.is_empty() && !t.starts_with('#')
    })
}

/// A line being parsed: where it is, for error messages.
struct LineCtx<'a> {
    path: &'a Path,
    line: usize,
    text: &'a str,
}

impl LineCtx<'_> {
    /// The whitespace-separated fields, exactly `N` of them.
    fn fields<const N: usize>(&self, expected: &'static str) -> Result<[&str; N], DatasetError> {
        let mut out = [""; N];
        let mut it = self.text.split_whitespace();
        for slot in &mut out {
            *slot = it.next().ok_or_else(|| self.field_count(expected))?;
        }
        match it.next() {
            Some(_) => Err(self.field_count(expected)),
            None => Ok(out),
        }
    }

    fn field_count(&self, expected: &'static str) -> DatasetError {
        DatasetError::FieldCount {
            path: self.path.to_owned(),
            line: self.line,
            expected,
            text: self.text.to_owned(),
        }
    }

    /// `value` as a finite `f64` (Rust's float syntax; `nan` and `inf` are rejected).
    fn number(&self, field: &'static str, value: &str) -> Result<f64, DatasetError> {
        match value.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(DatasetError::BadNumber {
                path: self.path.to_owned(),
                line: self.line,
                field,
                value: value.to_owned(),
                text: self.text.to_owned(),
            }),
        }
    }
}

/// Checks that timestamps strictly increase; remembers the last one.
struct Monotonic {
    previous: Option<(usize, f64)>,
}

impl Monotonic {
    fn check(&mut self, ctx: &LineCtx<'_>, timestamp_s: f64) -> Result<(), DatasetError> {
        if let Some((previous_line, previous_s)) = self.previous
            && timestamp_s <= previous_s
        {
            return Err(DatasetError::TimestampNotIncreasing {
                path: ctx.path.to_owned(),
                line: ctx.line,
                timestamp_s,
                previous_line,
                previous_s,
                text: ctx.text.to_owned(),
            });
        }
        self.previous = Some((ctx.line, timestamp_s));
        Ok(())
    }
}

/// Parses the text of an image list read from `path` (only named in errors); image paths are
/// joined to `dir`. What `Dataset::open` does with `rgb.txt` and `depth.txt` (public for
/// `cargo xtask fuzz`).
///
/// # Errors
/// [`DatasetError::FieldCount`], [`DatasetError::BadNumber`] or
/// [`DatasetError::TimestampNotIncreasing`], naming `path` and the line.
pub fn parse_image_list(
    path: &Path,
    text: &str,
    dir: &Path,
) -> Result<Vec<ListEntry>, DatasetError> {
    let mut entries = Vec::new();
    let mut order = Monotonic { previous: None };
    for (line, text) in data_lines(text) {
        let ctx = LineCtx { path, line, text };
        let [stamp, file] = ctx.fields::<2>(IMAGE_LINE)?;
        let timestamp_s = ctx.number("timestamp", stamp)?;
        order.check(&ctx, timestamp_s)?;
        entries.push(ListEntry { timestamp_s, path: dir.join(file), line });
    }
    Ok(entries)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(s: &str) -> PathBuf {
        PathBuf::from(s)
    }

    #[test]
    fn image_list_skips_comments_blanks_and_crlf() {
        let text = "# color images\n# timestamp filename\n\n  \n1305031102.175304 rgb/a.png\r\n\
                    \t# indented comment\n1305031102.211214\trgb/b.png  \n";
        let e = parse_image_list(&p("rgb.txt"), text, &p("/data")).unwrap();
        assert_eq!(e.len(), 2);
        assert_eq!(e[0].timestamp_s, 1305031102.175304);
        assert_eq!(e[0].path, p("/data/rgb/a.png"));
        assert_eq!(e[0].line, 5);
        assert_eq!(e[1].path, p("/data/rgb/b.png"));
        assert_eq!(e[1].line, 7);
    }

    #[test]
    fn image_list_errors_name_file_line_and_text() {
        let err = parse_image_list(&p("d/rgb.txt"), "# c\n1.0 a.png\n2.0\n", &p("d")).unwrap_err();
        assert_eq!(err.to_string(), "d/rgb.txt:3: expected 'timestamp path', got \"2.0\"");
        let err = parse_image_list(&p("rgb.txt"), "1.0 a.png extra\n", &p("")).unwrap_err();
        assert!(matches!(err, DatasetError::FieldCount { line: 1, .. }), "{err}");
        let err = parse_image_list(&p("rgb.txt"), "1.0 a\nx1 b\n", &p("")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "rgb.txt:2: timestamp \"x1\" is not a finite number, in \"x1 b\""
        );
        for bad in ["nan a", "inf a", "-inf a", "NaN a"] {
            let err = parse_image_list(&p("rgb.txt"), bad, &p("")).unwrap_err();
            assert!(matches!(err, DatasetError::BadNumber { line: 1, .. }), "{bad}: {err}");
        }
    }

    #[test]
    fn timestamps_must_increase() {
        let err = parse_image_list(&p("depth.txt"), "1.0 a\n\n2.0 b\n1.5 c\n", &p("")).unwrap_err();
        assert!(
            matches!(err, DatasetError::TimestampNotIncreasing { line: 4, previous_line: 3, .. }),
            "{err}"
        );
        assert!(err.to_string().starts_with("depth.txt:4: timestamp 1.5 s is not after 2 s"));
        // A repeated timestamp is not an increase either.
        assert!(parse_image_list(&p("depth.txt"), "1.0 a\n1.0 b\n", &p("")).is_err());
    }
}
