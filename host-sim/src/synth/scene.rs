//! The synthetic room and its ray caster.
//!
//! World frame: metres, `z` up, the floor at `z = 0`. The room is the box
//! `x in [-3, 3]`, `y in [-3.5, 3.5]`, `z in [0, 2.8]`: brick walls north (`y = 3.5`) and south,
//! plaster west (`x = -3`), tiles east, a plank floor and a panelled ceiling, with posters on the
//! walls. Six boxes stand on the floor or on each other (some rotated about the vertical axis) and a
//! checkered ball lies on one of them, so the camera sees parallax and occlusion.
//!
//! Face coordinates `(u, v)` (metres) parametrize every face for texturing: on a vertical face,
//! `u` runs to the right as seen from in front of the face and `v` is the height above the face's
//! bottom edge; on a horizontal face `(u, v)` are the (box-local) `x, y`.

use nalgebra::{Point3, Vector3};

use super::face::FaceId;
use super::noise::NoiseCache;
use super::poster::{Poster, demo_posters};
use super::texture::Material;

/// Minimum of the room's interior in world coordinates (metres).
pub const ROOM_MIN: [f64; 3] = [-3.0, -3.5, 0.0];
/// Maximum of the room's interior in world coordinates (metres).
pub const ROOM_MAX: [f64; 3] = [3.0, 3.5, 2.8];

/// Ambient part of the shading.
const AMBIENT: f64 = 0.42;
/// Directional (Lambertian) part of the shading.
const DIFFUSE: f64 = 0.62;
/// Hits closer than this along the ray (in ray parameter units) are ignored.
const T_MIN: f64 = 1e-9;

/// A ray hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Hit {
    /// Ray parameter: the hit is at `origin + t * dir`. With a camera ray whose direction has
    /// camera-frame `z = 1`, `t` is the z-depth in metres.
    pub t: f64,
    /// Unit surface normal in the world frame, on the side the ray came from.
    pub normal: Vector3<f64>,
    /// The face hit.
    pub face: FaceId,
    /// Face coordinates, metres.
    pub u: f64,
    /// Face coordinates, metres.
    pub v: f64,
}

/// A box standing upright, rotated by `yaw` about the vertical axis through its centre.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SceneBox {
    centre: [f64; 2],
    half: [f64; 3],
    z_mid: f64,
    cos_yaw: f64,
    sin_yaw: f64,
    side: Material,
    top: Material,
}

impl SceneBox {
    fn new(
        centre: [f64; 2],
        half: [f64; 2],
        z: [f64; 2],
        yaw_deg: f64,
        side: Material,
        top: Material,
    ) -> Self {
        let yaw = yaw_deg.to_radians();
        Self {
            centre,
            half: [half[0], half[1], 0.5 * (z[1] - z[0])],
            z_mid: 0.5 * (z[0] + z[1]),
            cos_yaw: libm::cos(yaw),
            sin_yaw: libm::sin(yaw),
            side,
            top,
        }
    }

    /// World vector (relative to the box centre when `offset`) into box-local coordinates.
    fn to_local(&self, w: &Vector3<f64>, offset: bool) -> [f64; 3] {
        let (x, y, z) = if offset {
            (w.x - self.centre[0], w.y - self.centre[1], w.z - self.z_mid)
        } else {
            (w.x, w.y, w.z)
        };
        [self.cos_yaw * x + self.sin_yaw * y, -self.sin_yaw * x + self.cos_yaw * y, z]
    }

    /// Whether the box's axes are the world's (no yaw): then a ray's direction and reciprocals
    /// are already box-local.
    fn is_axis_aligned(&self) -> bool {
        self.sin_yaw == 0.0 && self.cos_yaw == 1.0
    }

    /// The box's part of a [`CastOrigin`]: `origin` in box-local coordinates and its slab gaps.
    fn local_origin(&self, origin: &Point3<f64>) -> LocalOrigin {
        let o = self.to_local(&origin.coords, true);
        LocalOrigin {
            o,
            gap_min: [0, 1, 2].map(|a| -self.half[a] - o[a]),
            gap_max: [0, 1, 2].map(|a| self.half[a] - o[a]),
        }
    }

