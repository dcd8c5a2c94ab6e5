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
//! not found for longest make room ([`Insertions::make_room`]).

use core::cmp::Reverse;

use heapless::Vec;
use heapless::binary_heap::{BinaryHeap, Max};
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

    /// Moves the anchoring frame's pose by `c` (`T_new_old`, a loop's correction of the world).
    pub fn move_world(&mut self, c: &Pose) {
        self.anchor_t_wc = c * self.anchor_t_wc;
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

    /// Opens a batch of insertions that may evict landmarks to make room (a keyframe's new and
    /// re-acquired landmarks); the local map is in its final order again when the batch is
    /// dropped.
    pub fn insertions(&mut self) -> Insertions<'_, N> {
        Insertions {
            old_len: self.items.len(),
            slots: [Slot::Old; N],
            holes: Vec::new(),
            placed: Vec::new(),
            victims: BinaryHeap::new(),
            victims_now: None,
            local: self,
        }
    }
}

/// What a slot of the local map holds during a batch of [`Insertions`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Slot {
    /// A landmark held before the batch, in its order.
    Old,
    /// A landmark inserted during the batch.
    Placed,
    /// An evicted landmark's slot, not refilled: what it holds is ignored.
    Hole,
}

/// The key of an old landmark in slot `slot` not found for `age` frames: larger for a larger
/// age, then for a smaller slot (slots are below `N <= 2^16`).
fn victim_key(age: u32, slot: usize) -> u64 {
    (u64::from(age) << 16) | (0xFFFF - (slot as u64 & 0xFFFF))
}

/// The slot of a [`victim_key`].
fn victim_slot(key: u64) -> usize {
    0xFFFF - (key & 0xFFFF) as usize
}

/// A batch of insertions into a [`LocalMap`], each of which may first evict the landmark not
/// found for longest ([`Insertions::make_room`]), with the outcome of doing so literally: every
/// eviction removes its landmark (the others keep their order) and every insertion appends.
///
/// Done literally, an eviction shifts every later landmark (about 300 bytes each) down one slot:
/// a keyframe that brings up to 200 landmarks into a full local map of 256 moved up to about
/// 3 MB, 2-3 M instructions on the Cortex-M4. Here an insertion goes
/// into the slot of a landmark evicted before it, or at the end. Dropping the batch then puts the
/// landmarks in the literal procedure's order, one swap per displaced landmark (the cycles of
/// the permutation): the landmarks held before the batch less the evicted ones, in their order,
/// then the inserted ones in insertion order. Until then only this type's methods see the local
/// map, and they answer as the literal procedure would (the unit tests compare both on random
/// sequences of evictions, failed insertions and insertions).
///
/// The landmarks held before the batch do not change during it, so their eviction order is built
/// once, in a binary heap at the first eviction, instead of a scan of the whole local map per
/// victim; only the landmarks placed during the batch are scanned, and those the front end places
/// were all found in the current frame, which no eviction takes. The batch takes about 3.4 KB of
/// stack for `N = 256` (2 KB of it the heap), its drop 0.8 KB more. Why: docs/decisions.md,
/// "Local map evictions without shifting".
#[derive(Debug)]
pub struct Insertions<'a, const N: usize> {
    local: &'a mut LocalMap<N>,
    /// Length of the local map when the batch opened: the slots below it hold the landmarks held
    /// before, in order, except where [`Slot::Placed`] or [`Slot::Hole`].
    old_len: usize,
    slots: [Slot; N],
    /// The slots of [`Slot::Hole`]; the last one is refilled first.
    holes: Vec<u16, N>,
    /// The slots of [`Slot::Placed`], in insertion order.
    placed: Vec<u16, N>,
    /// The old landmarks not found in frame `victims_now`, by [`victim_key`]: the top is the
    /// next the literal procedure evicts among them. Filled at the first eviction; an entry
    /// whose slot is no longer [`Slot::Old`] has been evicted.
    victims: BinaryHeap<u64, Max, N>,
    /// The frame `victims` was built for.
    victims_now: Option<u32>,
}

