//! Known-answer tests of the Fast-Hessian detector, and the full-frame reference that the
//! strip-wise detector must reproduce bit for bit.
//!
//! Test code only: this file is compiled under #[cfg(test)] (see the `mod` line that includes it).

#![allow(clippy::needless_range_loop)] // index loops read clearer in the reference

extern crate std;

use super::bucket::{GridBuckets, rank};
use super::filter::{
    FIRST_SAMPLE, IntegralRows, LAYERS, derivatives_at, laplacian_positive_at, response_at,
};
use super::hessian::{Grid, candidate, last_sample, plane};
use super::*;
use crate::image::{GrayView, GrayViewMut, downsample_gray_2x};
use crate::test_rng::TestRng;
use std::boxed::Box;
use std::vec;
use std::vec::Vec;

/// A full-frame integral image (modulo 2^16, as the detector's rows), as the reference computes it.
struct FullIntegral {
    rows: Vec<Vec<u16>>,
}

impl FullIntegral {
    fn new(img: &GrayView<'_>) -> Self {
        let (w, h) = img.size();
        let mut rows = vec![vec![0u16; w]; h];
        for y in 0..h {
            let mut acc = 0u16;
            for x in 0..w {
                acc = acc.wrapping_add(u16::from(img.get(x, y).unwrap()));
                rows[y][x] = acc.wrapping_add(if y > 0 { rows[y - 1][x] } else { 0 });
            }
        }
        Self { rows }
    }
}

impl IntegralRows for FullIntegral {
    fn row(&self, y: usize) -> &[u16] {
        &self.rows[y]
    }
}

/// Every candidate of one level, computed on the whole level image: all responses of all four
/// layers first, then NMS.
fn level_candidates(img: &GrayView<'_>, level: usize, threshold: f32, out: &mut Vec<Feature>) {
    let (w, h) = img.size();
    let Some(grid) = Grid::new(level, w, h) else { return };
    let last_y = last_sample(h, grid.step).unwrap();
    let ii = FullIntegral::new(img);
    let s = grid.step;
    // resp[layer][y / s][x / s]
    let mut resp = vec![vec![vec![0f32; w / s + 1]; h / s + 1]; LAYERS.len()];
    for (layer, spec) in LAYERS.iter().enumerate() {
        for y in (FIRST_SAMPLE..=last_y).step_by(s) {
            for x in (FIRST_SAMPLE..=grid.last_x).step_by(s) {
                resp[layer][y / s][x / s] = response_at(&ii, spec, x, y).unwrap();
            }
        }
    }
    for yc in (FIRST_SAMPLE + s..last_y).step_by(s) {
        for m in 1..LAYERS.len() - 1 {
            let j = yc / s;
            let rows = |l: usize| [&resp[l][j - 1][..], &resp[l][j][..], &resp[l][j + 1][..]];
            for i in FIRST_SAMPLE / s + 1..grid.last_x / s {
                let cube = [rows(m - 1), rows(m), rows(m + 1)].map(|r| plane(&r, i).unwrap());
                if let Some(f) = candidate(&cube, threshold, grid, i, yc, &LAYERS[m]) {
                    let lap = laplacian_positive_at(&ii, &LAYERS[m], i * s, yc).unwrap();
                    out.push(Feature { laplacian_positive: lap, ..f });
                }
            }
        }
    }
}

/// Every candidate of a full-frame computation of both levels.
fn reference_candidates(img: &GrayView<'_>, params: &HessianParams) -> Vec<Feature> {
    let mut out = Vec::new();
    level_candidates(img, 0, params.threshold, &mut out);
    let (w, h) = (img.width() / 2, img.height() / 2);
    if params.octaves >= 2 && w > 0 && h > 0 {
        let mut half = vec![0u8; w * h];
        downsample_gray_2x(img, &mut GrayViewMut::packed(&mut half, w, h).unwrap()).unwrap();
        level_candidates(&GrayView::packed(&half, w, h).unwrap(), 1, params.threshold, &mut out);
    }
    out
}

fn strip_candidates(img: &GrayView<'_>, params: &HessianParams) -> Vec<Feature> {
    let mut det = Box::new(VgaHessianDetector::new());
    let mut out = Vec::new();
    det.detect_candidates(img, params, &mut |f| out.push(f)).unwrap();
    out
}

fn sorted(mut v: Vec<Feature>) -> Vec<Feature> {
    v.sort_by(rank);
    v
}

/// A gray image with Gaussian blobs `(x, y, sigma, amplitude)` on a 128 background.
fn blobs(w: usize, h: usize, spots: &[(f32, f32, f32, f32)]) -> Vec<u8> {
    let mut img = vec![0u8; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut v = 128.0f32;
            for &(bx, by, sigma, amp) in spots {
                let d2 = (x as f32 - bx).powi(2) + (y as f32 - by).powi(2);
                v += amp * (-d2 / (2.0 * sigma * sigma)).exp();
            }
            img[y * w + x] = v.round().clamp(0.0, 255.0) as u8;
        }
    }
    img
}

