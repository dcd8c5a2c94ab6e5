//! `cargo xtask fuzz`: fuzz targets for every parser and decoder, under a deterministic mutation
//! fuzzer that runs on the pinned stable toolchain (no nightly, so no libFuzzer).
//!
//! ```text
//! cargo xtask fuzz [--seconds N | --iterations N] [--target NAME[,NAME...]] [--seed S]
//! cargo xtask fuzz --target NAME --replay FILE
//! cargo xtask fuzz --write-corpus
//! ```
//!
//! Each target ([`TARGETS`]) runs its seed corpus (`fuzz/corpus/<target>/`, valid inputs made by
//! `--write-corpus` from real data, see `fuzz/README.md`), then inputs made from it by seeded
//! mutations and purely random inputs ([`mutate`]), for N seconds (default 10) or, with
//! `--iterations`, a fixed count (CI's deterministic run; the `frames` target, whose inputs are
//! SLAM runs, gets [`FRAMES_ITERATION_DIVISOR`] times fewer). Each input runs in process under
//! `catch_unwind`: a panic, or a broken property of a target, is a failure: the input is saved to
//! `target/fuzz/failures/<target>-<n>.bin`, the replay command printed, and the run exits
//! non-zero after the other targets. A failure already reported in code the harness may not
//! change (the core) is a known issue ([`runner::KNOWN_ISSUES`]): counted and printed, not a
//! failure.
//!
//! Guidance without coverage instrumentation: an input whose outcome class (the error variant
//! that refused it, or what was accepted) the run has not seen yet joins the pool the mutator
//! draws from, so inputs that reached a deeper check are mutated further. Per target the run
//! prints inputs run, what the parser accepted and refused (so it shows the fuzzer gets past the
//! first check), the outcome classes seen, and the time.
//!
//! Not caught in process: a stack overflow or an out-of-memory abort ends the run (the input is
//! the last one the run was making; `--iterations` and the seed reproduce it), and a hang is only
//! seen as a target that stops printing.
//!
//! Modules: this one (the command line, the targets' list), `runner` (one target's run, the
//! known issues), `targets` (the parser targets) and `frames` (the SLAM target), `mutate` (the
//! inputs) and `repair` (checksums), `corpus` (`--write-corpus`). Why a mutation fuzzer, and
//! each target's speed: docs/decisions.md, "Fuzzing on the stable toolchain".

mod corpus;
mod formats;
mod frames;
mod mutate;
mod repair;
mod runner;
mod targets;

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, Result, bail};

use crate::paths::root;
use mutate::Shape;
use runner::fuzz_target;

/// What one input did: units accepted and refused by the parser (one input is one unit for
/// most targets; frames for `frames`, wire frames for `wire`), and its outcome class.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Outcome {
    /// Units the code under test accepted.
    pub accepted: u64,
    /// Units it refused, with an error.
    pub refused: u64,
    /// What happened, in a few words (the refusing error's variant, or what was accepted).
    pub class: String,
}

/// A fuzz target: a name, what its counts count, the mutator's view of its inputs, and the
/// function that runs one input (`Err` when a property of the target does not hold).
#[derive(Debug, Clone, Copy)]
pub struct Target {
    /// The name on the command line and of the corpus folder.
    pub name: &'static str,
    /// What [`Outcome::accepted`] and [`Outcome::refused`] count.
    pub unit: &'static str,
    /// Input length, dictionary and checksum repair.
    pub shape: Shape,
    /// Runs one input.
    pub run: fn(&[u8]) -> Result<Outcome, String>,
}

/// The `frames` target runs `--iterations N / FRAMES_ITERATION_DIVISOR` inputs (each is up to
/// ten frames of SLAM, about a thousand times a parser input's cost).
pub const FRAMES_ITERATION_DIVISOR: u64 = 400;

/// The `mcap` target runs `--iterations N / MCAP_ITERATION_DIVISOR` inputs (each is written to
/// a file the reader opens, and decompressed twice: about a millisecond, fifty times a text
/// parser's input).
pub const MCAP_ITERATION_DIVISOR: u64 = 35;

