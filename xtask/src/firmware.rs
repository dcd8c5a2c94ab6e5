//! The firmware W(I) check: one frame through the Cortex-M firmware in QEMU and through the host,
//! which must agree bit for bit.
//!
//! [`run_wi_check`] builds `ferroslam-firmware` for the Cortex-M target, writes the frame as a raw
//! frame file (`ferroslam_firmware::frame_file`), boots the firmware in QEMU `mps2-an386` with
//! semihosting (killed after [`QEMU_TIMEOUT`]), decodes its defmt log, reads its result line and
//! compares it with the same computation on the host (`ferroslam_firmware::wi::compute`, i.e.
//! ferroslam-core's `downsample_*_2x` and `total_variation`).
//!
//! Files (kept for inspection) go to `target/xtask/firmware-wi/`: `frame.fsrf`, `wi-result.txt`,
//! `defmt.bin` (the raw log) and `qemu-stderr.txt`.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use ferroslam_core::image::{GrayView, ImageView};
use ferroslam_firmware::frame_file::{FrameHeader, write_frame};
use ferroslam_firmware::wi::{self, WiReport};

/// The Cortex-M target the firmware is built for.
const THUMB: &str = "thumbv7em-none-eabihf";

/// QEMU is killed after this long (the run takes well under a second).
const QEMU_TIMEOUT: Duration = Duration::from_secs(60);

/// Emulated instructions per SysTick tick under `-icount shift=0` (25 MHz SysTick, 1 GHz
/// virtual instruction clock).
const INSTRUCTIONS_PER_TICK: u64 = 40;

/// One RGB-D frame for the check, as the host decoded it (the dataset loader's output).
#[derive(Debug, Clone)]
pub struct FrameForCheck {
    /// 8-bit gray pixels, row-major, `width * height`.
    pub gray: Vec<u8>,
    /// Raw depth samples (0 = no reading), row-major, `width * height`.
    pub depth: Vec<u16>,
    /// Width in pixels (at most 640 for the firmware's buffers).
    pub width: u32,
    /// Height in pixels (at most 480 pixels' worth, `width * height <= 640 * 480`).
    pub height: u32,
    /// Raw depth units per metre.
    pub depth_scale: f32,
    /// Capture time in seconds.
    pub timestamp_s: f64,
}

/// Runs the check on `frame` from the workspace at `root` and prints one line:
///
/// `firmware W(I): vga=V qvga=Q depth_fnv=0xH | host: vga=V qvga=Q depth_fnv=0xH | bit-identical
/// (QEMU 0.21 s, ~N instructions)`
///
/// preceded by the firmware's decoded defmt log and its ELF section sizes.
///
/// # Errors
/// When the frame is inconsistent, the build or QEMU fails or times out, the firmware exits with
/// failure or writes no valid result, or any value differs from the host's.
pub fn run_wi_check(root: &Path, frame: FrameForCheck) -> Result<()> {
    let header = FrameHeader {
        width: frame.width,
        height: frame.height,
        depth_scale: frame.depth_scale,
        timestamp_s: frame.timestamp_s,
    };
    let mut file = Vec::new();
    write_frame::<()>(&header, &frame.gray, &frame.depth, |b| {
        file.extend_from_slice(b);
        Ok(())
    })
    .map_err(|e| anyhow!("frame cannot be written as a frame file: {e:?}"))?;
    let host = host_report(&frame)?;

    let elf = build_firmware(root)?;
    let dir = root.join("target").join("xtask").join("firmware-wi");
    fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    fs::write(dir.join("frame.fsrf"), &file).context("writing frame.fsrf")?;
    let result_path = dir.join("wi-result.txt");
    // A stale result from an earlier run must not pass for this one.
    let _ = fs::remove_file(&result_path);

    let run = run_qemu(&elf, &dir)?;
    let elf_bytes = fs::read(&elf).with_context(|| format!("reading {}", elf.display()))?;
    let log = decode_defmt(&elf_bytes, &run.defmt);
    for line in &log.lines {
        eprintln!("  [firmware] {line}");
    }
    if let Some(err) = &log.error {
        eprintln!("  [firmware] (log decoding: {err}; raw stream in {})", dir.display());
    }
    if let Some(sizes) = elf_sizes(&elf) {
        eprintln!("firmware ELF {}: {sizes}", elf.display());
    }
    if !run.success {
        let stderr = fs::read_to_string(dir.join("qemu-stderr.txt")).unwrap_or_default();
        let stderr = stderr.trim();
        let detail = if stderr.is_empty() { String::new() } else { format!("; QEMU: {stderr}") };
        bail!("firmware failed in QEMU ({}; its log is above){detail}", run.status);
    }
    let text = fs::read_to_string(&result_path)
        .with_context(|| format!("the firmware wrote no {}", result_path.display()))?;
    let fw = WiReport::parse(&text)
        .ok_or_else(|| anyhow!("unreadable firmware result line: {:?}", text.trim()))?;

    let cost = log
        .ticks
        .map_or_else(String::new, |t| format!(", ~{} instructions", t * INSTRUCTIONS_PER_TICK));
    let verdict = if fw == host { "bit-identical" } else { "DIFFERENT" };
    println!(
        "firmware W(I): {} | host: {} | {verdict} (QEMU {:.2} s{cost})",
        summary(&fw),
        summary(&host),
        run.elapsed.as_secs_f64()
    );
    if fw != host {
        bail!("firmware and host disagree:\n  firmware: {fw}\n  host:     {host}");
    }
    Ok(())
}

