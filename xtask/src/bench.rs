//! `cargo xtask bench-frontend`: what the odometry front end costs per frame, in total and per
//! stage, in instructions counted by callgrind.
//!
//! What it measures: each call of `Frontend::process` (one per frame) made by
//! `ferroslam-sim replay` on a real recording, inclusive of everything `process` calls. The unit is
//! host x86_64 instructions executed (callgrind's `Ir` event) by the release build: not time, and
//! not the Cortex-M's count, but deterministic for the same binary and input, so a change in the
//! numbers is a change in the code. Decoding, downsampling and the reader threads are not counted.
//!
//! How: `cargo build --release -p ferroslam-sim` (the release profile keeps line tables,
//! `debug = 1`, which callgrind needs for names), then, from the workspace root:
//!
//! ```text
//! valgrind --tool=callgrind \
//!     --callgrind-out-file=target/bench-frontend/callgrind/callgrind.out.%p \
//!     --toggle-collect='ferroslam_core::tracking::frontend::Frontend<*>::process' \
//!     --dump-after='*::tracking::frontend::Frontend<*>::process' \
//!     target/release/ferroslam-sim replay DATASET --out target/bench-frontend/replay \
//!     --max-frames N --mode odometry
//! ```
//!
//! Collection is on only inside `process` (callgrind keeps that state per thread, so the decoder
//! threads count nothing), and callgrind writes one dump per call: `callgrind.out.PID.1` to `.N`,
//! in frame order. The dump at exit (`callgrind.out.PID`, no suffix) holds nothing and is ignored.
//! The two options name `process` with two different patterns on purpose: given the very same
//! pattern, callgrind 3.19 ignores `--dump-after` and writes no per-frame dump.
//!
//! Each dump is read in callgrind's own format (no `callgrind_annotate`): a frame's total is the
//! dump's `totals:` line; a stage's cost is as defined at [`STAGES`].
//!
//! Statistics over the frames: median, p90 and p99 by nearest rank (the p-th percentile of n
//! sorted values is the value of rank `ceil(p * n / 100)`, counting from 1, so the median of an
//! even count is the lower middle value), the max and the arithmetic mean.
//!
//! Everything it writes goes to `target/bench-frontend/` (emptied at the start of each run):
//! `callgrind/` (the dumps, for `callgrind_annotate` or KCachegrind) and `replay/` (the replay's
//! output, `report.json` included).

use std::collections::{HashMap, HashSet};
use std::fs;
use std::io::ErrorKind;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use serde_json::{Value, json};

use crate::paths::{SEVEN_SCENES, root};
use crate::stats::{Stats, thousands};

/// The front end's stages: `(name, pattern)`, in print order. This table is the one place to
/// edit when front-end functions are renamed, added or split.
///
/// A pattern is one or more alternatives separated by `|`. An alternative is a glob (`*` matches
/// any run of characters, `::` included) that must match the *end* of a function's demangled
/// name, starting at the beginning of the name or right after `::`, `<` or a space: so
/// `ransac::track_pose` matches `ferroslam_core::pose::ransac::track_pose` but not
/// `...::retrack_pose` nor `...::track_pose_fast`. Generic parameters demangle as `<_,_>`; write
/// `Frontend<*>::process`.
///
/// A stage's cost in a frame is the inclusive cost of the *set* of functions its pattern matches,
/// counted once: their own instructions plus their calls to functions outside the set. So a
/// pattern matching both a function and one it calls (nesting, recursion, several instances of a
/// generic) does not count the callee twice. A stage matching nothing costs 0 (the run prints a
/// note). Stages are inclusive, not a partition: `keyframe` contains `detector`, `matching`
/// contains `track_patch`, `bank` and `guide_pose`, and `pose` includes the guides' pose.
///
/// Only functions that exist in the binary can be seen: an inlined function's instructions belong
/// to its caller, and where a function is inlined its out-of-line callees stand in beside it (a
/// pattern keeps the inlined name, which takes over once it is out of line again). The run prints a
/// note for a stage that matched nothing.
const STAGES: &[(&str, &str)] = &[
    (
        "detector",
        "HessianDetector<*>::detect|features::filter::Taps::derivatives\
         |features::hessian::candidate|features::bucket::GridBuckets::*",
    ),
    ("keyframe", "Frontend<*>::make_keyframe"),
    ("matching", "Frontend<*>::match_landmarks"),
    ("track_patch", "matching::patch_tracker::track_patch"),
    ("bank", "matching::region::match_region"),
    ("guide_pose", "landmark_matching::guide_pose"),
    ("pose", "pose::ransac::track_pose"),
    (
        "small_image",
        "small_image_rotation::SmallImage::build|small_image_rotation::estimate_rotation",
    ),
];

