//! Foxglove messages as JSON values, the fields [`super::schemas`] describes: times, poses,
//! transforms, point clouds, scene entities (arrows, cubes) and log lines. Numbers in metres,
//! quaternions `x, y, z, w`, colours 0 to 1.

use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use serde_json::{Value, json};

use super::schemas::EMPTY_PRIMITIVES;
use crate::dataset::mcap::time::stamp_of;

/// A time as Foxglove and MCAP hold it: whole seconds and nanoseconds (0 to 999,999,999).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct Time {
    /// Whole seconds.
    pub sec: u32,
    /// Nanoseconds past them.
    pub nsec: u32,
}

impl Time {
    /// `t_s` seconds as a ROS header stamp holds them (its shortest decimal, to the nearest
    /// nanosecond: [`stamp_of`]); a time no stamp holds (negative, not finite, past 2038) is 0.
    pub fn from_seconds(t_s: f64) -> Self {
        let zero = Self { sec: 0, nsec: 0 };
        stamp_of(t_s).map_or(zero, |s| match u32::try_from(s.sec) {
            Ok(sec) => Self { sec, nsec: s.nanosec },
            Err(_) => zero,
        })
    }

    /// Nanoseconds since 0 (an MCAP log time).
    pub fn nanos(self) -> u64 {
        u64::from(self.sec) * 1_000_000_000 + u64::from(self.nsec)
    }

    /// `{sec, nsec}`.
    pub fn json(self) -> Value {
        json!({ "sec": self.sec, "nsec": self.nsec })
    }
}

/// An RGBA colour, 0 to 1.
pub type Rgba = [f32; 4];

/// `x` as the shortest decimal that reads back as the same f32 (`0.1`, not
/// `0.10000000149011612`): smaller files, the same values.
pub fn short(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::NAN)
}

fn vector3(v: &Vector3<f64>) -> Value {
    json!({ "x": v.x, "y": v.y, "z": v.z })
}

fn quaternion(q: &UnitQuaternion<f64>) -> Value {
    json!({ "x": q.i, "y": q.j, "z": q.k, "w": q.w })
}

/// `{position, orientation}` of `pose`.
pub fn pose(pose: &Isometry3<f64>) -> Value {
    json!({
        "position": vector3(&pose.translation.vector),
        "orientation": quaternion(&pose.rotation),
    })
}

fn color([r, g, b, a]: Rgba) -> Value {
    json!({ "r": short(r), "g": short(g), "b": short(b), "a": short(a) })
}

/// `foxglove.PoseInFrame`: `t_wc` in `frame_id` at `time`.
pub fn pose_in_frame(time: Time, frame_id: &str, t_wc: &Isometry3<f64>) -> Value {
    json!({ "timestamp": time.json(), "frame_id": frame_id, "pose": pose(t_wc) })
}

/// `foxglove.PosesInFrame`: `poses` in `frame_id` at `time`.
pub fn poses_in_frame<'a>(
    time: Time,
    frame_id: &str,
    poses: impl Iterator<Item = &'a Isometry3<f64>>,
) -> Value {
    let poses: Vec<Value> = poses.map(pose).collect();
    json!({ "timestamp": time.json(), "frame_id": frame_id, "poses": poses })
}

/// `foxglove.FrameTransform`: the child frame's pose in the parent frame (`t_parent_child`).
pub fn frame_transform(
    time: Time,
    parent: &str,
    child: &str,
    t_parent_child: &Isometry3<f64>,
) -> Value {
    json!({
        "timestamp": time.json(),
        "parent_frame_id": parent,
        "child_frame_id": child,
        "translation": vector3(&t_parent_child.translation.vector),
        "rotation": quaternion(&t_parent_child.rotation),
    })
}

/// Foxglove's `NumericType` of a 32-bit float.
const FLOAT32: u8 = 7;

/// `foxglove.PointCloud`: `points` in `frame_id` (at its origin), fields `x, y, z` as
/// little-endian f32, 12 bytes a point, base64 as Foxglove's JSON carries bytes.
pub fn point_cloud(time: Time, frame_id: &str, points: &[[f32; 3]]) -> Value {
    let data: Vec<u8> = points.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    let fields: Vec<Value> = ["x", "y", "z"]
        .iter()
        .zip([0, 4, 8])
        .map(|(name, offset)| json!({ "name": name, "offset": offset, "type": FLOAT32 }))
        .collect();
    json!({
        "timestamp": time.json(),
        "frame_id": frame_id,
        "pose": pose(&Isometry3::identity()),
        "point_stride": 12,
        "fields": fields,
        "data": base64(&data),
    })
}

