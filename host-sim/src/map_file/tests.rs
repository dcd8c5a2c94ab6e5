//! Unit tests of [`super::MapFile`] on map files made from records here (a run's saved map is
//! read in `tests/cli_map.rs`).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use super::*;
use ferroslam_core::features::Descriptor;
use ferroslam_core::geometry::Pose;
use ferroslam_core::map::{PlaceKey, PlacePoint};
use nalgebra::{Point3, Translation3, UnitQuaternion, Vector3};

/// A record at `(x, 0, 0)`, turned a quarter turn about y, with `points` points along the
/// camera's z axis (`p_c = (0, 0, 1 + i / 100)`, metres).
fn record(seq: u32, timestamp_s: f64, x: f32, points: usize) -> PlaceRecord {
    let rotation = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f32::consts::FRAC_PI_2);
    let mut r = PlaceRecord {
        seq,
        timestamp_s,
        t_wc: Pose::from_parts(Translation3::new(x, 0.0, 0.0), rotation),
        key: PlaceKey::default(),
        points: Default::default(),
    };
    for i in 0..points {
        // Whole millimetres, as a record stores them.
        let p_c = Point3::new(0.0, 0.0, (1000 + 10 * i) as f32 / 1000.0);
        r.points.push(PlacePoint { p_c, descriptor: Descriptor(i as u64) }).unwrap();
    }
    r
}

fn three_records() -> Vec<PlaceRecord> {
    vec![record(0, 10.0, 0.0, 2), record(5, 12.5, 1.5, 48), record(9, 11.0, -0.5, 5)]
}

#[test]
fn a_map_reads_back_and_its_figures_are_the_records() {
    let bytes = encode_map_file(&three_records());
    assert_eq!(bytes.len(), MAP_HEADER_BYTES + 3 * PLACE_RECORD_BYTES);
    let map = MapFile::from_bytes(&bytes).unwrap();
    assert_eq!(map.records, three_records());
    assert_eq!(map.to_bytes(), bytes, "written back byte for byte");
    let s = map.summary();
    assert_eq!((s.version, s.keyframes, s.file_bytes), (MAP_VERSION, 3, bytes.len()));
    assert_eq!(s.checksum, MapHeader::decode(&bytes).unwrap().checksum);
    let p = s.points.unwrap();
    assert_eq!((p.total, p.min, p.median, p.max), (55, 2, 5.0, 48));
    assert_eq!(s.timestamps_s, Some((10.0, 12.5)));
    let e = s.extent_m.unwrap();
    assert_eq!((e.min, e.max), ([-0.5, 0.0, 0.0], [1.5, 0.0, 0.0]));
    assert_eq!(e.size(), [2.0, 0.0, 0.0]);
    let text = s.to_string();
    for line in [
        "format: version 3, 20-byte header, records of 1024 bytes, 48 points, a 16 x 12 key",
        "file: 3092 bytes",
        "keyframes: 3",
        "verification points: 55 (per keyframe: min 2, median 5, max 48)",
        "segments: not stored in this format",
        "planes and anchors: not in this file",
        "timestamps: 10.000000 s to 12.500000 s (2.500 s)",
        "x -0.500 to 1.500, y 0.000 to 0.000, z 0.000 to 0.000 (extent 2.000 x 0.000 x 0.000)",
    ] {
        assert!(text.contains(line), "{line:?} in {text}");
    }
    assert!(text.contains(&format!(
        "checksum: {:#010x} (FNV-1a of the records and world: matches)",
        s.checksum
    )));
    // The same file as version 2 wrote it (no world: its byte 10 was reserved) reads the same.
    let mut older = bytes.clone();
    older[4] = 2;
    let map = MapFile::from_bytes(&older).unwrap();
    assert_eq!((map.version, map.records.len(), map.world.is_none()), (2, 3, true));
    assert!(map.summary().to_string().contains("format: version 2, "));
}

