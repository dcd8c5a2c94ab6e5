//! `cargo xtask budgets`: RAM, flash, stack and instructions per frame of the firmware against
//! the budgets of `memory-budget.md`.
//!
//! ```text
//! cargo xtask budgets [--from DIR | --dataset DIR --frames N --out DIR] [--also NAME=DIR]...
//!                     [--json FILE] [--write] [--strict]
//! ```
//!
//! What it measures (profile QVGA, the reference board):
//! - **Flash and static RAM** of both firmware binaries, from their ELF sections
//!   (`arm-none-eabi-size -A`): flash = `.vector_table + .text + .rodata + .data` (the `.data`
//!   load image), static RAM = `.data + .bss + .uninit` plus the H7 regions `.axisram` and
//!   `.sram123` of `ref-board`. The figure checked is the larger of the two binaries.
//! - **Peak stack**: painted by the firmware and measured in QEMU (`qemu-mps2`; `ref-board` runs
//!   the same code), over the whole run. On `ref-board` the stack lives in the 128 KiB DTCM: a
//!   peak above what the DTCM statics leave fails the run.
//! - **Instructions per frame** on QEMU's Cortex-M4F (`-icount shift=0`: SysTick ticks x 40),
//!   median, p99 (nearest rank) and max over the replayed frames, for the front end, the back-end
//!   step (one fixed quota) and their sum, the pipeline, which the bars are about. Acquiring the
//!   frame (semihosting reads and the halving to QVGA) and the report are listed apart. A run
//!   needs [`MIN_FRAMES`] frames; p99 is given from [`P99_MIN_FRAMES`] on (below, it would be the
//!   max).
//! - The `size_of` of the core's structures on the host (`ferroslam_tests::structures`).
//!
//! Where the run comes from: `--from DIR` reads `DIR/cost.json` of a `firmware-replay` run (how
//! `cargo xtask ci` runs QEMU once for both checks; the ELF must be the one that ran, checked by
//! its hash); otherwise it runs `firmware-replay` itself on `--frames` (default 1000, at least
//! [`MIN_FRAMES`]) frames of `--dataset` (default 7-Scenes) into `--out` (default
//! `target/xtask/budgets`), bit-identical check included, and the same on the second recording,
//! [`fast_demo`](crate::fast_demo) (into `<out>-fast-demo`), on 7-Scenes' jump-back (`jump_back.*`,
//! into `<out>-jump-back`: the frames around a relocalization from the flash store) and on its
//! power cycle (`boot.*`: a run saves its map into `<out>-save-map`, a second boot localizes in
//! it into `<out>-boot`; see [`board_runs`]). `--also NAME=DIR` (repeatable) adds the
//! `firmware-replay` run in `DIR` of another recording, from the same build: its instructions per
//! frame and RAM are figures `NAME.insn_per_frame_median`, ..., `NAME.ram_total_bytes`, so the
//! bars can be held on more than one recording (CI: all five runs above). A run that booted from
//! a saved map also has `NAME.store_mount_insn` (mounting the store and indexing its records),
//! `NAME.frames_to_first_pose` (frames up to the first relocalized one, that one included) and
//! `NAME.insn_to_first_pose` (the mount and those frames' pipeline).
//!
//! How it judges: every budget of the block in `memory-budget.md` has the issue's `bar` and,
//! where the bar is not met today, a `ceiling` (a regression guard a few percent above the figure
//! when it was set) with its reason. A figure above its bar is reported `NOT MET (x times the
//! bar)`; the run fails when a figure exceeds its ceiling, or its bar when it has none, and with
//! `--strict` when it exceeds any bar. Ceilings and bars change only by hand, in the file.
//!
//! `--json FILE` writes every figure (`qvga.static_ram_bytes`, `qvga.insn_per_frame_median`, ...;
//! VGA with `runs: false` and nulls for what the firmware cannot run) and the checks.
//! `--write` regenerates the figures of `memory-budget.md` (its generated regions and the
//! block's `measured` values; never a bar or a ceiling); without it a stale file is reported.

use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use serde_json::{Map, Value, json};

