//! Runs the Fast-Hessian detector on real RGB-D colour frames, for instruction counts by
//! callgrind (the detector's cost is counted, not timed) and for a feature dump to compare
//! detectors.
//!
//! ```text
//! cargo build --release -p ferroslam-core --example detect_bench
//! valgrind --tool=callgrind --callgrind-out-file=/tmp/cg.out \
//!     --toggle-collect='*HessianDetector*::detect' \
//!     target/release/examples/detect_bench ../shared/datasets/7scenes-redkitchen-1000 qvga
//! ```
//!
//! A Cortex-M core has no SIMD for this code; for a count closer to it, build the bench without
//! auto-vectorization into its own target directory:
//! `RUSTFLAGS="-C llvm-args=-vectorize-loops=false -C llvm-args=-vectorize-slp=false"
//! CARGO_TARGET_DIR=/tmp/target-scalar cargo build --release -p ferroslam-core --example detect_bench`.
//!
//! Arguments: `DATASET [qvga|vga] [--frames N] [--stride S] [--threshold T] [--dump]`. Frames
//! `0, S, 2S, ...` (N of them, default 10 with stride 100) of `DATASET/rgb.txt` are decoded to gray
//! with OpenCV's BT.601 fixed-point luma (as host-sim does), halved once for `qvga` (the default)
//! with the core's 2x2 downsampler, and detected with the front end's threshold (30) unless
//! `--threshold` says otherwise. Instructions per call = callgrind's total / calls printed.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

extern crate std;

use ferroslam_core::features::{
    FeatureVec, HessianDetector, HessianParams, QvgaHessianDetector, VgaHessianDetector,
};
use ferroslam_core::image::{GrayView, GrayViewMut, downsample_gray_2x};
use std::path::{Path, PathBuf};

/// A decoded gray frame.
struct Gray {
    w: usize,
    h: usize,
    px: Vec<u8>,
}

fn load(dataset: &Path, name: &str, halve: bool) -> Gray {
    let rgb = image::open(dataset.join(name)).expect("image decodes").to_rgb8();
    let (w, h) = (rgb.width() as usize, rgb.height() as usize);
    let px: Vec<u8> = rgb
        .pixels()
        .map(|p| {
            let [r, g, b] = p.0.map(u32::from);
            ((4899 * r + 9617 * g + 1868 * b + 8192) >> 14) as u8
        })
        .collect();
    if !halve {
        return Gray { w, h, px };
    }
    let (hw, hh) = (w / 2, h / 2);
    let mut out = vec![0u8; hw * hh];
    let src = GrayView::packed(&px, w, h).unwrap();
    downsample_gray_2x(&src, &mut GrayViewMut::packed(&mut out, hw, hh).unwrap()).unwrap();
    Gray { w: hw, h: hh, px: out }
}

fn colour_frames(dataset: &Path) -> Vec<String> {
    let list = std::fs::read_to_string(dataset.join("rgb.txt")).expect("rgb.txt");
    list.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().nth(1).map(str::to_owned))
        .collect()
}

fn run<const W: usize>(
    det: &mut HessianDetector<W>,
    frames: &[Gray],
    params: &HessianParams,
    dump: bool,
) {
    let mut out = FeatureVec::new();
    for (k, g) in frames.iter().enumerate() {
        let img = GrayView::packed(&g.px, g.w, g.h).unwrap();
        det.detect(&img, params, &mut out).unwrap();
        println!("frame {k}: {} features", out.len());
        if dump {
            for f in &out {
                let lap = u8::from(f.laplacian_positive);
                println!("F {k} {} {} {} {} {lap}", f.x, f.y, f.scale, f.response);
            }
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dataset = PathBuf::from(args.first().expect("usage: detect_bench DATASET [qvga|vga]"));
    let vga = args.iter().any(|a| a == "vga");
    let dump = args.iter().any(|a| a == "--dump");
    let opt = |name: &str, default: f32| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .map_or(default, |v| v.parse().expect("a number"))
    };
    let (n, stride) = (opt("--frames", 10.0) as usize, opt("--stride", 100.0) as usize);
    let params = HessianParams { threshold: opt("--threshold", 30.0), ..HessianParams::DEFAULT };
    let names = colour_frames(&dataset);
    let frames: Vec<Gray> =
        names.iter().step_by(stride).take(n).map(|f| load(&dataset, f, !vga)).collect();
    println!("{} frames, {}x{}", frames.len(), frames[0].w, frames[0].h);

    if vga {
        run(&mut Box::new(VgaHessianDetector::new()), &frames, &params, dump);
    } else {
        run(&mut Box::new(QvgaHessianDetector::new()), &frames, &params, dump);
    }
}
