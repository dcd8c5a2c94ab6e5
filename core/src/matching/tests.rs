//! Known-answer tests of region matching on synthetic, deterministic images.
//!
//! Test code only: this file is compiled under #[cfg(test)] (see the `mod` line that includes it).

extern crate std;

use std::vec;
use std::vec::Vec;

use super::*;
use crate::image::{GrayView, GrayViewMut, variation_map};
use crate::test_rng::TestRng;

const W: usize = 320;
const H: usize = 240;

/// A smooth synthetic texture: a sum of sinusoids (wavelengths 12-40 px) plus Gaussian blobs
/// (sigma 3-7 px), defined at every real position.
struct Texture {
    waves: Vec<(f32, f32, f32, f32)>,
    blobs: Vec<(f32, f32, f32, f32)>,
}

impl Texture {
    fn new(seed: u32) -> Self {
        let mut rng = TestRng::xorshift32(seed);
        let waves = (0..6)
            .map(|_| {
                let angle = rng.uniform_f32(0.0, core::f32::consts::PI);
                let k = 2.0 * core::f32::consts::PI / rng.uniform_f32(12.0, 40.0);
                (k * libm::cosf(angle), k * libm::sinf(angle), rng.uniform_f32(0.0, 6.3), 14.0)
            })
            .collect();
        let blobs = (0..60)
            .map(|_| {
                let amp = rng.uniform_f32(-60.0, 60.0);
                (
                    rng.uniform_f32(0.0, W as f32),
                    rng.uniform_f32(0.0, H as f32),
                    rng.uniform_f32(3.0, 7.0),
                    amp,
                )
            })
            .collect();
        Self { waves, blobs }
    }

    fn value(&self, x: f32, y: f32) -> f32 {
        let mut v = 128.0;
        for &(kx, ky, ph, a) in &self.waves {
            v += a * libm::sinf(kx * x + ky * y + ph);
        }
        for &(bx, by, s, a) in &self.blobs {
            let d2 = (x - bx) * (x - bx) + (y - by) * (y - by);
            v += a * libm::expf(-d2 / (2.0 * s * s));
        }
        v
    }

    /// The QVGA image of the texture seen through `m`: pixel `q` shows `value(m^-1(q))`, rounded.
    fn render(&self, m: Motion) -> Vec<u8> {
        let inv = affine::mat_inverse(&m.a).unwrap();
        let mut img = vec![0u8; W * H];
        for (k, px) in img.iter_mut().enumerate() {
            let q = ((k % W) as f32 - C0.0 - m.t.0, (k / W) as f32 - C0.1 - m.t.1);
            let (dx, dy) = affine::mat_apply(&inv, q);
            *px = (self.value(C0.0 + dx, C0.1 + dy) + 0.5).clamp(0.0, 255.0) as u8;
        }
        img
    }
}

/// The texture of `seed` as a QVGA image.
fn textured(seed: u32) -> Vec<u8> {
    Texture::new(seed).render(Motion { a: IDENTITY, t: (0.0, 0.0) })
}

/// The source-to-target motion `q = C0 + A (p - C0) + t` about the image centre `C0`.
#[derive(Clone, Copy)]
struct Motion {
    a: Mat2,
    t: (f32, f32),
}

const C0: (f32, f32) = (160.0, 120.0);

impl Motion {
    fn similarity(deg: f32, scale: f32, t: (f32, f32)) -> Self {
        let (s, c) = (libm::sinf(deg.to_radians()), libm::cosf(deg.to_radians()));
        Self { a: [[c * scale, -s * scale], [s * scale, c * scale]], t }
    }

    fn apply(&self, p: (f32, f32)) -> (f32, f32) {
        let (dx, dy) = affine::mat_apply(&self.a, (p.0 - C0.0, p.1 - C0.1));
        (C0.0 + dx + self.t.0, C0.1 + dy + self.t.1)
    }
}