/// The stage that tells frames which ran the detector (keyframe attempts) from tracking-only
/// frames; without a stage of that name the split is not printed.
const DETECTOR_STAGE: &str = "detector";

/// `--toggle-collect`: `Frontend::process`, every instance.
const PROCESS_TOGGLE: &str = "ferroslam_core::tracking::frontend::Frontend<*>::process";

/// `--dump-after`: the same function, spelled differently on purpose (see the module docs).
const PROCESS_DUMP: &str = "*::tracking::frontend::Frontend<*>::process";

/// Frames measured without `--frames`.
const DEFAULT_FRAMES: usize = 200;

const USAGE: &str =
    "cargo xtask bench-frontend [--dataset DIR] [--frames N] [--json FILE] [--max-median INSN]";

/// The command line.
#[derive(Debug)]
struct Options {
    /// TUM-layout recording; default 7-Scenes in `shared/datasets`.
    dataset: PathBuf,
    /// Frames to replay (the earliest).
    frames: usize,
    /// Where to write the figures as JSON.
    json: Option<PathBuf>,
    /// Fail when the median total per frame is above this many instructions.
    max_median: Option<u64>,
}

/// Runs `bench-frontend` with its arguments (after the subcommand).
///
/// # Errors
/// Bad arguments, valgrind missing, a failed build or replay, unreadable dumps, or a median total
/// above `--max-median`.
pub fn run(args: &[String]) -> Result<()> {
    let mut opts = parse_args(args)?;
    opts.dataset = fs::canonicalize(&opts.dataset)
        .with_context(|| format!("dataset {} not found", opts.dataset.display()))?;
    require_valgrind()?;
    let root = root();
    let work = root.join("target").join("bench-frontend");
    if work.exists() {
        fs::remove_dir_all(&work).with_context(|| format!("emptying {}", work.display()))?;
    }
    let (dump_dir, replay_dir) = (work.join("callgrind"), work.join("replay"));
    fs::create_dir_all(&dump_dir).with_context(|| format!("creating {}", dump_dir.display()))?;

    let cargo = env!("CARGO");
    let build = ["build", "--release", "-p", "ferroslam-sim"];
    eprintln!("$ cargo {}", build.join(" "));
    let status = Command::new(cargo).args(build).current_dir(&root).status()?;
    if !status.success() {
        bail!("`cargo {}` failed with {status}", build.join(" "));
    }
    run_callgrind(&root, &opts, &dump_dir, &replay_dir)?;

    let dumps = dump_files(&dump_dir)?;
    if dumps.is_empty() {
        bail!(
            "callgrind wrote no per-frame dump in {}: no call matched \
             --dump-after='{PROCESS_DUMP}' (renamed or inlined?)",
            dump_dir.display()
        );
    }
    let frames = dumps
        .iter()
        .map(|path| Profile::read(path).map(|p| FrameCost::of(&p)))
        .collect::<Result<Vec<_>>>()?;
    let report = read_report(&replay_dir)?;
    if let Some(n) = report.as_ref().and_then(|r| r["frames"].as_u64())
        && n != frames.len() as u64
    {
        bail!("the replay processed {n} frames but callgrind wrote {} dumps", frames.len());
    }
    if frames.len() < opts.frames {
        eprintln!(
            "note: the dataset gave {} frames of the {} asked for",
            frames.len(),
            opts.frames
        );
    }

    let summary = Summary::of(&frames);
    print_summary(&opts, &summary, &frames, report.as_ref());
    if let Some(path) = &opts.json {
        let text = serde_json::to_string_pretty(&to_json(&opts, &summary, &frames))?;
        fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    if let Some(max) = opts.max_median {
        let median = summary.total.median;
        if median > max {
            bail!(
                "front-end cost over budget: median {} instructions per frame > --max-median {}",
                thousands(median),
                thousands(max)
            );
        }
        println!("median {} <= --max-median {}: ok", thousands(median), thousands(max));
    }
    Ok(())
}

fn parse_args(args: &[String]) -> Result<Options> {
    let mut opts = Options {
        dataset: root().join(SEVEN_SCENES),
        frames: DEFAULT_FRAMES,
        json: None,
        max_median: None,
    };
    let mut it = args.iter();
    while let Some(flag) = it.next() {
        let mut value = || it.next().with_context(|| format!("{flag} needs a value; {USAGE}"));
        match flag.as_str() {
            "--dataset" => opts.dataset = std::path::absolute(value()?)?,
            "--json" => opts.json = Some(PathBuf::from(value()?)),
            "--frames" => {
                let v = value()?;
                opts.frames = usize::try_from(parse_count(v)?)?;
                if opts.frames == 0 {
                    bail!("--frames must be at least 1");
                }
            }
            "--max-median" => opts.max_median = Some(parse_count(value()?)?),
            "-h" | "--help" => bail!("usage: {USAGE}"),
            _ => bail!("unknown argument {flag:?}; usage: {USAGE}"),
        }
    }
    Ok(opts)
}

/// A count such as `200`, `15000000`, `15_000_000` or `15,000,000`.
fn parse_count(text: &str) -> Result<u64> {
    let digits: String = text.chars().filter(|&c| c != '_' && c != ',').collect();
    digits.parse().with_context(|| format!("{text:?} is not a count"))
}

fn require_valgrind() -> Result<()> {
    match Command::new("valgrind").arg("--version").output() {
        Ok(out) if out.status.success() => Ok(()),
        Ok(out) => bail!("`valgrind --version` failed with {}", out.status),
        Err(e) if e.kind() == ErrorKind::NotFound => bail!(
            "valgrind not found on PATH: bench-frontend counts instructions with valgrind's \
             callgrind (apt-get install valgrind)"
        ),
        Err(e) => Err(e).context("could not run valgrind"),
    }
}

/// The replay under callgrind, from the workspace root; see the module docs for the command.
fn run_callgrind(root: &Path, opts: &Options, dump_dir: &Path, replay_dir: &Path) -> Result<()> {
    let rel = |p: &Path| p.strip_prefix(root).unwrap_or(p).display().to_string();
    let mut args = vec![
        "--tool=callgrind".to_owned(),
        format!("--callgrind-out-file={}/callgrind.out.%p", rel(dump_dir)),
        format!("--toggle-collect={PROCESS_TOGGLE}"),
        format!("--dump-after={PROCESS_DUMP}"),
        "target/release/ferroslam-sim".to_owned(),
        "replay".to_owned(),
        opts.dataset.display().to_string(),
        "--out".to_owned(),
        rel(replay_dir),
        "--max-frames".to_owned(),
        opts.frames.to_string(),
        // The default today; explicit so the benchmark keeps measuring the front end.
        "--mode".to_owned(),
        "odometry".to_owned(),
    ];
    if let Some(c) = crate::paths::calibration_for(&opts.dataset) {
        // The registered calibration of 7-Scenes, as CI replays it.
        args.extend(["--calibration".to_owned(), c.display().to_string()]);
    }
    eprintln!("$ valgrind {}", args.iter().map(|a| shell_quote(a)).collect::<Vec<_>>().join(" "));
    let start = Instant::now();
    let status = Command::new("valgrind").args(&args).current_dir(root).status();
    let status = status.context("could not start valgrind")?;
    if !status.success() {
        bail!("the replay under callgrind failed with {status}");
    }
    eprintln!("callgrind run: {:.0} s", start.elapsed().as_secs_f64());
    Ok(())
}

/// `arg` as a shell would need it, for printing a command that can be pasted.
fn shell_quote(arg: &str) -> String {
    if arg.contains(['*', '<', '>', ' ', '\'', '&', '(', ')']) {
        format!("'{}'", arg.replace('\'', r"'\''"))
    } else {
        arg.to_owned()
    }
}

/// The per-call dumps `callgrind.out.PID.K` in `dir`, by `K` (frame order); the final dump
/// `callgrind.out.PID` (no `K`) is left out.
fn dump_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut dumps = Vec::new();
    let mut pids = HashSet::new();
    for entry in fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
        let path = entry?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        let Some(rest) = name.strip_prefix("callgrind.out.") else { continue };
        let Some((pid, part)) = rest.split_once('.') else { continue };
        if let (Ok(pid), Ok(part)) = (pid.parse::<u32>(), part.parse::<u32>()) {
            pids.insert(pid);
            dumps.push((part, path));
        }
    }
    if pids.len() > 1 {
        bail!("dumps of {} processes in {}; expected one", pids.len(), dir.display());
    }
    dumps.sort();
    Ok(dumps.into_iter().map(|(_, path)| path).collect())
}

