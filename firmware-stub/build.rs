//! Links each firmware binary against its own memory map: `memory-<bin>.x` is copied to
//! `$OUT_DIR/<bin>/memory.x` and that folder is put on the binary's linker search path, where
//! cortex-m-rt's `link.x` finds it; defmt's `defmt.x` is linked too. Host builds (the library's
//! tests) get no link arguments.

use std::path::PathBuf;
use std::{env, fs};

/// The binaries and their memory maps.
const BINARIES: [(&str, &str); 2] =
    [("qemu-mps2", "memory-qemu-mps2.x"), ("ref-board", "memory-ref-board.x")];

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    for (_, map) in BINARIES {
        println!("cargo:rerun-if-changed={map}");
    }
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap_or_default());
    for (bin, map) in BINARIES {
        let dir = out.join(bin);
        let copied =
            fs::create_dir_all(&dir).and_then(|()| fs::copy(map, dir.join("memory.x")).map(|_| ()));
        if let Err(e) = copied {
            println!("cargo:warning=could not copy {map} to {}: {e}", dir.display());
        }
        println!("cargo:rustc-link-arg-bin={bin}=-L{}", dir.display());
    }
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    // defmt keeps only `error!` unless DEFMT_LOG says otherwise; default this crate to `info`
    // (the defmt macros read the variable while this crate compiles).
    println!("cargo:rerun-if-env-changed=DEFMT_LOG");
    if env::var_os("DEFMT_LOG").is_none() {
        println!("cargo:rustc-env=DEFMT_LOG=info");
    }
}
