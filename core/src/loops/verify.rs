//! Geometric verification of a remembered place against a lost frame: RGB-D gives 3D points on
//! both sides, so a rigid motion from three matched points (Horn/Umeyama,
//! [`align_rigid`]) is checked against all matches.
//!
//! 1. Matches: each of the place's points takes the query point with the nearest descriptor when
//!    it is within `max_descriptor_distance` bits and the second nearest is `descriptor_margin`
//!    bits further (no look-alike).
//! 2. RANSAC: [`RANSAC_ITERATIONS`] draws of three matches; a draw whose triangle's sides differ
//!    between the two views by more than the inlier distance cannot be rigid and is dropped
//!    unsolved; the others give a motion by the triad construction (an orthonormal frame on
//!    each triangle: about a hundred flops, against an SVD's thousands). A match is an inlier
//!    when the motion brings its query point within `inlier_base_m + inlier_depth_ratio z` of the
//!    place's (`z` the place point's depth: the sensor's noise grows with it). The first draw with
//!    the most inliers wins, then the motion is refitted on its inliers by Horn/Umeyama
//!    ([`align_rigid`]) and the inliers counted again.
//! 3. Acceptance: at least `min_inliers` inliers, at least `min_inlier_ratio` of the matches, and
//!    the inliers' pixels spread over at least `min_spread` of the frame's width and of its
//!    height (points on one small patch fix a pose poorly and are the typical false match).
//! 4. Ambiguity: RANSAC again on the matches the motion leaves out; a second motion with at least
//!    `min_inliers` inliers and `max_rival` of the first's (part of the scene moved, or two
//!    look-alike parts) refuses the place.

use heapless::Vec;
use nalgebra::{Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

use crate::config::capacity::PLACE_POINTS;
use crate::geometry::{Pose, align_rigid};
use crate::map::PlacePoint;
use crate::pose::TrackingRng;
use crate::tracking::PlaceQuery;

/// Draws of three matches per verification.
pub const RANSAC_ITERATIONS: usize = 96;

const _: () = assert!(PLACE_POINTS <= 64, "inlier sets are 64-bit masks");

/// The thresholds of a verification (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VerifyParams {
    /// Largest descriptor distance of a match, bits of 64.
    pub max_descriptor_distance: u32,
    /// The second-nearest query point must be at least this many bits further.
    pub descriptor_margin: u32,
    /// Inlier distance at zero depth, metres.
    pub inlier_base_m: f32,
    /// Inlier distance growth with depth, metres per metre.
    pub inlier_depth_ratio: f32,
    /// Fewest inliers of an accepted place.
    pub min_inliers: usize,
    /// Smallest fraction of the matches that must be inliers.
    pub min_inlier_ratio: f32,
    /// Smallest extent of the inliers' pixels, as a fraction of the frame's width and height.
    pub min_spread: f32,
    /// A second motion among the other matches with at least `min_inliers` inliers and this
    /// fraction of the first's makes the place ambiguous (refused).
    pub max_rival: f32,
}

impl VerifyParams {
    /// The defaults: matches as strict as map reuse's (a different view of the same point stays
    /// within about 12 of 64 bits; unrelated points differ by about 32), inliers within the
    /// depth noise of a Kinect-class sensor, and at least 10 inliers spread over a quarter of
    /// the frame each way. Why: docs/decisions.md, "Geometric verification of a place".
    pub const DEFAULT: Self = Self {
        max_descriptor_distance: 14,
        descriptor_margin: 4,
        inlier_base_m: 0.03,
        inlier_depth_ratio: 0.02,
        min_inliers: 10,
        min_inlier_ratio: 0.4,
        min_spread: 0.25,
        max_rival: 0.5,
    };

    /// The inlier distance (metres) of a place point at depth `z` (metres).
    pub fn inlier_distance(&self, z: f32) -> f32 {
        self.inlier_base_m + self.inlier_depth_ratio * z
    }
}

/// A descriptor match: the query point, the place's point (each in its camera, metres) and the
/// query point's pixel.
type Match = (Point3<f32>, Point3<f32>, (f32, f32));