/// The replay's `report.json`, when it wrote one.
fn read_report(replay_dir: &Path) -> Result<Option<Value>> {
    let path = replay_dir.join("report.json");
    match fs::read_to_string(&path) {
        Ok(text) => {
            Ok(Some(serde_json::from_str(&text).with_context(|| path.display().to_string())?))
        }
        Err(e) if e.kind() == ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e).with_context(|| format!("reading {}", path.display())),
    }
}

/// One function's costs in a dump, in instructions.
#[derive(Debug, Default)]
struct FnCost {
    /// Executed in the function itself (inlined code included).
    self_ir: u64,
    /// Inclusive cost of its calls, by callee name.
    calls: HashMap<String, u64>,
}

/// One callgrind dump: its total and the costs of each function, by demangled name (functions
/// of the same name, e.g. the instances of a generic, are one).
#[derive(Debug, Default)]
struct Profile {
    total: u64,
    functions: HashMap<String, FnCost>,
}

impl Profile {
    fn read(path: &Path) -> Result<Self> {
        let text =
            fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        Self::parse(&text).with_context(|| format!("parsing {}", path.display()))
    }

    /// Parses callgrind's profile format (name compression `(id) name` included); only the
    /// `Ir` event is kept.
    fn parse(text: &str) -> Result<Self> {
        let mut profile = Self::default();
        let mut names = HashMap::new();
        let (mut ir_col, mut positions) = (None, 1);
        let (mut current, mut callee) = (String::new(), None::<String>);
        let (mut call_cost_next, mut totals) = (false, None);
        for (i, line) in text.lines().enumerate() {
            let at = || format!("line {}", i + 1);
            if let Some(v) = line.strip_prefix("events:") {
                ir_col = v.split_whitespace().position(|e| e == "Ir");
            } else if let Some(v) = line.strip_prefix("positions:") {
                positions = v.split_whitespace().count().max(1);
            } else if let Some(v) = line.strip_prefix("totals:").or(line.strip_prefix("summary:")) {
                let col = ir_col.context("no Ir in `events:`")?;
                totals = Some(event(v.split_whitespace(), col).with_context(at)?);
            } else if let Some(v) = line.strip_prefix("fn=") {
                current = resolve(&mut names, v).with_context(at)?;
                callee = None;
            } else if let Some(v) = line.strip_prefix("cfn=") {
                callee = Some(resolve(&mut names, v).with_context(at)?);
            } else if line.starts_with("calls=") {
                call_cost_next = true;
            } else if line.starts_with(|c: char| c.is_ascii_digit() || "+-*".contains(c)) {
                let col = ir_col.context("cost line before `events:` or no Ir event")?;
                let ir = event(line.split_whitespace().skip(positions), col).with_context(at)?;
                let f = profile.functions.entry(current.clone()).or_default();
                if call_cost_next {
                    let to = callee.clone().unwrap_or_else(|| current.clone());
                    *f.calls.entry(to).or_default() += ir;
                    call_cost_next = false;
                } else {
                    f.self_ir += ir;
                }
            }
        }
        // Without a totals line, everything counted is the sum of the functions' own costs.
        profile.total =
            totals.unwrap_or_else(|| profile.functions.values().map(|f| f.self_ir).sum());
        Ok(profile)
    }

