//! Building the firmware and running it in QEMU: the pieces `firmware-replay` (see `replay.rs`)
//! is made of.
//!
//! QEMU runs `mps2-an386` with `-icount shift=0,align=off,sleep=off` (one instruction per virtual
//! nanosecond: SysTick ticks every 40 instructions, deterministically), semihosting on (the
//! firmware reads its input files and writes its defmt log there: QEMU's stdout), and UART0
//! captured to a file (`-serial file:...`).

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};

use crate::paths::THUMB;

/// The firmware binaries.
pub const BINARIES: [&str; 2] = ["qemu-mps2", "ref-board"];

/// Builds the firmware binaries (release, Cortex-M) and returns the path of `bin`.
pub fn build_firmware(root: &Path, bin: &str) -> Result<PathBuf> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let args = ["build", "--release", "-p", "ferroslam-firmware", "--target", THUMB];
    eprintln!("$ cargo {}", args.join(" "));
    let status = Command::new(&cargo)
        .args(args)
        .current_dir(root)
        .status()
        .with_context(|| format!("could not start {cargo}"))?;
    if !status.success() {
        bail!("firmware build failed with {status}");
    }
    Ok(elf_path(root, bin))
}

/// Where the release build puts `bin`.
pub fn elf_path(root: &Path, bin: &str) -> PathBuf {
    root.join("target").join(THUMB).join("release").join(bin)
}

/// What QEMU did.
#[derive(Debug)]
pub struct QemuRun {
    /// Whether the firmware exited with success.
    pub success: bool,
    /// The exit status, as text.
    pub status: String,
    /// Wall-clock time of the run.
    pub elapsed: Duration,
    /// The raw defmt stream (QEMU's stdout).
    pub defmt: Vec<u8>,
}

/// Boots `elf` in QEMU with `dir` as its working directory, `append` as its semihosting command
/// line and UART0 captured to `dir/uart_file`; stdout (the defmt stream) goes to `dir/defmt.bin`,
/// stderr to `dir/qemu-stderr.txt`; `extra` is appended to QEMU's arguments (a `-plugin`, say).
/// QEMU is killed after `timeout`.
pub fn run_qemu(
    elf: &Path,
    dir: &Path,
    append: &str,
    uart_file: &str,
    extra: &[String],
    timeout: Duration,
) -> Result<QemuRun> {
    let stdout = fs::File::create(dir.join("defmt.bin")).context("creating defmt.bin")?;
    let stderr = fs::File::create(dir.join("qemu-stderr.txt")).context("creating stderr file")?;
    let mut cmd = Command::new("qemu-system-arm");
    cmd.args(["-M", "mps2-an386", "-cpu", "cortex-m4", "-nographic", "-monitor", "none"])
        .args(["-serial", &format!("file:{uart_file}")])
        .args(["-semihosting-config", "enable=on,target=native"])
        .args(["-icount", "shift=0,align=off,sleep=off", "-kernel"])
        .arg(elf)
        .args(["-append", append])
        .args(extra)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(stdout)
        .stderr(stderr);
    eprintln!("$ (cd {} && {cmd:?})", dir.display());
    let start = Instant::now();
    let mut child =
        cmd.spawn().context("qemu-system-arm not found (apt-get install qemu-system-arm)")?;
    let status = loop {
        if let Some(status) = child.try_wait()? {
            break status;
        }
        if start.elapsed() > timeout {
            let _ = child.kill();
            let _ = child.wait();
            bail!("QEMU did not finish within {} s and was killed", timeout.as_secs());
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let elapsed = start.elapsed();
    let defmt = fs::read(dir.join("defmt.bin")).context("reading defmt.bin")?;
    Ok(QemuRun { success: status.success(), status: status.to_string(), elapsed, defmt })
}

/// The firmware's defmt log, decoded with the string table of its ELF: one line per message,
/// and why decoding stopped early, if it did.
pub fn decode_defmt(elf: &[u8], stream: &[u8]) -> (Vec<String>, Option<String>) {
    let mut lines = Vec::new();
    let table = match defmt_decoder::Table::parse(elf) {
        Ok(Some(table)) => table,
        Ok(None) => return (lines, Some("the ELF has no defmt table".into())),
        Err(e) => return (lines, Some(format!("bad defmt table: {e}"))),
    };
    let mut decoder = table.new_stream_decoder();
    decoder.received(stream);
    loop {
        match decoder.decode() {
            Ok(frame) => {
                let level = frame.level().map_or("PRINT", |l| l.as_str());
                let message = frame.display_message().to_string();
                lines.push(format!("{:<5} {message}", level.to_uppercase()));
            }
            Err(defmt_decoder::DecodeError::UnexpectedEof) => return (lines, None),
            Err(defmt_decoder::DecodeError::Malformed) => {
                return (lines, Some("malformed defmt frame".into()));
            }
        }
    }
}

/// The symbol table of an ELF: `arm-none-eabi-nm ARGS elf`'s output.
///
/// # Errors
/// The tool missing (with the package to install) or failing.
pub fn nm(elf: &Path, args: &[&str]) -> Result<String> {
    let out = Command::new("arm-none-eabi-nm")
        .args(args)
        .arg(elf)
        .output()
        .context("arm-none-eabi-nm not found: apt-get install binutils-arm-none-eabi")?;
    if !out.status.success() {
        bail!("arm-none-eabi-nm failed on {} ({})", elf.display(), out.status);
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// Section sizes of an ELF from `arm-none-eabi-size -A`: `(name, bytes)` of the sections that
/// take flash or RAM (None if the tool is missing).
pub fn elf_sections(elf: &Path) -> Option<Vec<(String, u64)>> {
    let out = Command::new("arm-none-eabi-size").arg("-A").arg(elf).output().ok()?;
    let text = String::from_utf8(out.stdout).ok()?;
    let wanted =
        [".vector_table", ".text", ".rodata", ".data", ".bss", ".uninit", ".axisram", ".sram123"];
    let sections = text
        .lines()
        .filter_map(|l| {
            let mut words = l.split_whitespace();
            let name = words.next()?;
            let size = words.next()?.parse().ok()?;
            wanted.contains(&name).then(|| (name.to_owned(), size))
        })
        .collect();
    Some(sections)
}

/// Flash and static RAM of an ELF: flash = vector table + text + rodata + data (its load image);
/// static RAM = data + bss + uninit + the H7 regions.
pub fn flash_and_ram(sections: &[(String, u64)]) -> (u64, u64) {
    let sum = |names: &[&str]| -> u64 {
        sections.iter().filter(|(n, _)| names.contains(&n.as_str())).map(|(_, s)| s).sum()
    };
    let flash = sum(&[".vector_table", ".text", ".rodata", ".data"]);
    let ram = sum(&[".data", ".bss", ".uninit", ".axisram", ".sram123"]);
    (flash, ram)
}