/// Deterministic texture: random 4x4-pixel blocks, everywhere.
fn texture(w: usize, h: usize, seed: u64) -> Vec<u8> {
    let mut rng = TestRng::new(seed);
    let blocks: Vec<u8> =
        (0..(w / 4 + 1) * (h / 4 + 1)).map(|_| (rng.next_u32() >> 24) as u8).collect();
    (0..w * h).map(|k| blocks[(k / w / 4) * (w / 4 + 1) + (k % w) / 4]).collect()
}

/// Pixel sum of rows `y0..=y1`, columns `x0..=x1`, in 64-bit integers.
fn brute_box(img: &GrayView<'_>, (x0, x1): (usize, usize), (y0, y1): (usize, usize)) -> i64 {
    (y0..=y1)
        .flat_map(|y| (x0..=x1).map(move |x| (x, y)))
        .map(|(x, y)| i64::from(img.get(x, y).unwrap()))
        .sum()
}

#[test]
fn lobe_sums_modulo_2_16_are_exact_even_on_saturated_images() {
    // The Laplacian's sign is checked here too: it reads only the `Dxx` and `Dyy` rows.
    // Saturated (255) blocks make the largest lobes reach their maximum sums; the texture around
    // them gives every sign of every derivative.
    let (w, h) = (120, 100);
    let mut data = texture(w, h, 13);
    for y in 20..70 {
        for x in 30..90 {
            if x < 60 || (x / 9 + y / 11) % 3 != 0 {
                data[y * w + x] = 255;
            }
        }
    }
    let img = GrayView::packed(&data, w, h).unwrap();
    let ii = FullIntegral::new(&img);
    for layer in &LAYERS {
        let (l, b) = (layer.size / 3, (layer.size - 1) / 2);
        let h2 = (l - 1) / 2;
        for y in (b + 1..h - b).step_by(3) {
            for x in (b + 1..w - b).step_by(3) {
                let rows_xx = (y - (l - 1), y + (l - 1));
                let dxx = brute_box(&img, (x - b, x + b), rows_xx)
                    - 3 * brute_box(&img, (x - h2, x + h2), rows_xx);
                let cols_yy = (x - (l - 1), x + (l - 1));
                let dyy = brute_box(&img, cols_yy, (y - b, y + b))
                    - 3 * brute_box(&img, cols_yy, (y - h2, y + h2));
                let (up, down, left, right) =
                    ((y - l, y - 1), (y + 1, y + l), (x - l, x - 1), (x + 1, x + l));
                let dxy = brute_box(&img, left, up) + brute_box(&img, right, down)
                    - brute_box(&img, right, up)
                    - brute_box(&img, left, down);
                let got = derivatives_at(&ii, layer, x, y).unwrap();
                let got = (i64::from(got.0), i64::from(got.1), i64::from(got.2));
                assert_eq!(got, (dxx, dyy, dxy), "size {} at ({x}, {y})", layer.size);
                let lap = laplacian_positive_at(&ii, layer, x, y);
                assert_eq!(lap, Some(dxx + dyy >= 0), "size {} at ({x}, {y})", layer.size);
            }
        }
    }
}

/// The workspace is built at compile time, so it can live in a `static` (no stack copy).
static _CONST_BUILT: QvgaHessianDetector = QvgaHessianDetector::new();

#[test]
fn workspace_sizes_are_as_documented() {
    assert_eq!(core::mem::size_of::<QvgaHessianDetector>(), 37_032);
    assert_eq!(core::mem::size_of::<VgaHessianDetector>(), 61_672);
}

/// Measured: det(H) of SURF's box filters peaks on a Gaussian blob of standard deviation `s` at a
/// filter size whose SURF sigma `1.2 * size / 9` is about `0.71..0.77 * s` (the 9x9 box acts like
/// a Gaussian of sigma ~1.6, not 1.2). A perfect Gaussian DoH would give 1.
const BLOB_SIGMA_RATIO: f32 = 0.75;