/// The target frame: `src` warped by `m` with bilinear sampling, then `gain * v + bias`, rounded
/// and clamped; 128 where the pre-image leaves the source.
fn warp(src: &[u8], m: Motion, gain: f32, bias: f32) -> Vec<u8> {
    let view = GrayView::packed(src, W, H).unwrap();
    let inv = affine::mat_inverse(&m.a).unwrap();
    let mut out = vec![0u8; W * H];
    for (k, px) in out.iter_mut().enumerate() {
        let q = ((k % W) as f32 - C0.0 - m.t.0, (k / W) as f32 - C0.1 - m.t.1);
        let (dx, dy) = affine::mat_apply(&inv, q);
        let v = sample_bilinear(&view, C0.0 + dx, C0.1 + dy).unwrap_or(128.0);
        *px = (v * gain + bias + 0.5).clamp(0.0, 255.0) as u8;
    }
    out
}

fn rois(src: &[u8]) -> heapless::Vec<Roi, 32> {
    let view = GrayView::packed(src, W, H).unwrap();
    let mut map = vec![0u8; W * H];
    variation_map(&view, &mut GrayViewMut::packed(&mut map, W, H).unwrap()).unwrap();
    select_rois::<32>(&GrayView::packed(&map, W, H).unwrap(), &RoiParams::default())
}

fn dist(a: (f32, f32), b: (f32, f32)) -> f32 {
    libm::sqrtf((a.0 - b.0) * (a.0 - b.0) + (a.1 - b.1) * (a.1 - b.1))
}

/// Matches every ROI whose true image lies well inside the target; returns the worst centre and
/// corner-point errors (pixels) and the number matched, after asserting at least `min_ok` matched
/// and printing how many were tried.
///
/// ROIs whose true target patch holds clipped pixels (0 or 255) are skipped: clipping is not a
/// gain and offset change, and ZNCC cannot see through it.
fn run(src: &[u8], dst: &[u8], m: Motion, min_ok: usize) -> (f32, f32, usize) {
    let (sv, dv) = (GrayView::packed(src, W, H).unwrap(), GrayView::packed(dst, W, H).unwrap());
    let p = MatchParams::default();
    let (mut worst_c, mut worst_p, mut ok, mut tried) = (0.0f32, 0.0f32, 0, 0);
    for roi in rois(src) {
        let truth = m.apply(roi.centre);
        if truth.0 < 30.0 || truth.1 < 30.0 || truth.0 > 290.0 || truth.1 > 210.0 {
            continue;
        }
        let clipped = (-9..=9).any(|j| {
            (-9..=9).any(|i| {
                let (x, y) = ((truth.0 as i32 + i) as usize, (truth.1 as i32 + j) as usize);
                matches!(dst.get(y * W + x), Some(0 | 255))
            })
        });
        if clipped {
            continue;
        }
        tried += 1;
        // A motion-model prediction off by a few pixels.
        let predicted = (truth.0 + 2.6, truth.1 - 1.7);
        let Ok(r) = match_region(&sv, roi.centre, &dv, predicted, &p) else {
            continue;
        };
        ok += 1;
        worst_c = worst_c.max(dist(r.centre_in_target, truth));
        for (i, j) in [(-7.0, -7.0), (7.0, -7.0), (-7.0, 7.0), (7.0, 7.0), (3.0, -5.0)] {
            let q = (roi.centre.0 + i, roi.centre.1 + j);
            worst_p = worst_p.max(dist(r.map_point(q), m.apply(q)));
        }
    }
    std::println!("{ok} of {tried} ROIs matched");
    assert!(ok >= min_ok, "{ok} of {tried} matched");
    (worst_c, worst_p, ok)
}

#[test]
fn rotation_scale_translation_is_recovered() {
    let src = textured(0x9E37_79B9);
    let m = Motion::similarity(7.0, 1.05, (3.3, -2.6));
    let dst = warp(&src, m, 1.0, 0.0);
    let (c, p, ok) = run(&src, &dst, m, 8);
    std::println!("affine: {ok} matched, centre error <= {c} px, points <= {p} px");
    assert!(c < 0.15, "centre error {c}");
    assert!(p < 0.3, "point error {p}");
}