/// Stack of the thread the targets run on: the core's structures are built on the stack before
/// they are boxed, and a test thread's 2 MiB is not enough for every target's.
const WORKER_STACK_BYTES: usize = 256 << 20;

/// Tokens of `calibration.toml`: its keys, TOML's syntax and values of other types.
const CALIBRATION_TOKENS: &[&[u8]] = &[
    b"fx",
    b"fy",
    b"cx",
    b"cy",
    b"width",
    b"height",
    b"depth_scale",
    b"depth_noise_coeff_per_m",
    b"[depth]",
    b"tx",
    b"ty",
    b"tz",
    b"k1",
    b"k2",
    b"p1",
    b"p2",
    b"k3",
    b"d0",
    b" = ",
    b"=",
    b"\"x\"",
    b"'x'",
    b"\"\"\"",
    b"[",
    b"]",
    b"[[depth]]",
    b"{",
    b"}",
    b"true",
    b"1979-05-27",
    b"[1, 2]",
    b"1e39",
    b"1e-46",
    b"65535",
    b"65536",
    b"1e6",
];
/// Tokens of the lists and TUM trajectories: paths, timestamps, a whole pose, a header.
const LIST_TOKENS: &[&[u8]] = &[
    b"rgb/frame-000000.color.png",
    b"/abs/x.png",
    b"..",
    b"depth/d.png",
    b"0.033333",
    b"1305031102.175304",
    b"0 0 0 0 0 0 0 1",
    b" 1 ",
    b"# timestamp filename\n",
];
/// Tokens of the map file: its magic, versions, the record magic and counts.
const MAP_TOKENS: &[&[u8]] = &[b"FSMP", b"\x02", b"\x01", b"FP", b"\x00\x04", b"\xFF\xFF\xFF\xFF"];
/// Tokens of the flash region: a table's and a record's first bytes, erased and zero words.
const FLASH_TOKENS: &[&[u8]] =
    &[b"FT\x01\x00", b"FP\x01", b"\xFF\xFF\xFF\xFF", b"\x00\x00\x00\x00"];
/// Tokens of the wire: the delimiter, the schema version, COBS code bytes.
const WIRE_TOKENS: &[&[u8]] = &[b"\x00", b"\x04", b"\x05", b"\xFF", b"\x01\x00", b"\x02\x04\x00"];
/// Tokens of PNG (and JPEG): the signatures, chunk types, bit depths and sizes.
const PNG_TOKENS: &[&[u8]] = &[
    b"\x89PNG\r\n\x1a\n",
    b"IHDR",
    b"IDAT",
    b"IEND",
    b"PLTE",
    b"tRNS",
    b"sBIT",
    b"\x00\x00\x00\x00",
    b"\x10",
    b"\x08",
    b"\x00\x00\xFF\xFF",
    b"\x7F\xFF\xFF\xFF",
    b"\xFF\xD8\xFF",
];
/// Tokens of MCAP: the magic, record opcodes, encodings and the message types the reader takes.
const MCAP_TOKENS: &[&[u8]] = &[
    b"\x89MCAP0\r\n",
    b"\x01",
    b"\x02",
    b"\x03",
    b"\x04",
    b"\x05",
    b"\x06",
    b"\x08",
    b"\x0c",
    b"cdr",
    b"ros2msg",
    b"zstd",
    b"rgb8",
    b"mono8",
    b"16UC1",
    b"32FC1",
    b"sensor_msgs/msg/Image",
    b"sensor_msgs/msg/CameraInfo",
    b"/groundtruth",
    b"\x00\x01\x00\x00",
    b"\xFF\xFF\xFF\xFF\xFF\xFF\xFF\x7F",
];
/// Tokens of anchor scripts: the table, keys, actions and values.
const SCRIPT_TOKENS: &[&[u8]] = &[
    b"[[step]]\n",
    b"frame = ",
    b"action = ",
    b"\"place\"",
    b"\"scale\"",
    b"\"remove\"",
    b"object = ",
    b"pixel = [1.0, 2.0]",
    b"scale = ",
    b"nan",
    b"inf",
    b"-1",
    b"65536",
    b"1e39",
    b"\n",
];
/// Whole frames of the `frames` target: a plausible one, a repeat, noise, a NaN time.
const FRAME_TOKENS: &[&[u8]] = &[
    &[0, 1, 4, 0, 33, 22, 0, 0],
    &[0, 2, 0, 4, 252, 22, 0, 0],
    &[12, 0, 0, 0, 240, 22, 0, 0],
    &[8, 9, 0, 0, 33, 22, 0, 0],
    &[0, 3, 0, 0, 242, 22, 0, 0],
];

