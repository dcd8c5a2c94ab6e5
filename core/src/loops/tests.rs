//! Place memory unit tests: records, keys, verification, the memory's policies.
//!
//! Test code only: compiled under #[cfg(test)] from `loops/mod.rs`.

extern crate std;

use heapless::Vec;
use nalgebra::{Point3, Translation3, UnitQuaternion, Vector3};

use super::*;
use crate::config::capacity::{PLACE_POINTS, PLACE_RECORD_BYTES};
use crate::features::Descriptor;
use crate::map::{Observation, PlaceKey, RamStore, RecordError};
use crate::test_rng::TestRng;
use crate::tracking::QueryPoint;

const FX: f32 = 260.0;
const C: (f32, f32) = (160.0, 120.0);

fn pose(t: [f32; 3], axis_angle: [f32; 3]) -> Pose {
    Pose::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_scaled_axis(Vector3::new(axis_angle[0], axis_angle[1], axis_angle[2])),
    )
}

/// `n` points in front of a camera (1-4 m deep, inside a 320 x 240 view), at millimetres so a
/// record holds them exactly, with random descriptors.
fn scene(rng: &mut TestRng, n: usize) -> Vec<PlacePoint, 512> {
    (0..n)
        .map(|_| {
            let z = rng.uniform_f32(1.0, 4.0);
            let (u, v) = (rng.uniform_f32(10.0, 310.0), rng.uniform_f32(10.0, 230.0));
            let mm = |x: f32| libm::roundf(x * 1000.0) / 1000.0;
            let p = Point3::new(mm((u - C.0) * z / FX), mm((v - C.1) * z / FX), mm(z));
            PlacePoint { p_c: p, descriptor: Descriptor(rng.next_u64()) }
        })
        .collect()
}

/// The place's points seen from a camera at `t_rq` in the place's camera (query to record),
/// their descriptors with up to `flips` bits changed, after `distractors` unrelated points.
fn query_of(
    rng: &mut TestRng,
    place: &[PlacePoint],
    t_rq: &Pose,
    flips: u32,
    distractors: usize,
) -> Vec<QueryPoint, 512> {
    let mut out: Vec<QueryPoint, 512> = scene(rng, distractors)
        .into_iter()
        .map(|p| QueryPoint { uv: project(&p.p_c), p_c: p.p_c, descriptor: p.descriptor })
        .collect();
    for p in place {
        let p_q = t_rq.inverse() * p.p_c;
        let mut d = p.descriptor.0;
        for _ in 0..rng.next_u32() % (flips + 1) {
            d ^= 1 << (rng.next_u32() % 64);
        }
        out.push(QueryPoint { uv: project(&p_q), p_c: p_q, descriptor: Descriptor(d) }).unwrap();
    }
    out
}

fn project(p: &Point3<f32>) -> (f32, f32) {
    (FX * p.x / p.z + C.0, FX * p.y / p.z + C.1)
}

fn query<'a>(points: &'a [QueryPoint]) -> PlaceQuery<'a> {
    PlaceQuery { key: PlaceKey::default(), points, size: (320, 240) }
}

fn record(rng: &mut TestRng, t_wc: Pose) -> PlaceRecord {
    let mut key = PlaceKey::default();
    key.0.iter_mut().for_each(|k| *k = rng.next_u32() as u8);
    let points = Vec::from_slice(&scene(rng, PLACE_POINTS)).unwrap();
    PlaceRecord { seq: 7, timestamp_s: 12.5, t_wc, key, points }
}

#[test]
fn records_round_trip_and_damage_is_an_error() {
    let mut rng = TestRng::new(1);
    let r = record(&mut rng, pose([0.5, -1.25, 2.0], [0.1, 0.2, -0.3]));
    let mut buf = [0; PLACE_RECORD_BYTES];
    r.encode(&mut buf);
    assert_eq!(PlaceRecord::decode(&buf), Ok(r.clone()));
    let mut again = [1; PLACE_RECORD_BYTES];
    PlaceRecord::decode(&buf).unwrap().encode(&mut again);
    assert_eq!(buf, again, "encode after decode gives the same bytes");
    for at in [5, 40, 300, PLACE_RECORD_BYTES - 1] {
        let mut bad = buf;
        bad[at] ^= 0x10;
        assert_eq!(PlaceRecord::decode(&bad), Err(RecordError::Corrupt), "byte {at}");
    }
    let mut other = buf;
    other[2] = 9;
    assert_eq!(PlaceRecord::decode(&other), Err(RecordError::Version(9)));
    for erased in [0x00, 0xFF] {
        assert_eq!(PlaceRecord::decode(&[erased; PLACE_RECORD_BYTES]), Err(RecordError::Empty));
    }
}