use crate::board_runs::{self, BootCost};
use crate::budget_doc::{self, Budget};
use crate::budget_figures::{Binary, Check, Measurements, VGA_DOES_NOT_RUN, show};
use crate::cost::{FirmwareRun, fnv1a64};
use crate::firmware::{self, BINARIES};
use crate::paths::{SEVEN_SCENES, calibration_for, root};
use crate::replay::{self, ReplayOptions};

/// Frames a run must have for the per-frame figures: enough for a median and a max that say
/// something (a second of camera time at 30 Hz).
pub const MIN_FRAMES: usize = 30;

/// Frames from which p99 is a figure: below, the nearest rank of p99 is the max.
pub const P99_MIN_FRAMES: usize = 100;

/// Frames replayed when no `--from` run is given (all of 7-Scenes, as CI).
const DEFAULT_FRAMES: usize = 1000;

/// The name of the figures of the jump-back run ([`board_runs::jump_back`]): the frames of a
/// relocalization from the flash store are budgeted too.
pub const JUMP_BACK_RUN: &str = "jump_back";

/// The name of the figures of the second boot ([`board_runs::power_cycle`]): its frames, and what
/// the boot cost up to its first pose ([`BootCost`]).
pub const BOOT_RUN: &str = "boot";

/// The options.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// A `firmware-replay` output folder whose `cost.json` to read instead of running QEMU.
    pub from: Option<PathBuf>,
    /// The dataset to replay (without `from`).
    pub dataset: PathBuf,
    /// Frames to replay (without `from`).
    pub frames: usize,
    /// Where the replay writes (without `from`).
    pub out: PathBuf,
    /// Other recordings' `firmware-replay` folders, by the name their figures take.
    pub also: Vec<(String, PathBuf)>,
    /// Where to write the JSON report.
    pub json: Option<PathBuf>,
    /// Regenerate the figures of `memory-budget.md`.
    pub write: bool,
    /// Fail on any bar not met, ceilings or not.
    pub strict: bool,
}

impl Options {
    /// The defaults: 1000 frames of 7-Scenes replayed into `target/xtask/budgets`.
    pub fn new(root: &Path) -> Self {
        Self {
            from: None,
            dataset: root.join(SEVEN_SCENES),
            frames: DEFAULT_FRAMES,
            out: root.join("target").join("xtask").join("budgets"),
            also: Vec::new(),
            json: None,
            write: false,
            strict: false,
        }
    }

    /// Parses the command line (see the module documentation).
    ///
    /// # Errors
    /// An unknown option, a missing or bad value, fewer than [`MIN_FRAMES`] frames.
    pub fn parse(args: &[String], root: &Path) -> Result<Self> {
        let mut o = Self::new(root);
        let mut it = args.iter();
        while let Some(a) = it.next() {
            let mut value = || it.next().ok_or_else(|| anyhow!("{a} needs a value"));
            match a.as_str() {
                "--from" => o.from = Some(value()?.into()),
                "--dataset" => o.dataset = value()?.into(),
                "--frames" => {
                    let v = value()?;
                    o.frames = v.parse().with_context(|| format!("--frames {v}"))?;
                }
                "--out" => o.out = value()?.into(),
                "--also" => {
                    let v = value()?;
                    let (name, dir) = v
                        .split_once('=')
                        .filter(|(n, d)| is_run_name(n) && !d.is_empty())
                        .ok_or_else(|| {
                            anyhow!("--also {v}: expected NAME=DIR, NAME of a-z, 0-9 and _")
                        })?;
                    if PROFILE_RUNS.contains(&name) || o.also.iter().any(|(n, _)| n == name) {
                        bail!("--also {v}: the name {name} is taken");
                    }
                    o.also.push((name.to_owned(), dir.into()));
                }
                "--json" => o.json = Some(value()?.into()),
                "--write" => o.write = true,
                "--strict" => o.strict = true,
                other => bail!("unknown argument {other}"),
            }
        }
        if o.frames < MIN_FRAMES {
            bail!("--frames {}: the per-frame figures need at least {MIN_FRAMES}", o.frames);
        }
        Ok(o)
    }
}

/// The runs every measurement has: the firmware run's figures are `qvga.*`, the host-side VGA
/// figures `vga.*`.
const PROFILE_RUNS: [&str; 2] = ["qvga", "vga"];

/// The run a figure's key names: the part before the first `.`.
fn run_of(key: &str) -> &str {
    key.split_once('.').map_or("", |(run, _)| run)
}

