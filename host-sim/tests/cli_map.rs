//! `ferroslam-sim map info` and `map export`: reading map files, refusing damaged or missing
//! ones, and the map a replay saves and loads.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::{sim, stderr};

/// A map file of `keyframes` records at x = 0, 1, ... m, each with 10 points 2 m ahead.
fn map_file_of(keyframes: u32) -> Vec<u8> {
    use ferroslam_core::features::Descriptor;
    use ferroslam_core::geometry::Pose;
    use ferroslam_core::map::{PlaceKey, PlacePoint, PlaceRecord};
    use nalgebra::{Point3, Translation3, UnitQuaternion};

    let records: Vec<PlaceRecord> = (0..keyframes)
        .map(|seq| {
            let mut r = PlaceRecord {
                seq,
                timestamp_s: f64::from(seq) / 2.0,
                t_wc: Pose::from_parts(
                    Translation3::new(seq as f32, 0.0, 0.0),
                    UnitQuaternion::identity(),
                ),
                key: PlaceKey::default(),
                points: Default::default(),
            };
            for i in 0..10 {
                let p = PlacePoint { p_c: Point3::new(0.0, 0.0, 2.0), descriptor: Descriptor(i) };
                r.points.push(p).unwrap();
            }
            r
        })
        .collect();
    ferroslam_sim::map_file::encode_map_file(&records)
}

/// The vertex lines of a PLY `text` after checking its header: how many the header declares and
/// the lines themselves.
fn ply_vertices(text: &str) -> (usize, Vec<&str>) {
    let (header, body) = text.split_once("end_header\n").expect("a PLY header");
    assert!(header.starts_with("ply\nformat ascii 1.0\n"), "{header}");
    let declared = header
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .expect("a vertex element")
        .parse()
        .unwrap();
    (declared, body.lines().collect())
}

#[test]
fn map_info_and_export_read_a_map_file() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("three.fsmp");
    std::fs::write(&map, map_file_of(3)).unwrap();
    let run = sim(&["map", "info", map.to_str().unwrap()]);
    assert!(run.status.success(), "{}", stderr(&run));
    let info = String::from_utf8_lossy(&run.stdout);
    for figure in [
        "keyframes: 3",
        "verification points: 30 (per keyframe: min 10, median 10, max 10)",
        "file: 3092 bytes",
        "(FNV-1a of the records and world: matches)",
        "segments: not stored in this format",
        "timestamps: 0.000000 s to 1.000000 s",
        "x 0.000 to 2.000",
    ] {
        assert!(info.contains(figure), "{figure:?} in {info}");
    }

    let ply = dir.path().join("three.ply");
    let run = sim(&["map", "export", map.to_str().unwrap(), "--ply", ply.to_str().unwrap()]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(String::from_utf8_lossy(&run.stdout).contains("wrote 33 vertices"));
    let text = std::fs::read_to_string(&ply).unwrap();
    let (declared, vertices) = ply_vertices(&text);
    assert_eq!((declared, vertices.len()), (33, 33));
    assert_eq!(vertices[10], "1.0000 0.0000 2.0000 170 170 170", "t_wc * p_c");
    assert_eq!(vertices[31], "1.0000 0.0000 0.0000 255 40 40", "a camera");
}

#[test]
fn map_of_a_damaged_or_missing_file_fails_saying_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let good = map_file_of(2);
    let ply = dir.path().join("out.ply");
    let mut flipped = good.clone();
    flipped[20 + 1024 + 40] ^= 0x01;
    let cases: [(&str, &[u8], &str); 4] = [
        (
            "truncated.fsmp",
            &good[..good.len() - 100],
            "truncated: 1968 bytes where the header says 2068",
        ),
        ("flipped.fsmp", &flipped, "the file changed since it was written"),
        ("text.fsmp", b"not a map at all\n", "not a ferroslam map file"),
        ("empty.fsmp", b"", "truncated: 0 bytes where the header says 20"),
    ];
    for (name, bytes, why) in cases {
        let file = dir.path().join(name);
        std::fs::write(&file, bytes).unwrap();
        let path = file.to_str().unwrap();
        for args in
            [vec!["map", "info", path], vec!["map", "export", path, "--ply", ply.to_str().unwrap()]]
        {
            let run = sim(&args);
            assert_eq!(run.status.code(), Some(1), "{args:?}");
            let msg = stderr(&run);
            assert!(msg.contains(&format!("map {path}: ")) && msg.contains(why), "{msg}");
            assert!(!msg.contains("panicked"), "{msg}");
            assert!(run.stdout.is_empty(), "nothing printed of a refused map");
        }
    }
    assert!(!ply.exists(), "no PLY written of a refused map");
    let run = sim(&["map", "info", "/nonexistent/map.fsmp"]);
    assert_eq!(run.status.code(), Some(1));
    assert!(stderr(&run).contains("cannot read the map /nonexistent/map.fsmp"), "{}", stderr(&run));
    assert_eq!(sim(&["map", "export", "x.fsmp"]).status.code(), Some(2), "--ply is required");
}