#[test]
fn place_keys_ignore_brightness_and_tell_scenes_apart() {
    let mut rng = TestRng::new(2);
    let mut img = [0u8; 80 * 60];
    img.iter_mut().for_each(|p| *p = 40 + (rng.next_u32() % 150) as u8);
    let brighter = img.map(|p| p + 30);
    let mut other = [0u8; 80 * 60];
    other.iter_mut().for_each(|p| *p = 40 + (rng.next_u32() % 150) as u8);
    let (a, b, c) =
        (PlaceKey::of(&img, 80, 60), PlaceKey::of(&brighter, 80, 60), PlaceKey::of(&other, 80, 60));
    assert_eq!(a.distance(&b), 0);
    assert!(a.distance(&c) > 5, "{}", a.distance(&c));
    assert_eq!(PlaceKey::of(&img, 8, 6), PlaceKey::default(), "smaller than the key");
}

#[test]
fn verification_recovers_the_motion_between_two_views() {
    let mut rng = TestRng::new(3);
    let place = scene(&mut rng, PLACE_POINTS);
    let t_rq = pose([0.12, -0.05, 0.2], [0.05, -0.1, 0.03]);
    let points = query_of(&mut rng, &place, &t_rq, 4, 120);
    let mut ransac = TrackingRng::new(9);
    let v = verify(&query(&points), &place, &VerifyParams::DEFAULT, &mut ransac).unwrap();
    let err = t_rq.inverse() * v.t_rq;
    assert!(err.translation.vector.norm() < 2e-3, "{err}");
    assert!(err.rotation.angle() < 2e-3, "{err}");
    assert!(v.inliers >= PLACE_POINTS - 2, "{v:?}");
}

#[test]
fn verification_refuses_unrelated_places_and_look_alikes() {
    let mut rng = TestRng::new(4);
    let params = VerifyParams::DEFAULT;
    let mut ransac = TrackingRng::new(9);
    for _ in 0..20 {
        let place = scene(&mut rng, PLACE_POINTS);
        let points = query_of(&mut rng, &[], &Pose::identity(), 0, 250);
        assert!(verify(&query(&points), &place, &params, &mut ransac).is_none());
    }
    // Repeated texture: every point looks the same, so no match is unambiguous.
    let mut place = scene(&mut rng, PLACE_POINTS);
    place.iter_mut().for_each(|p| p.descriptor = Descriptor(0xA5A5_5A5A_0F0F_F0F0));
    let points = query_of(&mut rng, &place, &Pose::identity(), 0, 0);
    assert!(verify(&query(&points), &place, &params, &mut ransac).is_none());
    // The same points on one small patch of the image: too little spread to trust.
    let mut patch = scene(&mut rng, PLACE_POINTS);
    patch.iter_mut().for_each(|p| p.p_c = Point3::new(p.p_c.x * 0.1, p.p_c.y * 0.1, p.p_c.z));
    let points = query_of(&mut rng, &patch, &Pose::identity(), 0, 0);
    assert!(verify(&query(&points), &patch, &params, &mut ransac).is_none());
}

/// A map with one keyframe at `t_wc` observing the landmarks of `place` (camera frame).
fn map_with(place: &[PlacePoint], t_wc: Pose) -> (Map<4, 128>, KeyFrameId) {
    let mut map = Map::new();
    let kf = map.add_keyframe(t_wc, 1.0).unwrap();
    for p in place {
        let lm = map.add_landmark(t_wc * p.p_c, kf).unwrap();
        map.landmark_mut(lm).unwrap().descriptor = Some(p.descriptor);
        map.add_observation(kf, Observation::new(lm, project(&p.p_c), Some(p.p_c.z)).unwrap())
            .unwrap();
    }
    (map, kf)
}

#[test]
fn a_lost_frame_relocalizes_in_a_remembered_keyframe() {
    let mut rng = TestRng::new(5);
    let place = scene(&mut rng, PLACE_POINTS);
    let t_wk = pose([2.0, 0.5, -1.0], [0.0, 1.2, 0.1]);
    let (map, kf) = map_with(&place, t_wk);
    let mut memory = PlaceMemory::new(RamStore::<4>::new(), 11);
    let empty: Map<4, 128> = Map::new();
    assert!(memory.is_empty());
    assert_eq!(memory.relocalize(&query(&[]), &empty), None);
    memory.remember(&map, kf);
    assert_eq!((memory.len(), memory.stats().remembered), (1, 1));
    let t_kq = pose([0.1, 0.0, 0.15], [0.0, 0.08, 0.0]);
    let points = query_of(&mut rng, &place, &t_kq, 3, 100);
    let t_wc = memory.relocalize(&query(&points), &empty).unwrap();
    let err = (t_wk * t_kq).inverse() * t_wc;
    assert!(err.translation.vector.norm() < 5e-3 && err.rotation.angle() < 5e-3, "{err}");
    assert_eq!(memory.stats().relocalized, 1);
    // Nothing of that place in view: no pose.
    let elsewhere = query_of(&mut rng, &[], &Pose::identity(), 0, 200);
    assert_eq!(memory.relocalize(&query(&elsewhere), &empty), None);
    // The same place still in the active map (and nothing stored) relocalizes too.
    let mut fresh = PlaceMemory::new(RamStore::<4>::new(), 11);
    let t_wc = fresh.relocalize(&query(&points), &map).unwrap();
    let err = (t_wk * t_kq).inverse() * t_wc;
    assert!(err.translation.vector.norm() < 5e-3 && err.rotation.angle() < 5e-3, "{err}");
}

