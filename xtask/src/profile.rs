//! `cargo xtask profile-firmware [--dataset DIR] [--frames N] [--top K] [--out DIR]`: where the
//! Cortex-M4's instructions go, function by function, on the firmware's QEMU run.
//!
//! `budgets` counts instructions per frame and per stage (SysTick in QEMU); this says which
//! functions execute them, on the emulated board rather than on the host (`bench-frontend`): the
//! two differ where the M4 has no instruction for what x86-64 does in one (a square root, a
//! rounding) or where the compilers inline differently.
//!
//! 1. Compiles `xtask/qemu-plugin/hotblocks.c` with `cc` into DIR (a QEMU TCG plugin that counts
//!    the instructions executed per translation block).
//! 2. Runs `firmware-replay` on the first N frames of DATASET (default 200 of 7-Scenes) with the
//!    plugin loaded: the same run, still checked bit-identical to the host replay.
//! 3. Attributes every block to the function symbol that holds its start address
//!    (`arm-none-eabi-nm -C -n`): inlined code counts in its caller, and a block that runs past the
//!    end of a function (it cannot: blocks end at branches) would count in the first one.
//! 4. Prints the top K functions (default 30) with their instructions per frame and share, and
//!    writes every function to `DIR/profile.txt`.
//!
//! The totals include frame acquisition (the VGA frame read through semihosting and halved) and
//! the report, which `budgets` lists apart from the pipeline. Not part of `ci`: it needs a C
//! compiler and gives no pass or fail, only the table.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::fs;
use std::io::ErrorKind;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, anyhow, bail};

use crate::cost::FirmwareRun;
use crate::firmware;
use crate::paths::{SEVEN_SCENES, calibration_for, root};
use crate::replay::{self, ReplayOptions};

/// Options of `profile-firmware`.
#[derive(Debug, Clone, PartialEq)]
struct Options {
    dataset: PathBuf,
    frames: usize,
    top: usize,
    out: PathBuf,
}

/// Runs `profile-firmware` (see the module documentation).
///
/// # Errors
/// Bad arguments, no C compiler or `arm-none-eabi-nm`, or a failed firmware replay.
pub fn run(args: &[String]) -> Result<()> {
    let root = root();
    let opts = parse_args(args, &root)?;
    fs::create_dir_all(&opts.out).with_context(|| format!("creating {}", opts.out.display()))?;
    let out = fs::canonicalize(&opts.out)?;
    let plugin = out.join("libhotblocks.so");
    compile_plugin(&root.join("xtask/qemu-plugin/hotblocks.c"), &plugin)?;
    let blocks_file = out.join("hotblocks.txt");
    let _ = fs::remove_file(&blocks_file);
    let replay = ReplayOptions {
        dataset: opts.dataset.clone(),
        calibration: calibration_for(&opts.dataset),
        max_frames: opts.frames,
        frames: None,
        out: out.clone(),
        qemu_args: vec![
            "-plugin".into(),
            format!("{},out={}", plugin.display(), blocks_file.display()),
        ],
        maps: Default::default(),
        // The budgets' run, commands included.
        anchors: (opts.dataset == root.join(SEVEN_SCENES))
            .then(|| root.join(crate::board_runs::BOARD_ANCHORS)),
    };
    replay::run(&root, &replay)?;
    let frames = FirmwareRun::read(&out.join("cost.json"))?.frames.len();
    let elf = firmware::elf_path(&root, "qemu-mps2");
    let symbols = parse_symbols(&firmware::nm(&elf, &["-C", "-n"])?);
    let blocks = fs::read_to_string(&blocks_file)
        .with_context(|| format!("reading {} (did the plugin load?)", blocks_file.display()))?;
    let functions = attribute(&parse_blocks(&blocks)?, &symbols);
    let table = render(&functions, frames);
    fs::write(out.join("profile.txt"), &table)?;
    let total: u64 = functions.iter().map(|f| f.1).sum();
    println!(
        "Cortex-M4 instructions by function over {frames} frames of {} (QEMU; acquisition and \
         report included): {:.2} M per frame",
        opts.dataset.display(),
        total as f64 / frames.max(1) as f64 / 1e6
    );
    for line in table.lines().take(opts.top + 1) {
        println!("{line}");
    }
    println!("all {} functions: {}", functions.len(), out.join("profile.txt").display());
    Ok(())
}

fn parse_args(args: &[String], root: &Path) -> Result<Options> {
    let mut opts = Options {
        dataset: root.join(SEVEN_SCENES),
        frames: 200,
        top: 30,
        out: root.join("target/xtask/profile-firmware"),
    };
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = || it.next().ok_or_else(|| anyhow!("{a} needs a value"));
        match a.as_str() {
            "--dataset" => opts.dataset = value()?.into(),
            "--out" => opts.out = value()?.into(),
            "--frames" => {
                opts.frames =
                    value()?.parse().with_context(|| format!("{a} takes a whole number"))?
            }
            "--top" => {
                opts.top = value()?.parse().with_context(|| format!("{a} takes a whole number"))?
            }
            other => bail!(
                "unknown argument {other}; usage: profile-firmware [--dataset DIR] [--frames N] \
                 [--top K] [--out DIR]"
            ),
        }
    }
    if opts.frames == 0 {
        bail!("--frames must be at least 1");
    }
    Ok(opts)
}

