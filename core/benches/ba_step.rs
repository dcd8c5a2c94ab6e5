//! Cost of the bundle adjuster in bounded steps: a realistic local-BA window (65 keyframes, 1000
//! points, ~5900 observations, Kinect-like noise at QVGA, 2 cm / 0.5 deg / 3 cm start error)
//! solved in steps of a fixed work quota; with `segmented`, the same 65 keyframes as 13
//! segments of 5 (segmented global BA: 12 free segment poses).
//!
//! Prints the work units of every step, then the solve's figures. Under callgrind each call of
//! `one_step` is one dump, so each step's instruction count is the dump's `totals:` line. From
//! the workspace root:
//!
//! ```text
//! cargo bench -p ferroslam-core --bench ba_step --no-run
//! BIN=$(ls -t target/release/deps/ba_step-* | grep -v '\.d$' | head -1)
//! mkdir -p target/ba-cg
//! valgrind --tool=callgrind --callgrind-out-file=target/ba-cg/cg.out.%p \
//!     --toggle-collect='ba_step::one_step*' --dump-after='*::one_step*' $BIN 6000 > target/ba-cg/steps.txt
//! grep -h '^totals:' target/ba-cg/cg.out.*.* | sort -k2 -n | tail -1   # the largest step
//! ```
//!
//! Arguments: the work quota per step (default 6000), then `segmented` for the rig mode.
//! Without valgrind it just runs and prints.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

#[path = "../tests/support/ba_synth.rs"]
mod ba_synth;

use std::sync::Mutex;

use ba_synth::{LocalBundleAdjuster, SegmentedBundleAdjuster, Synth, SynthConfig, segmented};
use ferroslam_core::optim::{BaParams, BaStatus, BaSummary, BundleAdjuster};

static LOCAL: Mutex<LocalBundleAdjuster> = Mutex::new(LocalBundleAdjuster::new());
static SEGMENTED: Mutex<SegmentedBundleAdjuster> = Mutex::new(SegmentedBundleAdjuster::new());

/// One bounded step: the function callgrind counts.
#[inline(never)]
fn one_step<const R: usize, const C: usize, const P: usize, const O: usize>(
    ba: &mut BundleAdjuster<R, C, P, O>,
    quota: u32,
) -> BaStatus {
    ba.step(quota).unwrap()
}

/// Runs the solve in steps of `quota`, printing each step's units.
fn run<const R: usize, const C: usize, const P: usize, const O: usize>(
    ba: &mut BundleAdjuster<R, C, P, O>,
    synth: &Synth,
    quota: u32,
) -> (u32, BaSummary) {
    ba.start(&synth.camera, &BaParams::DEFAULT).unwrap();
    let mut steps = 0u32;
    loop {
        let before = ba.summary().work_units;
        let status = std::hint::black_box(one_step(ba, quota));
        steps += 1;
        println!("step {steps}: {} units", ba.summary().work_units - before);
        if let BaStatus::Finished(s) = status {
            return (steps, s);
        }
    }
}

fn main() {
    let mut args = std::env::args().skip(1);
    let quota: u32 = args.next().and_then(|a| a.parse().ok()).unwrap_or(6000);
    let segmented_mode = args.next().is_some_and(|a| a == "segmented");
    let (steps, summary, counts, before, after) = if segmented_mode {
        let mut ba = SEGMENTED.lock().unwrap();
        let cfg = SynthConfig { keyframes: 65, points: 1000, ..ba_synth::SEGMENT_CFG };
        let seg = segmented(&cfg, 5, &mut *ba).unwrap();
        let before = seg.rig_error(|r| ba.rig_pose(r).unwrap());
        let (steps, s) = run(&mut *ba, &seg.synth, quota);
        let after = seg.rig_error(|r| ba.rig_pose(r).unwrap());
        (steps, s, ba.counts(), before, after)
    } else {
        let mut ba = LOCAL.lock().unwrap();
        let synth = Synth::generate(&SynthConfig::REALISTIC);
        let f = synth.fill_local(&mut *ba).unwrap();
        let before = synth.pose_rmse(|k| ba.camera_pose(f.cams[k]).unwrap()).0;
        let (steps, s) = run(&mut *ba, &synth, quota);
        let after = synth.pose_rmse(|k| ba.camera_pose(f.cams[k]).unwrap()).0;
        (steps, s, ba.counts(), before, after)
    };
    let (rigs, cams, points, obs) = counts;
    let mode = if segmented_mode { "segmented" } else { "local" };
    println!(
        "{mode}: {rigs} rigs, {cams} cameras, {points} points, {obs} observations; quota {quota}"
    );
    println!("{summary:?}");
    println!("steps {steps}, work units {}", summary.work_units);
    println!("pose (local) or segment centre RMSE: {before:.4} m -> {after:.4} m");
}