#[test]
fn two_places_that_verify_different_poses_are_ambiguous() {
    let mut rng = TestRng::new(6);
    let place = scene(&mut rng, PLACE_POINTS);
    let mut memory = PlaceMemory::new(RamStore::<4>::new(), 11);
    for t in [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]] {
        let (map, kf) = map_with(&place, pose(t, [0.0; 3]));
        memory.remember(&map, kf);
    }
    let points = query_of(&mut rng, &place, &Pose::identity(), 0, 50);
    assert_eq!(memory.relocalize(&query(&points), &Map::<4, 128>::new()), None);
    assert_eq!(memory.stats().ambiguous, 1);
}

#[test]
fn a_full_store_replaces_its_most_redundant_record() {
    let mut rng = TestRng::new(7);
    let place = scene(&mut rng, PLACE_POINTS);
    // Two records (two slots more are kept for the world).
    let mut memory = PlaceMemory::new(RamStore::<4>::new(), 1);
    for x in [0.0, 2.0, 0.1] {
        let (map, kf) = map_with(&place, pose([x, 0.0, 0.0], [0.0; 3]));
        memory.remember(&map, kf);
    }
    let s = memory.stats();
    assert_eq!((memory.len(), s.remembered, s.thinned, s.store_errors), (2, 3, 1, 0));
    // The last record waits in the memory until flushed (the back end's step).
    let mut store = memory.store().clone();
    let mut buf = [0; PLACE_RECORD_BYTES];
    store.read(0, &mut buf).unwrap();
    assert_eq!(PlaceRecord::decode(&buf).unwrap().t_wc.translation.x, 0.0, "not written yet");
    memory.flush();
    let mut store = memory.store().clone();
    let mut buf = [0; PLACE_RECORD_BYTES];
    let xs = [0, 1].map(|slot| {
        store.read(slot, &mut buf).unwrap();
        PlaceRecord::decode(&buf).unwrap().t_wc.translation.x
    });
    assert_eq!(xs, [0.1, 2.0], "the record at 0 m gave way to the one at 0.1 m");
    // A keyframe with too few points to verify is not remembered.
    let (map, kf) = map_with(&place[..MIN_RECORD_POINTS - 1], Pose::identity());
    memory.remember(&map, kf);
    assert_eq!(memory.stats().too_few_points, 1);
}

#[test]
fn a_place_with_a_moved_part_is_refused_unless_the_part_is_small() {
    let mut rng = TestRng::new(8);
    let params = VerifyParams::DEFAULT;
    let mut ransac = TrackingRng::new(9);
    let place = scene(&mut rng, PLACE_POINTS);
    let t_rq = pose([0.05, 0.0, 0.1], [0.0, 0.05, 0.0]);
    // The same room, the points from `moved` on shifted 0.6 m (furniture moved since).
    let seen = |moved: usize, rng: &mut TestRng| {
        let mut points = query_of(rng, &place, &t_rq, 2, 60);
        for q in points.iter_mut().skip(60 + moved) {
            q.p_c.x += 0.6;
            q.uv = project(&q.p_c);
        }
        points
    };
    // Half moved: two rigid motions as strong as each other, no telling which is the camera's.
    let half = seen(PLACE_POINTS / 2, &mut rng);
    assert!(verify(&query(&half), &place, &params, &mut ransac).is_none());
    // A quarter moved: the static three quarters give the camera's pose.
    let quarter = seen(PLACE_POINTS * 3 / 4, &mut rng);
    let v = verify(&query(&quarter), &place, &params, &mut ransac).unwrap();
    let err = t_rq.inverse() * v.t_rq;
    assert!(err.translation.vector.norm() < 5e-3, "{err}");
}

