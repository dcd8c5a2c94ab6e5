//! The generated regions of `memory-budget.md` (see `budget_doc.rs`), written from what
//! `budgets` measured: `checks` (budget vs measured), `block` (its `measured` values only),
//! `structures` (the core's `size_of` table), `binaries` (flash, static RAM and stack of each
//! binary), `cost` (instructions per frame by stage, and by what the front end ran) and `vga`.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use ferroslam_core::tracking::FrontendWork;

use crate::budget_doc::{replace_region, write_measured};
use crate::budget_figures::{Check, Measurements, VGA_DOES_NOT_RUN, show};
use crate::cost::{FrameCost, describe_work};
use crate::stats::{Stats, millions, thousands};

/// `doc` with every generated region rewritten from `m` and `checks`.
///
/// # Errors
/// A region missing from `doc`; a budget without its figure.
pub fn render(doc: &str, m: &Measurements, checks: &[Check]) -> Result<String> {
    let doc = write_measured(doc, |key| m.figure(key))?;
    let doc = replace_region(&doc, "checks", &checks_table(m, checks))?;
    let doc = replace_region(&doc, "ram", &ram_table(m, checks))?;
    let doc = replace_region(&doc, "structures", &structures_table(m))?;
    let doc = replace_region(&doc, "binaries", &binaries_table(m))?;
    let doc = replace_region(&doc, "cost", &cost_table(m, checks))?;
    replace_region(&doc, "vga", &vga_table(m))
}