#[test]
fn a_map_with_planes_and_anchors_says_so_and_writes_them_back() {
    use ferroslam_core::ar::{Anchor, Anchors, MapPlane, Plane, PlaneMap, World};
    use ferroslam_core::loops::PlaceMemory;
    use ferroslam_core::map::RamStore;
    let floor = Plane {
        normal: [0.0, -1.0, 0.0],
        offset_m: 1.2,
        centroid: [0.3, 1.2, 2.0],
        rms_m: 0.003,
        cells: 50,
        samples: 8000,
    };
    let planes = PlaneMap::restored(&[MapPlane { plane: floor, observations: 4, track: 0 }]);
    let cup = Anchor { object: 2, p_w: [0.3, 1.2, 2.0], up_w: [0.0, -1.0, 0.0], scale: 0.5 };
    let anchors = Anchors::restored(&[cup]);
    let mut memory = PlaceMemory::new(RamStore::<8>::new(), 1);
    let mut bytes = Vec::new();
    memory
        .save(Some(&World { planes: &planes, anchors: &anchors }), |b: &[u8]| {
            bytes.extend_from_slice(b);
            Ok::<(), ()>(())
        })
        .unwrap();
    let map = MapFile::from_bytes(&bytes).unwrap();
    let world = map.world.as_ref().unwrap();
    assert_eq!((world.planes()[0].plane, world.anchors()), (floor, &[cup][..]));
    assert_eq!(map.to_bytes(), bytes, "written back byte for byte");
    let s = map.summary();
    assert_eq!((s.keyframes, s.planes, s.anchors), (0, Some(1), Some(1)));
    assert!(s.to_string().contains("planes: 1, anchors: 1"));
    // The PLY: the plane's centroid in blue, then the anchor in green.
    let mut ply = Vec::new();
    let counts = map.write_ply(&mut ply).unwrap();
    assert_eq!((counts.planes, counts.anchors, counts.vertices()), (1, 1, 2));
    let text = String::from_utf8(ply).unwrap();
    let body: Vec<&str> = text.split_once("end_header\n").unwrap().1.lines().collect();
    assert_eq!(body, ["0.3000 1.2000 2.0000 40 110 255", "0.3000 1.2000 2.0000 40 200 60"]);
}

#[test]
fn the_median_of_an_even_count_is_the_mean_of_the_middle_two() {
    let map = MapFile { records: vec![record(0, 0.0, 0.0, 3), record(1, 1.0, 0.0, 4)], ..empty() };
    let p = map.summary().points.unwrap();
    assert_eq!((p.total, p.min, p.median, p.max), (7, 3, 3.5, 4));
}

fn empty() -> MapFile {
    MapFile::from_bytes(&encode_map_file(&[])).unwrap()
}

#[test]
fn an_empty_map_has_no_figures_and_an_empty_cloud() {
    let map = empty();
    let s = map.summary();
    assert_eq!(
        (s.keyframes, s.file_bytes, s.points, s.timestamps_s),
        (0, MAP_HEADER_BYTES, None, None)
    );
    assert!(s.to_string().contains("keyframes: 0\nverification points: 0\n"), "{s}");
    let mut ply = Vec::new();
    let counts = map.write_ply(&mut ply).unwrap();
    assert_eq!(counts.vertices(), 0);
    assert!(String::from_utf8(ply).unwrap().contains("element vertex 0\n"));
}