/// A place remembered from a keyframe (the map holding it, and the keyframe) and the camera
/// back near it: its true pose and what it sees of the place (`seed` draws both).
fn revisit(seed: u64) -> (Map<4, 128>, KeyFrameId, Pose, Vec<QueryPoint, 512>) {
    let mut rng = TestRng::new(seed);
    let place = scene(&mut rng, PLACE_POINTS);
    let t_wk = pose([1.0, 0.0, 0.5], [0.0, 0.4, 0.0]);
    let (old, kf) = map_with(&place, t_wk);
    let t_kq = pose([0.05, 0.02, 0.1], [0.0, 0.06, 0.0]);
    let points = query_of(&mut rng, &place, &t_kq, 2, 80);
    (old, kf, t_wk * t_kq, points)
}

#[test]
fn a_new_keyframe_in_a_remembered_place_closes_a_loop_beyond_the_drift_a_view_resolves() {
    let (old, kf, truth, points) = revisit(10);
    let mut memory = PlaceMemory::new(RamStore::<4>::new(), 3);
    memory.remember(&old, kf);
    // The camera back near the remembered keyframe, where the map has drifted by `drift`.
    for (drift, closes) in [
        (pose([0.25, -0.1, 0.05], [0.0, 0.1, 0.02]), true),
        (pose([0.01, 0.0, 0.0], [0.0, 0.002, 0.0]), false),
    ] {
        let (now, new_kf) = map_with(&[], drift * truth);
        // Tracking restarted after the remembered keyframe (creation number 0) was made.
        let closure = memory.close_loop(&query(&points), &now, new_kf, 1);
        assert_eq!(closure.is_some(), closes, "drift {drift}");
        if let Some(c) = closure {
            // The correction moves the drifted keyframe onto its true pose (the drift undone).
            let err = (c.correction * drift).translation.vector.norm();
            assert!(err < 5e-3, "left {err} m");
            assert_eq!(c.record_seq, 0);
        }
    }
    let s = memory.loop_stats();
    assert_eq!((s.queries, s.detected, s.accepted, s.consistent, s.rejected), (2, 2, 1, 1, 0));
    // Tracked without a restart since: the same disagreement is held, not applied.
    let (now, new_kf) = map_with(&[], pose([0.25, -0.1, 0.05], [0.0, 0.1, 0.02]) * truth);
    assert!(memory.close_loop(&query(&points), &now, new_kf, 0).is_none());
    assert_eq!(memory.loop_stats().held, 1);
}

#[test]
fn a_localizing_memory_gives_the_map_points_a_new_keyframe_matches() {
    let (old, kf, truth, points) = revisit(16);
    let mut memory = PlaceMemory::new(RamStore::<4>::new(), 3);
    memory.remember(&old, kf);
    memory.freeze(true);
    // The camera back near the remembered keyframe, the run 3 cm and half a degree off the map.
    let (now, new_kf) = map_with(&[], pose([0.03, 0.0, 0.01], [0.0, 0.01, 0.0]) * truth);
    assert!(
        memory.close_loop(&query(&points), &now, new_kf, 0).is_none(),
        "within a view's accuracy"
    );
    assert_eq!(memory.loop_stats().consistent, 1);
    let mut pairs: std::vec::Vec<(usize, Point3<f32>)> = std::vec::Vec::new();
    memory.map_points(&query(&points), |i, p_w| pairs.push((i, p_w)));
    assert!(pairs.len() >= PLACE_POINTS - 4, "{} of {PLACE_POINTS}", pairs.len());
    for (i, p_w) in &pairs {
        // The place's points follow the 80 distractors; each pair is the same point.
        assert!(*i >= 80, "distractor {i} matched");
        let err = (truth * points[*i].p_c - p_w).norm();
        assert!(err < 2e-3, "point {i} off by {err} m");
    }
    let mut again = 0;
    memory.map_points(&query(&points), |_, _| again += 1);
    assert_eq!(again, 0, "given once per loop query");
    // Mapping (not frozen): the map's points are not offered.
    memory.freeze(false);
    let _ = memory.close_loop(&query(&points), &now, new_kf, 0);
    memory.map_points(&query(&points), |_, _| again += 1);
    assert_eq!(again, 0);
}

/// A keyframe of creation number `seq` at `t_wc`, alone in a map.
fn keyframe_numbered(seq: u32, t_wc: Pose) -> (Map<4, 128>, KeyFrameId) {
    let mut map = Map::new();
    map.number_from(seq);
    let kf = map.add_keyframe(t_wc, 1.0).unwrap();
    (map, kf)
}