    /// The inclusive cost of the functions matching `pattern` (see [`STAGES`]), each instruction
    /// counted once; 0 when nothing matches.
    fn inclusive(&self, pattern: &str) -> u64 {
        let matched: HashSet<&str> = self
            .functions
            .keys()
            .map(String::as_str)
            .filter(|n| pattern_matches(pattern, n))
            .collect();
        let outside =
            |(callee, ir): (&String, &u64)| (!matched.contains(callee.as_str())).then_some(*ir);
        self.functions
            .iter()
            .filter(|(name, _)| matched.contains(name.as_str()))
            .map(|(_, f)| f.self_ir + f.calls.iter().filter_map(outside).sum::<u64>())
            .sum()
    }
}

/// Column `col` of the event counts in `values` (a missing trailing count is 0).
fn event<'a>(mut values: impl Iterator<Item = &'a str>, col: usize) -> Result<u64> {
    values.nth(col).map_or(Ok(0), |v| v.parse().with_context(|| format!("bad count {v:?}")))
}

/// A compressed name `(id) name` (defines `id`), `(id)` (uses it) or a plain `name`.
fn resolve(names: &mut HashMap<u64, String>, spec: &str) -> Result<String> {
    let spec = spec.trim();
    let Some(rest) = spec.strip_prefix('(') else { return Ok(spec.to_owned()) };
    let (id, name) = rest.split_once(')').with_context(|| format!("bad name {spec:?}"))?;
    let id: u64 = id.parse().with_context(|| format!("bad name id in {spec:?}"))?;
    let name = name.trim();
    if name.is_empty() {
        names.get(&id).cloned().with_context(|| format!("name ({id}) used before it is defined"))
    } else {
        names.insert(id, name.to_owned());
        Ok(name.to_owned())
    }
}