/// Whether `name` can key figures: lower-case letters, digits and `_`, a letter first.
fn is_run_name(name: &str) -> bool {
    name.starts_with(|c: char| c.is_ascii_lowercase())
        && name.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
}

/// Runs `budgets` with the command line `args`.
///
/// # Errors
/// As [`run_with`].
pub fn run(args: &[String]) -> Result<()> {
    run_with(&root(), &Options::parse(args, &root())?)
}

/// Builds the firmware, gets the run (see [`Options::from`]) and gathers every figure.
fn measure(root: &Path, opts: &Options) -> Result<Measurements> {
    let mut also_dirs = opts.also.clone();
    let dir = match &opts.from {
        Some(dir) => {
            firmware::build_firmware(root, "qemu-mps2")?;
            dir.clone()
        }
        None => {
            let fast_demo = out_beside(&opts.out, "fast-demo");
            crate::fast_demo::write_and_replay(root, &fast_demo)?;
            also_dirs.push((crate::fast_demo::NAME.to_owned(), fast_demo));
            let jump_back = out_beside(&opts.out, "jump-back");
            board_runs::jump_back(&jump_back)?;
            also_dirs.push((JUMP_BACK_RUN.to_owned(), jump_back));
            let boot = out_beside(&opts.out, "boot");
            board_runs::power_cycle(&out_beside(&opts.out, "save-map"), &boot)?;
            also_dirs.push((BOOT_RUN.to_owned(), boot));
            let replay = ReplayOptions {
                dataset: opts.dataset.clone(),
                calibration: calibration_for(&opts.dataset),
                max_frames: opts.frames,
                frames: None,
                out: opts.out.clone(),
                qemu_args: Vec::new(),
                maps: Default::default(),
                // On 7-Scenes the board also receives anchor commands (their cost is in the
                // figures; the anchors are checked against the host's).
                anchors: (opts.dataset == root.join(SEVEN_SCENES))
                    .then(|| root.join(board_runs::BOARD_ANCHORS)),
            };
            replay::run(root, &replay)?;
            opts.out.clone()
        }
    };
    let elf = firmware::elf_path(root, "qemu-mps2");
    let bytes = fs::read(&elf).with_context(|| format!("reading {}", elf.display()))?;
    let elf_hash = format!("{:016x}", fnv1a64(&bytes));
    let read_run = |dir: &Path| -> Result<FirmwareRun> {
        let cost_json = dir.join("cost.json");
        let run = FirmwareRun::read(&cost_json)?;
        if run.elf_fnv1a64 != elf_hash {
            bail!(
                "{} is from another build of qemu-mps2 than {}: run firmware-replay again (or \
                 budgets without --from)",
                cost_json.display(),
                elf.display()
            );
        }
        if run.frames.len() < MIN_FRAMES {
            bail!(
                "{}: {} frames, the budgets need at least {MIN_FRAMES}",
                cost_json.display(),
                run.frames.len()
            );
        }
        Ok(run)
    };
    let cost_json = dir.join("cost.json");
    let run = read_run(&dir)?;
    let also = also_dirs
        .iter()
        .map(|(name, dir)| Ok((name.clone(), read_run(dir)?)))
        .collect::<Result<Vec<_>>>()?;
    let mut boots = Vec::new();
    for (name, dir) in &also_dirs {
        if let Some(boot) = BootCost::read(dir)? {
            boots.push((name.clone(), boot));
        }
    }
    let binaries = BINARIES.iter().map(|b| Binary::read(root, b)).collect::<Result<Vec<_>>>()?;
    let mut m = Measurements {
        run,
        cost_json,
        also,
        boots,
        binaries,
        structures: ferroslam_tests::structures::core_structures(),
        figures: Vec::new(),
    };
    m.figures = figures(&m);
    Ok(m)
}

/// Where `budgets` without `--from` replays another run: `<out>-<what>`.
fn out_beside(out: &Path, what: &str) -> PathBuf {
    let mut name = out.file_name().unwrap_or_default().to_os_string();
    name.push("-");
    name.push(what);
    out.with_file_name(name)
}