#[test]
fn the_cloud_has_every_point_in_the_world_frame_then_the_cameras() {
    let map = MapFile::from_bytes(&encode_map_file(&three_records())).unwrap();
    let mut ply = Vec::new();
    let counts = map.write_ply(&mut ply).unwrap();
    assert_eq!(counts, PlyCounts { points: 55, cameras: 3, planes: 0, anchors: 0, skipped: 0 });
    let text = String::from_utf8(ply).unwrap();
    let (header, body) = text.split_once("end_header\n").unwrap();
    assert!(header.starts_with("ply\nformat ascii 1.0\n"), "{header}");
    assert!(header.contains("element vertex 58\n"), "{header}");
    for property in ["float x", "float y", "float z", "uchar red", "uchar green", "uchar blue"] {
        assert!(header.contains(&format!("property {property}\n")), "{header}");
    }
    assert!(header.contains("coloured 170 170 170 (grey)") && header.contains("255 40 40 (red)"));
    let lines: Vec<&str> = body.lines().collect();
    assert_eq!(lines.len(), 58);
    // The first record's first point: z = 1 m in a camera turned a quarter turn about y at the
    // origin is x = 1 m in the world.
    assert_eq!(lines[0], "1.0000 0.0000 0.0000 170 170 170");
    // The second record's camera sits at x = 1.5 m.
    assert_eq!(lines[56], "1.5000 0.0000 0.0000 255 40 40");
    for line in lines {
        let fields: Vec<f32> = line.split(' ').map(|f| f.parse().unwrap()).collect();
        assert_eq!(fields.len(), 6, "{line}");
    }
}

#[test]
fn a_damaged_or_foreign_file_says_what_is_wrong() {
    let good = encode_map_file(&three_records());
    let fault = |bytes: &[u8]| MapFile::from_bytes(bytes).unwrap_err().to_string();

    assert_eq!(fault(&good[..10]), "truncated: 10 bytes where the header says 20");
    assert_eq!(fault(&good[..2000]), "truncated: 2000 bytes where the header says 3092");
    let mut longer = good.clone();
    longer.push(0);
    assert_eq!(fault(&longer), "3093 bytes where the header says 3092: trailing bytes");
    assert_eq!(
        fault(b"PK\x03\x04 a zip file, not a map"),
        "not a ferroslam map file (no FSMP magic)"
    );
    let mut version = good.clone();
    version[4] = 7;
    assert!(fault(&version).starts_with("map format version 7"), "{}", fault(&version));

    // One bit flipped in a record's points: the records' checksum says so.
    let mut flipped = good.clone();
    flipped[MAP_HEADER_BYTES + PLACE_RECORD_BYTES + 300] ^= 0x10;
    let msg = fault(&flipped);
    assert!(msg.contains("the file changed since it was written"), "{msg}");

    // A record erased (zeros) under a header whose checksum was made over it: the record's own
    // check (the core's RecordError) names it.
    let mut erased = good.clone();
    erased[MAP_HEADER_BYTES + PLACE_RECORD_BYTES..MAP_HEADER_BYTES + 2 * PLACE_RECORD_BYTES]
        .fill(0);
    let mut checksum = RecordsChecksum::default();
    checksum.add(&erased[MAP_HEADER_BYTES..]);
    erased[..MAP_HEADER_BYTES].copy_from_slice(
        &MapHeader { records: 3, world_units: 0, checksum: checksum.value() }.encode(),
    );
    assert_eq!(fault(&erased), "record 1 does not decode: the slot holds no record");

    // More records than the host's store takes on --load-map.
    let records = MAX_MAP_RECORDS as u32 + 1;
    let mut many = MapHeader { records, world_units: 0, checksum: 0 }.encode().to_vec();
    many.resize(MAP_HEADER_BYTES + records as usize * PLACE_RECORD_BYTES, 0);
    assert_eq!(fault(&many), format!("{records} records, more than the store's {MAX_MAP_RECORDS}"));
}

#[test]
fn a_file_is_named_in_its_error() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("none.fsmp");
    let e = MapFile::read(&missing).unwrap_err();
    assert!(matches!(e, MapReadError::Io { .. }), "{e}");
    assert!(e.to_string().starts_with(&format!("cannot read the map {}: ", missing.display())));

    let file = dir.path().join("short.fsmp");
    let good = encode_map_file(&three_records());
    std::fs::write(&file, &good[..good.len() - 1]).unwrap();
    let e = MapFile::read(&file).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!("map {}: truncated: 3091 bytes where the header says 3092", file.display())
    );
    std::fs::write(&file, &good).unwrap();
    assert_eq!(MapFile::read(&file).unwrap().records.len(), 3);
}