/// Whether a stage pattern (see [`STAGES`]) matches the demangled function `name`.
fn pattern_matches(pattern: &str, name: &str) -> bool {
    let starts = name
        .char_indices()
        .filter(|&(i, _)| i == 0 || name[..i].ends_with("::") || name[..i].ends_with(['<', ' ']));
    let starts: Vec<usize> = starts.map(|(i, _)| i).collect();
    pattern
        .split('|')
        .map(str::trim)
        .filter(|alt| !alt.is_empty())
        .any(|alt| starts.iter().any(|&i| glob(alt.as_bytes(), &name.as_bytes()[i..])))
}

/// Whether `text` matches `pattern` entirely, `*` matching any run of bytes.
fn glob(pattern: &[u8], text: &[u8]) -> bool {
    let (mut p, mut t) = (0, 0);
    // The last star seen and the text position it is currently made to end at.
    let mut star = None;
    while t < text.len() {
        match pattern.get(p) {
            Some(b'*') => {
                star = Some((p, t));
                p += 1;
            }
            Some(&c) if Some(&c) == text.get(t) => (p, t) = (p + 1, t + 1),
            _ => match star {
                Some((sp, st)) => {
                    star = Some((sp, st + 1));
                    (p, t) = (sp + 1, st + 1);
                }
                None => return false,
            },
        }
    }
    pattern.get(p..).is_some_and(|rest| rest.iter().all(|&c| c == b'*'))
}

/// One frame's costs, instructions.
#[derive(Debug, Clone)]
struct FrameCost {
    total: u64,
    /// By [`STAGES`] index.
    stages: Vec<u64>,
}

impl FrameCost {
    fn of(profile: &Profile) -> Self {
        let stages = STAGES.iter().map(|(_, pattern)| profile.inclusive(pattern)).collect();
        Self { total: profile.total, stages }
    }
}

/// The statistics of a run.
#[derive(Debug)]
struct Summary {
    total: Stats,
    /// By [`STAGES`] index.
    stages: Vec<Stats>,
}