/// Every figure of both profiles, by JSON key.
fn figures(m: &Measurements) -> Vec<(String, Option<u64>)> {
    let largest = |f: fn(&Binary) -> u64| m.binaries.iter().map(f).max();
    let static_ram = largest(|b| b.static_ram);
    let stack = u64::from(m.run.status.stack_peak_bytes);
    let q: [(&str, Option<u64>); 11] = [
        ("static_ram_bytes", static_ram),
        ("stack_peak_bytes", Some(stack)),
        ("ram_total_bytes", static_ram.map(|r| r + stack)),
        ("flash_bytes", largest(|b| b.flash)),
        (
            "frame_buffers_bytes",
            Some(m.size_of("config::QvgaGrayBuffer") + m.size_of("config::QvgaDepthBuffer")),
        ),
        ("pipeline_state_bytes", Some(u64::from(m.run.status.state_bytes))),
        ("slam_state_bytes", Some(m.size_of("system::QvgaSlam"))),
        ("ba_workspace_bytes", Some(m.size_of("backend::BoardBundleAdjuster"))),
        ("ref_board_stack_room_bytes", m.ref_board_stack_room()),
        ("frames", Some(m.run.frames.len() as u64)),
        ("keyframes", Some(m.run.keyframe_count() as u64)),
    ];
    let mut insn = per_frame_figures("qvga", &m.run);
    for (name, run) in &m.also {
        insn.extend(per_frame_figures(name, run));
        let stack = u64::from(run.status.stack_peak_bytes);
        insn.push((format!("{name}.stack_peak_bytes"), Some(stack)));
        insn.push((format!("{name}.ram_total_bytes"), static_ram.map(|r| r + stack)));
        insn.push((format!("{name}.frames"), Some(run.frames.len() as u64)));
        insn.push((format!("{name}.keyframes"), Some(run.keyframe_count() as u64)));
        if let Some((_, boot)) = m.boots.iter().find(|(n, _)| n == name) {
            let first = boot.first_relocalized.map(|i| i as u64 + 1);
            insn.push((format!("{name}.store_mount_insn"), Some(boot.mount)));
            insn.push((format!("{name}.frames_to_first_pose"), first));
            insn.push((format!("{name}.insn_to_first_pose"), boot.insn_to_first_pose(run)));
        }
    }
    let vga_known = [
        (
            "frame_buffers_bytes",
            m.size_of("config::VgaGrayBuffer") + m.size_of("config::VgaDepthBuffer"),
        ),
        ("slam_state_bytes", m.size_of("system::VgaSlam")),
        ("frontend_state_bytes", m.size_of("tracking::VgaFrontend")),
        ("ba_workspace_bytes", m.size_of("backend::BoardBundleAdjuster")),
    ];
    let vga_firmware = [
        "static_ram_bytes",
        "stack_peak_bytes",
        "ram_total_bytes",
        "flash_bytes",
        "insn_per_frame_median",
        "insn_per_frame_p99",
        "insn_per_frame_max",
        "frontend_insn_per_frame_median",
        "frontend_insn_per_frame_p99",
        "frontend_insn_per_frame_max",
        "backend_step_insn_per_frame_median",
        "backend_step_insn_per_frame_p99",
        "backend_step_insn_per_frame_max",
    ];
    q.iter()
        .map(|(k, v)| (format!("qvga.{k}"), *v))
        .chain(insn)
        .chain(vga_known.iter().map(|(k, v)| (format!("vga.{k}"), Some(*v))))
        .chain(vga_firmware.iter().map(|k| (format!("vga.{k}"), None)))
        .collect()
}

/// The instructions per frame of `run`'s stages, keyed `{name}.{stage figure}_{statistic}`; p99
/// is `None` below [`P99_MIN_FRAMES`] frames.
fn per_frame_figures(name: &str, run: &FirmwareRun) -> Vec<(String, Option<u64>)> {
    let mut out = Vec::new();
    let p99_says_something = run.frames.len() >= P99_MIN_FRAMES;
    for (stage, prefix) in [
        ("pipeline", "insn_per_frame"),
        ("frontend", "frontend_insn_per_frame"),
        ("backend_step", "backend_step_insn_per_frame"),
        ("acquire", "acquire_insn_per_frame"),
    ] {
        let s = run.stats(stage);
        let p99 = p99_says_something.then_some(s.p99);
        for (statistic, v) in [("median", Some(s.median)), ("p99", p99), ("max", Some(s.max))] {
            out.push((format!("{name}.{prefix}_{statistic}"), v));
        }
    }
    out
}