    /// Entry `(t, face)` of the ray, if it enters the box in front of its origin. `local` is the
    /// origin prepared for this box, `d` the box-local direction, `inv` holds `1 / d` per axis.
    #[inline]
    fn intersect(&self, local: &LocalOrigin, d: &[f64; 3], inv: &[f64; 3]) -> Option<(f64, u8)> {
        let (mut t_near, mut t_far, mut face) = (f64::NEG_INFINITY, f64::INFINITY, 0u8);
        for a in 0..3 {
            if d[a] == 0.0 {
                if local.o[a].abs() >= self.half[a] {
                    return None;
                }
                continue;
            }
            let t1 = local.gap_min[a] * inv[a];
            let t2 = local.gap_max[a] * inv[a];
            // Entering through the minimum side when moving towards +axis.
            let (ta, tb, f) = if t1 < t2 { (t1, t2, 2 * a) } else { (t2, t1, 2 * a + 1) };
            if ta > t_near {
                t_near = ta;
                face = f as u8;
            }
            t_far = t_far.min(tb);
        }
        (t_near <= t_far && t_near > T_MIN).then_some((t_near, face))
    }

    /// Distance from a world point outside the box to the box (0 inside).
    #[cfg(test)]
    pub(crate) fn distance(&self, p: &Vector3<f64>) -> f64 {
        let l = self.to_local(p, true);
        let q = [0, 1, 2].map(|a| (l[a].abs() - self.half[a]).max(0.0));
        libm::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2])
    }
}

/// A sphere.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Sphere {
    centre: Point3<f64>,
    radius: f64,
    material: Material,
}

/// A box's share of a [`CastOrigin`]: the origin in box-local coordinates (metres) and, per
/// axis, `-half - o` and `half - o`, the numerators of the slab test.
#[derive(Debug, Clone, PartialEq)]
struct LocalOrigin {
    o: [f64; 3],
    gap_min: [f64; 3],
    gap_max: [f64; 3],
}

/// A ray origin prepared for casting many rays from it ([`Scene::prepare`], [`Scene::cast_from`]):
/// the parts of the room and box tests that depend on the origin alone, computed once. Casting
/// from it gives exactly the bits of [`Scene::cast`] (the same expressions, evaluated earlier).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct CastOrigin {
    origin: Point3<f64>,
    /// Per axis, `ROOM_MIN - origin` and `ROOM_MAX - origin`, metres.
    room_gap: [[f64; 2]; 3],
    /// Per box of the scene, in order.
    boxes: Vec<LocalOrigin>,
}

impl CastOrigin {
    /// The origin, world frame, metres.
    #[cfg(test)]
    pub(crate) fn origin(&self) -> &Point3<f64> {
        &self.origin
    }
}

/// The room with its furniture and posters.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Scene {
    boxes: Vec<SceneBox>,
    spheres: Vec<Sphere>,
    /// Posters sorted by face slot (see [`Scene::slot`]).
    posters: Vec<Poster>,
    /// Per face slot, the range of `posters` on that face.
    poster_ranges: Vec<core::ops::Range<usize>>,
    /// Per face slot, the material and the texture salt of the face (see [`Scene::index_faces`]).
    surfaces: Vec<(Material, u32)>,
    room_materials: [Material; 6],
    light_dir: Vector3<f64>,
}

/// The vector with `sign` on `axis` and zeros elsewhere, built in registers: written into a zeroed
/// array at a variable index and read back whole, it waits for that store on every ray
/// (docs/decisions.md, "The demo's renderer").
#[inline]
fn axis_vector(axis: usize, sign: f64) -> [f64; 3] {
    [0, 1, 2].map(|a| if a == axis { sign } else { 0.0 })
}

/// Face coordinates on a vertical face with outward normal `(nx, ny)` at point `(x, y)`.
#[inline]
fn vertical_u(nx: f64, ny: f64, x: f64, y: f64) -> f64 {
    // u runs along up x n: to the right for a viewer facing the face.
    -ny * x + nx * y
}