impl<const N: usize> Insertions<'_, N> {
    /// Landmarks held.
    pub fn len(&self) -> usize {
        self.local.items.len() - self.holes.len()
    }

    /// Whether none is held.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether `N` are held.
    pub fn is_full(&self) -> bool {
        self.len() == N
    }

    /// Whether `id` is held (an evicted landmark is not).
    pub fn contains(&self, id: LandmarkId) -> bool {
        let mut items = self.local.items.iter().zip(&self.slots);
        items.any(|(t, s)| t.id == id && *s != Slot::Hole)
    }

    /// Frees one slot if none is free, by evicting the landmark not found for longest (the first
    /// in order among equals), never one found in frame `now`; `false` (nothing evicted) when
    /// every landmark was found in frame `now`.
    pub fn make_room(&mut self, now: u32) -> bool {
        if !self.is_full() {
            return true;
        }
        if self.victims_now != Some(now) {
            self.rank_victims(now);
        }
        // The next old victim: evicted ones are holes now.
        while let Some(&k) = self.victims.peek()
            && self.slots.get(victim_slot(k)) != Some(&Slot::Old)
        {
            self.victims.pop();
        }
        let items = &self.local.items;
        // Ranks in the literal order: the old landmarks by slot, then the placed ones.
        let old = self.victims.peek().and_then(|&k| {
            let i = victim_slot(k);
            items.get(i).map(|t| (i, i, t))
        });
        let placed = self.placed.iter().enumerate().filter_map(|(k, &i)| {
            let i = usize::from(i);
            items.get(i).map(|t| (i, self.old_len + k, t))
        });
        let victim = old
            .into_iter()
            .chain(placed)
            .filter(|(_, _, t)| t.last_found_frame != now)
            .max_by_key(|&(_, rank, t)| (now.wrapping_sub(t.last_found_frame), Reverse(rank)))
            .map(|(i, _, _)| i);
        let (Some(i), Some(&slot)) = (victim, victim.and_then(|i| self.slots.get(i))) else {
            return false;
        };
        if slot == Slot::Placed
            && let Some(k) = self.placed.iter().position(|&p| usize::from(p) == i)
        {
            self.placed.remove(k);
        }
        // Cannot fail: slots are below `N <= u16::MAX + 1` and each is a hole at most once.
        if let (Some(s), Ok(h)) = (self.slots.get_mut(i), u16::try_from(i))
            && self.holes.push(h).is_ok()
        {
            *s = Slot::Hole;
        }
        true
    }

    /// Puts the old landmarks not found in frame `now` into the `victims` heap, keyed so that
    /// the largest key is the literal procedure's victim among them: not found for longest, the
    /// first in slot order among equals. Each key holds its slot, so keys are unique.
    #[inline(never)]
    fn rank_victims(&mut self, now: u32) {
        self.victims.clear();
        let old = self.local.items.iter().zip(&self.slots).take(self.old_len).enumerate();
        for (i, (t, s)) in old {
            if *s == Slot::Old && t.last_found_frame != now {
                // Cannot fail: at most `N` old landmarks.
                let _ = self.victims.push(victim_key(now.wrapping_sub(t.last_found_frame), i));
            }
        }
        self.victims_now = Some(now);
    }

    /// Inserts `item`, last in order; `false` (nothing inserted) when `N` are held.
    pub fn push(&mut self, item: TrackedLandmark) -> bool {
        let items = &mut self.local.items;
        let i = match self.holes.last().map(|&h| usize::from(h)) {
            Some(h) => match items.get_mut(h) {
                Some(t) => {
                    *t = item;
                    self.holes.pop();
                    h
                }
                None => return false,
            },
            None => {
                if items.push(item).is_err() {
                    return false;
                }
                items.len() - 1
            }
        };
        if let (Some(s), Ok(p)) = (self.slots.get_mut(i), u16::try_from(i)) {
            *s = Slot::Placed;
            // Cannot fail: at most `N` slots are placed.
            let _ = self.placed.push(p);
        }
        true
    }
}