#[test]
fn pure_translation_is_recovered() {
    let m = Motion { a: IDENTITY, t: (3.3, -2.6) };
    // Target rendered exactly from the texture: the error is the matcher's alone.
    let tex = Texture::new(0x1234_5678);
    let (src, dst) = (tex.render(Motion { a: IDENTITY, t: (0.0, 0.0) }), tex.render(m));
    let (c, p, ok) = run(&src, &dst, m, 10);
    std::println!("translation (exact target): {ok} matched, centre <= {c} px, points <= {p} px");
    assert!(c < 0.05, "centre error {c}");
    assert!(p < 0.1, "point error {p}");
    // Target bilinearly resampled from the source image: the resampling's own phase error at
    // this sub-pixel shift (up to a few hundredths of a pixel) adds to the matcher's.
    let dst = warp(&src, m, 1.0, 0.0);
    let (c, p, ok) = run(&src, &dst, m, 10);
    std::println!(
        "translation (bilinear target): {ok} matched, centre <= {c} px, points <= {p} px"
    );
    assert!(c < 0.08, "centre error {c}");
    assert!(p < 0.25, "point error {p}");
}

#[test]
fn gain_and_offset_change_still_matches() {
    let src = textured(0x9E37_79B9);
    let m = Motion::similarity(7.0, 1.05, (3.3, -2.6));
    let dst = warp(&src, m, 1.3, 20.0);
    let (c, p, ok) = run(&src, &dst, m, 5);
    std::println!("gain/offset: {ok} matched, centre error <= {c} px, points <= {p} px");
    assert!(c < 0.2, "centre error {c}");
    assert!(p < 0.4, "point error {p}");
}

fn params_no_fb() -> MatchParams {
    MatchParams { forward_backward_max_px: None, ..MatchParams::default() }
}

#[test]
fn unrelated_target_is_rejected() {
    let src = textured(0x0BAD_F00D);
    let other = textured(0x5EED_0001);
    let (sv, ov) = (GrayView::packed(&src, W, H).unwrap(), GrayView::packed(&other, W, H).unwrap());
    let mut accepted = 0;
    let all = rois(&src);
    for roi in &all {
        if match_region(&sv, roi.centre, &ov, roi.centre, &MatchParams::default()).is_ok() {
            accepted += 1;
        }
    }
    std::println!("unrelated: {accepted} of {} accepted", all.len());
    assert!(all.len() >= 8);
    assert!(accepted * 10 <= all.len(), "{accepted} of {} accepted", all.len());
}

#[test]
fn flat_template_is_rejected() {
    let flat = vec![77u8; W * H];
    let src = textured(7);
    let (fv, sv) = (GrayView::packed(&flat, W, H).unwrap(), GrayView::packed(&src, W, H).unwrap());
    let r = match_region(&fv, (100.0, 100.0), &sv, (100.0, 100.0), &MatchParams::default());
    assert!(matches!(r, Err(MatchError::FlatTemplate { std_dev }) if std_dev == 0.0), "{r:?}");
}

