//! The JSON Schemas of the Foxglove message types written (schema encoding `jsonschema`): each
//! names the type as Foxglove does (`foxglove.PoseInFrame`, ...), which is what makes Foxglove
//! and other MCAP tools draw it, and describes the fields [`super::foxglove`] writes, with the
//! names, types and nesting of Foxglove's published schemas. Built here rather than copied, so
//! that the two modules describe the same fields.

use serde_json::{Value, json};

/// A Foxglove message type: its schema name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Schema {
    /// `foxglove.PoseInFrame`: one timestamped pose in a frame.
    PoseInFrame,
    /// `foxglove.PosesInFrame`: timestamped poses in a frame.
    PosesInFrame,
    /// `foxglove.FrameTransform`: a parent-to-child transform.
    FrameTransform,
    /// `foxglove.PointCloud`: packed points.
    PointCloud,
    /// `foxglove.SceneUpdate`: 3D entities added and deleted.
    SceneUpdate,
    /// `foxglove.Log`: a log line.
    Log,
}

impl Schema {
    /// The schema's name, as Foxglove names it.
    pub fn name(self) -> &'static str {
        match self {
            Self::PoseInFrame => "foxglove.PoseInFrame",
            Self::PosesInFrame => "foxglove.PosesInFrame",
            Self::FrameTransform => "foxglove.FrameTransform",
            Self::PointCloud => "foxglove.PointCloud",
            Self::SceneUpdate => "foxglove.SceneUpdate",
            Self::Log => "foxglove.Log",
        }
    }

    /// The JSON Schema text.
    pub fn text(self) -> String {
        let (description, properties) = match self {
            Self::PoseInFrame => (
                "A timestamped pose for an object or reference frame in 3D space",
                json!({ "timestamp": time(), "frame_id": string(), "pose": pose() }),
            ),
            Self::PosesInFrame => (
                "An array of timestamped poses for an object or reference frame in 3D space",
                json!({ "timestamp": time(), "frame_id": string(), "poses": array(pose()) }),
            ),
            Self::FrameTransform => (
                "A transform between two reference frames in 3D space",
                json!({
                    "timestamp": time(),
                    "parent_frame_id": string(),
                    "child_frame_id": string(),
                    "translation": vector3(),
                    "rotation": quaternion(),
                }),
            ),
            Self::PointCloud => ("A collection of N-dimensional points", point_cloud()),
            Self::SceneUpdate => (
                "An update to the entities displayed in a 3D scene",
                json!({ "deletions": array(deletion()), "entities": array(entity()) }),
            ),
            Self::Log => ("A log message", log()),
        };
        let schema = json!({
            "title": self.name(),
            "description": description,
            "type": "object",
            "properties": properties,
        });
        schema.to_string()
    }
}

fn string() -> Value {
    json!({ "type": "string" })
}

fn number() -> Value {
    json!({ "type": "number" })
}

fn unsigned() -> Value {
    json!({ "type": "integer", "minimum": 0 })
}

fn array(items: Value) -> Value {
    json!({ "type": "array", "items": items })
}

/// An object type titled `title` with `properties`.
fn object(title: &str, properties: Value) -> Value {
    json!({ "title": title, "type": "object", "properties": properties })
}

/// An enumeration: `(name, value)` pairs.
fn enumeration(title: &str, values: &[(&str, u8)]) -> Value {
    let one_of: Vec<Value> =
        values.iter().map(|(name, value)| json!({ "title": name, "const": value })).collect();
    json!({ "title": title, "oneOf": one_of })
}

fn time() -> Value {
    json!({
        "type": "object",
        "title": "time",
        "properties": {
            "sec": unsigned(),
            "nsec": { "type": "integer", "minimum": 0, "maximum": 999_999_999 },
        },
    })
}

fn duration() -> Value {
    json!({
        "type": "object",
        "title": "duration",
        "properties": {
            "sec": { "type": "integer" },
            "nsec": { "type": "integer", "minimum": 0, "maximum": 999_999_999 },
        },
    })
}

fn vector3() -> Value {
    object("foxglove.Vector3", json!({ "x": number(), "y": number(), "z": number() }))
}

fn quaternion() -> Value {
    let properties = json!({ "x": number(), "y": number(), "z": number(), "w": number() });
    object("foxglove.Quaternion", properties)
}