#[test]
fn gaussian_blobs_are_found_at_their_position_scale_and_sign() {
    let (w, h) = (160, 180);
    let spots = [
        (40.3, 30.6, 2.4, 90.0),
        (110.0, 35.0, 3.0, -90.0),
        (45.0, 85.0, 4.4, -80.0),
        (115.5, 80.2, 5.2, 80.0),
        (80.0, 140.0, 7.0, -80.0),
    ];
    let data = blobs(w, h, &spots);
    let img = GrayView::packed(&data, w, h).unwrap();
    let mut det = Box::new(QvgaHessianDetector::new());
    let mut out = FeatureVec::new();
    det.detect(&img, &HessianParams::default(), &mut out).unwrap();
    for &(bx, by, sigma, amp) in &spots {
        let near: Vec<&Feature> =
            out.iter().filter(|f| (f.x - bx).abs() < 3.0 && (f.y - by).abs() < 3.0).collect();
        let best = near.iter().max_by(|a, b| a.response.total_cmp(&b.response));
        let f = best.unwrap_or_else(|| panic!("no feature near blob ({bx}, {by}); got {out:?}"));
        std::println!("blob ({bx}, {by}, sigma {sigma}): {f:?}");
        assert!(
            (f.x - bx).abs() <= 0.5 && (f.y - by).abs() <= 0.5,
            "position {f:?} vs ({bx}, {by})"
        );
        // SURF's sigma (1.2 * size / 9) of the peak is BLOB_SIGMA_RATIO times the blob's sigma.
        let expected = BLOB_SIGMA_RATIO * sigma;
        assert!((f.scale / expected - 1.0).abs() <= 0.2, "scale {} vs {expected}", f.scale);
        // A bright blob has negative second derivatives: the Laplacian is negative.
        assert_eq!(f.laplacian_positive, amp < 0.0);
    }
}

#[test]
fn a_flat_image_has_no_features() {
    let data = vec![77u8; 320 * 240];
    let img = GrayView::packed(&data, 320, 240).unwrap();
    let mut det = Box::new(QvgaHessianDetector::new());
    let mut out = FeatureVec::new();
    det.detect(&img, &HessianParams::default(), &mut out).unwrap();
    assert!(out.is_empty());
}

#[test]
fn strip_detector_matches_the_full_frame_reference() {
    let images = [
        (320, 240, texture(320, 240, 1)),
        (101, 77, texture(101, 77, 7)),
        (
            160,
            120,
            blobs(
                160,
                120,
                &[(40.3, 30.6, 2.4, 90.0), (110.0, 35.0, 3.0, -90.0), (80.0, 80.0, 5.0, 70.0)],
            ),
        ),
    ];
    for (w, h, data) in &images {
        let img = GrayView::packed(data, *w, *h).unwrap();
        for octaves in [1, 2] {
            let params = HessianParams { octaves, threshold: 50.0, ..HessianParams::default() };
            let strip = sorted(strip_candidates(&img, &params));
            let full = sorted(reference_candidates(&img, &params));
            assert!(!full.is_empty());
            // Bit-exact equality, including the float fields.
            let bits = |v: &[Feature]| {
                v.iter()
                    .map(|f| {
                        (
                            f.x.to_bits(),
                            f.y.to_bits(),
                            f.scale.to_bits(),
                            f.response.to_bits(),
                            f.laplacian_positive,
                        )
                    })
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(&strip), bits(&full), "{w}x{h}, {octaves} octaves");
            // And the bucketed selections agree too.
            let mut buckets = Box::new(GridBuckets::new());
            buckets.reset(&params, *w, *h);
            full.iter().for_each(|f| buckets.insert(f));
            let mut expected = FeatureVec::new();
            buckets.select(usize::from(params.max_features), &mut expected).unwrap();
            let mut det = Box::new(VgaHessianDetector::new());
            let mut got = FeatureVec::new();
            det.detect(&img, &params, &mut got).unwrap();
            assert_eq!(bits(&got), bits(&expected));
        }
    }
}

#[test]
fn bucketing_spreads_features_over_every_cell_within_the_caps() {
    let (w, h) = (320, 240);
    let data = texture(w, h, 3);
    let img = GrayView::packed(&data, w, h).unwrap();
    let mut det = Box::new(QvgaHessianDetector::new());
    for (cap, max) in [(12u8, 512u16), (4, 512), (12, 100)] {
        let params = HessianParams {
            per_cell_cap: cap,
            max_features: max,
            threshold: 20.0,
            ..HessianParams::default()
        };
        let mut out = FeatureVec::new();
        det.detect(&img, &params, &mut out).unwrap();
        let mut per_cell = [0usize; 48];
        for f in &out {
            let (cx, cy) = (((f.x + 0.5) as usize) * 8 / w, ((f.y + 0.5) as usize) * 6 / h);
            per_cell[cy * 8 + cx] += 1;
        }
        std::println!("cap {cap} max {max}: {} features, per cell {per_cell:?}", out.len());
        let mut cands = [0usize; 48];
        det.detect_candidates(&img, &params, &mut |f| {
            cands[((f.y + 0.5) as usize) * 6 / h * 8 + ((f.x + 0.5) as usize) * 8 / w] += 1;
        })
        .unwrap();
        let available: usize = cands.iter().map(|&n| n.min(usize::from(cap))).sum();
        assert!(per_cell.iter().all(|&n| n >= 1 && n <= usize::from(cap)));
        assert_eq!(out.len(), usize::from(max).min(available));
        // A cell below its cap got every candidate it had (the budget was not the limit).
        if out.len() < usize::from(max) {
            assert!(per_cell.iter().zip(&cands).all(|(&n, &c)| n == c.min(usize::from(cap))));
        }
        // Within a cell the features come strongest first, and no duplicates.
        let sorted_out = sorted(out.to_vec());
        assert!(sorted_out.windows(2).all(|p| rank(&p[0], &p[1]).is_lt()));
    }
}