/// Every target, in the order they run.
pub const TARGETS: [Target; 10] = [
    Target {
        name: "map-file",
        unit: "inputs",
        shape: Shape {
            max_len: 8 * 1024,
            dictionary: MAP_TOKENS,
            repair: Some(repair::map_file),
            text: false,
        },
        run: targets::map_file,
    },
    Target {
        name: "flash-mount",
        unit: "inputs",
        shape: Shape {
            max_len: targets::MAX_REGION_BYTES,
            dictionary: FLASH_TOKENS,
            repair: Some(repair::flash),
            text: false,
        },
        run: targets::flash_mount,
    },
    Target {
        name: "wire",
        unit: "wire frames",
        shape: Shape {
            max_len: 2048,
            dictionary: WIRE_TOKENS,
            repair: Some(repair::wire),
            text: false,
        },
        run: targets::wire,
    },
    Target {
        name: "calibration",
        unit: "inputs",
        shape: Shape { max_len: 4096, dictionary: CALIBRATION_TOKENS, repair: None, text: true },
        run: targets::calibration,
    },
    Target {
        name: "lists",
        unit: "readings (image list, ground truth)",
        shape: Shape { max_len: 4096, dictionary: LIST_TOKENS, repair: None, text: true },
        run: targets::lists,
    },
    Target {
        name: "trajectory",
        unit: "inputs",
        shape: Shape { max_len: 4096, dictionary: LIST_TOKENS, repair: None, text: true },
        run: targets::trajectory,
    },
    Target {
        name: "image",
        unit: "decodes (colour, depth)",
        shape: Shape {
            max_len: 4096,
            dictionary: PNG_TOKENS,
            repair: Some(repair::png),
            text: false,
        },
        run: targets::image,
    },
    Target {
        name: "mcap",
        unit: "recordings",
        shape: Shape { max_len: 16 * 1024, dictionary: MCAP_TOKENS, repair: None, text: false },
        run: formats::mcap,
    },
    Target {
        name: "anchor-script",
        unit: "scripts",
        shape: Shape { max_len: 4096, dictionary: SCRIPT_TOKENS, repair: None, text: true },
        run: formats::anchor_script,
    },
    Target {
        name: "frames",
        unit: "frames",
        shape: Shape {
            max_len: frames::HEADER_BYTES + frames::MAX_FRAMES * frames::FRAME_BYTES,
            dictionary: FRAME_TOKENS,
            repair: None,
            text: false,
        },
        run: frames::frames,
    },
];

/// How long each target runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Budget {
    /// Seconds per target (the inputs made in that time depend on the machine).
    Seconds(f64),
    /// Inputs per target (the `frames` target: fewer, see [`FRAMES_ITERATION_DIVISOR`]).
    Iterations(u64),
}

impl Budget {
    /// Whether `target`'s run is over after `inputs` inputs in `elapsed`.
    fn done(&self, target: &Target, inputs: u64, elapsed: Duration) -> bool {
        match *self {
            Self::Seconds(s) => elapsed.as_secs_f64() >= s,
            Self::Iterations(n) => inputs >= iterations_for(target, n),
        }
    }
}

/// Inputs `target` runs under `--iterations n`.
pub fn iterations_for(target: &Target, n: u64) -> u64 {
    match target.name {
        "frames" => (n / FRAMES_ITERATION_DIVISOR).max(1),
        "mcap" => (n / MCAP_ITERATION_DIVISOR).max(1),
        _ => n,
    }
}

/// The command line of `cargo xtask fuzz`.
#[derive(Debug, Clone)]
struct Options {
    budget: Budget,
    targets: Vec<Target>,
    seed: u64,
    replay: Option<PathBuf>,
    write_corpus: bool,
}