impl<const N: usize> Drop for Insertions<'_, N> {
    /// Puts the landmarks in the literal order (see [`Insertions`]) and drops the holes.
    fn drop(&mut self) {
        let items = &mut self.local.items;
        let len = items.len();
        // `order[j]`: the slot whose landmark goes to slot `j`.
        let mut order: Vec<u16, N> = Vec::new();
        let old = (0..self.old_len.min(len)).filter(|&i| self.slots.get(i) == Some(&Slot::Old));
        let old = old.filter_map(|i| u16::try_from(i).ok());
        let all = old.chain(self.placed.iter().copied()).chain(self.holes.iter().copied());
        for i in all {
            // Cannot fail: each slot is listed once.
            let _ = order.push(i);
        }
        if order.len() != len {
            // Not a permutation: cannot happen (each slot is old, placed or a hole).
            debug_assert!(false, "the insertion slots do not cover the local map");
            return;
        }
        // Each cycle of the permutation is applied by swaps along it.
        let mut done = [false; N];
        for start in 0..len {
            if done.get(start) != Some(&false) {
                continue;
            }
            let mut j = start;
            loop {
                if let Some(d) = done.get_mut(j) {
                    *d = true;
                }
                let Some(next) = order.get(j).map(|&n| usize::from(n)) else { break };
                if next == start {
                    break;
                }
                items.swap(j, next);
                j = next;
            }
        }
        items.truncate(len - self.holes.len());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::Arena;

    const N: usize = 8;

    /// A small deterministic generator (64-bit LCG, high bits).
    struct Lcg(u64);

    impl Lcg {
        fn below(&mut self, n: u32) -> u32 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((self.0 >> 33) % u64::from(n)) as u32
        }
    }

    /// The literal procedure [`Insertions`] stands for: ids and frames last found, in order.
    #[derive(Default)]
    struct Literal(Vec<(LandmarkId, u32), N>);

    impl Literal {
        /// As [`Insertions::make_room`], with the evicted landmark.
        fn make_room(&mut self, now: u32) -> (bool, Option<LandmarkId>) {
            if !self.0.is_full() {
                return (true, None);
            }
            let victim = self
                .0
                .iter()
                .enumerate()
                .filter(|(_, e)| e.1 != now)
                .max_by_key(|&(i, e)| (now.wrapping_sub(e.1), Reverse(i)))
                .map(|(i, _)| i);
            let Some(v) = victim else { return (false, None) };
            (true, Some(self.0.remove(v).0))
        }
    }

    fn landmark(id: LandmarkId, last_found_frame: u32) -> TrackedLandmark {
        let pixels = [7u8; 20 * 20];
        let img = GrayView::packed(&pixels, 20, 20).expect("a 20 x 20 image");
        let t = TrackedLandmark::new(id, &img, (10.0, 10.0), 1.0, &Pose::identity(), 0);
        TrackedLandmark { last_found_frame, ..t.expect("the template fits") }
    }

    fn contents(local: &LocalMap<N>) -> Vec<(LandmarkId, u32), N> {
        local.items().iter().map(|t| (t.id, t.last_found_frame)).collect()
    }

    #[test]
    fn insertions_give_the_order_of_literal_evictions() {
        let (mut evictions, mut holes_left, mut placed_evicted) = (0, 0, 0);
        for seed in 0..1000 {
            let mut rng = Lcg(seed);
            let mut arena: Arena<(), { 4 * N }> = Arena::new();
            let mut new_id = || LandmarkId(arena.insert(()).expect("room in the arena"));
            let now = 100;
            let (mut local, mut literal) = (LocalMap::<N>::new(), Literal::default());
            for _ in 0..rng.below(N as u32 + 1) {
                let (id, found) = (new_id(), now - rng.below(4));
                assert!(local.push(landmark(id, found)));
                literal.0.push((id, found)).expect("room");
            }
            {
                let mut batch = local.insertions();
                let mut inserted: Vec<LandmarkId, { 3 * N }> = Vec::new();
                for _ in 0..rng.below(3 * N as u32) {
                    // Now and then a later frame, which the ranked victims must not outlive.
                    let at = if rng.below(8) == 0 { now + 1 } else { now };
                    let room = batch.make_room(at);
                    let (literal_room, victim) = literal.make_room(at);
                    assert_eq!(room, literal_room, "seed {seed}");
                    evictions += usize::from(victim.is_some());
                    placed_evicted += usize::from(victim.is_some_and(|v| inserted.contains(&v)));
                    // Sometimes nothing follows the eviction (a creation that failed after it).
                    if !room || rng.below(5) == 0 {
                        holes_left += usize::from(victim.is_some());
                        continue;
                    }
                    // Mostly found now, as the front end's new landmarks; older ones can be
                    // evicted again within the batch.
                    let found = if rng.below(4) == 0 { now - 1 - rng.below(3) } else { now };
                    let id = new_id();
                    inserted.push(id).expect("room");
                    assert!(batch.push(landmark(id, found)), "seed {seed}");
                    literal.0.push((id, found)).expect("room");
                    assert_eq!(batch.len(), literal.0.len(), "seed {seed}");
                    for &(id, _) in &literal.0 {
                        assert!(batch.contains(id), "seed {seed}");
                    }
                }
                assert_eq!(batch.len(), literal.0.len(), "seed {seed}");
            }
            assert_eq!(contents(&local), literal.0, "seed {seed}");
        }
        // The cases that matter were exercised.
        let counts = (evictions, holes_left, placed_evicted);
        assert!(evictions > 3000 && holes_left > 500 && placed_evicted > 1000, "{counts:?}");
    }
}