/// The rigid motion taking the triangle `src` onto `dst` (query to place camera): the rotation
/// between orthonormal frames built on each triangle (its first side, the normal, their cross
/// product), the translation between the centroids. `None` for a triangle too thin to fix a
/// frame, or sides that differ by more than the inlier distance at the place's depth.
fn triad(src: [Point3<f32>; 3], dst: [Point3<f32>; 3], params: &VerifyParams) -> Option<Pose> {
    let [a, b, c] = src;
    let [a2, b2, c2] = dst;
    let tol = params.inlier_distance(a2.z.max(b2.z).max(c2.z));
    let len = |v: Vector3<f32>| ferroslam_fpu::sqrtf(v.norm_squared());
    for (p, q) in [(b - a, b2 - a2), (c - a, c2 - a2), (c - b, c2 - b2)] {
        if (len(p) - len(q)).abs() > tol {
            return None;
        }
    }
    let frame = |a: Point3<f32>, b: Point3<f32>, c: Point3<f32>| -> Option<Matrix3<f32>> {
        let (u, w) = (b - a, c - a);
        let n = u.cross(&w);
        let (lu, ln) = (len(u), len(n));
        // Sides of a few centimetres at least, and not collinear (sine above about 0.1).
        if lu < 1e-2 || ln < 0.1 * lu * len(w) || ln <= 0.0 {
            return None;
        }
        let e1 = u / lu;
        let e3 = n / ln;
        Some(Matrix3::from_columns(&[e1, e3.cross(&e1), e3]))
    };
    let r = frame(a2, b2, c2)? * frame(a, b, c)?.transpose();
    // Orthonormal up to rounding: Shepperd's conversion, no iteration.
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    let centroid = |p: [Point3<f32>; 3]| (p[0].coords + p[1].coords + p[2].coords) / 3.0;
    let t = centroid(dst) - rotation * centroid(src);
    Some(Pose::from_parts(Translation3::from(t), rotation))
}

/// An accepted place.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Verified {
    /// The query camera's pose in the place keyframe's camera (`t_rq`: query to record).
    pub t_rq: Pose,
    /// Inliers of the refitted motion.
    pub inliers: usize,
    /// Descriptor matches.
    pub matches: usize,
}

/// Verifies the place whose points are `points` (in its camera frame) against `query`; `None`
/// when it is not accepted.
pub fn verify(
    query: &PlaceQuery<'_>,
    points: &[PlacePoint],
    params: &VerifyParams,
    rng: &mut TrackingRng,
) -> Option<Verified> {
    let mut matches: Vec<Match, PLACE_POINTS> = Vec::new();
    for p in points {
        let Some(q) = matched(query, p, params).and_then(|i| query.points.get(i)) else {
            continue;
        };
        if matches.push((q.p_c, p.p_c, q.uv)).is_err() {
            break;
        }
    }
    let n = matches.len();
    if n < params.min_inliers.max(3) {
        return None;
    }
    let inliers_of = |t: &Pose| -> u64 {
        let mut mask = 0u64;
        for (k, (q, r, _)) in matches.iter().enumerate() {
            let tol = params.inlier_distance(r.z);
            if (t * q - r).norm_squared() <= tol * tol {
                mask |= 1 << k;
            }
        }
        mask
    };
    let all = u64::MAX >> (64 - n);
    let best_mask = ransac(&matches, all, params, rng, &inliers_of);
    let mut src: Vec<Point3<f32>, PLACE_POINTS> = Vec::new();
    let mut dst: Vec<Point3<f32>, PLACE_POINTS> = Vec::new();
    for (k, (q, r, _)) in matches.iter().enumerate() {
        if best_mask & (1 << k) != 0 {
            let _ = (src.push(*q), dst.push(*r));
        }
    }
    let t_rq = align_rigid(&src, &dst).ok()?;
    let mask = inliers_of(&t_rq);
    let inliers = mask.count_ones() as usize;
    let (mut lo, mut hi) = ((f32::MAX, f32::MAX), (f32::MIN, f32::MIN));
    for (k, (_, _, uv)) in matches.iter().enumerate() {
        if mask & (1 << k) != 0 {
            lo = (lo.0.min(uv.0), lo.1.min(uv.1));
            hi = (hi.0.max(uv.0), hi.1.max(uv.1));
        }
    }
    let (w, h) = (query.size.0 as f32, query.size.1 as f32);
    let spread = hi.0 - lo.0 >= params.min_spread * w && hi.1 - lo.1 >= params.min_spread * h;
    let accepted = inliers >= params.min_inliers
        && inliers as f32 >= params.min_inlier_ratio * n as f32
        && spread;
    if !accepted {
        return None;
    }
    // Another rigid motion among the matches this one leaves out: part of the scene moved, or two
    // look-alike parts. Which one is the camera's cannot be told: refused.
    let rest = all & !mask;
    if rest.count_ones() as usize >= params.min_inliers {
        let rival = (ransac(&matches, rest, params, rng, &inliers_of) & rest).count_ones();
        if rival as usize >= params.min_inliers && rival as f32 >= params.max_rival * inliers as f32
        {
            return None;
        }
    }
    Some(Verified { t_rq, inliers, matches: n })
}