/// The runs `budgets` name (the part of their keys before the first `.`) that `m` does not have.
fn runs_not_given(budgets: &[Budget], m: &Measurements) -> Vec<String> {
    let mut missing: Vec<String> = Vec::new();
    for b in budgets {
        let run = run_of(&b.key);
        let given = PROFILE_RUNS.contains(&run) || m.also.iter().any(|(n, _)| n == run);
        if !given && !missing.iter().any(|r| r == run) {
            missing.push(run.to_owned());
        }
    }
    missing
}

/// Pairs every budget of a run `m` has with its figure.
fn check(budgets: &[Budget], m: &Measurements, missing: &[String]) -> Result<Vec<Check>> {
    budgets
        .iter()
        .filter(|b| !missing.iter().any(|r| r == run_of(&b.key)))
        .map(|b| {
            let measured = m.figure(&b.key).ok_or_else(|| {
                anyhow!("memory-budget.md budgets `{}`, which is not a measured figure", b.key)
            })?;
            Ok(Check { budget: b.clone(), measured })
        })
        .collect()
}

/// Measures, checks, prints, writes what was asked; fails as the module documentation says.
///
/// # Errors
/// A build, QEMU or file failure; a bad budget block; a figure over its limit.
pub fn run_with(root: &Path, opts: &Options) -> Result<()> {
    let doc_path = root.join("memory-budget.md");
    let doc =
        fs::read_to_string(&doc_path).with_context(|| format!("reading {}", doc_path.display()))?;
    let budgets = budget_doc::parse_block(&doc)?;
    let m = measure(root, opts)?;
    let missing = runs_not_given(&budgets, &m);
    if opts.write && !missing.is_empty() {
        bail!(
            "--write needs every run memory-budget.md budgets; not given: {}",
            missing.join(", ")
        );
    }
    let checks = check(&budgets, &m, &missing)?;
    print_report(&m, &checks, opts.strict);
    for run in &missing {
        println!(
            "not checked: the budgets of `{run}.*` (give its firmware-replay folder with --also \
             {run}=DIR; `budgets` without --from makes it)"
        );
    }
    if let Some(path) = &opts.json {
        let report = json_report(&m, &checks, opts.strict);
        fs::write(path, serde_json::to_string_pretty(&report)? + "\n")
            .with_context(|| format!("writing {}", path.display()))?;
        println!("JSON: {}", path.display());
    }
    let rendered = if missing.is_empty() {
        crate::budget_tables::render(&doc, &m, &checks)?
    } else {
        doc.clone()
    };
    if opts.write {
        if rendered == doc {
            println!("memory-budget.md: already up to date");
        } else {
            fs::write(&doc_path, &rendered)
                .with_context(|| format!("writing {}", doc_path.display()))?;
            println!("memory-budget.md: figures regenerated");
        }
    } else if rendered != doc {
        println!(
            "note: memory-budget.md states other figures than these: `cargo xtask budgets --write` \
             regenerates them"
        );
    }
    let failed: Vec<&Check> = checks.iter().filter(|c| c.fails(opts.strict)).collect();
    let room = m.ref_board_stack_room().unwrap_or(0);
    let stack = u64::from(m.run.status.stack_peak_bytes);
    if stack > room {
        bail!(
            "ref-board: the peak stack ({stack} B) does not fit the {room} B of DTCM left by its statics"
        );
    }
    if !failed.is_empty() {
        let list: Vec<String> = failed
            .iter()
            .map(|c| {
                let which =
                    if c.budget.ceiling.is_some() && !opts.strict { "ceiling" } else { "bar" };
                format!(
                    "{} = {} is over its {which} of {}",
                    c.budget.key,
                    show(&c.budget.key, c.measured),
                    show(&c.budget.key, c.limit(opts.strict))
                )
            })
            .collect();
        bail!("budgets exceeded: {}", list.join("; "));
    }
    Ok(())
}

