//! The tracker's local map: the landmarks it follows frame to frame, each with a small template
//! taken from the frame that anchored it.
//!
//! Tracking is frame-to-map: a landmark's template comes from the keyframe that created it (or
//! last re-anchored it), and every frame matches that same template, warped by the map the
//! predicted motion induces (see [`induced_affine`]), so errors do not chain from frame to frame.
//! Landmarks persist across keyframes: a new keyframe adds landmarks where the image is not yet
//! covered, and the old ones keep being tracked while they are in view.
//!
//! # Templates
//!
//! A template is the [`PATCH_SIDE`] x [`PATCH_SIDE`] block of gray pixels around the landmark's
//! pixel in the anchoring frame: 256 bytes, against the 76,800 bytes of a QVGA keyframe image.
//! [`track_patch`](crate::matching::track_patch) samples it under the inverse of the induced map;
//! the 9 x 9 template of the fine stage with its one-pixel gradient margin fits inside for scale
//! changes down to ~0.77 and in-plane rotations up to ~15 degrees. Beyond that the landmark is
//! re-anchored at the next keyframe (its template re-taken from that keyframe's image, its 3D
//! position kept), see [`TrackedLandmark::reanchor`].
//!
//! # Capacity
//!
//! [`LocalMap`] holds at most `N` landmarks ([`capacity::MAX_TRACKED_LANDMARKS`] on the board,
//! about 300 bytes each). When a keyframe brings new landmarks and the local map is full, the ones
//! not seen for longest make room (see `Frontend`).

use heapless::Vec;
use nalgebra::{Point2, Point3};

use crate::config::capacity;
use crate::geometry::{PinholeCamera, Pose};
use crate::image::GrayView;
use crate::map::LandmarkId;
use crate::matching::{IDENTITY, Mat2};

/// Side of a landmark template, pixels.
pub const PATCH_SIDE: usize = 16;

/// Offset of the template's centre pixel from its top-left pixel (the landmark's rounded pixel is
/// at patch index `(PATCH_CENTRE, PATCH_CENTRE)`).
const PATCH_CENTRE: usize = PATCH_SIDE / 2;

/// The tracker's local map at the board's capacity.
pub type BoardLocalMap = LocalMap<{ capacity::MAX_TRACKED_LANDMARKS }>;

/// A landmark the tracker follows.
#[derive(Debug, Clone)]
pub struct TrackedLandmark {
    /// The map landmark (its position lives in the map, where the back end refines it).
    pub id: LandmarkId,
    patch: [u8; PATCH_SIDE * PATCH_SIDE],
    /// The landmark's pixel in patch coordinates.
    centre: (f32, f32),
    /// Camera-to-world pose of the anchoring frame.
    anchor_t_wc: Pose,
    /// The landmark's pixel in the anchoring frame.
    anchor_uv: (f32, f32),
    /// Its depth in the anchoring frame, metres.
    anchor_depth_m: f32,
    /// Frames in which it was predicted inside the image.
    pub visible: u16,
    /// Frames in which it was matched and an inlier of the pose.
    pub found: u16,
    /// Frame number of the last time it was found.
    pub last_found_frame: u32,
    /// Sum of the weights of the depth measurements fused into its position (see
    /// `FrontendParams::fuse_depth`).
    pub fused_weight: f32,
}

impl TrackedLandmark {
    /// A landmark anchored in `img` at pixel `uv` with depth `depth_m`, seen from `t_wc`; `None`
    /// when the template would leave the image or the inputs are not finite.
    pub fn new(
        id: LandmarkId,
        img: &GrayView<'_>,
        uv: (f32, f32),
        depth_m: f32,
        t_wc: &Pose,
        frame: u32,
    ) -> Option<Self> {
        let mut lm = Self {
            id,
            patch: [0; PATCH_SIDE * PATCH_SIDE],
            centre: (0.0, 0.0),
            anchor_t_wc: *t_wc,
            anchor_uv: uv,
            anchor_depth_m: depth_m,
            visible: 0,
            found: 0,
            last_found_frame: frame,
            fused_weight: 0.0,
        };
        lm.reanchor(img, uv, depth_m, t_wc).then_some(lm)
    }

    /// Re-takes the template from `img` around pixel `uv` (depth `depth_m`, camera `t_wc`);
    /// returns `false` and changes nothing when it would leave the image or an input is not
    /// finite or the depth not positive.
    pub fn reanchor(
        &mut self,
        img: &GrayView<'_>,
        uv: (f32, f32),
        depth_m: f32,
        t_wc: &Pose,
    ) -> bool {
        // NaN fails the comparisons.
        if !(uv.0 >= 0.0 && uv.1 >= 0.0 && depth_m > 0.0 && depth_m.is_finite()) {
            return false;
        }
        let (rx, ry) = (libm::roundf(uv.0), libm::roundf(uv.1));
        let (w, h) = img.size();
        let (x0, y0) =
            ((rx as usize).wrapping_sub(PATCH_CENTRE), (ry as usize).wrapping_sub(PATCH_CENTRE));
        if rx < PATCH_CENTRE as f32
            || ry < PATCH_CENTRE as f32
            || x0 + PATCH_SIDE > w
            || y0 + PATCH_SIDE > h
        {
            return false;
        }
        for (j, dst) in self.patch.chunks_exact_mut(PATCH_SIDE).enumerate() {
            match img.row(y0 + j).and_then(|r| r.get(x0..x0 + PATCH_SIDE)) {
                Some(src) => dst.copy_from_slice(src),
                None => return false,
            }
        }
        // `x0`, `y0` are below 2^24: exact in f32.
        self.centre = (uv.0 - x0 as f32, uv.1 - y0 as f32);
        (self.anchor_t_wc, self.anchor_uv, self.anchor_depth_m) = (*t_wc, uv, depth_m);
        true
    }