impl Options {
    fn parse(args: &[String]) -> Result<Self> {
        let mut o = Self {
            budget: Budget::Seconds(10.0),
            targets: TARGETS.to_vec(),
            seed: 1,
            replay: None,
            write_corpus: false,
        };
        let mut it = args.iter();
        while let Some(arg) = it.next() {
            let mut value = || it.next().with_context(|| format!("{arg} needs a value"));
            match arg.as_str() {
                "--seconds" => {
                    let seconds: f64 = value()?.parse().context("--seconds")?;
                    if !(seconds.is_finite() && seconds >= 0.0) {
                        bail!("--seconds {seconds}: a number of seconds, at least 0");
                    }
                    o.budget = Budget::Seconds(seconds);
                }
                "--iterations" => {
                    o.budget = Budget::Iterations(value()?.parse().context("--iterations")?)
                }
                "--seed" => o.seed = value()?.parse().context("--seed")?,
                "--replay" => o.replay = Some(PathBuf::from(value()?)),
                "--target" => o.targets = named_targets(value()?)?,
                "--write-corpus" => o.write_corpus = true,
                other => bail!(
                    "unknown argument {other}; usage: cargo xtask fuzz [--seconds N | --iterations \
                     N] [--target NAME[,NAME...]] [--seed S] | --target NAME --replay FILE | \
                     --write-corpus"
                ),
            }
        }
        if o.replay.is_some() && o.targets.len() != 1 {
            bail!("--replay needs one --target");
        }
        Ok(o)
    }
}

/// The targets named in `list` (comma-separated).
fn named_targets(list: &str) -> Result<Vec<Target>> {
    list.split(',')
        .map(|name| {
            TARGETS.iter().find(|t| t.name == name).copied().with_context(|| {
                let names: Vec<&str> = TARGETS.iter().map(|t| t.name).collect();
                format!("no fuzz target {name}; the targets are {}", names.join(", "))
            })
        })
        .collect()
}

/// `cargo xtask fuzz ARGS` (see the module documentation).
pub fn run(args: &[String]) -> Result<()> {
    let o = Options::parse(args)?;
    if o.write_corpus {
        return corpus::write_all(&corpus_dir());
    }
    if let Some(file) = &o.replay {
        let target = o.targets.first().copied().context("--replay needs one --target")?;
        return replay(&target, file);
    }
    let mut failed = Vec::new();
    for target in &o.targets {
        let seeds = load_corpus(&corpus_dir().join(target.name))?;
        let report = on_worker({
            let (target, budget, seed) = (*target, o.budget, o.seed);
            move || fuzz_target(&target, &seeds, budget, seed)
        })?;
        eprintln!("{}", report.summary(target));
        if let Some(f) = &report.failure {
            let file = save_failure(target, &f.input)?;
            eprintln!(
                "  FAILED on input {} ({} bytes): {}\n  saved to {}\n  replay: cargo xtask fuzz \
                 --target {} --replay {}",
                f.index,
                f.input.len(),
                f.what,
                file.display(),
                target.name,
                file.display()
            );
            failed.push(target.name);
        }
    }
    if !failed.is_empty() {
        bail!("fuzz targets failed: {}", failed.join(", "));
    }
    Ok(())
}

/// Where the seed corpora live: `<root>/fuzz/corpus`.
fn corpus_dir() -> PathBuf {
    root().join("fuzz").join("corpus")
}

/// The files of `dir`, by name.
fn load_corpus(dir: &Path) -> Result<Vec<Vec<u8>>> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| {
            format!("no seed corpus {} (cargo xtask fuzz --write-corpus)", dir.display())
        })?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    paths.sort();
    if paths.is_empty() {
        bail!("the seed corpus {} is empty (cargo xtask fuzz --write-corpus)", dir.display());
    }
    paths
        .iter()
        .map(|p| std::fs::read(p).with_context(|| format!("reading {}", p.display())))
        .collect()
}