#[test]
fn borders_and_bad_input_do_not_panic() {
    let src = textured(11);
    let m = Motion { a: IDENTITY, t: (1.5, 0.5) };
    let dst = warp(&src, m, 1.0, 0.0);
    let (sv, dv) = (GrayView::packed(&src, W, H).unwrap(), GrayView::packed(&dst, W, H).unwrap());
    let p = MatchParams::default();
    // The template with its margin must fit: 8 px from the border at h = 7.
    assert_eq!(
        match_region(&sv, (7.0, 50.0), &dv, (8.5, 50.5), &p),
        Err(MatchError::TemplateOutOfImage)
    );
    assert_eq!(
        match_region(&sv, (50.0, 232.0), &dv, (51.5, 232.5), &p),
        Err(MatchError::TemplateOutOfImage)
    );
    // Search windows hanging over every border: candidates outside are skipped, never read.
    for c in [(8.0, 8.0), (311.0, 8.0), (8.0, 231.0), (311.0, 231.0), (160.0, 8.0)] {
        let r = match_region(&sv, c, &dv, c, &p);
        if let Ok(r) = r {
            assert!(dist(r.centre_in_target, m.apply(c)) < 0.2, "{c:?}: {r:?}");
        }
    }
    // A prediction far outside the target.
    assert_eq!(
        match_region(&sv, (100.0, 100.0), &dv, (-500.0, 100.0), &p),
        Err(MatchError::NoCandidate)
    );
    for bad in [(f32::NAN, 100.0), (100.0, f32::INFINITY)] {
        assert_eq!(match_region(&sv, bad, &dv, (100.0, 100.0), &p), Err(MatchError::InvalidParams));
        assert_eq!(match_region(&sv, (100.0, 100.0), &dv, bad, &p), Err(MatchError::InvalidParams));
    }
    for q in [
        MatchParams { half_size: 0, ..p },
        MatchParams { half_size: MAX_HALF_SIZE + 1, ..p },
        MatchParams { coarse_step: 0, ..p },
        MatchParams { coarse_step: usize::MAX, ..p },
        MatchParams { search_radius: usize::MAX, ..p },
        MatchParams { bank: &[], ..p },
        MatchParams { initial_affine: [[0.0, 0.0], [0.0, 0.0]], ..p },
        MatchParams { min_zncc: f32::NAN, ..p },
    ] {
        assert_eq!(
            match_region(&sv, (100.0, 100.0), &dv, (100.0, 100.0), &q),
            Err(MatchError::InvalidParams)
        );
    }
    // Tiny images.
    let tiny = [0u8, 255, 0, 255];
    let tv = GrayView::packed(&tiny, 2, 2).unwrap();
    assert_eq!(
        match_region(&tv, (0.5, 0.5), &tv, (0.5, 0.5), &p),
        Err(MatchError::TemplateOutOfImage)
    );
    assert_eq!(
        match_region(&sv, (100.0, 100.0), &tv, (0.5, 0.5), &params_no_fb()),
        Err(MatchError::NoCandidate)
    );
}

#[test]
fn largest_template_and_initial_guess() {
    let src = textured(0x00C0_FFEE);
    let m = Motion::similarity(25.0, 1.0, (2.0, 1.0));
    let dst = warp(&src, m, 1.0, 0.0);
    let (sv, dv) = (GrayView::packed(&src, W, H).unwrap(), GrayView::packed(&dst, W, H).unwrap());
    let c = (150.0, 110.0);
    let truth = m.apply(c);
    // 25 degrees is outside the bank; an initial guess of 20 degrees brings it back in reach.
    let guess = Motion::similarity(20.0, 1.0, (0.0, 0.0)).a;
    let p =
        MatchParams { half_size: MAX_HALF_SIZE, initial_affine: guess, ..MatchParams::default() };
    let r = match_region(&sv, c, &dv, (truth.0 + 1.0, truth.1 - 2.0), &p).unwrap();
    assert!(dist(r.centre_in_target, truth) < 0.1, "{r:?}");
    let q = (c.0 + 10.0, c.1 - 10.0);
    assert!(dist(r.map_point(q), m.apply(q)) < 0.3);
    assert!((r.translation().0 - (truth.0 - c.0)).abs() < 0.1);
}