/// Prose `text` as lines of at most 100 columns (the file's width), with a final newline.
fn wrap(text: &str) -> String {
    // A unit ("M", "B", with punctuation) stays on the line of its number.
    let mut words: Vec<String> = Vec::new();
    for word in text.split_whitespace() {
        let unit = word.trim_end_matches([',', ';', '.', ':', ')']);
        match words.last_mut() {
            Some(last) if unit == "M" || unit == "B" => {
                last.push(' ');
                last.push_str(word);
            }
            _ => words.push(word.to_owned()),
        }
    }
    let mut out = String::new();
    let mut line = String::new();
    for word in &words {
        if !line.is_empty() && line.len() + 1 + word.len() > 100 {
            out.push_str(&line);
            out.push('\n');
            line.clear();
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(word);
    }
    out.push_str(&line);
    out.push('\n');
    out
}

/// The dataset's folder name.
fn dataset_name(m: &Measurements) -> String {
    folder_name(&m.run.dataset)
}

/// The last component of the path `dataset`.
fn folder_name(dataset: &str) -> String {
    Path::new(dataset)
        .file_name()
        .map_or_else(|| dataset.to_owned(), |n| n.to_string_lossy().into_owned())
}

fn checks_table(m: &Measurements, checks: &[Check]) -> String {
    let also: String = m
        .also
        .iter()
        .map(|(name, run)| {
            format!(
                "; `{name}.*` over {} frames of {} ({} keyframes)",
                run.frames.len(),
                folder_name(&run.dataset),
                run.keyframe_count()
            )
        })
        .collect();
    let mut s = wrap(&format!(
        "Measured by `cargo xtask budgets`: `qvga.*` over {} frames of {} ({} keyframes){also}:",
        m.run.frames.len(),
        dataset_name(m),
        m.run.keyframe_count()
    ));
    s.push_str(
        "\n| figure, QVGA reference board | bar | ceiling | measured | status |\n\
         | --- | --- | --- | --- | --- |\n",
    );
    for c in checks {
        let k = &c.budget.key;
        let ceiling = c.budget.ceiling.map_or_else(|| "none".to_owned(), |v| show(k, v));
        let status = if c.met() { c.status() } else { format!("**{}**", c.status()) };
        let _ = writeln!(
            s,
            "| {} (`{k}`) | {} | {ceiling} | {} | {status} |",
            c.budget.what,
            show(k, c.budget.bar),
            show(k, c.measured)
        );
    }
    s
}

/// The RAM bar's figure taken apart: frame buffers, pipeline state, other statics, stack.
fn ram_table(m: &Measurements, checks: &[Check]) -> String {
    let get = |k: &str| m.figure(k).unwrap_or(0);
    let (statics, stack) = (get("qvga.static_ram_bytes"), get("qvga.stack_peak_bytes"));
    let (buffers, state) = (get("qvga.frame_buffers_bytes"), get("qvga.pipeline_state_bytes"));
    let total = statics + stack;
    let bar = checks.iter().find(|c| c.budget.key == "qvga.ram_total_bytes").map(|c| c.budget.bar);
    let share =
        |v: u64| bar.map_or_else(|| "-".into(), |b| format!("{:.1}%", 100.0 * v as f64 / b as f64));
    let mut s = "| part | bytes | of the bar |\n| --- | ---: | ---: |\n".to_owned();
    for (label, v) in [
        ("frame buffers: QVGA gray + depth (the frame store)", buffers),
        ("pipeline state: front end, map, back end (`size_of::<Pipeline>()` on the board)", state),
        ("other statics", statics.saturating_sub(buffers + state)),
        ("peak stack", stack),
        ("**static RAM + peak stack**", total),
    ] {
        let _ = writeln!(s, "| {label} | {} | {} |", thousands(v), share(v));
    }
    if let Some(b) = bar.filter(|&b| total > b) {
        let _ =
            writeln!(s, "| over the bar by | {} | {} |", thousands(total - b), share(total - b));
    }
    s
}

fn structures_table(m: &Measurements) -> String {
    let mut s = "| structure | capacity that drives it | bytes |\n| --- | --- | --- |\n".to_owned();
    for st in &m.structures {
        let _ = writeln!(s, "| `{}` | {} | {} |", st.name, st.capacity, thousands(st.bytes as u64));
    }
    s
}

fn binaries_table(m: &Measurements) -> String {
    let names: Vec<&str> = m.binaries.iter().map(|b| b.name).collect();
    let mut s = format!(
        "| figure, bytes | {} |\n| --- |{}\n",
        names.join(" | "),
        " ---: |".repeat(names.len())
    );
    let mut row = |label: &str, cell: &dyn Fn(&crate::budget_figures::Binary) -> String| {
        let cells: Vec<String> = m.binaries.iter().map(cell).collect();
        let _ = writeln!(s, "| {label} | {} |", cells.join(" | "));
    };
    row("**flash**: `.vector_table + .text + .rodata + .data` (its load image)", &|b| {
        format!("**{}**", thousands(b.flash))
    });
    row("**static RAM**: `.data + .bss + .uninit + .axisram + .sram123`", &|b| {
        format!("**{}**", thousands(b.static_ram))
    });
    let stack = u64::from(m.run.status.stack_peak_bytes);
    row("peak stack (painted, measured in QEMU; the same code on both)", &|_| thousands(stack));
    row("**static RAM + peak stack**", &|b| format!("**{}**", thousands(b.static_ram + stack)));
    let room = m.ref_board_stack_room();
    row("DTCM left for the stack (128 KiB less the DTCM statics)", &|b| {
        if b.name == "ref-board" { room.map_or_else(|| "-".into(), thousands) } else { "-".into() }
    });
    s
}

fn cost_table(m: &Measurements, checks: &[Check]) -> String {
    // The run (frames, dataset, keyframes) is named by the `checks` region.
    let mut s =
        "| stage | median | p90 | p99 | max | mean |\n| --- | ---: | ---: | ---: | ---: | ---: |\n"
            .to_owned();
    for ((key, label, _), st) in m.run.stage_stats() {
        let cell = |v: u64| if v < 100_000 { thousands(v) } else { millions(v) };
        let bold = |t: String| if key == "pipeline" { format!("**{t}**") } else { t };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} |",
            bold(label.to_owned()),
            bold(cell(st.median)),
            cell(st.p90),
            bold(cell(st.p99)),
            bold(cell(st.max)),
            cell(st.mean.round() as u64)
        );
    }
    let bar =
        checks.iter().find(|c| c.budget.key == "qvga.insn_per_frame_max").map(|c| c.budget.bar);
    if let Some(kinds) = kinds_table(m, bar) {
        s.push('\n');
        s.push_str(&kinds);
    }
    s
}

