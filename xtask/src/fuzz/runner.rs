//! Running a target: its seeds, then made inputs, each under `catch_unwind` ([`run_caught`]),
//! until its budget is spent or an input fails ([`fuzz_target`]); what the run saw
//! ([`Report`]), and the failures already known in code the harness may not change
//! ([`KNOWN_ISSUES`]).

use std::cell::{Cell, RefCell};
use std::collections::BTreeMap;
use std::panic::{self, AssertUnwindSafe};
use std::sync::Once;
use std::time::{Duration, Instant};

use super::mutate::{Rng, make_input};
use super::{Budget, Outcome, Target};
use crate::paths::root;

/// A failure this fuzzer found in code the harness may not change (the core), reported and not
/// fixed yet. A target that recognises one returns `Err(format!("known issue {id}: ..."))`; the
/// run counts it, saves its first input to `target/fuzz/known/<id>.bin` and goes on, so that the
/// issue does not hide what lies behind it nor fail every CI run. Its smallest input is kept in
/// `fuzz/known/<id>.bin`, and a test checks that it still fails: when it stops failing, the fix
/// has landed, the input moves to `fuzz/fixed/<target>.<id>.bin` (a test checks those pass) and
/// the entry goes. None is listed today: the five found so far are fixed.
#[derive(Debug, Clone, Copy)]
pub struct KnownIssue {
    /// Its name, in messages and file names.
    pub id: &'static str,
    /// The target that finds it.
    pub target: &'static str,
    /// What is wrong, and where.
    pub note: &'static str,
}

/// The known issues (see [`KnownIssue`]).
pub const KNOWN_ISSUES: [KnownIssue; 0] = [];

/// The known issue of `target` a failure message names, if it names one.
fn known_issue(target: &Target, what: &str) -> Option<&'static KnownIssue> {
    let rest = what.strip_prefix("property broken: known issue ")?;
    KNOWN_ISSUES.iter().find(|k| {
        k.target == target.name && rest.strip_prefix(k.id).is_some_and(|r| r.starts_with(':'))
    })
}

/// Inputs kept in a target's pool beyond its seeds, at most.
const MAX_KEPT: usize = 256;

/// Saves the first input of a run that hit known issue `k` as `target/fuzz/known/<id>.bin`
/// (best effort: the run goes on without it).
fn save_known(k: &KnownIssue, input: &[u8]) {
    let dir = root().join("target").join("fuzz").join("known");
    let saved = std::fs::create_dir_all(&dir)
        .and_then(|()| std::fs::write(dir.join(format!("{}.bin", k.id)), input));
    if let Err(e) = saved {
        eprintln!("  (could not save the input of known issue {}: {e})", k.id);
    }
}

/// A failing input.
#[derive(Debug, Clone)]
pub struct Failure {
    /// Its index in the run (seeds first).
    pub index: u64,
    /// The panic (message and place) or the broken property.
    pub what: String,
    /// Its bytes.
    pub input: Vec<u8>,
}

/// One target's run.
#[derive(Debug, Clone)]
pub struct Report {
    /// Inputs run (seeds included).
    pub inputs: u64,
    /// Seeds in the corpus.
    pub seeds: usize,
    /// Seeds the target refused: a corpus gone stale.
    pub seeds_refused: usize,
    /// Inputs kept in the pool for a new outcome class.
    pub kept: usize,
    /// Units accepted and refused, over all inputs.
    pub accepted: u64,
    /// Units refused.
    pub refused: u64,
    /// Inputs by outcome class.
    pub classes: BTreeMap<String, u64>,
    /// Inputs that hit a known issue, by its id.
    pub known: BTreeMap<&'static str, u64>,
    /// Time the run took.
    pub elapsed: Duration,
    /// The slowest input's time.
    pub slowest: Duration,
    /// The first failure, which ended the run.
    pub failure: Option<Failure>,
}

impl Report {
    /// What the run printed for `target`: one line of figures, one of outcome classes.
    pub fn summary(&self, target: &Target) -> String {
        let mut classes: Vec<(&String, &u64)> = self.classes.iter().collect();
        classes.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
        let shown: Vec<String> =
            classes.iter().take(8).map(|(c, n)| format!("{c} ({n})")).collect();
        let refused_seeds = if self.seeds_refused > 0 {
            format!(", {} OF THEM REFUSED", self.seeds_refused)
        } else {
            String::new()
        };
        format!(
            "{:<12} {} inputs ({} seeds{refused_seeds}, {} kept) in {:.1} s (slowest {:.0} ms): \
             {}: {} accepted, {} refused\n  {} outcome classes: {}{}",
            target.name,
            self.inputs,
            self.seeds,
            self.kept,
            self.elapsed.as_secs_f64(),
            self.slowest.as_secs_f64() * 1e3,
            target.unit,
            self.accepted,
            self.refused,
            self.classes.len(),
            shown.join(", "),
            if classes.len() > shown.len() { ", ..." } else { "" }
        ) + &self.known_lines()
    }

    /// One line per known issue the run hit, with its note.
    fn known_lines(&self) -> String {
        self.known
            .iter()
            .filter_map(|(id, n)| {
                let k = KNOWN_ISSUES.iter().find(|k| k.id == *id)?;
                Some(format!(
                    "\n  known issue {id}: {n} inputs (first in target/fuzz/known/{id}.bin): {}",
                    k.note
                ))
            })
            .collect()
    }
}