#[test]
fn held_loops_are_applied_once_enough_in_a_row_agree() {
    let (old, kf, truth, points) = revisit(13);
    let drift = pose([0.25, -0.1, 0.05], [0.0, 0.1, 0.02]);
    // Another drift, 10 cm from it: a held loop that does not agree.
    let other = pose([0.35, -0.1, 0.05], [0.0, 0.1, 0.02]);
    // Over the loop threshold, under the held one: held, never applied.
    let small = pose([0.12, 0.0, 0.0], [0.0, 0.0, 0.0]);
    let run = |memory: &mut PlaceMemory<RamStore<4>>, steps: &[(u32, Pose)]| {
        steps
            .iter()
            .map(|&(seq, d)| {
                let (now, new_kf) = keyframe_numbered(seq, d * truth);
                // Tracked since creation number 0 with no restart: every loop is held first.
                memory.close_loop(&query(&points), &now, new_kf, 0)
            })
            .collect::<std::vec::Vec<_>>()
    };
    let confirmations = usize::from(HELD_LOOP_CONFIRMATIONS);

    // Agreeing held loops on consecutive keyframes: the last of them is applied, and undoes the
    // drift.
    let mut memory = PlaceMemory::new(RamStore::<4>::new(), 3);
    memory.remember(&old, kf);
    let steps: std::vec::Vec<_> = (0..confirmations as u32).map(|i| (10 + i, drift)).collect();
    let closures = run(&mut memory, &steps);
    assert!(closures[..confirmations - 1].iter().all(Option::is_none));
    let c = closures[confirmations - 1].expect("applied once confirmed");
    assert!((c.correction * drift).translation.vector.norm() < 5e-3);
    let s = memory.loop_stats();
    let held = HELD_LOOP_CONFIRMATIONS.into();
    assert_eq!((s.held, s.accepted, s.confirmed), (held, 1, 1));

    // A disagreeing one in between, or a gap of more than `HELD_MAX_GAP` keyframes, starts the
    // count again, and corrections under `HELD_MIN_CORRECTION_M` do not count: nothing is
    // applied.
    for steps in [
        [(10, drift), (11, other), (12, drift)],
        [(10, drift), (11, drift), (12 + HELD_MAX_GAP, drift)],
        [(10, small), (11, small), (12, small)],
    ] {
        let mut memory = PlaceMemory::new(RamStore::<4>::new(), 3);
        memory.remember(&old, kf);
        assert!(run(&mut memory, &steps).iter().all(Option::is_none), "{steps:?}");
        let s = memory.loop_stats();
        assert_eq!((s.detected, s.held, s.accepted), (3, 3, 0), "{steps:?}");
    }
}

#[test]
fn a_loop_is_looked_for_in_the_map_only_before_tracking_last_restarted() {
    let mut rng = TestRng::new(12);
    let place = scene(&mut rng, PLACE_POINTS);
    let t_wk = pose([0.0, 0.0, 0.0], [0.0, 0.3, 0.0]);
    // Keyframe 0 saw the place; keyframe 1, made after a restart 0.4 m off, sees it again.
    let (mut map, _) = map_with(&place, t_wk);
    let off = pose([0.4, 0.0, 0.0], [0.0, 0.0, 0.0]);
    let new_kf = map.add_keyframe(off * t_wk, 2.0).unwrap();
    let points = query_of(&mut rng, &place, &Pose::identity(), 0, 60);
    let mut memory = PlaceMemory::new(RamStore::<4>::new(), 3);
    // Tracking restarted at keyframe 1: keyframe 0 is not connected to it, a loop candidate.
    let c = memory.close_loop(&query(&points), &map, new_kf, 1).unwrap();
    assert!((c.correction * off).translation.vector.norm() < 5e-3);
    // Tracking never restarted (and nothing stored): the map is one piece, nothing to close.
    assert!(memory.close_loop(&query(&points), &map, new_kf, 0).is_none());
}

/// A store that counts its reads.
#[derive(Clone)]
struct Counting<const N: usize> {
    store: RamStore<N>,
    reads: usize,
}

impl<const N: usize> KeyframeStore for Counting<N> {
    type Error = crate::map::SlotOutOfRange;

    fn capacity(&self) -> usize {
        self.store.capacity()
    }

    fn read(&mut self, slot: usize, buf: &mut RecordBytes) -> Result<(), Self::Error> {
        self.reads += 1;
        self.store.read(slot, buf)
    }

    fn write(&mut self, slot: usize, buf: &RecordBytes) -> Result<(), Self::Error> {
        self.store.write(slot, buf)
    }
}