impl Scene {
    /// The fixed demo room (its layout does not depend on any option or seed).
    pub(crate) fn demo() -> Self {
        use Material::{Brick, Checker, Dots, Plaster, WallTiles, Wood};
        let boxes = vec![
            SceneBox::new(
                [-1.3, 0.5],
                [0.45, 0.45],
                [0.0, 0.9],
                0.0,
                Wood { along_v: false },
                Wood { along_v: true },
            ),
            SceneBox::new(
                [1.2, 1.2],
                [0.4, 0.3],
                [0.0, 1.2],
                30.0,
                Checker { square_m: 0.1 },
                Plaster,
            ),
            SceneBox::new([-2.35, 2.6], [0.4, 0.5], [0.0, 2.0], 0.0, Dots, Plaster),
            SceneBox::new(
                [-1.2, 0.45],
                [0.2, 0.15],
                [0.9, 1.2],
                -20.0,
                Checker { square_m: 0.05 },
                WallTiles,
            ),
            SceneBox::new([0.3, -0.3], [0.3, 0.25], [0.0, 0.5], 15.0, Wood { along_v: true }, Dots),
            SceneBox::new([2.2, 2.7], [0.35, 0.35], [0.0, 1.5], -35.0, Plaster, Brick),
        ];
        let spheres = vec![Sphere {
            centre: Point3::new(1.2, 1.2, 1.45),
            radius: 0.25,
            material: Checker { square_m: 0.06 },
        }];
        let mut scene = Self {
            boxes,
            spheres,
            posters: Vec::new(),
            poster_ranges: Vec::new(),
            surfaces: Vec::new(),
            room_materials: [
                Plaster,
                WallTiles,
                Brick,
                Brick,
                Material::FloorPlanks,
                Material::CeilingPanels,
            ],
            light_dir: Vector3::new(0.45, -0.6, 0.66).normalize(),
        };
        scene.set_posters(demo_posters());
        scene.index_faces();
        scene
    }

    /// Dense index of a face: room faces, then six per box, then one per sphere.
    fn slot(&self, face: FaceId) -> usize {
        match face {
            FaceId::Room(f) => usize::from(f),
            FaceId::Box { index, face } => 6 + 6 * usize::from(index) + usize::from(face),
            FaceId::Sphere(i) => 6 + 6 * self.boxes.len() + usize::from(i),
        }
    }

    /// Every face, in slot order (see [`Scene::slot`]).
    fn faces(&self) -> impl Iterator<Item = FaceId> {
        let boxes = (0..self.boxes.len() as u8)
            .flat_map(|index| (0..6).map(move |face| FaceId::Box { index, face }));
        (0..6)
            .map(FaceId::Room)
            .chain(boxes)
            .chain((0..self.spheres.len() as u8).map(FaceId::Sphere))
    }

    /// Tabulates each face's material and texture salt by slot, so that shading a hit looks them
    /// up instead of matching and hashing.
    fn index_faces(&mut self) {
        self.surfaces = self.faces().map(|f| (self.material(f), f.salt())).collect();
    }

    /// Stores the posters grouped by face so that shading finds a face's posters directly.
    fn set_posters(&mut self, mut posters: Vec<Poster>) {
        let slots = 6 + 6 * self.boxes.len() + self.spheres.len();
        // Stable: posters of one face keep their order.
        posters.sort_by_key(|p| self.slot(p.face));
        self.poster_ranges = (0..slots)
            .map(|k| {
                let start = posters.partition_point(|p| self.slot(p.face) < k);
                let end = posters.partition_point(|p| self.slot(p.face) <= k);
                start..end
            })
            .collect();
        self.posters = posters;
    }

    /// Number of objects (boxes, then spheres) that the bits of a cast mask select.
    pub(crate) fn object_count(&self) -> usize {
        self.boxes.len() + self.spheres.len()
    }

    /// Eight world points whose convex hull contains object `k` (boxes, then spheres).
    pub(crate) fn object_corners(&self, k: usize) -> Option<[Point3<f64>; 8]> {
        let signs = |i: usize| {
            [
                (i & 1) as f64 * 2.0 - 1.0,
                (i >> 1 & 1) as f64 * 2.0 - 1.0,
                (i >> 2 & 1) as f64 * 2.0 - 1.0,
            ]
        };
        if let Some(b) = self.boxes.get(k) {
            return Some(core::array::from_fn(|i| {
                let [sx, sy, sz] = signs(i);
                let (lx, ly) = (sx * b.half[0], sy * b.half[1]);
                Point3::new(
                    b.centre[0] + b.cos_yaw * lx - b.sin_yaw * ly,
                    b.centre[1] + b.sin_yaw * lx + b.cos_yaw * ly,
                    b.z_mid + sz * b.half[2],
                )
            }));
        }
        let s = self.spheres.get(k - self.boxes.len())?;
        Some(core::array::from_fn(|i| {
            let [sx, sy, sz] = signs(i);
            s.centre + Vector3::new(sx, sy, sz) * s.radius
        }))
    }