/// Saves a failing input as `target/fuzz/failures/<target>-<n>.bin`, `n` the first number free.
fn save_failure(target: &Target, input: &[u8]) -> Result<PathBuf> {
    let dir = root().join("target").join("fuzz").join("failures");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let path = (0..)
        .map(|n| dir.join(format!("{}-{n}.bin", target.name)))
        .find(|p| !p.exists())
        .context("no free failure file name")?;
    std::fs::write(&path, input).with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}

/// Runs `job` on a thread with [`WORKER_STACK_BYTES`] of stack.
fn on_worker<T: Send + 'static>(job: impl FnOnce() -> T + Send + 'static) -> Result<T> {
    let worker = std::thread::Builder::new()
        .name("fuzz".into())
        .stack_size(WORKER_STACK_BYTES)
        .spawn(job)
        .context("starting the fuzz thread")?;
    worker.join().map_err(|_| anyhow::anyhow!("the fuzz thread panicked outside a target"))
}

/// `--replay FILE`: runs the one input, printing what happened; fails when it fails.
fn replay(target: &Target, file: &Path) -> Result<()> {
    let input = std::fs::read(file).with_context(|| format!("reading {}", file.display()))?;
    let target = *target;
    // Not through `run_caught`: a panic prints as usual, with its backtrace under RUST_BACKTRACE.
    let result = on_worker(move || {
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| (target.run)(&input)))
    })?;
    let name = format!("{} on {}", target.name, file.display());
    match result {
        Ok(Ok(o)) => {
            let (unit, accepted, refused) = (target.unit, o.accepted, o.refused);
            eprintln!(
                "{name}: no failure; {unit}: {accepted} accepted, {refused} refused ({})",
                o.class
            );
            Ok(())
        }
        Ok(Err(property)) => bail!("{name}: property broken: {property}"),
        Err(_) => bail!("{name}: panicked (above)"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_target_runs_its_corpus_and_mutations_without_failing() {
        for target in TARGETS {
            let seeds = load_corpus(&corpus_dir().join(target.name)).unwrap();
            let iterations = match target.name {
                "frames" => 3 * FRAMES_ITERATION_DIVISOR,
                "mcap" => 30 * MCAP_ITERATION_DIVISOR,
                _ => 300,
            };
            let report =
                on_worker(move || fuzz_target(&target, &seeds, Budget::Iterations(iterations), 1))
                    .unwrap();
            assert!(report.failure.is_none(), "{}: {:?}", target.name, report.failure);
            assert_eq!(report.inputs, iterations_for(&target, iterations), "{}", target.name);
            assert_eq!(report.seeds_refused, 0, "{}: a seed is refused", target.name);
            assert!(report.accepted > 0, "{}", report.summary(&target));
            // A few SLAM runs need not include a refused frame; 300 parser inputs do.
            assert!(target.name == "frames" || report.refused > 0, "{}", report.summary(&target));
        }
    }

    #[test]
    fn a_run_is_the_same_run_again() {
        let target = named_targets("wire").unwrap()[0];
        let seeds = load_corpus(&corpus_dir().join(target.name)).unwrap();
        let run = |seeds: Vec<Vec<u8>>| {
            on_worker(move || fuzz_target(&target, &seeds, Budget::Iterations(500), 9)).unwrap()
        };
        let (a, b) = (run(seeds.clone()), run(seeds));
        assert_eq!((a.accepted, a.refused, a.kept), (b.accepted, b.refused, b.kept));
        assert_eq!(a.classes, b.classes);
    }

    #[test]
    fn options_parse_and_name_unknown_targets() {
        let args = |s: &str| s.split(' ').map(String::from).collect::<Vec<_>>();
        let o = Options::parse(&args("--iterations 50 --target wire,image --seed 3")).unwrap();
        assert_eq!(o.budget, Budget::Iterations(50));
        assert_eq!(o.targets.iter().map(|t| t.name).collect::<Vec<_>>(), ["wire", "image"]);
        let err = Options::parse(&args("--target nope")).unwrap_err().to_string();
        assert!(err.contains("map-file, flash-mount"), "{err}");
        assert!(Options::parse(&args("--replay x.bin")).is_err());
    }
}
