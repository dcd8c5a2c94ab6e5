//! The figures `cargo xtask budgets` measures and each budget judged against its figure: the
//! types `budgets` (which measures, judges and reports) and `budget_tables` (which writes them
//! into `memory-budget.md`) share.

use std::path::{Path, PathBuf};

use anyhow::{Result, anyhow, bail};

use crate::budget_doc::Budget;
use crate::cost::FirmwareRun;
use crate::firmware;
use crate::stats::{millions, thousands};

/// The reference board's DTCM, which holds `ref-board`'s `.data`, `.bss` and stack
/// (`memory-ref-board.x`, region `RAM`).
const REF_BOARD_DTCM_BYTES: u64 = 128 * 1024;

/// Why the firmware figures of VGA are null.
pub const VGA_DOES_NOT_RUN: &str = "the firmware runs QVGA only: a VGA gray + depth frame pair \
    alone is 921,600 B, more than the reference board's 512 KB budget for everything and than \
    its largest SRAM region (AXI SRAM, 512 KiB); VGA runs on the host (`ferroslam-sim replay \
    --profile vga`)";

/// One firmware binary's memory figures.
#[derive(Debug, Clone, PartialEq)]
pub struct Binary {
    /// The binary's name.
    pub name: &'static str,
    /// `(section, bytes)` of the sections that take flash or RAM.
    pub sections: Vec<(String, u64)>,
    /// Flash: vector table, text, rodata and the data load image.
    pub flash: u64,
    /// Static RAM: data, bss, uninit and the H7 regions.
    pub static_ram: u64,
}

impl Binary {
    /// The sections and figures of the release ELF of `name` (see [`firmware::elf_path`]).
    pub fn read(root: &Path, name: &'static str) -> Result<Self> {
        let elf = firmware::elf_path(root, name);
        let sections = firmware::elf_sections(&elf)
            .ok_or_else(|| anyhow!("arm-none-eabi-size failed on {}", elf.display()))?;
        if sections.is_empty() {
            bail!("{}: no sections read", elf.display());
        }
        let (flash, static_ram) = firmware::flash_and_ram(&sections);
        Ok(Self { name, sections, flash, static_ram })
    }

    /// The bytes of `section` (0 when absent).
    pub fn section(&self, section: &str) -> u64 {
        self.sections.iter().find(|(n, _)| n == section).map_or(0, |(_, b)| *b)
    }
}

/// Everything measured.
#[derive(Debug, Clone)]
pub struct Measurements {
    /// The firmware run (per-frame costs, final status).
    pub run: FirmwareRun,
    /// Where its `cost.json` is.
    pub cost_json: PathBuf,
    /// Other recordings' runs of the same build, by the name keying their figures.
    pub also: Vec<(String, FirmwareRun)>,
    /// What the boot cost, for the runs of `also` that booted from a saved map.
    pub boots: Vec<(String, crate::board_runs::BootCost)>,
    /// Both firmware binaries, in [`firmware::BINARIES`] order.
    pub binaries: Vec<Binary>,
    /// The core structures' `size_of` on this host.
    pub structures: Vec<ferroslam_tests::structures::Structure>,
    /// Every figure by key (`qvga.static_ram_bytes`); `None` where it is not measured.
    pub figures: Vec<(String, Option<u64>)>,
}

impl Measurements {
    /// The figure keyed `key`, when measured.
    pub fn figure(&self, key: &str) -> Option<u64> {
        self.figures.iter().find(|(k, _)| k == key).and_then(|(_, v)| *v)
    }

    /// The core structure `name`'s bytes (0 when unknown).
    pub fn size_of(&self, name: &str) -> u64 {
        self.structures.iter().find(|s| s.name == name).map_or(0, |s| s.bytes as u64)
    }

    /// `ref-board`'s DTCM left for the stack.
    pub fn ref_board_stack_room(&self) -> Option<u64> {
        let b = self.binaries.iter().find(|b| b.name == "ref-board")?;
        let dtcm = b.section(".data") + b.section(".bss") + b.section(".uninit");
        Some(REF_BOARD_DTCM_BYTES.saturating_sub(dtcm))
    }
}

/// A budget judged against its figure.
#[derive(Debug, Clone, PartialEq)]
pub struct Check {
    /// The budget, as the file states it.
    pub budget: Budget,
    /// The figure measured now.
    pub measured: u64,
}

impl Check {
    /// Whether the bar is met.
    pub fn met(&self) -> bool {
        self.measured <= self.budget.bar
    }

    /// `measured / bar`.
    pub fn times_bar(&self) -> f64 {
        self.measured as f64 / self.budget.bar.max(1) as f64
    }

    /// `met`, or `NOT MET (x.x times the bar)`.
    pub fn status(&self) -> String {
        if self.met() {
            return "met".into();
        }
        let t = self.times_bar();
        if t < 1.1 {
            format!("NOT MET ({t:.2} times the bar)")
        } else {
            format!("NOT MET ({t:.1} times the bar)")
        }
    }

    /// The limit the run holds the figure to: the ceiling, or the bar without one or when
    /// `strict`.
    pub fn limit(&self, strict: bool) -> u64 {
        match self.budget.ceiling {
            Some(c) if !strict => c,
            _ => self.budget.bar,
        }
    }

    /// Whether the run fails on this figure.
    pub fn fails(&self, strict: bool) -> bool {
        self.measured > self.limit(strict)
    }
}

/// `value` in the unit its key implies: bytes, or instructions in millions.
pub fn show(key: &str, value: u64) -> String {
    if key.contains("insn") {
        millions(value)
    } else if key.ends_with("bytes") {
        format!("{} B", thousands(value))
    } else {
        thousands(value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn budget(bar: u64, ceiling: Option<u64>) -> Budget {
        Budget {
            key: "qvga.flash_bytes".into(),
            what: "flash".into(),
            bar,
            ceiling,
            reason: ceiling.map(|_| "why".into()),
            measured: None,
        }
    }

    #[test]
    fn a_ceiling_holds_a_bar_not_met_and_strict_ignores_it() {
        let c = Check { budget: budget(100, Some(150)), measured: 140 };
        assert!(!c.met());
        assert_eq!(c.status(), "NOT MET (1.4 times the bar)");
        assert!(!c.fails(false));
        assert!(c.fails(true));
        let over = Check { measured: 151, ..c.clone() };
        assert!(over.fails(false));
        let close = Check { measured: 104, ..c };
        assert_eq!(close.status(), "NOT MET (1.04 times the bar)");
        let met = Check { budget: budget(100, None), measured: 100 };
        assert!(met.met() && !met.fails(true));
        assert_eq!(met.status(), "met");
        assert!(Check { budget: budget(100, None), measured: 101 }.fails(false));
    }

    #[test]
    fn units_follow_the_key() {
        assert_eq!(show("qvga.flash_bytes", 725_000), "725,000 B");
        assert_eq!(show("qvga.insn_per_frame_max", 138_000_000), "138.00 M");
        assert_eq!(show("qvga.frames", 1000), "1,000");
    }
}