impl Summary {
    fn of(frames: &[FrameCost]) -> Self {
        let column = |i: usize| -> Vec<u64> {
            frames.iter().map(|f| f.stages.get(i).copied().unwrap_or(0)).collect()
        };
        Self {
            total: Stats::of(&frames.iter().map(|f| f.total).collect::<Vec<_>>()),
            stages: (0..STAGES.len()).map(|i| Stats::of(&column(i))).collect(),
        }
    }
}

fn print_summary(opts: &Options, summary: &Summary, frames: &[FrameCost], report: Option<&Value>) {
    println!(
        "front end, instructions per frame over {} frames of {}\n(host x86_64 instructions, \
         release build, callgrind Ir; stages inclusive and nested)",
        frames.len(),
        opts.dataset.display()
    );
    let rows: Vec<(&str, Stats)> = std::iter::once(("total", summary.total))
        .chain(STAGES.iter().map(|(name, _)| *name).zip(summary.stages.iter().copied()))
        .collect();
    let cells = |s: &Stats| [s.median, s.p90, s.p99, s.max, s.mean.round() as u64].map(thousands);
    let name_w = rows.iter().map(|(n, _)| n.len()).max().unwrap_or(0);
    let num_w = rows.iter().flat_map(|(_, s)| cells(s)).map(|c| c.len()).max().unwrap_or(0);
    let header = ["median", "p90", "p99", "max", "mean"].map(|h| format!("{h:>num_w$}"));
    println!("{:name_w$}  {}", "stage", header.join("  "));
    for (name, stats) in &rows {
        let row = cells(stats).map(|c| format!("{c:>num_w$}"));
        println!("{name:name_w$}  {}", row.join("  "));
    }

    if let Some(d) = STAGES.iter().position(|(name, _)| *name == DETECTOR_STAGE) {
        let (detecting, tracking): (Vec<&FrameCost>, Vec<&FrameCost>) =
            frames.iter().partition(|f| f.stages.get(d).is_some_and(|&c| c > 0));
        let median = |group: &[&FrameCost]| {
            let totals: Vec<u64> = group.iter().map(|f| f.total).collect();
            if totals.is_empty() { "n/a".to_owned() } else { thousands(Stats::of(&totals).median) }
        };
        println!(
            "median total: {} on {} tracking-only frames ({DETECTOR_STAGE} 0), {} on {} frames \
             running the {DETECTOR_STAGE} (keyframe attempts)",
            median(&tracking),
            tracking.len(),
            median(&detecting),
            detecting.len()
        );
    }
    if let Some(r) = report {
        let n = |key: &str| r[key].as_u64().map_or("?".to_owned(), |v| v.to_string());
        println!(
            "replay report: {} frames, {} tracked, {} lost, {} keyframes made",
            n("frames"),
            n("tracked_frames"),
            n("lost_frames"),
            n("keyframes")
        );
    }
    for ((name, pattern), stats) in STAGES.iter().zip(&summary.stages) {
        if stats.max == 0 {
            println!(
                "note: stage {name} cost 0 in every frame: not called in these frames, or \
                 renamed or inlined? (pattern {pattern})"
            );
        }
    }
}