/// A pattern that repeats every 6 px: every search window holds several equally good peaks.
#[test]
fn repeated_pattern_is_rejected() {
    let period = 6.0 * core::f32::consts::FRAC_1_PI * 0.5;
    let mut src = vec![0u8; W * H];
    for (k, px) in src.iter_mut().enumerate() {
        let (x, y) = ((k % W) as f32, (k / W) as f32);
        *px = (128.0 + 60.0 * libm::sinf(x / period) + 50.0 * libm::sinf(y / period)) as u8;
    }
    let m = Motion { a: IDENTITY, t: (2.4, -1.3) };
    let dst = warp(&src, m, 1.0, 0.0);
    let (sv, dv) = (GrayView::packed(&src, W, H).unwrap(), GrayView::packed(&dst, W, H).unwrap());
    let fb_only = MatchParams { min_peak_margin: None, ..MatchParams::default() };
    let (mut ambiguous, mut fb_rejected, mut wrong_fb_only, mut total) = (0, 0, 0, 0);
    for cy in (40..200).step_by(20) {
        for cx in (40..280).step_by(20) {
            let c = (cx as f32, cy as f32);
            let truth = m.apply(c);
            let predicted = (truth.0 + 2.9, truth.1 - 2.2);
            total += 1;
            match match_region(&sv, c, &dv, predicted, &MatchParams::default()) {
                Err(MatchError::Ambiguous { .. }) => ambiguous += 1,
                Ok(r) => assert!(dist(r.centre_in_target, truth) < 0.2, "{c:?}: {r:?}"),
                Err(_) => {}
            }
            // Without the peak test, the forward-backward check is the only guard.
            match match_region(&sv, c, &dv, predicted, &fb_only) {
                Err(MatchError::ForwardBackward { .. }) => fb_rejected += 1,
                Ok(r) if dist(r.centre_in_target, truth) > 0.5 => wrong_fb_only += 1,
                _ => {}
            }
        }
    }
    std::println!(
        "repeated: {ambiguous} of {total} ambiguous; forward-backward alone rejects {fb_rejected} \
         and accepts {wrong_fb_only} wrong"
    );
    assert!(ambiguous * 10 >= total * 9, "{ambiguous} of {total}");
    assert!(fb_rejected * 2 >= total, "{fb_rejected} of {total}");
}

#[test]
fn rois_are_spread_and_disjoint() {
    let src = textured(0x9E37_79B9);
    let all = rois(&src);
    assert!(all.len() >= 20, "{}", all.len());
    for (k, a) in all.iter().enumerate() {
        assert!(
            a.centre.0 >= 9.0 && a.centre.1 >= 9.0 && a.centre.0 <= 310.0 && a.centre.1 <= 230.0
        );
        if let Some(b) = all.get(k + 1) {
            assert!(a.score >= b.score);
        }
        for b in all.iter().skip(k + 1) {
            let apart =
                (a.centre.0 - b.centre.0).abs() >= 15.0 || (a.centre.1 - b.centre.1).abs() >= 15.0;
            assert!(apart, "{a:?} overlaps {b:?}");
        }
    }
    // A cap below the number of cells keeps the best.
    let view = GrayView::packed(&src, W, H).unwrap();
    let mut map = vec![0u8; W * H];
    variation_map(&view, &mut GrayViewMut::packed(&mut map, W, H).unwrap()).unwrap();
    let mv = GrayView::packed(&map, W, H).unwrap();
    let few = select_rois::<4>(&mv, &RoiParams::default());
    assert_eq!(few.len(), 4);
    assert_eq!(few.first().map(|r| r.score), all.first().map(|r| r.score));
    // Flat and tiny maps give nothing, without panicking.
    let flat = vec![0u8; W * H];
    assert!(
        select_rois::<8>(&GrayView::packed(&flat, W, H).unwrap(), &RoiParams::default()).is_empty()
    );
    let tiny = [200u8; 9];
    assert!(
        select_rois::<8>(&GrayView::packed(&tiny, 3, 3).unwrap(), &RoiParams::default()).is_empty()
    );
    let odd = RoiParams { cell_px: 0, candidate_step: 0, half_size: 0, ..RoiParams::default() };
    let _ = select_rois::<8>(&mv, &odd);
    let huge = RoiParams { half_size: usize::MAX, border_px: usize::MAX, ..RoiParams::default() };
    assert!(select_rois::<8>(&mv, &huge).is_empty());
    let wide = RoiParams { border_px: usize::MAX, cell_px: usize::MAX, ..RoiParams::default() };
    assert!(select_rois::<8>(&mv, &wide).is_empty());
}