/// The pipeline's cost by kind of frame (what the front end ran on it), with how many frames of
/// each kind are over `bar` (the max's); `None` when the run does not say what ran.
fn kinds_table(m: &Measurements, bar: Option<u64>) -> Option<String> {
    let mut kinds: BTreeMap<FrontendWork, Vec<u64>> = BTreeMap::new();
    for f in &m.run.frames {
        kinds.entry(f.work?).or_default().push(f.pipeline());
    }
    let over = |v: &[u64]| {
        bar.map_or_else(|| "-".into(), |b| v.iter().filter(|&&x| x > b).count().to_string())
    };
    let all: Vec<u64> = m.run.frames.iter().map(FrameCost::pipeline).collect();
    let mut s = wrap(&format!(
        "{} of the {} frames are over the max's bar{}. The pipeline by what the front end ran on \
         the frame (`work` in `cost.json`, from the host replay):",
        over(&all),
        all.len(),
        bar.map_or_else(String::new, |b| format!(" of {}", millions(b)))
    ));
    s.push_str(
        "\n| what the front end ran | frames | median | max | over the bar |\n\
         | --- | ---: | ---: | ---: | ---: |\n",
    );
    for (work, v) in &kinds {
        let st = Stats::of(v);
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} |",
            describe_work(work),
            v.len(),
            millions(st.median),
            millions(st.max),
            over(v)
        );
    }
    Some(s)
}

fn vga_table(m: &Measurements) -> String {
    let total = m.figure("vga.frame_buffers_bytes").unwrap_or(0)
        + m.figure("vga.slam_state_bytes").unwrap_or(0);
    wrap(&format!(
        "The firmware figures of VGA are `null` in the JSON, with `vga.runs = false` and this \
         reason: {VGA_DOES_NOT_RUN}. On the host, VGA's frame buffers and `system::VgaSlam` \
         (`vga.frame_buffers_bytes` + `vga.slam_state_bytes`) are {} B before code, stack or any \
         other state; its other sizes are in the core structures' table.",
        thousands(total)
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prose_wraps_at_100_columns() {
        let text = "word ".repeat(60);
        let out = wrap(&text);
        assert!(out.lines().all(|l| l.len() <= 100));
        assert_eq!(out.split_whitespace().count(), 60);
        assert!(out.ends_with("word\n"));
        assert_eq!(wrap(""), "\n");
        let numbers = wrap(&format!("{} 30.89 M.", "x".repeat(96)));
        assert!(numbers.ends_with("\n30.89 M.\n"), "{numbers}");
    }

    #[test]
    fn frames_are_grouped_by_what_ran_and_counted_over_the_bar() {
        let work = |final_stages, detected| FrontendWork {
            final_stages,
            guide_runs: final_stages - 1,
            rotation_estimated: false,
            detected,
        };
        let frame = |i, work, frontend| FrameCost {
            frame_index: i,
            keyframe: false,
            work,
            acquire: 0,
            frontend,
            backend_step: 1_000_000,
            report: 0,
        };
        let mut m = Measurements {
            run: crate::cost::FirmwareRun {
                dataset: "data".into(),
                elf: "fw.elf".into(),
                elf_fnv1a64: String::new(),
                status: ferroslam_core::wire::StatusMessage::default(),
                frames: vec![
                    frame(0, Some(work(2, true)), 16_000_000),
                    frame(1, Some(work(1, false)), 5_000_000),
                    frame(2, Some(work(2, true)), 13_000_000),
                    frame(3, Some(work(1, false)), 4_000_000),
                ],
            },
            cost_json: "cost.json".into(),
            also: Vec::new(),
            boots: Vec::new(),
            binaries: Vec::new(),
            structures: Vec::new(),
            figures: Vec::new(),
        };
        let table = kinds_table(&m, Some(15_000_000)).unwrap_or_default();
        assert!(table.contains("1 of the 4 frames are over the max's bar of 15.00 M."), "{table}");
        let rows: Vec<&str> =
            table.lines().filter(|l| l.starts_with("| 1 ") || l.starts_with("| 2 ")).collect();
        assert_eq!(
            rows,
            [
                "| 1 final stage, 0 guide runs | 2 | 5.00 M | 6.00 M | 0 |",
                "| 2 final stages, 1 guide run, detection (a keyframe) | 2 | 14.00 M | 17.00 M | 1 |",
            ],
            "{table}"
        );
        m.run.frames[3].work = None;
        assert_eq!(kinds_table(&m, Some(15_000_000)), None);
    }
}