    /// The nearest hit of the ray `origin + t * dir`, `t > 0`, testing only the objects whose bit
    /// is set in `mask` (bit `k` = object `k`, see [`Scene::object_count`]; the room is always
    /// tested). `dir` need not be unit length. Inside the closed room every ray hits something;
    /// `None` only for a degenerate direction. Many rays from one origin: [`Scene::cast_from`].
    pub(crate) fn cast(&self, origin: &Point3<f64>, dir: &Vector3<f64>, mask: u32) -> Option<Hit> {
        self.cast_from(&self.prepare(origin), dir, mask)
    }

    /// `origin` prepared for [`Scene::cast_from`] (a few dozen operations per box).
    pub(crate) fn prepare(&self, origin: &Point3<f64>) -> CastOrigin {
        CastOrigin {
            origin: *origin,
            room_gap: [0, 1, 2].map(|a| [ROOM_MIN[a] - origin[a], ROOM_MAX[a] - origin[a]]),
            boxes: self.boxes.iter().map(|b| b.local_origin(origin)).collect(),
        }
    }

    /// [`Scene::cast`] from a prepared origin (of this scene), with the same result. Inlined into
    /// each caller, so that a caller that needs only `t` drops the face coordinates.
    #[inline(always)]
    pub(crate) fn cast_from(
        &self,
        from: &CastOrigin,
        dir: &Vector3<f64>,
        mask: u32,
    ) -> Option<Hit> {
        let origin = &from.origin;
        let inv_world = [1.0 / dir.x, 1.0 / dir.y, 1.0 / dir.z];
        let (mut best_t, room_face) = Self::room_exit(&from.room_gap, dir, &inv_world)?;
        let mut best_box: Option<(usize, u8, [f64; 3])> = None;
        // Only the set bits, in increasing order (so ties go to the same object as a full scan).
        let n_boxes = self.boxes.len();
        let mut box_bits = if n_boxes >= 32 { mask } else { mask & ((1 << n_boxes) - 1) };
        while box_bits != 0 {
            let i = box_bits.trailing_zeros() as usize;
            box_bits &= box_bits - 1;
            let (Some(b), Some(local)) = (self.boxes.get(i), from.boxes.get(i)) else { break };
            // The rotation is about z: the z reciprocal is shared, and unrotated boxes share all.
            let (d, inv) = if b.is_axis_aligned() {
                ([dir.x, dir.y, dir.z], inv_world)
            } else {
                let d = b.to_local(dir, false);
                (d, [1.0 / d[0], 1.0 / d[1], inv_world[2]])
            };
            if let Some((t, face)) = b.intersect(local, &d, &inv)
                && t < best_t
            {
                best_t = t;
                best_box = Some((i, face, d));
            }
        }
        let mut best_sphere = None;
        for (i, s) in self.spheres.iter().enumerate() {
            if mask & (1 << (n_boxes + i)) == 0 {
                continue;
            }
            if let Some(t) = sphere_t(s, origin, dir)
                && t < best_t
            {
                best_t = t;
                best_box = None;
                best_sphere = Some(i);
            }
        }
        if let Some(i) = best_sphere {
            return Some(self.sphere_hit(i, origin, dir, best_t));
        }
        if let Some((i, face, d)) = best_box
            && let Some(local) = from.boxes.get(i)
        {
            return Some(self.box_hit(i, face, &local.o, &d, best_t));
        }
        Some(Self::room_hit(origin, dir, best_t, room_face))
    }

    /// Radiance of a hit in `[0, 1]`: albedo times ambient plus Lambertian light. It depends on
    /// the surface point only, never on the viewpoint (nor on `noise`, which only saves work).
    pub(crate) fn radiance(&self, hit: &Hit, noise: &mut NoiseCache) -> f64 {
        let slot = self.slot(hit.face);
        let on_face = self.poster_ranges.get(slot).and_then(|r| self.posters.get(r.clone()));
        let poster = on_face.unwrap_or_default().iter().find_map(|p| p.albedo(hit.u, hit.v, noise));
        let albedo = poster.unwrap_or_else(|| self.surface_albedo(slot, hit, noise));
        let lambert = hit.normal.dot(&self.light_dir).max(0.0);
        albedo * (AMBIENT + DIFFUSE * lambert)
    }