#[test]
fn a_full_store_reads_a_shortlist_to_thin_and_to_query() {
    let mut rng = TestRng::new(13);
    let place = scene(&mut rng, PLACE_POINTS);
    // 64 records (two slots more are kept for the world) along a line, each with its own random
    // key.
    let mut memory = PlaceMemory::new(Counting { store: RamStore::<66>::new(), reads: 0 }, 1);
    let key_of = |rng: &mut TestRng| {
        let mut key = PlaceKey::default();
        key.0.iter_mut().for_each(|k| *k = rng.next_u32() as u8);
        key
    };
    let mut keys: Vec<PlaceKey, 64> = Vec::new();
    for i in 0..64 {
        let (mut map, kf) = map_with(&place, pose([i as f32 * 0.5, 0.0, 0.0], [0.0; 3]));
        let key = key_of(&mut rng);
        map.keyframe_mut(kf).unwrap().place_key = key;
        keys.push(key).unwrap();
        memory.remember(&map, kf);
    }
    assert_eq!(memory.len(), 64);
    // One more, with the key of record 40 but nearest in pose to record 10: one of the records
    // that look like it gives way, not record 10 (which the seeded keys leave out of the shortlist).
    let (mut map, kf) = map_with(&place, pose([5.1, 0.0, 0.0], [0.0; 3]));
    map.keyframe_mut(kf).unwrap().place_key = keys[40];
    let before = memory.store().reads;
    memory.remember(&map, kf);
    assert!(memory.store().reads - before <= SHORTLIST, "thinning reads a shortlist");
    assert_eq!(memory.stats().thinned, 1);
    memory.flush();
    let mut store = memory.store().clone();
    let mut buf = [0; PLACE_RECORD_BYTES];
    let x = |store: &mut Counting<66>, buf: &mut RecordBytes, slot| {
        store.read(slot, buf).unwrap();
        PlaceRecord::decode(buf).unwrap().t_wc.translation.x
    };
    assert_eq!(x(&mut store, &mut buf, 10), 5.0, "the record nearest in pose but unlike it stays");
    let replaced = (0..64).filter(|&slot| x(&mut store, &mut buf, slot) == 5.1).count();
    assert_eq!(replaced, 1);
    // A query reads the shortlist and its candidates again, not the whole store.
    let before = memory.store().reads;
    let points = query_of(&mut rng, &place, &Pose::identity(), 0, 50);
    let _ = memory.relocalize(&query(&points), &Map::<4, 128>::new());
    assert!(memory.store().reads - before <= SHORTLIST + CANDIDATES);
}

/// A memory of three records (different poses and keys) over a store of `N`.
fn three_records<const N: usize>(rng: &mut TestRng) -> PlaceMemory<RamStore<N>> {
    let place = scene(rng, PLACE_POINTS);
    let mut memory = PlaceMemory::new(RamStore::<N>::new(), 1);
    for x in [0.0, 1.0, 2.0] {
        let (mut map, kf) = map_with(&place, pose([x, 0.0, 0.0], [0.0; 3]));
        map.keyframe_mut(kf)
            .unwrap()
            .place_key
            .0
            .iter_mut()
            .for_each(|k| *k = rng.next_u32() as u8);
        memory.remember(&map, kf);
    }
    memory
}

fn saved<S: KeyframeStore>(memory: &mut PlaceMemory<S>) -> std::vec::Vec<u8> {
    saved_with(memory, None)
}

/// The map file `memory` saves, with `world` after its records.
fn saved_with<S: KeyframeStore>(
    memory: &mut PlaceMemory<S>,
    world: Option<&crate::ar::World<'_>>,
) -> std::vec::Vec<u8> {
    let mut file = std::vec::Vec::new();
    memory
        .save(world, |b: &[u8]| -> Result<(), ()> {
            file.extend_from_slice(b);
            Ok(())
        })
        .unwrap();
    file
}

#[test]
fn a_saved_map_loads_and_saves_to_the_same_bytes_and_relocalizes() {
    let mut rng = TestRng::new(14);
    let mut memory = three_records::<8>(&mut rng);
    let file = saved(&mut memory);
    assert_eq!(file.len(), crate::persist::MAP_HEADER_BYTES + 3 * PLACE_RECORD_BYTES);
    let mut loaded = PlaceMemory::new(RamStore::<8>::new(), 1);
    assert!(!loaded.holds_places());
    loaded.load(&file).unwrap();
    assert!(loaded.holds_places() && loaded.len() == 3);
    assert_eq!(saved(&mut loaded), file, "save -> load -> save gives the same bytes");
    // Frozen (localization): a keyframe leaving the map is not remembered.
    loaded.freeze(true);
    let (map, kf) = map_with(&scene(&mut rng, PLACE_POINTS), Pose::identity());
    loaded.remember(&map, kf);
    assert_eq!(loaded.len(), 3);
}

