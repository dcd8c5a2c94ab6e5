//! The ROS 2 messages an MCAP recording is read from and written as, in CDR: `sensor_msgs/msg/Image`,
//! `sensor_msgs/msg/CameraInfo` and `geometry_msgs/msg/PoseStamped` (the ground truth), and the
//! `ros2msg` schema texts the writer declares them with.

use super::cdr::{CdrError, CdrReader, CdrWriter};

/// Schema name of an image message.
pub const IMAGE: &str = "sensor_msgs/msg/Image";
/// Schema name of a camera calibration message.
pub const CAMERA_INFO: &str = "sensor_msgs/msg/CameraInfo";
/// Schema name of a stamped pose message (the ground truth `convert` writes).
pub const POSE_STAMPED: &str = "geometry_msgs/msg/PoseStamped";

/// A `std_msgs/msg/Header`'s stamp: seconds and nanoseconds of `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Stamp {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds, below 1e9.
    pub nanosec: u32,
}

impl Stamp {
    /// The stamp in nanoseconds (an MCAP log time); 0 for a stamp before 1970.
    pub fn as_nanos(self) -> u64 {
        u64::try_from(self.sec).map_or(0, |s| s * 1_000_000_000 + u64::from(self.nanosec))
    }
}

/// Reads a `std_msgs/msg/Header`: the stamp, then `frame_id` (not kept).
fn read_header(r: &mut CdrReader<'_>) -> Result<Stamp, CdrError> {
    let sec = r.i32("header.stamp.sec")?;
    let nanosec = r.u32("header.stamp.nanosec")?;
    r.string("header.frame_id")?;
    Ok(Stamp { sec, nanosec })
}

/// Writes a `std_msgs/msg/Header`.
fn write_header(w: &mut CdrWriter, stamp: Stamp, frame_id: &str) {
    w.i32(stamp.sec);
    w.u32(stamp.nanosec);
    w.string(frame_id);
}

/// A `sensor_msgs/msg/Image`, its pixel bytes borrowed from the message.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageMsg<'a> {
    /// The header's stamp.
    pub stamp: Stamp,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// The pixel encoding (`rgb8`, `16UC1`, ...).
    pub encoding: &'a str,
    /// Whether multi-byte samples are big-endian.
    pub is_bigendian: bool,
    /// Bytes per row.
    pub step: u32,
    /// The pixel bytes, `step * height` of them.
    pub data: &'a [u8],
}

impl<'a> ImageMsg<'a> {
    /// Decodes an image message's CDR bytes.
    ///
    /// # Errors
    /// The [`CdrError`] of the first field that cannot be read.
    pub fn decode(bytes: &'a [u8]) -> Result<Self, CdrError> {
        let mut r = CdrReader::new(bytes)?;
        let stamp = read_header(&mut r)?;
        let height = r.u32("height")?;
        let width = r.u32("width")?;
        let encoding = r.string("encoding")?;
        let is_bigendian = r.u8("is_bigendian")? != 0;
        let step = r.u32("step")?;
        let data = r.bytes("data")?;
        Ok(Self { stamp, height, width, encoding, is_bigendian, step, data })
    }

    /// The message's CDR bytes (little-endian), with `frame_id`.
    pub fn encode(&self, frame_id: &str) -> Vec<u8> {
        let mut w = CdrWriter::new();
        write_header(&mut w, self.stamp, frame_id);
        w.u32(self.height);
        w.u32(self.width);
        w.string(self.encoding);
        w.u8(u8::from(self.is_bigendian));
        w.u32(self.step);
        w.bytes(self.data);
        w.finish()
    }
}

/// The fields of a `sensor_msgs/msg/CameraInfo` the loader uses.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraInfoMsg {
    /// The header's stamp.
    pub stamp: Stamp,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// `plumb_bob` (OpenCV's k1, k2, p1, p2, k3), `rational_polynomial`, ...
    pub distortion_model: String,
    /// The distortion coefficients, in the model's order.
    pub d: Vec<f64>,
    /// The intrinsic matrix, row-major: `[fx 0 cx; 0 fy cy; 0 0 1]`.
    pub k: [f64; 9],
}

impl CameraInfoMsg {
    /// Decodes a camera info message's CDR bytes (the fields after `k` are not read).
    ///
    /// # Errors
    /// The [`CdrError`] of the first field that cannot be read.
    pub fn decode(bytes: &[u8]) -> Result<Self, CdrError> {
        let mut r = CdrReader::new(bytes)?;
        let stamp = read_header(&mut r)?;
        let height = r.u32("height")?;
        let width = r.u32("width")?;
        let distortion_model = r.string("distortion_model")?.to_owned();
        let d = r.f64_sequence("d")?;
        let k = r.f64_array::<9>("k")?;
        Ok(Self { stamp, height, width, distortion_model, d, k })
    }