/// Fuzzes `target` from `seeds` within `budget` (see the module documentation); stops at the
/// first failure.
pub fn fuzz_target(target: &Target, seeds: &[Vec<u8>], budget: Budget, seed: u64) -> Report {
    let shape = target.shape;
    let mut pool = seeds.to_vec();
    let mut report = Report {
        inputs: 0,
        seeds: seeds.len(),
        seeds_refused: 0,
        kept: 0,
        accepted: 0,
        refused: 0,
        classes: BTreeMap::new(),
        known: BTreeMap::new(),
        elapsed: Duration::ZERO,
        slowest: Duration::ZERO,
        failure: None,
    };
    let start = Instant::now();
    for index in 0u64.. {
        if budget.done(target, index, start.elapsed()) {
            break;
        }
        let seed_input = usize::try_from(index).ok().and_then(|i| seeds.get(i));
        let input = match seed_input {
            Some(s) => s.clone(),
            None => make_input(&mut Rng::for_input(seed, target.name, index), &pool, &shape),
        };
        let t0 = Instant::now();
        let result = run_caught(target, &input);
        report.slowest = report.slowest.max(t0.elapsed());
        report.inputs += 1;
        match result {
            Ok(o) => {
                report.accepted += o.accepted;
                report.refused += o.refused;
                if seed_input.is_some() && o.accepted == 0 {
                    report.seeds_refused += 1;
                }
                let count = report.classes.entry(o.class).or_insert(0);
                *count += 1;
                if *count == 1 && seed_input.is_none() && report.kept < MAX_KEPT {
                    pool.push(input);
                    report.kept += 1;
                }
            }
            Err(what) => match known_issue(target, &what) {
                Some(k) => {
                    let count = report.known.entry(k.id).or_insert(0);
                    *count += 1;
                    if *count == 1 {
                        save_known(k, &input);
                    }
                }
                None => {
                    report.failure = Some(Failure { index, what, input });
                    break;
                }
            },
        }
    }
    report.elapsed = start.elapsed();
    report
}

thread_local! {
    /// Whether panics on this thread are being caught by [`run_caught`] (not printed).
    static CATCHING: Cell<bool> = const { Cell::new(false) };
    /// The last caught panic's message and place.
    static LAST_PANIC: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// Installs, once, a panic hook that records the panics of threads inside [`run_caught`]
/// instead of printing them, and leaves every other panic to the hook that was there.
fn install_panic_hook() {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let previous = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            if CATCHING.with(Cell::get) {
                LAST_PANIC.with(|p| *p.borrow_mut() = Some(info.to_string()));
            } else {
                previous(info);
            }
        }));
    });
}

/// Runs one input of `target`, a panic caught and returned as `Err` with its message.
pub fn run_caught(target: &Target, input: &[u8]) -> Result<Outcome, String> {
    install_panic_hook();
    CATCHING.with(|c| c.set(true));
    let result = panic::catch_unwind(AssertUnwindSafe(|| (target.run)(input)));
    CATCHING.with(|c| c.set(false));
    match result {
        Ok(Ok(o)) => Ok(o),
        Ok(Err(property)) => Err(format!("property broken: {property}")),
        Err(_) => Err(LAST_PANIC
            .with(|p| p.borrow_mut().take())
            .unwrap_or_else(|| "panicked".into())
            .replace('\n', " ")),
    }
}

#[cfg(test)]
mod tests {
    use super::super::{TARGETS, named_targets, on_worker};
    use super::*;

    #[test]
    fn a_panic_is_caught_with_its_message_and_a_property_is_named() {
        fn panics(input: &[u8]) -> Result<Outcome, String> {
            let at = input.len() + 3;
            Ok(Outcome::accepted(format!("{}", input[at])))
        }
        fn breaks(_: &[u8]) -> Result<Outcome, String> {
            Err("two and two".into())
        }
        let base = TARGETS[0];
        let panicking = Target { run: panics, ..base };
        let err = on_worker(move || run_caught(&panicking, b"ab")).unwrap().unwrap_err();
        assert!(err.contains("index out of bounds") && err.contains("runner.rs:"), "{err}");
        let broken = Target { run: breaks, ..base };
        let err = on_worker(move || run_caught(&broken, b"")).unwrap().unwrap_err();
        assert_eq!(err, "property broken: two and two");
    }

    #[test]
    fn every_known_issue_still_fails_on_its_input() {
        for k in KNOWN_ISSUES {
            let target = named_targets(k.target).unwrap()[0];
            let input =
                std::fs::read(root().join("fuzz/known").join(format!("{}.bin", k.id))).unwrap();
            let what = on_worker(move || run_caught(&target, &input)).unwrap().unwrap_err();
            assert_eq!(
                known_issue(&target, &what).map(|k| k.id),
                Some(k.id),
                "{}: {what} (fixed? then move its input to fuzz/fixed/ and drop the entry)",
                k.id
            );
        }
    }

    /// The inputs of the issues found and fixed (`fuzz/fixed/<target>.<id>.bin`) pass.
    #[test]
    fn every_fixed_issue_passes_on_its_input() {
        let mut checked = 0;
        for entry in std::fs::read_dir(root().join("fuzz/fixed")).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            let target_name = name.split('.').next().unwrap().to_owned();
            let target = named_targets(&target_name).unwrap()[0];
            let input = std::fs::read(&path).unwrap();
            let done = on_worker(move || run_caught(&target, &input)).unwrap();
            assert!(done.is_ok(), "{name}: {done:?}");
            checked += 1;
        }
        assert_eq!(checked, 5, "three issues fixed in core, two in the MCAP reader");
    }
}
