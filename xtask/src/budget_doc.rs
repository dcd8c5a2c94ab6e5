//! `memory-budget.md` as `cargo xtask budgets` reads and writes it.
//!
//! The file is prose with generated regions, each between two marker lines:
//!
//! ```text
//! <!-- budgets:begin NAME -->
//! ...
//! <!-- budgets:end NAME -->
//! ```
//!
//! Region `block` holds the budgets as TOML in a fenced code block: one table per figure,
//! `[PROFILE.FIGURE]`, with `what` (a label), `bar` (the issue's budget), optionally `ceiling`
//! (a regression guard above a bar not met today) with its `reason`, and `measured`. `budgets`
//! reads the bars and ceilings from it; `--write` replaces only the `measured` lines there (so it
//! can never move a bar or a ceiling) and the whole content of every other region. Text outside
//! the regions is never touched.

use std::collections::HashSet;

use anyhow::{Context, Result, anyhow, bail};

/// One budget of the block.
#[derive(Debug, Clone, PartialEq)]
pub struct Budget {
    /// `PROFILE.FIGURE`, e.g. `qvga.flash_bytes`: the figure's key in the JSON output.
    pub key: String,
    /// What the figure is, for the tables.
    pub what: String,
    /// The issue's bar.
    pub bar: u64,
    /// Where the bar is not met today: the figure may not exceed this instead (see the file).
    pub ceiling: Option<u64>,
    /// Why the ceiling is there (required with one).
    pub reason: Option<String>,
    /// The figure the file states.
    pub measured: Option<u64>,
}

/// The `(begin, end)` byte range of region `name`'s content: from after its begin marker line to
/// the start of its end marker line.
fn region(doc: &str, name: &str) -> Result<(usize, usize)> {
    let begin = format!("<!-- budgets:begin {name} -->\n");
    let end = format!("<!-- budgets:end {name} -->");
    let b = doc.find(&begin).ok_or_else(|| anyhow!("memory-budget.md has no `{begin}` line"))?;
    let from = b + begin.len();
    let e = doc[from..].find(&end).ok_or_else(|| anyhow!("region {name} has no `{end}` line"))?;
    Ok((from, from + e))
}

/// `doc` with region `name`'s content replaced by `content` (which must end with a newline).
pub fn replace_region(doc: &str, name: &str, content: &str) -> Result<String> {
    let (from, to) = region(doc, name)?;
    Ok(format!("{}{content}{}", &doc[..from], &doc[to..]))
}

/// The byte range of the TOML inside region `block`'s fenced code block.
fn block_range(doc: &str) -> Result<(usize, usize)> {
    let (from, to) = region(doc, "block")?;
    let text = &doc[from..to];
    let start = text.find("```toml\n").ok_or_else(|| anyhow!("region block has no ```toml"))? + 8;
    let len = text[start..].find("```").ok_or_else(|| anyhow!("region block's code is open"))?;
    Ok((from + start, from + start + len))
}

/// The TOML inside region `block`'s fenced code block.
fn block_toml(doc: &str) -> Result<&str> {
    let (from, to) = block_range(doc)?;
    Ok(&doc[from..to])
}

/// The table headers `[a.b]` of `toml`, in file order.
fn headers(toml: &str) -> Vec<String> {
    toml.lines()
        .filter_map(|l| l.trim().strip_prefix('[')?.strip_suffix(']').map(str::to_owned))
        .collect()
}

/// The budgets of the block, in file order.
///
/// # Errors
/// No block; bad TOML; a table that is not `[PROFILE.FIGURE]`; a missing `what` or `bar`; a
/// ceiling without a reason, or at or below its bar.
pub fn parse_block(doc: &str) -> Result<Vec<Budget>> {
    let toml = block_toml(doc)?;
    let table: toml::Table = toml::from_str(toml).context("memory-budget.md: the budget block")?;
    let mut seen = HashSet::new();
    let mut budgets = Vec::new();
    for key in headers(toml) {
        let (profile, figure) =
            key.split_once('.').ok_or_else(|| anyhow!("budget [{key}]: not PROFILE.FIGURE"))?;
        let t = table
            .get(profile)
            .and_then(|p| p.get(figure))
            .and_then(toml::Value::as_table)
            .ok_or_else(|| anyhow!("budget [{key}]: not a table"))?;
        let int = |name: &str| -> Result<Option<u64>> {
            t.get(name)
                .map(|v| {
                    v.as_integer()
                        .and_then(|i| u64::try_from(i).ok())
                        .ok_or_else(|| anyhow!("budget [{key}]: `{name}` is not a count"))
                })
                .transpose()
        };
        let text = |name: &str| t.get(name).and_then(toml::Value::as_str).map(str::to_owned);
        let budget = Budget {
            key: key.clone(),
            what: text("what").ok_or_else(|| anyhow!("budget [{key}]: no `what`"))?,
            bar: int("bar")?.ok_or_else(|| anyhow!("budget [{key}]: no `bar`"))?,
            ceiling: int("ceiling")?,
            reason: text("reason"),
            measured: int("measured")?,
        };
        if let Some(c) = budget.ceiling {
            if budget.reason.is_none() {
                bail!("budget [{key}]: a ceiling needs its `reason`");
            }
            if c <= budget.bar {
                bail!("budget [{key}]: the ceiling {c} is not above the bar {}", budget.bar);
            }
        }
        if !seen.insert(key.clone()) {
            bail!("budget [{key}] appears twice");
        }
        budgets.push(budget);
    }
    Ok(budgets)
}