/// The table of checks and the other figures, to stdout.
fn print_report(m: &Measurements, checks: &[Check], strict: bool) {
    let dataset = Path::new(&m.run.dataset)
        .file_name()
        .map_or_else(|| m.run.dataset.clone(), |n| n.to_string_lossy().into_owned());
    println!(
        "\nbudgets, QVGA reference board: {} frames of {dataset} ({} keyframes) on QEMU's \
         Cortex-M4F (mps2-an386, -icount shift=0), run {}",
        m.run.frames.len(),
        m.run.keyframe_count(),
        m.cost_json.display()
    );
    let mut rows =
        vec![["figure", "bar", "ceiling", "measured", "status", "check"].map(String::from)];
    for c in checks {
        let k = &c.budget.key;
        let verdict = if c.fails(strict) {
            format!(
                "FAIL (over the {})",
                if c.budget.ceiling.is_some() && !strict { "ceiling" } else { "bar" }
            )
        } else {
            "ok".to_owned()
        };
        rows.push([
            c.budget.what.clone(),
            show(k, c.budget.bar),
            c.budget.ceiling.map_or_else(|| "-".to_owned(), |v| show(k, v)),
            show(k, c.measured),
            c.status(),
            verdict,
        ]);
    }
    print_rows(&rows);
    let not_met: Vec<&str> =
        checks.iter().filter(|c| !c.met()).map(|c| c.budget.key.as_str()).collect();
    if not_met.is_empty() {
        println!("every bar is met");
    } else {
        println!(
            "{} of {} bars NOT MET: {}{}",
            not_met.len(),
            checks.len(),
            not_met.join(", "),
            if strict { " (--strict: each fails the run)" } else { " (held to their ceilings)" }
        );
    }
    for c in checks.iter().filter(|c| c.met() && c.budget.ceiling.is_some()) {
        println!("{}: the bar is met now, its ceiling can go", c.budget.key);
    }
    println!("\nother figures (no budget):");
    let mut rows = vec![["figure".to_owned(), "measured".to_owned()]];
    let mut unmeasured = Vec::new();
    for (k, v) in &m.figures {
        if checks.iter().any(|c| &c.budget.key == k) {
            continue;
        }
        match v {
            Some(v) => rows.push([k.clone(), show(k, *v)]),
            None => unmeasured.push(k.as_str()),
        }
    }
    for b in &m.binaries {
        rows.push([format!("{}: flash", b.name), show("bytes", b.flash)]);
        rows.push([format!("{}: static RAM", b.name), show("bytes", b.static_ram)]);
    }
    print_rows(&rows);
    if !unmeasured.is_empty() {
        println!(
            "{} firmware figures of vga are null (`vga.runs = false`): {VGA_DOES_NOT_RUN}",
            unmeasured.len()
        );
    }
}

/// Left-aligned columns, two spaces apart.
fn print_rows<const N: usize>(rows: &[[String; N]]) {
    let widths: Vec<usize> =
        (0..N).map(|i| rows.iter().map(|r| r[i].chars().count()).max().unwrap_or(0)).collect();
    for r in rows {
        let cells: Vec<String> = r.iter().zip(&widths).map(|(c, w)| format!("{c:w$}")).collect();
        println!("{}", cells.join("  ").trim_end());
    }
}