/// Tracks the centre of every ROI whose true image lies well inside the target with
/// [`track_patch`], the true linear map as the predicted one and the prediction off by
/// `pred_err`; returns the worst centre error (pixels) after asserting at least `min_ok`
/// tracked. ROIs whose true target patch holds clipped pixels are skipped.
fn run_track(
    src: &[u8],
    dst: &[u8],
    m: Motion,
    pred_err: (f32, f32),
    params: &TrackParams,
    min_ok: usize,
) -> f32 {
    let (sv, dv) = (GrayView::packed(src, W, H).unwrap(), GrayView::packed(dst, W, H).unwrap());
    let (mut worst, mut ok, mut tried) = (0.0f32, 0, 0);
    for roi in rois(src) {
        let truth = m.apply(roi.centre);
        if truth.0 < 30.0 || truth.1 < 30.0 || truth.0 > 290.0 || truth.1 > 210.0 {
            continue;
        }
        // Clipped pixels (0 or 255) are not a gain and offset change: skip, as `run` does.
        let clipped = (-6..=6).any(|j| {
            (-6..=6).any(|i| {
                let (x, y) = ((truth.0 as i32 + i) as usize, (truth.1 as i32 + j) as usize);
                matches!(dst.get(y * W + x), Some(0 | 255))
            })
        });
        if clipped {
            continue;
        }
        tried += 1;
        let predicted = (truth.0 + pred_err.0, truth.1 + pred_err.1);
        let Ok(r) = track_patch(&sv, roi.centre, &m.a, &dv, predicted, params) else {
            continue;
        };
        ok += 1;
        worst = worst.max(dist(r.uv, truth));
        assert!((r.offset_px - dist(r.uv, predicted)).abs() < 1e-4);
    }
    std::println!("{ok} of {tried} tracked, worst centre error {worst} px");
    assert!(ok >= min_ok, "{ok} of {tried} tracked");
    worst
}

#[test]
fn track_recovers_translation_from_a_close_prediction() {
    let m = Motion { a: IDENTITY, t: (3.3, -2.6) };
    // Target rendered exactly from the texture: the error is the tracker's alone.
    let tex = Texture::new(0x1234_5678);
    let (src, dst) = (tex.render(Motion { a: IDENTITY, t: (0.0, 0.0) }), tex.render(m));
    let worst = run_track(&src, &dst, m, (0.7, -0.45), &TrackParams::FINE, 10);
    assert!(worst < 0.05, "centre error {worst}");
}

#[test]
fn track_recovers_rotation_scale_with_the_predicted_map() {
    let src = textured(0x9E37_79B9);
    let m = Motion::similarity(7.0, 1.05, (3.3, -2.6));
    let dst = warp(&src, m, 1.0, 0.0);
    // The guide stage: a prediction several pixels off.
    let worst = run_track(&src, &dst, m, (4.6, -3.2), &TrackParams::GUIDE, 8);
    assert!(worst < 0.15, "centre error {worst}");
    // With a gain and offset change.
    let dst = warp(&src, m, 1.3, 20.0);
    let worst = run_track(&src, &dst, m, (0.6, 0.3), &TrackParams::FINE, 5);
    assert!(worst < 0.2, "centre error {worst}");
}