fn pose() -> Value {
    object("foxglove.Pose", json!({ "position": vector3(), "orientation": quaternion() }))
}

fn color() -> Value {
    object("foxglove.Color", json!({ "r": number(), "g": number(), "b": number(), "a": number() }))
}

fn point_cloud() -> Value {
    let numeric = enumeration(
        "foxglove.NumericType",
        &[
            ("UNKNOWN", 0),
            ("UINT8", 1),
            ("INT8", 2),
            ("UINT16", 3),
            ("INT16", 4),
            ("UINT32", 5),
            ("INT32", 6),
            ("FLOAT32", 7),
            ("FLOAT64", 8),
        ],
    );
    let field = object(
        "foxglove.PackedElementField",
        json!({ "name": string(), "offset": unsigned(), "type": numeric }),
    );
    json!({
        "timestamp": time(),
        "frame_id": string(),
        "pose": pose(),
        "point_stride": unsigned(),
        "fields": array(field),
        "data": { "type": "string", "contentEncoding": "base64" },
    })
}

fn deletion() -> Value {
    let kind = enumeration("foxglove.SceneEntityDeletionType", &[("MATCHING_ID", 0), ("ALL", 1)]);
    object(
        "foxglove.SceneEntityDeletion",
        json!({ "timestamp": time(), "type": kind, "id": string() }),
    )
}

/// A scene entity: the arrows and cubes written are described in full; the other primitive
/// lists are written empty.
fn entity() -> Value {
    let key_value = object("foxglove.KeyValuePair", json!({ "key": string(), "value": string() }));
    let arrow = object(
        "foxglove.ArrowPrimitive",
        json!({
            "pose": pose(),
            "shaft_length": number(),
            "shaft_diameter": number(),
            "head_length": number(),
            "head_diameter": number(),
            "color": color(),
        }),
    );
    let cube = object(
        "foxglove.CubePrimitive",
        json!({ "pose": pose(), "size": vector3(), "color": color() }),
    );
    let mut properties = json!({
        "timestamp": time(),
        "frame_id": string(),
        "id": string(),
        "lifetime": duration(),
        "frame_locked": { "type": "boolean" },
        "metadata": array(key_value),
        "arrows": array(arrow),
        "cubes": array(cube),
    });
    for (list, title) in EMPTY_PRIMITIVES {
        properties[list] = array(json!({ "title": title, "type": "object" }));
    }
    object("foxglove.SceneEntity", properties)
}

/// The primitive lists of a scene entity written empty, and their item types.
pub(super) const EMPTY_PRIMITIVES: [(&str, &str); 6] = [
    ("spheres", "foxglove.SpherePrimitive"),
    ("cylinders", "foxglove.CylinderPrimitive"),
    ("lines", "foxglove.LinePrimitive"),
    ("triangles", "foxglove.TriangleListPrimitive"),
    ("texts", "foxglove.TextPrimitive"),
    ("models", "foxglove.ModelPrimitive"),
];

fn log() -> Value {
    let level = enumeration(
        "foxglove.LogLevel",
        &[("UNKNOWN", 0), ("DEBUG", 1), ("INFO", 2), ("WARNING", 3), ("ERROR", 4), ("FATAL", 5)],
    );
    json!({
        "timestamp": time(),
        "level": level,
        "message": string(),
        "name": string(),
        "file": string(),
        "line": unsigned(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every schema is JSON titled with its Foxglove name, and lists `timestamp` (a
    /// SceneUpdate's entities and deletions carry theirs).
    #[test]
    fn schemas_are_titled_with_foxglove_names() {
        for schema in ALL {
            let value: Value = serde_json::from_str(&schema.text()).unwrap();
            assert_eq!(value["title"], schema.name());
            assert!(schema.name().starts_with("foxglove."));
            let properties = &value["properties"];
            let stamped = match schema {
                Schema::SceneUpdate => &properties["entities"]["items"]["properties"],
                _ => properties,
            };
            assert!(stamped.get("timestamp").is_some(), "{}", schema.name());
        }
    }

    const ALL: [Schema; 6] = [
        Schema::PoseInFrame,
        Schema::PosesInFrame,
        Schema::FrameTransform,
        Schema::PointCloud,
        Schema::SceneUpdate,
        Schema::Log,
    ];
}
