#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! `memory-budget.md` must not lie: its core table lists exactly the structures of
//! `ferroslam_tests::structures` (the list `cargo xtask budgets --write` writes the table from),
//! in that order, with the bytes `size_of` measures here.

use ferroslam_tests::structures::core_structures;

/// The `(type, bytes)` rows of the table under the heading "Core structures".
fn documented(text: &str) -> Vec<(String, usize)> {
    let section = text.split("## Core structures").nth(1).unwrap_or("");
    let table = section.split("\n## ").next().unwrap_or("");
    table
        .lines()
        .filter(|l| l.starts_with("| `"))
        .map(|l| {
            let cells: Vec<&str> = l.split('|').map(str::trim).collect();
            let name = cells[1].trim_matches('`').to_string();
            let bytes = cells[3].replace(',', "").parse().unwrap_or_else(|_| {
                panic!("memory-budget.md: row {l:?} has no byte count in its third column")
            });
            (name, bytes)
        })
        .collect()
}

#[test]
fn core_structure_sizes_match_the_budget_file() {
    let known = core_structures();
    for s in &known {
        println!("{}: {}", s.name, s.bytes);
    }
    // The table documents the host (64-bit) sizes; views and frames hold pointers and are smaller on
    // the 32-bit Cortex-M, buffers are the same.
    let path = ferroslam_tests::workspace_root().join("memory-budget.md");
    let text = std::fs::read_to_string(&path).expect("memory-budget.md is readable");
    let rows = documented(&text);
    let names: Vec<&str> = rows.iter().map(|(n, _)| n.as_str()).collect();
    let expected: Vec<&str> = known.iter().map(|s| s.name).collect();
    assert_eq!(
        names, expected,
        "the table must list exactly the known structures, in order (`cargo xtask budgets \
         --write` rewrites it)"
    );
    for ((name, bytes), s) in rows.iter().zip(&known) {
        assert_eq!(
            s.bytes, *bytes,
            "memory-budget.md says {name} is {bytes} bytes, size_of is {} (`cargo xtask budgets \
             --write` rewrites the table)",
            s.bytes
        );
    }
}