/// A primitive of a scene entity.
#[derive(Debug, Clone, Copy)]
pub enum Primitive {
    /// An arrow from `pose`'s origin along its x axis, `length_m` long (shaft and head).
    Arrow {
        /// Tail and direction.
        pose: Isometry3<f64>,
        /// Overall length, metres.
        length_m: f64,
        /// Colour.
        color: Rgba,
    },
    /// A box centred on `pose`'s origin, `size_m` along its axes.
    Cube {
        /// Centre and orientation.
        pose: Isometry3<f64>,
        /// Sides, metres.
        size_m: [f64; 3],
        /// Colour.
        color: Rgba,
    },
}

/// A `foxglove.SceneEntity` in `frame_id`, kept until replaced or deleted, of one primitive.
pub fn entity(time: Time, frame_id: &str, id: &str, primitive: &Primitive) -> Value {
    let (arrows, cubes) = match *primitive {
        Primitive::Arrow { pose: p, length_m, color: c } => {
            let arrow = json!({
                "pose": pose(&p),
                "shaft_length": 0.7 * length_m,
                "shaft_diameter": 0.1 * length_m,
                "head_length": 0.3 * length_m,
                "head_diameter": 0.25 * length_m,
                "color": color(c),
            });
            (vec![arrow], Vec::new())
        }
        Primitive::Cube { pose: p, size_m: [x, y, z], color: c } => {
            let cube = json!({
                "pose": pose(&p),
                "size": { "x": x, "y": y, "z": z },
                "color": color(c),
            });
            (Vec::new(), vec![cube])
        }
    };
    let mut entity = json!({
        "timestamp": time.json(),
        "frame_id": frame_id,
        "id": id,
        "lifetime": { "sec": 0, "nsec": 0 },
        "frame_locked": false,
        "metadata": [],
        "arrows": arrows,
        "cubes": cubes,
    });
    for (list, _) in EMPTY_PRIMITIVES {
        entity[list] = json!([]);
    }
    entity
}

/// `foxglove.SceneUpdate`: `entities` added (each replacing one of its id), and the entities of
/// ids `deleted` removed.
pub fn scene_update(time: Time, entities: Vec<Value>, deleted: &[String]) -> Value {
    // Deletion type 0: MATCHING_ID.
    let deletions: Vec<Value> =
        deleted.iter().map(|id| json!({ "timestamp": time.json(), "type": 0, "id": id })).collect();
    json!({ "deletions": deletions, "entities": entities })
}

/// Foxglove's log level `INFO`.
pub const INFO: u8 = 2;
/// Foxglove's log level `WARNING`.
pub const WARNING: u8 = 3;

/// `foxglove.Log`: `message` from `name` at `level`.
pub fn log(time: Time, level: u8, name: &str, message: &str) -> Value {
    json!({
        "timestamp": time.json(),
        "level": level,
        "message": message,
        "name": name,
        "file": "",
        "line": 0,
    })
}