    /// Albedo of the bare surface (no poster) at a hit on the face of slot `slot`.
    fn surface_albedo(&self, slot: usize, hit: &Hit, noise: &mut NoiseCache) -> f64 {
        let (material, salt) = self
            .surfaces
            .get(slot)
            .copied()
            .unwrap_or_else(|| (self.material(hit.face), hit.face.salt()));
        material.albedo(hit.u, hit.v, salt, noise)
    }

    /// Distance from a world point to the nearest box, sphere, wall, floor or ceiling (metres).
    #[cfg(test)]
    pub(crate) fn clearance(&self, p: &Vector3<f64>) -> f64 {
        let walls = (0..3)
            .map(|a| (p[a] - ROOM_MIN[a]).min(ROOM_MAX[a] - p[a]))
            .fold(f64::INFINITY, f64::min);
        let boxes = self.boxes.iter().map(|b| b.distance(p)).fold(f64::INFINITY, f64::min);
        let spheres = self
            .spheres
            .iter()
            .map(|s| (p - s.centre.coords).norm() - s.radius)
            .fold(f64::INFINITY, f64::min);
        walls.min(boxes).min(spheres)
    }

    fn material(&self, face: FaceId) -> Material {
        match face {
            FaceId::Room(f) => self.room_materials[usize::from(f.min(5))],
            FaceId::Box { index, face } => match self.boxes.get(usize::from(index)) {
                Some(b) if face >= 4 => b.top,
                Some(b) => b.side,
                None => Material::Plaster,
            },
            FaceId::Sphere(i) => {
                self.spheres.get(usize::from(i)).map_or(Material::Plaster, |s| s.material)
            }
        }
    }

    /// Where the ray leaves the room: `(t, face)`. `gap` holds, per axis, `ROOM_MIN - origin` and
    /// `ROOM_MAX - origin`; `inv` holds `1 / d`.
    #[inline]
    fn room_exit(gap: &[[f64; 2]; 3], d: &Vector3<f64>, inv: &[f64; 3]) -> Option<(f64, u8)> {
        let (mut t, mut face) = (f64::INFINITY, 0u8);
        for a in 0..3 {
            let (ta, f) = if d[a] > 0.0 {
                (gap[a][1] * inv[a], 2 * a + 1)
            } else if d[a] < 0.0 {
                (gap[a][0] * inv[a], 2 * a)
            } else {
                continue;
            };
            if ta < t {
                t = ta;
                face = f as u8;
            }
        }
        t.is_finite().then_some((t, face))
    }

    /// The hit on the room's interior surface `face` at ray parameter `t`.
    fn room_hit(o: &Point3<f64>, d: &Vector3<f64>, t: f64, face: u8) -> Hit {
        let p = o + d * t;
        let axis = usize::from(face / 2);
        // Inward normal: +axis on the minimum side.
        let sign = if face.is_multiple_of(2) { 1.0 } else { -1.0 };
        let normal = Vector3::from(axis_vector(axis, sign));
        let (u, v) =
            if axis == 2 { (p.x, p.y) } else { (vertical_u(normal.x, normal.y, p.x, p.y), p.z) };
        Hit { t, normal, face: FaceId::Room(face), u, v }
    }

    fn box_hit(&self, i: usize, face: u8, o: &[f64; 3], d: &[f64; 3], t: f64) -> Hit {
        let b = &self.boxes[i];
        let l = [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]];
        let axis = usize::from(face / 2);
        let sign = if face.is_multiple_of(2) { -1.0 } else { 1.0 };
        let nl = axis_vector(axis, sign);
        let normal = Vector3::new(
            b.cos_yaw * nl[0] - b.sin_yaw * nl[1],
            b.sin_yaw * nl[0] + b.cos_yaw * nl[1],
            nl[2],
        );
        let (u, v) = if axis == 2 {
            (l[0], l[1])
        } else {
            (vertical_u(nl[0], nl[1], l[0], l[1]), l[2] + b.half[2])
        };
        Hit { t, normal, face: FaceId::Box { index: i as u8, face }, u, v }
    }

    fn sphere_hit(&self, i: usize, o: &Point3<f64>, d: &Vector3<f64>, t: f64) -> Hit {
        let s = &self.spheres[i];
        let n = (o + d * t - s.centre) / s.radius;
        // Arc-length coordinates: longitude and latitude times the radius.
        let u = s.radius * libm::atan2(n.y, n.x);
        let v = s.radius * libm::asin(n.z.clamp(-1.0, 1.0));
        Hit { t, normal: n, face: FaceId::Sphere(i as u8), u, v }
    }
}

