//! Running cargo (the cargo that runs xtask) in the workspace root, echoed as `$ cargo args...`,
//! failing on a non-zero exit.

use std::process::Command;

use anyhow::{Context, Result, bail};

use crate::paths::root;

/// Runs `cargo args...` in the workspace root, failing on non-zero exit.
pub fn cargo(args: &[&str]) -> Result<()> {
    cargo_with_env(args, &[])
}

/// Runs `cargo args...` in the workspace root with extra environment, failing on non-zero exit.
pub fn cargo_with_env(args: &[&str], env: &[(&str, &str)]) -> Result<()> {
    let program = env!("CARGO");
    let mut cmd = Command::new(program);
    cmd.args(args).current_dir(root());
    for (k, v) in env {
        cmd.env(k, v);
    }
    eprintln!("$ {program} {}", args.join(" "));
    let status = cmd.status().with_context(|| format!("could not start {program}"))?;
    if !status.success() {
        bail!("`{program} {}` failed with {status}", args.join(" "));
    }
    Ok(())
}