/// `bytes` in standard base64 with padding (RFC 4648).
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], chunk.get(1).copied().unwrap_or(0), chunk.get(2).copied().unwrap_or(0)];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for (i, shift) in [18, 12, 6, 0].into_iter().enumerate() {
            let c = if i <= chunk.len() { ALPHABET[((n >> shift) & 63) as usize] } else { b'=' };
            out.push(char::from(c));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Translation3;

    #[test]
    fn times_split_into_seconds_and_nanoseconds() {
        let t = Time::from_seconds(1_305_031_102.175_304);
        assert_eq!((t.sec, t.nsec), (1_305_031_102, 175_304_000));
        assert_eq!(Time::from_seconds(0.5).nanos(), 500_000_000);
        assert_eq!(Time::from_seconds(-1.0), Time { sec: 0, nsec: 0 });
        assert_eq!(Time::from_seconds(f64::NAN), Time { sec: 0, nsec: 0 });
        assert_eq!(Time::from_seconds(1e12), Time { sec: 0, nsec: 0 });
        assert_eq!(Time::from_seconds(1.0 / 30.0), Time { sec: 0, nsec: 33_333_333 });
    }

    #[test]
    fn base64_matches_rfc_4648_vectors() {
        let cases =
            [("", ""), ("f", "Zg=="), ("fo", "Zm8="), ("foo", "Zm9v"), ("foobar", "Zm9vYmFy")];
        for (plain, encoded) in cases {
            assert_eq!(base64(plain.as_bytes()), encoded);
        }
    }

    #[test]
    fn a_pose_in_frame_has_foxglove_fields() {
        let t = Isometry3::from_parts(
            Translation3::new(1.0, 2.0, 3.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5),
        );
        let m = pose_in_frame(Time::from_seconds(2.25), "world", &t);
        assert_eq!(m["timestamp"], json!({ "sec": 2, "nsec": 250_000_000 }));
        assert_eq!(m["frame_id"], "world");
        assert_eq!(m["pose"]["position"], json!({ "x": 1.0, "y": 2.0, "z": 3.0 }));
        let q = &m["pose"]["orientation"];
        assert!((q["z"].as_f64().unwrap() - 0.25f64.sin()).abs() < 1e-12);
        assert!((q["w"].as_f64().unwrap() - 0.25f64.cos()).abs() < 1e-12);
        let many = poses_in_frame(Time::from_seconds(0.0), "world", [t, t].iter());
        assert_eq!(many["poses"].as_array().unwrap().len(), 2);
        assert_eq!(many["poses"][1], m["pose"]);
    }

    #[test]
    fn a_frame_transform_gives_the_child_in_the_parent() {
        let t = Isometry3::translation(0.5, 0.0, -1.0);
        let m = frame_transform(Time::from_seconds(1.0), "world", "camera", &t);
        assert_eq!(
            (m["parent_frame_id"].as_str(), m["child_frame_id"].as_str()),
            (Some("world"), Some("camera"))
        );
        assert_eq!(m["translation"], json!({ "x": 0.5, "y": 0.0, "z": -1.0 }));
        assert_eq!(m["rotation"], json!({ "x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0 }));
    }

    #[test]
    fn a_point_cloud_packs_little_endian_floats() {
        let m = point_cloud(Time::from_seconds(0.0), "world", &[[1.0, 2.0, 3.0], [0.5, 0.0, 0.0]]);
        assert_eq!(m["point_stride"], 12);
        assert_eq!(m["fields"][2], json!({ "name": "z", "offset": 8, "type": 7 }));
        let mut bytes = Vec::new();
        for v in [1.0f32, 2.0, 3.0, 0.5, 0.0, 0.0] {
            bytes.extend(v.to_le_bytes());
        }
        assert_eq!(m["data"], base64(&bytes));
    }

    #[test]
    fn a_scene_update_carries_every_primitive_list() {
        let cube = Primitive::Cube {
            pose: Isometry3::identity(),
            size_m: [0.1, 0.2, 0.3],
            color: [1.0, 0.5, 0.0, 1.0],
        };
        let e = entity(Time::from_seconds(3.0), "world", "object-0", &cube);
        let m = scene_update(Time::from_seconds(3.0), vec![e], &["object-1".to_owned()]);
        let e = &m["entities"][0];
        assert_eq!(e["id"], "object-0");
        assert_eq!(e["cubes"][0]["size"], json!({ "x": 0.1, "y": 0.2, "z": 0.3 }));
        assert_eq!(e["cubes"][0]["color"], json!({ "r": 1.0, "g": 0.5, "b": 0.0, "a": 1.0 }));
        for list in ["arrows", "spheres", "cylinders", "lines", "triangles", "texts", "models"] {
            assert!(e[list].is_array(), "{list}");
        }
        assert_eq!(
            m["deletions"][0],
            json!({
                "timestamp": { "sec": 3, "nsec": 0 },
                "type": 0,
                "id": "object-1"
            })
        );
    }

    #[test]
    fn a_log_line_has_level_and_message() {
        let m = log(Time::from_seconds(1.0), INFO, "ferroslam", "frame 3: loop closed");
        assert_eq!(m["level"], 2);
        assert_eq!(m["message"], "frame 3: loop closed");
        assert_eq!(m["timestamp"]["sec"], 1);
    }

    #[test]
    fn short_floats_read_back_as_the_same_f32() {
        assert_eq!(short(0.1), 0.1);
        #[allow(clippy::cast_possible_truncation)]
        let back = short(0.123_456_79) as f32;
        assert_eq!(back, 0.123_456_79_f32);
    }
}