/// The `--json` document.
fn json_report(m: &Measurements, checks: &[Check], strict: bool) -> Value {
    let mut root = Map::new();
    for (key, value) in &m.figures {
        let Some((profile, figure)) = key.split_once('.') else { continue };
        let entry = root.entry(profile).or_insert_with(|| Value::Object(Map::new()));
        if let Value::Object(p) = entry {
            p.insert(figure.to_owned(), value.map_or(Value::Null, Value::from));
        }
    }
    if let Some(Value::Object(q)) = root.get_mut("qvga") {
        q.insert("runs".into(), Value::Bool(true));
        let stages: Map<String, Value> = m
            .run
            .stage_stats()
            .into_iter()
            .map(|((k, _, _), s)| (k.to_owned(), s.to_json()))
            .collect();
        q.insert("insn_per_frame_stages".into(), Value::Object(stages));
        let binaries: Map<String, Value> = m
            .binaries
            .iter()
            .map(|b| {
                let sections: Map<String, Value> =
                    b.sections.iter().map(|(n, s)| (n.clone(), Value::from(*s))).collect();
                let v = json!({"flash_bytes": b.flash, "static_ram_bytes": b.static_ram, "sections": sections});
                (b.name.to_owned(), v)
            })
            .collect();
        q.insert("binaries".into(), Value::Object(binaries));
    }
    if let Some(Value::Object(v)) = root.get_mut("vga") {
        v.insert("runs".into(), Value::Bool(false));
        v.insert("reason".into(), Value::from(VGA_DOES_NOT_RUN));
    }
    let checks_json: Vec<Value> = checks
        .iter()
        .map(|c| {
            json!({
                "figure": c.budget.key, "what": c.budget.what, "bar": c.budget.bar,
                "ceiling": c.budget.ceiling, "reason": c.budget.reason, "measured": c.measured,
                "met": c.met(), "times_bar": c.times_bar(), "status": c.status(),
                "fails": c.fails(strict),
            })
        })
        .collect();
    root.insert("checks".into(), Value::Array(checks_json));
    root.insert("strict".into(), Value::Bool(strict));
    root.insert("passed".into(), Value::Bool(!checks.iter().any(|c| c.fails(strict))));
    let s = &m.run;
    root.insert(
        "source".into(),
        json!({
            "dataset": s.dataset, "frames": s.frames.len(), "cost_json": m.cost_json.display().to_string(),
            "elf_fnv1a64": s.elf_fnv1a64,
            "unit": "instructions (QEMU mps2-an386, -icount shift=0: SysTick ticks x 40); \
                     insn_per_frame = front end + back-end step, acquire excluded",
            "sizes": "bytes; *_state_bytes and ba_workspace_bytes: size_of on the 64-bit host, \
                      except pipeline_state_bytes (size_of on the board, from its status)",
        }),
    );
    Value::Object(root)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    #[test]
    fn arguments() {
        let root = Path::new("/r");
        let args: Vec<String> =
            ["--from", "d", "--json", "b.json", "--write", "--strict", "--frames", "300"]
                .map(String::from)
                .into();
        let o = Options::parse(&args, root).unwrap();
        assert_eq!(o.from, Some(PathBuf::from("d")));
        assert_eq!(o.json, Some(PathBuf::from("b.json")));
        assert!(o.write && o.strict);
        assert_eq!(o.frames, 300);
        let d = Options::parse(&[], root).unwrap();
        assert_eq!((d.frames, d.from, d.write, d.strict), (1000, None, false, false));
        assert!(Options::parse(&["--frames".into(), "29".into()], root).is_err());
        let also = |v: &str| Options::parse(&["--also".into(), v.into()], root);
        assert_eq!(also("fast_demo=out/fd").unwrap().also, [("fast_demo".into(), "out/fd".into())]);
        for bad in ["fast_demo", "=d", "Fast=d", "qvga=d", "a.b=d", "x="] {
            assert!(also(bad).is_err(), "{bad}");
        }
        assert!(Options::parse(&["--frames".into()], root).is_err());
        assert!(Options::parse(&["--bogus".into()], root).is_err());
    }

    /// p99 is a figure from [`P99_MIN_FRAMES`] frames on; median and max always.
    #[test]
    fn p99_needs_enough_frames() {
        let run = |n: u64| crate::cost::FirmwareRun {
            dataset: "data".into(),
            elf: "fw.elf".into(),
            elf_fnv1a64: String::new(),
            status: ferroslam_core::wire::StatusMessage::default(),
            frames: (0..n)
                .map(|i| crate::cost::FrameCost {
                    frame_index: i as u32,
                    keyframe: false,
                    work: None,
                    acquire: 0,
                    frontend: 1_000 * (i + 1),
                    backend_step: 0,
                    report: 0,
                })
                .collect(),
        };
        let get = |figures: &[(String, Option<u64>)], k: &str| {
            figures.iter().find(|(key, _)| key == k).and_then(|(_, v)| *v)
        };
        let few = per_frame_figures("x", &run(MIN_FRAMES as u64));
        assert_eq!(get(&few, "x.insn_per_frame_max"), Some(1_000 * MIN_FRAMES as u64));
        assert!(get(&few, "x.insn_per_frame_median").is_some());
        assert_eq!(get(&few, "x.insn_per_frame_p99"), None);
        let many = per_frame_figures("x", &run(P99_MIN_FRAMES as u64));
        assert_eq!(get(&many, "x.insn_per_frame_p99"), Some(99_000));
    }
}