/// `524288` as `524_288` (a TOML integer a reader can count).
pub fn toml_int(value: u64) -> String {
    crate::stats::thousands(value).replace(',', "_")
}

/// `doc` with every `measured = ...` line of the block set from `measured(key)` (a line is added
/// under a table that has none). Nothing else in the block changes.
///
/// # Errors
/// No block; a budget whose figure `measured` does not know.
pub fn write_measured(doc: &str, measured: impl Fn(&str) -> Option<u64>) -> Result<String> {
    let toml = block_toml(doc)?;
    let mut out = String::with_capacity(toml.len() + 64);
    let lines: Vec<&str> = toml.lines().collect();
    let mut current: Option<String> = None;
    let mut written = true;
    let value_line = |key: &str| -> Result<String> {
        let v = measured(key).ok_or_else(|| anyhow!("budget [{key}]: no such figure measured"))?;
        Ok(format!("measured = {}\n", toml_int(v)))
    };
    for line in lines {
        let trimmed = line.trim();
        if let Some(key) = trimmed.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            if let (Some(prev), false) = (&current, written) {
                out.push_str(&value_line(prev)?);
            }
            current = Some(key.to_owned());
            written = false;
        } else if trimmed.starts_with("measured") && trimmed.contains('=') {
            if let Some(key) = &current {
                out.push_str(&value_line(key)?);
                written = true;
                continue;
            }
        } else if trimmed.is_empty() {
            // A table ends at the blank line after it: add its missing `measured` there.
            if let (Some(prev), false) = (&current, written) {
                out.push_str(&value_line(prev)?);
                written = true;
            }
        }
        out.push_str(line);
        out.push('\n');
    }
    if let (Some(prev), false) = (&current, written) {
        out.push_str(&value_line(prev)?);
    }
    let (from, to) = block_range(doc)?;
    Ok(format!("{}{out}{}", &doc[..from], &doc[to..]))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    const DOC: &str = "# Budget\n\nprose\n\n<!-- budgets:begin block -->\n```toml\n# comment\n\
        [qvga.flash_bytes]\nwhat = \"flash\"\nbar = 1_048_576\nmeasured = 1\n\n\
        [qvga.ram_total_bytes]\nwhat = \"RAM\"\nbar = 524_288\nceiling = 760_000\n\
        reason = \"the map\"\n```\n<!-- budgets:end block -->\n\n<!-- budgets:begin t -->\n\
        old\n<!-- budgets:end t -->\ntail\n";

    #[test]
    fn the_block_parses_in_file_order() {
        let b = parse_block(DOC).unwrap();
        assert_eq!(b.len(), 2);
        assert_eq!(
            (b[0].key.as_str(), b[0].bar, b[0].measured),
            ("qvga.flash_bytes", 1_048_576, Some(1))
        );
        assert_eq!((b[1].ceiling, b[1].measured), (Some(760_000), None));
        assert_eq!(b[1].reason.as_deref(), Some("the map"));
    }

    #[test]
    fn bad_blocks_are_errors() {
        assert!(parse_block("no block").is_err());
        let no_reason = DOC.replace("reason = \"the map\"\n", "");
        assert!(parse_block(&no_reason).is_err());
        let low = DOC.replace("ceiling = 760_000", "ceiling = 500_000");
        assert!(parse_block(&low).is_err());
        let no_bar = DOC.replace("bar = 1_048_576\n", "");
        assert!(parse_block(&no_bar).is_err());
    }

    #[test]
    fn writing_measured_touches_only_measured_lines() {
        let figure = |k: &str| match k {
            "qvga.flash_bytes" => Some(725_000),
            "qvga.ram_total_bytes" => Some(741_976),
            _ => None,
        };
        let out = write_measured(DOC, figure).unwrap();
        assert!(out.contains("bar = 1_048_576\nmeasured = 725_000\n"), "{out}");
        assert!(out.contains("reason = \"the map\"\nmeasured = 741_976\n```"), "{out}");
        let b = parse_block(&out).unwrap();
        assert_eq!((b[0].bar, b[1].ceiling), (1_048_576, Some(760_000)));
        assert!(
            out.starts_with("# Budget\n\nprose\n")
                && out.ends_with("old\n<!-- budgets:end t -->\ntail\n")
        );
        // Idempotent.
        assert_eq!(write_measured(&out, figure).unwrap(), out);
        assert!(write_measured(DOC, |_| None).is_err());
    }

    #[test]
    fn regions_are_replaced_whole() {
        let out = replace_region(DOC, "t", "new\nlines\n").unwrap();
        assert!(
            out.ends_with("<!-- budgets:begin t -->\nnew\nlines\n<!-- budgets:end t -->\ntail\n")
        );
        assert!(replace_region(DOC, "missing", "x\n").is_err());
        assert_eq!(toml_int(524_288), "524_288");
    }
}