#[test]
fn tiny_and_odd_images_do_not_panic() {
    let mut det = Box::new(QvgaHessianDetector::new());
    let mut out = FeatureVec::new();
    for (w, h) in [
        (1, 1),
        (2, 3),
        (9, 9),
        (27, 27),
        (28, 40),
        (40, 28),
        (52, 52),
        (53, 61),
        (320, 1),
        (1, 240),
        (33, 17),
    ] {
        let data = texture(w, h, 5);
        let img = GrayView::packed(&data, w, h).unwrap();
        det.detect(&img, &HessianParams::default(), &mut out).unwrap();
        if w < 30 || h < 30 {
            assert!(out.is_empty(), "{w}x{h}");
        }
        let mut n = 0;
        det.detect_candidates(
            &img,
            &HessianParams { threshold: 0.0, ..HessianParams::default() },
            &mut |_| n += 1,
        )
        .unwrap();
        assert_eq!(
            n,
            reference_candidates(
                &img,
                &HessianParams { threshold: 0.0, ..HessianParams::default() }
            )
            .len()
        );
    }
}

#[test]
fn a_stride_padded_view_gives_the_same_features() {
    let (w, h, stride) = (150, 110, 157);
    let packed = texture(w, h, 9);
    let mut padded = vec![255u8; stride * h];
    for y in 0..h {
        padded[y * stride..y * stride + w].copy_from_slice(&packed[y * w..(y + 1) * w]);
        padded[y * stride + w..(y + 1) * stride].fill((y * 37) as u8);
    }
    let a = GrayView::packed(&packed, w, h).unwrap();
    let b = GrayView::new(&padded, w, h, stride).unwrap();
    let mut det = Box::new(QvgaHessianDetector::new());
    let (mut fa, mut fb) = (FeatureVec::new(), FeatureVec::new());
    det.detect(&a, &HessianParams::default(), &mut fa).unwrap();
    det.detect(&b, &HessianParams::default(), &mut fb).unwrap();
    assert!(!fa.is_empty());
    assert_eq!(fa, fb);
}

#[test]
fn bad_input_is_an_error_value() {
    let data = vec![0u8; 65 * 10];
    let img = GrayView::packed(&data, 65, 10).unwrap();
    let mut det = Box::new(HessianDetector::<64>::new());
    let mut out = FeatureVec::new();
    assert_eq!(
        det.detect(&img, &HessianParams::default(), &mut out),
        Err(FeatureError::ImageTooWide { width: 65, max: 64 })
    );
    let bad = [
        HessianParams { threshold: f32::NAN, ..HessianParams::default() },
        HessianParams { threshold: -1.0, ..HessianParams::default() },
        HessianParams { octaves: 0, ..HessianParams::default() },
        HessianParams { octaves: 3, ..HessianParams::default() },
        HessianParams { grid_cols: 9, grid_rows: 8, ..HessianParams::default() },
        HessianParams { per_cell_cap: 13, ..HessianParams::default() },
        HessianParams { max_features: 513, ..HessianParams::default() },
    ];
    let small = GrayView::packed(&data, 64, 10).unwrap();
    for p in &bad {
        assert!(
            matches!(det.detect(&small, p, &mut out), Err(FeatureError::InvalidParams { .. })),
            "{p:?}"
        );
    }
    assert!(HessianParams::default().validate().is_ok());
}

#[test]
fn detection_is_repeatable_on_a_reused_workspace() {
    let (w, h) = (200, 150);
    let a = texture(w, h, 11);
    let b = blobs(w, h, &[(100.0, 75.0, 3.0, 90.0)]);
    let mut det = Box::new(QvgaHessianDetector::new());
    let mut first = FeatureVec::new();
    let mut again = FeatureVec::new();
    let mut other = FeatureVec::new();
    let p = HessianParams::default();
    det.detect(&GrayView::packed(&a, w, h).unwrap(), &p, &mut first).unwrap();
    det.detect(&GrayView::packed(&b, w, h).unwrap(), &p, &mut other).unwrap();
    det.detect(&GrayView::packed(&a, w, h).unwrap(), &p, &mut again).unwrap();
    assert_eq!(first, again);
}