#[test]
fn a_damaged_map_file_is_refused_whole_with_what_is_wrong() {
    let mut rng = TestRng::new(15);
    let file = saved(&mut three_records::<8>(&mut rng));
    // A memory that holds something already keeps it when a load fails.
    let mut memory = three_records::<6>(&mut rng);
    let before = saved(&mut memory);
    // Two slots of four: the other two are kept for the world's planes and anchors.
    let mut small = three_records::<4>(&mut rng);
    let small_before = saved(&mut small);
    let err = small.load(&file).unwrap_err();
    assert_eq!(err, crate::persist::MapFileError::TooManyRecords { records: 3, capacity: 2 });
    assert_eq!(saved(&mut small), small_before);
    let h = crate::persist::MAP_HEADER_BYTES;
    let mut flipped = file.clone();
    flipped[h + PLACE_RECORD_BYTES + 100] ^= 0x04;
    let mut version = file.clone();
    version[4] = 9;
    let mut layout = file.clone();
    layout[5] = 32;
    let mut unreadable = file.clone();
    // A record whose bytes are all erased (the checksum in the header made to match).
    unreadable[h..h + PLACE_RECORD_BYTES].fill(0xFF);
    let mut sum = crate::persist::RecordsChecksum::default();
    unreadable[h..].chunks(PLACE_RECORD_BYTES).for_each(|r| sum.add(r));
    unreadable[h - 4..h].copy_from_slice(&sum.value().to_le_bytes());
    let mut trailing = file.clone();
    trailing.push(0);
    for (bad, wrong) in [
        (&file[..file.len() - 1], "Truncated"),
        (&trailing[..], "TrailingBytes"),
        (&flipped[..], "Checksum"),
        (&version[..], "Version(9)"),
        (&layout[..], "Layout(RecordLayout { record_bytes: 1024, points: 32"),
        (&unreadable[..], "Record { index: 0 }"),
        (&file[..h], "Truncated"),
        (&b"not a map at all"[..], "NotAMap"),
    ] {
        let err = memory.load(bad).unwrap_err();
        assert!(std::format!("{err:?}").starts_with(wrong), "{wrong}: {err:?}");
        assert_eq!(saved(&mut memory), before, "{wrong}: nothing half loaded");
    }
}

#[test]
fn a_map_committed_to_flash_is_what_the_next_boot_holds() {
    use crate::persist::{FlashStore, SliceFlash, flash_bytes_for};
    let mut rng = TestRng::new(16);
    let file = saved(&mut three_records::<8>(&mut rng));
    let mut image = std::vec![0xFF; flash_bytes_for(8)];
    let mut memory = PlaceMemory::new(FlashStore::mount(SliceFlash::new(&mut image)).unwrap(), 1);
    memory.load(&file).unwrap();
    // Loaded but not committed: a boot finds an empty store.
    let mut copy = memory.store().flash().bytes().to_vec();
    let mut booted = PlaceMemory::new(FlashStore::unmounted(SliceFlash::empty()), 1);
    booted.attach(FlashStore::mount(SliceFlash::new(&mut copy)).unwrap());
    assert!(booted.is_empty());
    memory.commit(None).unwrap();
    let mut copy = memory.store().flash().bytes().to_vec();
    let mut booted = PlaceMemory::new(FlashStore::unmounted(SliceFlash::empty()), 1);
    booted.attach(FlashStore::mount(SliceFlash::new(&mut copy)).unwrap());
    assert!(booted.holds_places() && booted.len() == 3);
    assert_eq!(saved(&mut booted), file, "the boot's map is the committed one, byte for byte");
    assert_eq!(booted.stats().store_errors, 0);
}

/// Two planes (a floor and a wall) and two objects on them: a world to save.
fn a_world() -> (crate::ar::PlaneMap, crate::ar::Anchors) {
    use crate::ar::{Anchor, Anchors, MapPlane, Plane, PlaneMap};
    let plane = |normal: [f32; 3], offset_m: f32, samples: u32| MapPlane {
        plane: Plane {
            normal,
            offset_m,
            centroid: normal.map(|n| -n * offset_m),
            rms_m: 0.004,
            cells: 40,
            samples,
        },
        observations: 3,
        track: 0,
    };
    let planes = PlaneMap::restored(&[
        plane([0.0, -1.0, 0.0], 1.2, 9000),
        plane([0.0, 0.0, -1.0], 3.0, 5000),
    ]);
    let anchor =
        |object: u16, p_w: [f32; 3], up_w: [f32; 3]| Anchor { object, p_w, up_w, scale: 1.5 };
    let anchors = Anchors::restored(&[
        anchor(7, [0.2, 1.2, 2.0], [0.0, -1.0, 0.0]),
        anchor(3, [-0.4, 0.1, 3.0], [0.0, 0.0, -1.0]),
    ]);
    (planes, anchors)
}