#[test]
fn a_map_saved_by_a_replay_reads_back_with_its_keyframes() {
    let dir = tempfile::tempdir().unwrap();
    let (data, out) = (dir.path().join("data"), dir.path().join("out"));
    let map = dir.path().join("run.fsmp");
    let run = sim(&["demo", "--frames", "40", "--write-dataset", data.to_str().unwrap()]);
    assert!(run.status.success(), "{}", stderr(&run));
    let args = ["replay", data.to_str().unwrap(), "--out", out.to_str().unwrap()];
    let run = sim(&[&args[..], &["--save-map", map.to_str().unwrap()]].concat());
    assert!(run.status.success(), "{}", stderr(&run));
    // The replay says "map: N keyframes, P planes and A anchors saved to FILE (B bytes)".
    let msg = stderr(&run);
    let (keyframes, planes) = msg
        .lines()
        .filter(|l| l.contains(" anchors saved to "))
        .find_map(|l| {
            let (n, rest) = l.strip_prefix("map: ")?.split_once(" keyframes, ")?;
            Some((n.parse::<usize>().ok()?, rest.split_once(" planes")?.0.parse::<usize>().ok()?))
        })
        .unwrap_or_else(|| panic!("the replay names the keyframes and planes saved: {msg}"));
    assert!(keyframes > 1 && planes > 0, "{msg}");

    let run = sim(&["map", "info", map.to_str().unwrap()]);
    assert!(run.status.success(), "{}", stderr(&run));
    let info = String::from_utf8_lossy(&run.stdout);
    assert!(info.contains(&format!("keyframes: {keyframes}\n")), "{info}");
    assert!(info.contains(&format!("planes: {planes}, anchors: 0\n")), "{info}");
    assert!(info.contains("(FNV-1a of the records and world: matches)"), "{info}");
    let file_bytes = std::fs::metadata(&map).unwrap().len();
    assert!(info.contains(&format!("file: {file_bytes} bytes")), "{info}");

    let ply = dir.path().join("run.ply");
    let run = sim(&["map", "export", map.to_str().unwrap(), "--ply", ply.to_str().unwrap()]);
    assert!(run.status.success(), "{}", stderr(&run));
    let text = std::fs::read_to_string(&ply).unwrap();
    let (declared, vertices) = ply_vertices(&text);
    assert_eq!(declared, vertices.len());
    let cameras = vertices.iter().filter(|v| v.ends_with(" 255 40 40")).count();
    assert_eq!(cameras, keyframes, "one camera vertex per keyframe");
    let centroids = vertices.iter().filter(|v| v.ends_with(" 40 110 255")).count();
    assert_eq!(centroids, planes, "one vertex per saved plane");
    assert!(declared > keyframes + planes, "and the verification points");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains(&format!("wrote {declared} vertices")), "{stdout}");

    // Played again in the saved map: it starts with the keyframes and the planes, and says so.
    let again = dir.path().join("again");
    let args = ["replay", data.to_str().unwrap(), "--out", again.to_str().unwrap()];
    let run = sim(&[&args[..], &["--load-map", map.to_str().unwrap(), "--localize"]].concat());
    assert!(run.status.success(), "{}", stderr(&run));
    let loaded = format!("map: {keyframes} keyframes, {planes} planes and 0 anchors loaded from ");
    assert!(stderr(&run).contains(&loaded), "{}", stderr(&run));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(again.join("report.json")).unwrap()).unwrap();
    let expected = serde_json::json!({"keyframes": keyframes, "planes": planes, "anchors": 0});
    assert_eq!(report["places"]["loaded"], expected);
}