#[test]
fn track_rejects_an_unrelated_target_and_a_repeated_pattern() {
    let src = textured(0x0BAD_F00D);
    let other = textured(0x5EED_0001);
    let (sv, ov) = (GrayView::packed(&src, W, H).unwrap(), GrayView::packed(&other, W, H).unwrap());
    let all = rois(&src);
    let accepted = all
        .iter()
        .filter(|r| {
            track_patch(&sv, r.centre, &IDENTITY, &ov, r.centre, &TrackParams::GUIDE).is_ok()
        })
        .count();
    std::println!("unrelated: {accepted} of {} accepted", all.len());
    assert!(all.len() >= 8);
    assert!(accepted * 10 <= all.len(), "{accepted} of {} accepted", all.len());

    let period = 6.0 * core::f32::consts::FRAC_1_PI * 0.5;
    let mut rep = vec![0u8; W * H];
    for (k, px) in rep.iter_mut().enumerate() {
        let (x, y) = ((k % W) as f32, (k / W) as f32);
        *px = (128.0 + 60.0 * libm::sinf(x / period) + 50.0 * libm::sinf(y / period)) as u8;
    }
    let m = Motion { a: IDENTITY, t: (2.4, -1.3) };
    let dst = warp(&rep, m, 1.0, 0.0);
    let (rv, dv) = (GrayView::packed(&rep, W, H).unwrap(), GrayView::packed(&dst, W, H).unwrap());
    let (mut ambiguous, mut total) = (0, 0);
    for cy in (40..200).step_by(20) {
        for cx in (40..280).step_by(20) {
            let c = (cx as f32, cy as f32);
            let truth = m.apply(c);
            total += 1;
            let p = (truth.0 + 2.9, truth.1 - 2.2);
            match track_patch(&rv, c, &IDENTITY, &dv, p, &TrackParams::GUIDE) {
                Err(MatchError::Ambiguous { .. }) => ambiguous += 1,
                Ok(r) => assert!(dist(r.uv, truth) < 0.2, "{c:?}: {r:?}"),
                Err(_) => {}
            }
        }
    }
    std::println!("repeated: {ambiguous} of {total} ambiguous");
    assert!(ambiguous * 10 >= total * 9, "{ambiguous} of {total}");
}

#[test]
fn track_bad_input_and_borders_do_not_panic() {
    let src = textured(11);
    let dst = warp(&src, Motion { a: IDENTITY, t: (1.5, 0.5) }, 1.0, 0.0);
    let (sv, dv) = (GrayView::packed(&src, W, H).unwrap(), GrayView::packed(&dst, W, H).unwrap());
    let p = TrackParams::FINE;
    let c = (100.0, 100.0);
    let flat = vec![77u8; W * H];
    let fv = GrayView::packed(&flat, W, H).unwrap();
    assert!(matches!(
        track_patch(&fv, c, &IDENTITY, &dv, c, &p),
        Err(MatchError::FlatTemplate { std_dev }) if std_dev == 0.0
    ));
    // Template with its margin must fit (5 px at h = 4); the search window too (6 px at R = 1).
    assert_eq!(
        track_patch(&sv, (4.0, 50.0), &IDENTITY, &dv, (50.0, 50.0), &p),
        Err(MatchError::TemplateOutOfImage)
    );
    let (p1, p0) = (TrackParams { search_radius: 1, ..p }, TrackParams { search_radius: 0, ..p });
    for edge in [(4.4, 50.0), (50.0, 234.6), (-500.0, 100.0), (314.5, 100.0)] {
        assert_eq!(track_patch(&sv, c, &IDENTITY, &dv, edge, &p1), Err(MatchError::NoCandidate));
        // Without a search, Lucas-Kanade meets the border instead.
        assert_eq!(
            track_patch(&sv, c, &IDENTITY, &dv, edge, &p0),
            Err(MatchError::RefinementFailed)
        );
    }
    for bad in [(f32::NAN, 100.0), (100.0, f32::INFINITY)] {
        assert_eq!(track_patch(&sv, bad, &IDENTITY, &dv, c, &p), Err(MatchError::InvalidParams));
        assert_eq!(track_patch(&sv, c, &IDENTITY, &dv, bad, &p), Err(MatchError::InvalidParams));
    }
    let singular = [[1.0, 2.0], [2.0, 4.0]];
    assert_eq!(track_patch(&sv, c, &singular, &dv, c, &p), Err(MatchError::InvalidParams));
    for q in [
        TrackParams { half_size: 0, ..p },
        TrackParams { half_size: MAX_TRACK_HALF_SIZE + 1, ..p },
        TrackParams { search_radius: MAX_TRACK_SEARCH_RADIUS + 1, ..p },
        TrackParams { search_step: 0, ..p },
        TrackParams { search_step: 9, ..p },
        TrackParams { search_radius: 9, search_step: 1, ..p },
        TrackParams { min_zncc: f32::NAN, ..p },
        TrackParams { max_refine_shift_px: 0.0, ..p },
    ] {
        assert_eq!(track_patch(&sv, c, &IDENTITY, &dv, c, &q), Err(MatchError::InvalidParams));
    }
    // The largest template and radius work, and every window inside the image is accepted.
    let big = TrackParams {
        half_size: MAX_TRACK_HALF_SIZE,
        search_radius: MAX_TRACK_SEARCH_RADIUS,
        search_step: 4,
        ..TrackParams::GUIDE
    };
    let truth = (c.0 + 1.5, c.1 + 0.5);
    let r = track_patch(&sv, c, &IDENTITY, &dv, (truth.0 - 9.0, truth.1 + 7.0), &big).unwrap();
    assert!(dist(r.uv, truth) < 0.1, "{r:?}");
    let tiny = [0u8, 255, 0, 255];
    let tv = GrayView::packed(&tiny, 2, 2).unwrap();
    assert_eq!(track_patch(&sv, c, &IDENTITY, &tv, (0.5, 0.5), &p1), Err(MatchError::NoCandidate));
}