    /// The template as an image, and the landmark's pixel in it (always `Some`: the buffer is
    /// exactly `PATCH_SIDE`^2 pixels).
    pub fn template(&self) -> Option<(GrayView<'_>, (f32, f32))> {
        GrayView::packed(&self.patch, PATCH_SIDE, PATCH_SIDE).ok().map(|v| (v, self.centre))
    }

    /// The linear map from the anchoring frame's pixels to the pixels of a camera at `t_cw`,
    /// at this landmark (see [`induced_affine`]).
    pub fn warp_to(&self, cam: &PinholeCamera, t_cw: &Pose) -> Mat2 {
        induced_affine(cam, &(t_cw * self.anchor_t_wc), self.anchor_uv, self.anchor_depth_m)
    }

    /// Whether the warp from the anchoring frame to `t_cw` has drifted far enough from a pure
    /// translation that the template should be re-taken: any entry of `A - I` beyond `limit`.
    pub fn needs_reanchor(&self, cam: &PinholeCamera, t_cw: &Pose, limit: f32) -> bool {
        let a = self.warp_to(cam, t_cw);
        let d = [a[0][0] - 1.0, a[0][1], a[1][0], a[1][1] - 1.0];
        d.iter().any(|x| x.is_nan() || x.abs() > limit)
    }

    /// The centre of the anchoring camera, world metres.
    pub fn anchor_centre(&self) -> Point3<f32> {
        Point3::from(self.anchor_t_wc.translation.vector)
    }

    /// The ratio of frames found to frames visible (1 before it was ever visible).
    pub fn found_ratio(&self) -> f32 {
        if self.visible == 0 { 1.0 } else { f32::from(self.found) / f32::from(self.visible) }
    }
}

/// The linear map `d(uv_cur) / d(uv_anchor)` that the motion `t_ca` (anchoring camera to current
/// camera) induces at anchor pixel `uv_a` on a fronto-parallel patch at depth `z_m`, by finite
/// differences of one pixel; the identity when a projection fails or the map is implausible
/// (area scale outside 1/16..16, or NaN).
pub fn induced_affine(cam: &PinholeCamera, t_ca: &Pose, uv_a: (f32, f32), z_m: f32) -> Mat2 {
    let map = |du: f32, dv: f32| -> Option<Point2<f32>> {
        let p_a: Point3<f32> = cam.back_project(uv_a.0 + du, uv_a.1 + dv, z_m);
        cam.project(&(t_ca * p_a))
    };
    let (Some(c), Some(cu), Some(cv)) = (map(0.0, 0.0), map(1.0, 0.0), map(0.0, 1.0)) else {
        return IDENTITY;
    };
    let a = [[cu.x - c.x, cv.x - c.x], [cu.y - c.y, cv.y - c.y]];
    let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
    if det > 1.0 / 16.0 && det < 16.0 { a } else { IDENTITY }
}

/// At most `N` tracked landmarks (see the module documentation).
#[derive(Debug, Clone)]
pub struct LocalMap<const N: usize> {
    items: Vec<TrackedLandmark, N>,
}

impl<const N: usize> Default for LocalMap<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> LocalMap<N> {
    /// An empty local map (`const`, for `static` use).
    pub const fn new() -> Self {
        Self { items: Vec::new() }
    }

    /// The tracked landmarks, in insertion order (removals keep the order of the rest).
    pub fn items(&self) -> &[TrackedLandmark] {
        &self.items
    }

    /// The tracked landmarks, mutably.
    pub fn items_mut(&mut self) -> &mut [TrackedLandmark] {
        &mut self.items
    }

    /// Landmarks held.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// Whether none is held.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Whether `N` are held.
    pub fn is_full(&self) -> bool {
        self.items.is_full()
    }

    /// Whether `id` is tracked.
    pub fn contains(&self, id: LandmarkId) -> bool {
        self.items.iter().any(|t| t.id == id)
    }

    /// Adds a landmark; `false` (and nothing added) when `N` are held.
    pub fn push(&mut self, item: TrackedLandmark) -> bool {
        self.items.push(item).is_ok()
    }

    /// Keeps only the landmarks for which `keep` is true, in order.
    pub fn retain(&mut self, keep: impl FnMut(&TrackedLandmark) -> bool) {
        self.items.retain(keep);
    }

    /// Removes every landmark.
    pub fn clear(&mut self) {
        self.items.clear();
    }
}