/// `vga=.. qvga=.. depth_fnv=0x..` of a report.
fn summary(r: &WiReport) -> String {
    format!("vga={} qvga={} depth_fnv={:#018x}", r.wi_vga, r.wi_qvga, r.depth_qvga_fnv1a)
}

/// The same computation as the firmware's, on the host.
fn host_report(frame: &FrameForCheck) -> Result<WiReport> {
    let (w, h) = (usize::try_from(frame.width)?, usize::try_from(frame.height)?);
    let gray = GrayView::packed(&frame.gray, w, h).map_err(|e| anyhow!("gray: {e}"))?;
    let depth = ImageView::packed(&frame.depth, w, h).map_err(|e| anyhow!("depth: {e}"))?;
    let half = (w / 2) * (h / 2);
    let (mut half_gray, mut half_depth) = (vec![0u8; half], vec![0u16; half]);
    wi::compute(&gray, &depth, &mut half_gray, &mut half_depth)
        .map_err(|e| anyhow!("host W(I) computation failed (frames must be at least 2x2): {e}"))
}

/// Builds the firmware (release, Cortex-M) and returns the ELF's path.
fn build_firmware(root: &Path) -> Result<PathBuf> {
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
    Ok(root.join("target").join(THUMB).join("release").join("qemu-mps2"))
}

/// What QEMU did.
struct QemuRun {
    success: bool,
    status: String,
    elapsed: Duration,
    defmt: Vec<u8>,
}

/// Boots `elf` in QEMU with `dir` as its working directory (where the firmware finds
/// `frame.fsrf` and writes `wi-result.txt`); stdout (the defmt stream) goes to `defmt.bin`.
fn run_qemu(elf: &Path, dir: &Path) -> Result<QemuRun> {
    let stdout = fs::File::create(dir.join("defmt.bin")).context("creating defmt.bin")?;
    let stderr = fs::File::create(dir.join("qemu-stderr.txt")).context("creating stderr file")?;
    let mut cmd = Command::new("qemu-system-arm");
    cmd.args(["-M", "mps2-an386", "-cpu", "cortex-m4", "-nographic", "-monitor", "none"])
        .args(["-serial", "null", "-semihosting-config", "enable=on,target=native"])
        .args(["-icount", "shift=0", "-kernel"])
        .arg(elf)
        .args(["-append", "frame.fsrf wi-result.txt"])
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(stdout)
        .stderr(stderr);
    eprintln!("$ {cmd:?}");
    let start = Instant::now();
    let mut child =
        cmd.spawn().context("qemu-system-arm not found (apt-get install qemu-system-arm)")?;
    let status = loop {
        if let Some(status) = child.try_wait()? {
            break status;
        }
        if start.elapsed() > QEMU_TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            bail!("QEMU did not finish within {} s and was killed", QEMU_TIMEOUT.as_secs());
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let elapsed = start.elapsed();
    let defmt = fs::read(dir.join("defmt.bin")).context("reading defmt.bin")?;
    Ok(QemuRun { success: status.success(), status: status.to_string(), elapsed, defmt })
}

/// The decoded defmt log.
struct DefmtLog {
    lines: Vec<String>,
    /// SysTick ticks of the computation, from the firmware's "compute: N SysTick ticks" message.
    ticks: Option<u64>,
    /// Why decoding stopped early, if it did.
    error: Option<String>,
}

/// Decodes the firmware's defmt stream with the string table of its ELF.
fn decode_defmt(elf: &[u8], stream: &[u8]) -> DefmtLog {
    let mut log = DefmtLog { lines: Vec::new(), ticks: None, error: None };
    let table = match defmt_decoder::Table::parse(elf) {
        Ok(Some(table)) => table,
        Ok(None) => {
            log.error = Some("the ELF has no defmt table".into());
            return log;
        }
        Err(e) => {
            log.error = Some(format!("bad defmt table: {e}"));
            return log;
        }
    };
    let mut decoder = table.new_stream_decoder();
    decoder.received(stream);
    loop {
        match decoder.decode() {
            Ok(frame) => {
                let level = frame.level().map_or("PRINT", |l| l.as_str());
                let message = frame.display_message().to_string();
                if let Some(n) = message.strip_prefix("compute: ") {
                    log.ticks = n.split_whitespace().next().and_then(|t| t.parse().ok());
                }
                log.lines.push(format!("{:<5} {message}", level.to_uppercase()));
            }
            Err(defmt_decoder::DecodeError::UnexpectedEof) => break,
            Err(defmt_decoder::DecodeError::Malformed) => {
                log.error = Some("malformed defmt frame".into());
                break;
            }
        }
    }
    log
}

/// `.text=N .rodata=N .data=N .bss=N` bytes, from `arm-none-eabi-size -A` (None if unavailable).
fn elf_sizes(elf: &Path) -> Option<String> {
    let out = Command::new("arm-none-eabi-size").arg("-A").arg(elf).output().ok()?;
    let text = String::from_utf8(out.stdout).ok()?;
    let sizes: Vec<String> = [".vector_table", ".text", ".rodata", ".data", ".bss", ".uninit"]
        .iter()
        .filter_map(|name| {
            let line = text.lines().find(|l| l.split_whitespace().next() == Some(name))?;
            let size = line.split_whitespace().nth(1)?;
            Some(format!("{name}={size}"))
        })
        .collect();
    Some(sizes.join(" "))
}