/// The index of the query point that place point `p` matches (see the module documentation,
/// step 1): the nearest by descriptor, within `max_descriptor_distance` bits and with the second
/// nearest `descriptor_margin` bits further.
fn matched(query: &PlaceQuery<'_>, p: &PlacePoint, params: &VerifyParams) -> Option<usize> {
    let mut best = (u32::MAX, None);
    let mut second = u32::MAX;
    for (i, q) in query.points.iter().enumerate() {
        let d = q.descriptor.distance(p.descriptor);
        if d < best.0 {
            second = best.0;
            best = (d, Some(i));
        } else if d < second {
            second = d;
        }
    }
    let (d, i) = best;
    (d <= params.max_descriptor_distance && second >= d.saturating_add(params.descriptor_margin))
        .then_some(i)
        .flatten()
}

/// Calls `f(query index, place index)` for each match of [`verify`]'s rule that the motion
/// `t_rq` (query camera to place camera, as [`Verified::t_rq`]) brings within the inlier
/// distance: the inliers of a verified place, for a caller that uses its points. Cost: the
/// place's points times the query's descriptor comparisons.
pub fn inlier_pairs(
    query: &PlaceQuery<'_>,
    points: &[PlacePoint],
    params: &VerifyParams,
    t_rq: &Pose,
    mut f: impl FnMut(usize, usize),
) {
    for (pi, p) in points.iter().enumerate() {
        let Some(qi) = matched(query, p, params) else { continue };
        let Some(q) = query.points.get(qi) else { continue };
        let tol = params.inlier_distance(p.p_c.z);
        if (t_rq * q.p_c - p.p_c).norm_squared() <= tol * tol {
            f(qi, pi);
        }
    }
}

/// The inlier mask of the best motion drawn from the matches in `allowed` ([`RANSAC_ITERATIONS`]
/// draws of three; the first with the most inliers among all matches wins; 0 when none solved).
fn ransac(
    matches: &[Match],
    allowed: u64,
    params: &VerifyParams,
    rng: &mut TrackingRng,
    inliers_of: &impl Fn(&Pose) -> u64,
) -> u64 {
    let mut pool: Vec<u8, PLACE_POINTS> = Vec::new();
    for k in 0..matches.len() {
        if allowed & (1 << k) != 0 {
            let _ = pool.push(k as u8);
        }
    }
    let n = pool.len();
    let mut best_mask = 0u64;
    if n < 3 {
        return best_mask;
    }
    let at = |i: usize| pool.get(i).and_then(|&k| matches.get(usize::from(k)));
    for _ in 0..RANSAC_ITERATIONS {
        // Three draws in order, each an index into the pool.
        let [i, j, k] = [(); 3].map(|()| rng.next_u32() as usize % n);
        if i == j || j == k || i == k {
            continue;
        }
        let (Some(a), Some(b), Some(c)) = (at(i), at(j), at(k)) else { continue };
        let Some(t) = triad([a.0, b.0, c.0], [a.1, b.1, c.1], params) else { continue };
        let mask = inliers_of(&t);
        if mask.count_ones() > best_mask.count_ones() {
            best_mask = mask;
        }
    }
    best_mask
}