/// Ray parameter of the first intersection of a ray with a sphere in front of the origin.
fn sphere_t(s: &Sphere, o: &Point3<f64>, d: &Vector3<f64>) -> Option<f64> {
    let oc = o - s.centre;
    let a = d.dot(d);
    let b = oc.dot(d);
    let c = oc.dot(&oc) - s.radius * s.radius;
    let disc = b * b - a * c;
    if disc < 0.0 || a == 0.0 {
        return None;
    }
    let t = (-b - libm::sqrt(disc)) / a;
    (t > T_MIN).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn faces_are_in_slot_order() {
        let s = Scene::demo();
        let faces: Vec<FaceId> = s.faces().collect();
        assert_eq!(faces.len(), s.surfaces.len());
        for (k, f) in faces.into_iter().enumerate() {
            assert_eq!(s.slot(f), k);
            assert_eq!(s.surfaces[k], (s.material(f), f.salt()));
        }
    }

    #[test]
    fn ray_to_north_wall() {
        let s = Scene::demo();
        // From high up near the north wall, straight north: nothing in between.
        let o = Point3::new(0.0, 3.0, 2.5);
        let h = s.cast(&o, &Vector3::new(0.0, 2.0, 0.0), u32::MAX).unwrap();
        assert!((h.t - 0.25).abs() < 1e-12);
        assert_eq!(h.face, FaceId::Room(3));
        assert_eq!(h.normal, Vector3::new(0.0, -1.0, 0.0));
        assert!((h.u - 0.0).abs() < 1e-12 && (h.v - 2.5).abs() < 1e-12);
    }

    #[test]
    fn ray_hits_box_front_face() {
        let s = Scene::demo();
        // Towards the crate (box 0, x in [-1.75, -0.85], y in [0.05, 0.95], z in [0, 0.9]).
        let o = Point3::new(-1.3, -2.0, 0.5);
        let h = s.cast(&o, &Vector3::new(0.0, 1.0, 0.0), u32::MAX).unwrap();
        assert_eq!(h.face, FaceId::Box { index: 0, face: 2 });
        assert!((h.t - 2.05).abs() < 1e-12);
        assert!((h.normal - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn rotated_box_normal_is_rotated() {
        let s = Scene::demo();
        // Box 1 is rotated by 30 degrees: its local +x face normal is (cos 30, sin 30, 0).
        let n = Vector3::new(30f64.to_radians().cos(), 30f64.to_radians().sin(), 0.0);
        let c = Point3::new(1.2, 1.2, 0.6);
        let o = c + n * 1.5;
        let h = s.cast(&o, &(-n), u32::MAX).unwrap();
        assert_eq!(h.face, FaceId::Box { index: 1, face: 1 });
        assert!((h.normal - n).norm() < 1e-12);
        assert!((h.t - 1.1).abs() < 1e-12);
    }

    #[test]
    fn sphere_hit_from_above() {
        let s = Scene::demo();
        let h =
            s.cast(&Point3::new(1.2, 1.2, 2.5), &Vector3::new(0.0, 0.0, -1.0), u32::MAX).unwrap();
        assert_eq!(h.face, FaceId::Sphere(0));
        assert!((h.t - (2.5 - 1.7)).abs() < 1e-12);
    }

    #[test]
    fn radiance_is_bounded() {
        let s = Scene::demo();
        let o = Point3::new(0.0, -2.0, 1.4);
        let mut noise = NoiseCache::new();
        for k in 0..500 {
            let a = f64::from(k) * 0.0126;
            let d = Vector3::new(libm::cos(a), libm::sin(a), 0.3 * libm::sin(7.0 * a));
            let h = s.cast(&o, &d, u32::MAX).unwrap();
            let r = s.radiance(&h, &mut noise);
            assert!((0.0..=1.0).contains(&r));
        }
    }
}