#[test]
fn the_world_is_saved_and_committed_after_the_records_and_read_back_whole() {
    use crate::ar::World;
    use crate::persist::{FlashStore, SliceFlash, flash_bytes_for};
    let (planes, anchors) = a_world();
    let world = World { planes: &planes, anchors: &anchors };
    let mut rng = TestRng::new(17);
    let mut memory = three_records::<8>(&mut rng);
    let file = saved_with(&mut memory, Some(&world));
    assert_eq!(file.len(), crate::persist::MAP_HEADER_BYTES + 5 * PLACE_RECORD_BYTES);
    // A file: loaded, its world given back whole.
    let mut loaded = PlaceMemory::new(RamStore::<8>::new(), 1);
    let back = loaded.load(&file).unwrap().unwrap();
    assert_eq!(loaded.len(), 3);
    let planes_back: std::vec::Vec<_> = back.planes().iter().map(|m| m.plane).collect();
    let planes_saved: std::vec::Vec<_> = planes.planes().iter().map(|m| m.plane).collect();
    assert_eq!(planes_back, planes_saved);
    assert!(back.anchors().iter().eq(anchors.iter()));
    // Flash: committed with the world, a boot finds the records and the world.
    let mut image = std::vec![0xFF; flash_bytes_for(8)];
    let mut memory = PlaceMemory::new(FlashStore::mount(SliceFlash::new(&mut image)).unwrap(), 1);
    memory.load(&file).unwrap();
    memory.commit(Some(&world)).unwrap();
    // Committed again unchanged: nothing is written (a periodic commit spares the flash).
    let before = memory.store().flash().bytes().to_vec();
    memory.commit(Some(&world)).unwrap();
    assert!(memory.store().flash().bytes() == &before[..], "an unchanged map writes nothing");
    let mut copy = memory.store().flash().bytes().to_vec();
    let mut booted = PlaceMemory::new(FlashStore::unmounted(SliceFlash::empty()), 1);
    booted.attach(FlashStore::mount(SliceFlash::new(&mut copy)).unwrap());
    assert_eq!((booted.len(), booted.stats().store_errors), (3, 0));
    let held = booted.held_world().unwrap().unwrap();
    assert_eq!(held, back, "the boot's world is the committed one");
    // A bit flipped in a world unit on the flash: the boot takes the records and refuses the
    // world.
    let mut flipped = memory.store().flash().bytes().to_vec();
    let at = flipped
        .chunks(PLACE_RECORD_BYTES)
        .position(|u| crate::ar::is_world_unit(u.try_into().unwrap()))
        .unwrap();
    flipped[at * PLACE_RECORD_BYTES + 40] ^= 0x02;
    let mut damaged = PlaceMemory::new(FlashStore::unmounted(SliceFlash::empty()), 1);
    damaged.attach(FlashStore::mount(SliceFlash::new(&mut flipped)).unwrap());
    assert_eq!(damaged.len(), 3);
    assert_eq!(damaged.held_world(), Some(Err(crate::ar::WorldError::Checksum)));
    // An anchor scaled: the next commit writes the world again, and the boot finds the change.
    let mut anchors = anchors.clone();
    anchors.scale(7, 3.0).unwrap();
    memory.commit(Some(&World { planes: &planes, anchors: &anchors })).unwrap();
    let mut copy = memory.store().flash().bytes().to_vec();
    let mut booted = PlaceMemory::new(FlashStore::unmounted(SliceFlash::empty()), 1);
    booted.attach(FlashStore::mount(SliceFlash::new(&mut copy)).unwrap());
    let scaled = booted.held_world().unwrap().unwrap();
    assert_eq!(scaled.anchors().iter().map(|a| a.scale).collect::<std::vec::Vec<_>>(), [3.0, 1.5]);
    // A record remembered over the world's first slot: it is no longer there to read.
    let (map, kf) = map_with(&scene(&mut rng, PLACE_POINTS), Pose::identity());
    booted.remember(&map, kf);
    booted.flush();
    assert_eq!(booted.len(), 4);
    assert!(booted.held_world().is_none());
}

#[test]
fn a_damaged_world_is_refused_with_the_file() {
    use crate::ar::World;
    use crate::persist::{MAP_HEADER_BYTES, MapFileError, RecordsChecksum};
    let (planes, anchors) = a_world();
    let world = World { planes: &planes, anchors: &anchors };
    let mut rng = TestRng::new(18);
    let mut memory = three_records::<8>(&mut rng);
    let mut file = saved_with(&mut memory, Some(&world));
    // A bit flipped in the second world unit, the file's checksum made to match: the unit's own
    // checksum refuses it.
    let h = MAP_HEADER_BYTES;
    file[h + 4 * PLACE_RECORD_BYTES + 20] ^= 0x10;
    let mut sum = RecordsChecksum::default();
    file[h..].chunks(PLACE_RECORD_BYTES).for_each(|r| sum.add(r));
    file[h - 4..h].copy_from_slice(&sum.value().to_le_bytes());
    let mut loaded = PlaceMemory::new(RamStore::<8>::new(), 1);
    assert_eq!(loaded.load(&file), Err(MapFileError::World(crate::ar::WorldError::Checksum)));
    assert!(loaded.is_empty(), "nothing half loaded");
}