/// `cc -shared -fPIC -O2 -o plugin source`.
fn compile_plugin(source: &Path, plugin: &Path) -> Result<()> {
    let status = match Command::new("cc")
        .args(["-shared", "-fPIC", "-O2", "-o"])
        .arg(plugin)
        .arg(source)
        .status()
    {
        Ok(status) => status,
        Err(e) if e.kind() == ErrorKind::NotFound => {
            bail!("no C compiler `cc` on PATH: the QEMU plugin is C (apt-get install gcc)")
        }
        Err(e) => return Err(e).context("running cc"),
    };
    if !status.success() {
        bail!("cc failed on {} ({status})", source.display());
    }
    Ok(())
}

/// The code symbols of `nm -C -n` output (types `t`, `T`, `w`, `W`), sorted by address, with the
/// Thumb bit cleared.
fn parse_symbols(text: &str) -> Vec<(u64, String)> {
    let mut symbols: Vec<(u64, String)> = text
        .lines()
        .filter_map(|line| {
            let mut parts = line.splitn(3, ' ');
            let (addr, kind, name) = (parts.next()?, parts.next()?, parts.next()?);
            let code = matches!(kind, "t" | "T" | "w" | "W");
            let addr = u64::from_str_radix(addr, 16).ok()?;
            code.then(|| (addr & !1, name.to_string()))
        })
        .collect();
    symbols.sort();
    symbols
}

/// The plugin's lines `start_hex instructions executions` as `(start, instructions executed)`.
fn parse_blocks(text: &str) -> Result<Vec<(u64, u64)>> {
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|line| {
            let v: Vec<&str> = line.split_whitespace().collect();
            let [pc, insns, runs] = v.as_slice() else {
                bail!("bad plugin line {line:?}");
            };
            let pc = u64::from_str_radix(pc, 16).with_context(|| format!("line {line:?}"))?;
            let insns: u64 = insns.parse().with_context(|| format!("line {line:?}"))?;
            let runs: u64 = runs.parse().with_context(|| format!("line {line:?}"))?;
            Ok((pc, insns.saturating_mul(runs)))
        })
        .collect()
}

/// Instructions per function (the symbol at or below each block's start; `?` below the first),
/// most first (ties by name).
fn attribute(blocks: &[(u64, u64)], symbols: &[(u64, String)]) -> Vec<(String, u64)> {
    let mut per: HashMap<&str, u64> = HashMap::new();
    for &(pc, n) in blocks {
        let i = symbols.partition_point(|s| s.0 <= pc);
        let name = i.checked_sub(1).and_then(|i| symbols.get(i)).map_or("?", |s| s.1.as_str());
        *per.entry(name).or_default() += n;
    }
    let mut out: Vec<(String, u64)> = per.into_iter().map(|(k, v)| (k.to_string(), v)).collect();
    out.sort_by(|a, b| b.1.cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
    out
}

/// One line per function: instructions per frame, share of the total, name.
fn render(functions: &[(String, u64)], frames: usize) -> String {
    let total: u64 = functions.iter().map(|f| f.1).sum::<u64>().max(1);
    let mut s = format!("{:>12}  {:>6}  function\n", "per frame", "share");
    for (name, n) in functions {
        let per_frame = *n as f64 / frames.max(1) as f64;
        let share = 100.0 * *n as f64 / total as f64;
        let _ = writeln!(s, "{per_frame:>12.0}  {share:>5.1}%  {name}");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_count_in_the_function_holding_their_start() {
        let nm = "00000400 T main\n00000401 t thumb_fn\n00000500 W weak\n00000600 D data\n\
                  00000700 T core::f<u8>::g\n";
        let symbols = parse_symbols(nm);
        // Data is not code; the Thumb bit is cleared.
        assert_eq!(symbols.len(), 4);
        assert_eq!(symbols.get(1), Some(&(0x400, "thumb_fn".to_string())));
        let blocks = parse_blocks("3fe 2 5\n400 4 10\n4f0 3 1\n500 1 7\n800 2 2\n").unwrap();
        let f = attribute(&blocks, &symbols);
        // 0x400 has two symbols: the later in `nm` order (sorted by name on ties) holds it.
        assert_eq!(
            f,
            vec![
                ("thumb_fn".to_string(), 43),
                ("?".to_string(), 10),
                ("weak".to_string(), 7),
                ("core::f<u8>::g".to_string(), 4),
            ]
        );
        let table = render(&f, 2);
        assert!(table.contains("          22   67.2%  thumb_fn\n"), "{table}");
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(parse_blocks("400 x 1\n").is_err());
        assert!(parse_blocks("400 1\n").is_err());
        let root = Path::new("/r");
        assert!(parse_args(&["--frames".into(), "0".into()], root).is_err());
        assert!(parse_args(&["--frames".into()], root).is_err());
        assert!(parse_args(&["--bogus".into()], root).is_err());
        let o = parse_args(&["--top".into(), "5".into()], root).unwrap();
        assert_eq!((o.frames, o.top), (200, 5));
    }
}