/// One scratch reused by every call gives each call's result bit for bit as a fresh one does,
/// whatever the calls before it left in the scratch: successes, failures part way through (an
/// ambiguous search, a refinement off the image), other radii, steps and template sizes.
#[test]
fn track_with_a_reused_scratch_equals_a_fresh_one() {
    let m = Motion::similarity(4.0, 1.04, (2.6, -1.8));
    let src = textured(0x51DE_CAFE);
    let dst = warp(&src, m, 1.1, -6.0);
    let (sv, dv) = (GrayView::packed(&src, W, H).unwrap(), GrayView::packed(&dst, W, H).unwrap());
    let f = TrackParams::FINE;
    let params = [
        f,
        TrackParams::GUIDE,
        TrackParams { search_radius: 0, ..f },
        TrackParams::GUIDE_WIDE,
        TrackParams { half_size: 6, ..f },
        TrackParams { search_radius: 2, search_step: 2, ..TrackParams::GUIDE },
    ];
    let mut scratch = TrackScratch::new();
    let (mut calls, mut ok, mut failed) = (0, 0, 0);
    for (k, (cy, cx)) in
        (8..232).step_by(11).flat_map(|y| (8..312).step_by(13).map(move |x| (y, x))).enumerate()
    {
        let c = (cx as f32 + 0.3, cy as f32 - 0.2);
        let truth = m.apply(c);
        // Prediction errors of up to 3 px; near the border, searches and refinements leave the
        // image.
        let e = ((k % 7) as f32 - 3.0, (k % 5) as f32 * 0.7 - 1.4);
        let pred = (truth.0 + e.0, truth.1 + e.1);
        let p = &params[k % params.len()];
        let fresh = track_patch(&sv, c, &m.a, &dv, pred, p);
        let reused = track_patch_with(&mut scratch, &sv, c, &m.a, &dv, pred, p);
        let bits = |r: &Result<PatchTrack, MatchError>| {
            r.as_ref().map(|t| (t.uv.0.to_bits(), t.uv.1.to_bits(), t.zncc.to_bits())).ok()
        };
        assert_eq!(bits(&reused), bits(&fresh), "call {k} at {c:?}");
        assert_eq!(reused, fresh, "call {k} at {c:?}");
        calls += 1;
        if fresh.is_ok() { ok += 1 } else { failed += 1 }
    }
    std::println!("{calls} calls: {ok} tracked, {failed} failed");
    assert!(ok >= 150 && failed >= 50, "{ok} tracked, {failed} failed");
}