    /// The message's CDR bytes with `frame_id`: `r` the identity, `p` = `[K | 0]`, no binning,
    /// an empty region of interest.
    pub fn encode(&self, frame_id: &str) -> Vec<u8> {
        let mut w = CdrWriter::new();
        write_header(&mut w, self.stamp, frame_id);
        w.u32(self.height);
        w.u32(self.width);
        w.string(&self.distortion_model);
        w.f64_sequence(&self.d);
        w.f64_array(&self.k);
        w.f64_array(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
        let k = &self.k;
        w.f64_array(&[k[0], k[1], k[2], 0.0, k[3], k[4], k[5], 0.0, k[6], k[7], k[8], 0.0]);
        w.u32(0);
        w.u32(0);
        (0..4).for_each(|_| w.u32(0));
        w.u8(0);
        w.finish()
    }
}

/// A `geometry_msgs/msg/PoseStamped`: a position in metres and an orientation quaternion, kept
/// as written (not normalized).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseStampedMsg {
    /// The header's stamp.
    pub stamp: Stamp,
    /// `x, y, z`, metres.
    pub position_m: [f64; 3],
    /// `x, y, z, w`.
    pub orientation_xyzw: [f64; 4],
}

impl PoseStampedMsg {
    /// Decodes a stamped pose message's CDR bytes.
    ///
    /// # Errors
    /// The [`CdrError`] of the first field that cannot be read.
    pub fn decode(bytes: &[u8]) -> Result<Self, CdrError> {
        let mut r = CdrReader::new(bytes)?;
        let stamp = read_header(&mut r)?;
        let position_m = r.f64_array::<3>("pose.position")?;
        let orientation_xyzw = r.f64_array::<4>("pose.orientation")?;
        Ok(Self { stamp, position_m, orientation_xyzw })
    }

    /// The message's CDR bytes with `frame_id`.
    pub fn encode(&self, frame_id: &str) -> Vec<u8> {
        let mut w = CdrWriter::new();
        write_header(&mut w, self.stamp, frame_id);
        w.f64_array(&self.position_m);
        w.f64_array(&self.orientation_xyzw);
        w.finish()
    }
}

/// The `ros2msg` definition of `std_msgs/msg/Header`, as a dependency block.
const HEADER_DEFINITION: &str =
    "================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
";

/// The `ros2msg` schema text of `name` (one of [`IMAGE`], [`CAMERA_INFO`], [`POSE_STAMPED`]),
/// with the definitions it depends on, as `ros2 bag record` writes them.
pub fn schema_text(name: &str) -> String {
    let body = match name {
        IMAGE => {
            "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n\
             uint8 is_bigendian\nuint32 step\nuint8[] data\n"
        }
        CAMERA_INFO => {
            "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n\
             float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n\
             uint32 binning_y\nsensor_msgs/RegionOfInterest roi\n"
        }
        _ => "std_msgs/Header header\ngeometry_msgs/Pose pose\n",
    };
    let extra = match name {
        CAMERA_INFO => {
            "================================================================================
MSG: sensor_msgs/RegionOfInterest
uint32 x_offset
uint32 y_offset
uint32 height
uint32 width
bool do_rectify
"
        }
        IMAGE => "",
        _ => {
            "================================================================================
MSG: geometry_msgs/Pose
geometry_msgs/Point position
geometry_msgs/Quaternion orientation
================================================================================
MSG: geometry_msgs/Point
float64 x
float64 y
float64 z
================================================================================
MSG: geometry_msgs/Quaternion
float64 x
float64 y
float64 z
float64 w
"
        }
    };
    format!("{body}{HEADER_DEFINITION}{extra}")
}

#[cfg(test)]
mod tests {
    use super::*;

    const STAMP: Stamp = Stamp { sec: 12, nanosec: 345_000_000 };

    #[test]
    fn image_round_trip() {
        let data = [1u8, 2, 3, 4, 5, 6];
        let msg = ImageMsg {
            stamp: STAMP,
            height: 1,
            width: 2,
            encoding: "rgb8",
            is_bigendian: false,
            step: 6,
            data: &data,
        };
        let bytes = msg.encode("camera");
        assert_eq!(ImageMsg::decode(&bytes).unwrap(), msg);
        // Every prefix is an error, never a panic.
        for len in 0..bytes.len() {
            assert!(ImageMsg::decode(&bytes[..len]).is_err(), "{len}");
        }
    }

    #[test]
    fn camera_info_and_pose_round_trip() {
        let info = CameraInfoMsg {
            stamp: STAMP,
            height: 480,
            width: 640,
            distortion_model: "plumb_bob".into(),
            d: vec![0.1, -0.2, 0.0, 0.0, 0.05],
            k: [525.0, 0.0, 319.5, 0.0, 525.0, 239.5, 0.0, 0.0, 1.0],
        };
        assert_eq!(CameraInfoMsg::decode(&info.encode("camera")).unwrap(), info);
        let pose = PoseStampedMsg {
            stamp: STAMP,
            position_m: [1.0, -2.0, 0.5],
            orientation_xyzw: [0.0, 0.0, 0.1, 0.99],
        };
        assert_eq!(PoseStampedMsg::decode(&pose.encode("world")).unwrap(), pose);
    }

    #[test]
    fn schemas_name_their_dependencies() {
        assert!(schema_text(IMAGE).contains("MSG: std_msgs/Header"));
        assert!(schema_text(CAMERA_INFO).contains("MSG: sensor_msgs/RegionOfInterest"));
        assert!(schema_text(POSE_STAMPED).contains("MSG: geometry_msgs/Quaternion"));
    }
}