fn to_json(opts: &Options, summary: &Summary, frames: &[FrameCost]) -> Value {
    let stages: serde_json::Map<String, Value> = STAGES
        .iter()
        .zip(&summary.stages)
        .map(|((name, _), stats)| ((*name).to_owned(), stats.to_json()))
        .collect();
    let per_frame: Vec<Value> = frames
        .iter()
        .map(|f| {
            let mut m = serde_json::Map::new();
            m.insert("total".to_owned(), f.total.into());
            for ((name, _), cost) in STAGES.iter().zip(&f.stages) {
                m.insert((*name).to_owned(), (*cost).into());
            }
            Value::Object(m)
        })
        .collect();
    json!({
        "dataset": opts.dataset.display().to_string(),
        "frames": frames.len(),
        "unit": "host x86_64 instructions per frame (callgrind Ir), release build",
        "total": summary.total.to_json(),
        "stages": stages,
        "per_frame": per_frame,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patterns_match_name_ends_at_path_boundaries() {
        let process = "ferroslam_core::tracking::frontend::Frontend<_,_>::process";
        assert!(pattern_matches("Frontend<*>::process", process));
        assert!(pattern_matches(
            "ferroslam_core::tracking::frontend::Frontend<*>::process",
            process
        ));
        assert!(pattern_matches("*::process", process));
        assert!(!pattern_matches("Frontend<*>::proc", process));
        assert!(!pattern_matches("rontend<*>::process", process));
        let pose = "ferroslam_core::pose::ransac::track_pose";
        assert!(pattern_matches("ransac::track_pose", pose));
        assert!(pattern_matches("nothing|track_pose", pose));
        assert!(!pattern_matches("pose::track_pose", pose));
        assert!(!pattern_matches("ransac::track_pose", "x::ransac::retrack_pose"));
        assert!(pattern_matches(
            "GridBuckets::*",
            "ferroslam_core::features::bucket::GridBuckets::insert"
        ));
        assert!(!pattern_matches("Foo::bar", "<x::Foo::bar as y::Baz>::go"));
        assert!(pattern_matches("Baz>::go", "<x::Foo::bar as y::Baz>::go"));
        assert!(!pattern_matches("", "anything"));
    }

    #[test]
    fn glob_backtracks() {
        assert!(glob(b"a*b*c", b"aXbYbZc"));
        assert!(glob(b"*", b""));
        assert!(glob(b"a**", b"a"));
        assert!(!glob(b"a*b", b"aXbY"));
        assert!(!glob(b"abc", b"ab"));
    }

    /// outer (self 10) calls inner (60) and other (30); inner (self 40) calls leaf (20).
    const DUMP: &str = "\
# callgrind format
version: 1
positions: line
events: Ir
summary: 100

ob=(1) /bin/x
fl=(1) a.rs
fn=(1) m::outer
5 4
+1 6
cfn=(2) m::inner
calls=1 7
* 60
cfn=(3) m::other
calls=1 8
6 30

fn=(2)
7 40
cfn=(4) m::leaf
calls=1 9
8 20

fn=(4)
9 20
fn=(3)
fi=(2) b.rs
8 30

totals: 100
";

    #[test]
    fn parses_callgrind_format_and_counts_sets_once() -> Result<()> {
        let p = Profile::parse(DUMP)?;
        assert_eq!(p.total, 100);
        assert_eq!(p.inclusive("outer"), 100);
        assert_eq!(p.inclusive("inner"), 60);
        assert_eq!(p.inclusive("outer|inner"), 100);
        assert_eq!(p.inclusive("inner|leaf"), 60);
        assert_eq!(p.inclusive("leaf|other"), 50);
        assert_eq!(p.inclusive("missing"), 0);
        Ok(())
    }

    #[test]
    fn self_recursion_is_counted_once() -> Result<()> {
        let text = "events: Ir\nfn=(1) r\n1 5\ncfn=(1)\ncalls=1 1\n1 3\nfn=(1)\n1 3\n";
        let p = Profile::parse(text)?;
        assert_eq!(p.total, 8);
        assert_eq!(p.inclusive("r"), 8);
        Ok(())
    }

    #[test]
    fn undefined_name_is_an_error() {
        assert!(Profile::parse("events: Ir\nfn=(7)\n1 5\n").is_err());
    }

    #[test]
    fn arguments() -> Result<()> {
        let args: Vec<String> = ["--frames", "5", "--max-median", "15_000_000", "--json", "b.json"]
            .map(String::from)
            .into();
        let o = parse_args(&args)?;
        assert_eq!((o.frames, o.max_median), (5, Some(15_000_000)));
        assert_eq!(o.json, Some(PathBuf::from("b.json")));
        assert!(o.dataset.ends_with("7scenes-redkitchen-1000"));
        assert!(parse_args(&["--frames".to_owned()]).is_err());
        assert!(parse_args(&["--frames".to_owned(), "0".to_owned()]).is_err());
        assert!(parse_args(&["--bogus".to_owned()]).is_err());
        Ok(())
    }
}
