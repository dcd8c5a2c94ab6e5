//! Pinhole intrinsics and depth scale: `calibration.toml` or a TUM preset; optionally the depth
//! camera's own intrinsics and offset when depth is not registered to colour (see
//! [`DepthCamera`]).

use std::path::Path;

use super::DatasetError;
use super::lists::read_text;
use keys::check_keys;

mod keys;

/// Pinhole intrinsics of the (colour) camera and the depth scale, for images of `width` x `height`.
///
/// Pixel coordinates have their origin at the centre of the top-left pixel, x to the right, y
/// downwards (the convention of the TUM and 7-Scenes calibrations and of the core's image views).
/// A lens distortion ([`Calibration::distortion`]) is removed from the frames as they are decoded
/// (see [`super::undistort`]); the core sees a pinhole camera with the same intrinsics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// Focal length along x, in pixels.
    pub fx: f32,
    /// Focal length along y, in pixels.
    pub fy: f32,
    /// Principal point x, in pixels.
    pub cx: f32,
    /// Principal point y, in pixels.
    pub cy: f32,
    /// Image width, in pixels.
    pub width: u32,
    /// Image height, in pixels.
    pub height: u32,
    /// Raw depth units per metre (`raw / depth_scale` = depth in metres along the optical axis).
    pub depth_scale: f32,
    /// The depth camera, when the depth images are not registered to the colour images (the
    /// `[depth]` table of `calibration.toml`); `None` when they are (every preset, and the
    /// frames [`super::Dataset::load_frame`] gives, which it registers).
    pub depth: Option<DepthCamera>,
    /// The colour camera's lens distortion ([`Distortion::NONE`] for a pinhole camera, and for the
    /// frames [`super::Dataset::load_frame`] gives, which it undistorts).
    pub distortion: Distortion,
    /// The depth sensor's noise as the core weighs it (`sigma_z = k z^2`: `k` in 1/m, the
    /// `depth_noise_coeff_per_m` key); `None`: the core's default, a Kinect v1-class sensor.
    pub depth_noise_coeff_per_m: Option<f32>,
}

/// A lens distortion in OpenCV's model (radial `k1`, `k2`, `k3` and tangential `p1`, `p2`; TUM
/// calls them `d0` to `d4` in the order `k1 k2 p1 p2 k3`), on normalized image coordinates: see
/// [`Distortion::distort`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distortion {
    /// Radial coefficient of `r^2`.
    pub k1: f32,
    /// Radial coefficient of `r^4`.
    pub k2: f32,
    /// First tangential coefficient.
    pub p1: f32,
    /// Second tangential coefficient.
    pub p2: f32,
    /// Radial coefficient of `r^6`.
    pub k3: f32,
}

/// A depth camera beside the colour camera, for depth images that are not registered to colour
/// (the raw output of a Kinect v1, as in Microsoft 7-Scenes): its pinhole intrinsics at the same
/// image size (pixels, same pixel convention as [`Calibration`]) and where it sits, as the
/// translation `t` (metres, colour camera axes) that takes a point from the depth camera's frame
/// to the colour camera's: `p_colour = p_depth + t`. The two cameras are taken as parallel (no
/// rotation): a Kinect's are aligned to a fraction of a degree, and the offset and focal lengths
/// are what moves a depth sample by pixels (see [`super::registration`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthCamera {
    /// Focal length along x, pixels.
    pub fx: f32,
    /// Focal length along y, pixels.
    pub fy: f32,
    /// Principal point x, pixels.
    pub cx: f32,
    /// Principal point y, pixels.
    pub cy: f32,
    /// Translation from the depth camera's frame to the colour camera's, metres: `[tx, ty, tz]`.
    pub t_m: [f32; 3],
}

/// The float keys of `calibration.toml`, in the order they are checked.
const FLOAT_KEYS: [&str; 5] = ["fx", "fy", "cx", "cy", "depth_scale"];

impl Calibration {
    /// Reads and validates a `calibration.toml` with the keys `fx`, `fy`, `cx`, `cy`,
    /// `depth_scale` (numbers) and `width`, `height` (integers), an optional `[depth]` table for
    /// depth that is not registered to colour: the depth camera's `fx`, `fy`, `cx`, `cy` and its
    /// offset `tx`, `ty`, `tz` in metres (see [`DepthCamera`]), an optional lens distortion and an
    /// optional `depth_noise_coeff_per_m` (see [`Calibration::depth_noise_coeff_per_m`]). Any
    /// other key is refused: a misspelt `k1` or `[depth]` would silently turn off distortion
    /// removal or registration.
    ///
    /// # Errors
    /// [`DatasetError::Io`] when the file cannot be read; [`DatasetError::CalibrationUnknownKey`]
    /// naming the line and the nearest valid key for a key the file does not define;
    /// [`DatasetError::CalibrationSyntax`],
    /// [`DatasetError::CalibrationMissingKey`] or [`DatasetError::CalibrationValue`] naming the file
    /// and the key when it is not valid TOML, a key is missing, or a value is of the wrong type,
    /// NaN, infinite, zero or negative, an image side is above 8192 pixels, or the principal
    /// point lies outside the image.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, DatasetError> {
        let path = path.as_ref();
        Self::from_toml_str(&read_text(path)?, path)
    }

    /// Parses and validates the text of a calibration file; `path` is only used in errors.
    ///
    /// # Errors
    /// As [`Calibration::load`], without the I/O error.
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Self, DatasetError> {
        let table: toml::Table =
            text.parse().map_err(|e: toml::de::Error| DatasetError::CalibrationSyntax {
                path: path.to_owned(),
                message: e.to_string().trim_end().to_owned(),
            })?;
        check_keys(text, path)?;
        let mut floats = [0.0f32; 5];
        for (slot, key) in floats.iter_mut().zip(FLOAT_KEYS) {
            *slot = float_key(&table, path, key)?;
        }
        let [fx, fy, cx, cy, depth_scale] = floats;
        let width = int_key(&table, path, "width")?;
        let height = int_key(&table, path, "height")?;
        let depth = match table.get("depth") {
            None => None,
            Some(toml::Value::Table(t)) => Some(depth_camera(t, path)?),
            Some(other) => return Err(wrong_type(path, "depth", other, "must be a table")),
        };
        let distortion = distortion(&table, path)?;
        let depth_noise_coeff_per_m = match table.get("depth_noise_coeff_per_m") {
            None => None,
            Some(_) => Some(float_key(&table, path, "depth_noise_coeff_per_m")?),
        };
        let calibration = Self {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
            depth_scale,
            depth,
            distortion,
            depth_noise_coeff_per_m,
        };
        calibration.validate(path)?;
        Ok(calibration)
    }

    /// TUM RGB-D's published calibration of the Freiburg 1, 2 and 3 colour cameras, `"tum1"`,
    /// `"tum2"`, `"tum3"` (the intrinsics and distortion of the benchmark's "file formats" page):
    /// 640x480, depth scale 5000 (raw units per metre), depth registered to colour by the sensor.
    /// Freiburg 1 and 2 recorded images that are not undistorted, so their presets carry the
    /// distortion that goes with their intrinsics (`d0..d4` there); Freiburg 3's images were
    /// undistorted when recorded (zero distortion).
    ///
    /// # Errors
    /// [`DatasetError::UnknownPreset`] for any other name.
    pub fn preset(name: &str) -> Result<Self, DatasetError> {
        let (fx, fy, cx, cy, [k1, k2, p1, p2, k3]) = match name {
            "tum1" => (517.3, 516.5, 318.6, 255.3, [0.2624, -0.9531, -0.0054, 0.0026, 1.1633]),
            "tum2" => (520.9, 521.0, 325.1, 249.7, [0.2312, -0.7849, -0.0033, -0.0001, 0.9172]),
            "tum3" => (535.4, 539.2, 320.1, 247.6, [0.0; 5]),
            _ => return Err(DatasetError::UnknownPreset { name: name.to_owned() }),
        };
        let distortion = Distortion { k1, k2, p1, p2, k3 };
        let (width, height, depth_scale) = (640, 480, 5000.0);
        let depth_noise_coeff_per_m = None;
        Ok(Self {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
            depth_scale,
            depth: None,
            distortion,
            depth_noise_coeff_per_m,
        })
    }

    /// The preset a TUM RGB-D folder's name implies (`rgbd_dataset_freiburg1_xyz` and the like:
    /// the benchmark names every sequence after its sensor), if exactly one of `freiburg1`,
    /// `freiburg2`, `freiburg3` occurs in the folder's last name.
    pub fn preset_for_folder(dir: &Path) -> Option<&'static str> {
        let name = dir.file_name()?.to_str()?.to_ascii_lowercase();
        let mut found = [("freiburg1", "tum1"), ("freiburg2", "tum2"), ("freiburg3", "tum3")]
            .into_iter()
            .filter(|(sensor, _)| name.contains(sensor))
            .map(|(_, preset)| preset);
        match (found.next(), found.next()) {
            (Some(one), None) => Some(one),
            _ => None,
        }
    }

    /// Checks every value: finite and positive, principal point inside the image, each side of
    /// the image between 1 and 8192 pixels.
    ///
    /// # Errors
    /// [`DatasetError::CalibrationValue`] naming `origin` (the file the values came from) and the
    /// first key at fault.
    pub fn validate(&self, origin: &Path) -> Result<(), DatasetError> {
        let bad = |key: &'static str, value: String, reason: &'static str| {
            Err(DatasetError::CalibrationValue { path: origin.to_owned(), key, value, reason })
        };
        // Intrinsics and depth scale: finite and positive.
        let positive = |key: &'static str, v: f32| {
            if !v.is_finite() {
                return bad(key, v.to_string(), "must be a finite number");
            }
            if v <= 0.0 {
                return bad(key, v.to_string(), "must be positive");
            }
            Ok(())
        };
        // The principal point of a real camera is near the image centre; one outside the image is
        // a swapped or mistyped value.
        let inside = |(kx, ky): (&'static str, &'static str), cx: f32, cy: f32| {
            if cx >= self.width as f32 {
                return bad(kx, cx.to_string(), "lies outside the image width");
            }
            if cy >= self.height as f32 {
                return bad(ky, cy.to_string(), "lies outside the image height");
            }
            Ok(())
        };
        let values = [self.fx, self.fy, self.cx, self.cy, self.depth_scale];
        for (key, v) in FLOAT_KEYS.into_iter().zip(values) {
            positive(key, v)?;
        }
        if let Some(k) = self.depth_noise_coeff_per_m {
            positive("depth_noise_coeff_per_m", k)?;
        }
        for (key, v) in [("width", self.width), ("height", self.height)] {
            if v == 0 {
                return bad(key, v.to_string(), "must be positive");
            }
            if v > MAX_IMAGE_SIDE_PX {
                return bad(key, v.to_string(), "must be at most 8192 pixels");
            }
        }
        inside(("cx", "cy"), self.cx, self.cy)?;
        if let Some(d) = &self.depth {
            for (key, v) in DEPTH_KEYS.into_iter().zip([d.fx, d.fy, d.cx, d.cy]) {
                positive(key, v)?;
            }
            inside(("depth.cx", "depth.cy"), d.cx, d.cy)?;
            for (key, v) in OFFSET_KEYS.into_iter().zip(d.t_m) {
                if !(v.is_finite() && v.abs() <= MAX_OFFSET_M) {
                    return bad(key, v.to_string(), "must be a number of metres within +-1");
                }
            }
        }
        Ok(())
    }

    /// The calibration of the image obtained by halving this one `levels` times with 2x2 block
    /// averaging: focal lengths halve, and since a block's centre sits between its four pixels,
    /// `c' = (c + 0.5) / 2 - 0.5` for each principal-point coordinate. Sizes are halved rounding
    /// down; the depth scale is unchanged.
    pub fn downsampled(&self, levels: u8) -> Self {
        let mut c = *self;
        for _ in 0..levels {
            c.fx /= 2.0;
            c.fy /= 2.0;
            c.cx = (c.cx + 0.5) / 2.0 - 0.5;
            c.cy = (c.cy + 0.5) / 2.0 - 0.5;
            c.width /= 2;
            c.height /= 2;
        }
        c
    }
}

/// The largest image side taken as real, pixels: RGB-D sensors deliver VGA to 4K, so a larger
/// value is a typing mistake, and the loader's tables of one entry a pixel (the undistortion map,
/// 16 bytes each) would not fit in memory: a width and height of 2^32 - 2 with a distortion made
/// `Undistorter::new` panic (capacity overflow; found by `cargo xtask fuzz --target
/// calibration`), 65,536 abort allocating 64 GiB.
const MAX_IMAGE_SIDE_PX: u32 = 8192;

/// The intrinsic keys of the `[depth]` table, as errors name them.
const DEPTH_KEYS: [&str; 4] = ["depth.fx", "depth.fy", "depth.cx", "depth.cy"];
/// The offset keys of the `[depth]` table, as errors name them.
const OFFSET_KEYS: [&str; 3] = ["depth.tx", "depth.ty", "depth.tz"];
/// The largest offset between the depth and colour cameras taken as real, metres: a sensor's two
/// cameras are centimetres apart; a metre is a unit mistake (millimetres written as metres).
const MAX_OFFSET_M: f32 = 1.0;

/// The `[depth]` table (see [`Calibration::load`]); the values are checked by
/// [`Calibration::validate`].
fn depth_camera(table: &toml::Table, path: &Path) -> Result<DepthCamera, DatasetError> {
    let mut v = [0.0f32; 7];
    let keys = DEPTH_KEYS.into_iter().chain(OFFSET_KEYS);
    for (slot, key) in v.iter_mut().zip(keys) {
        let (value, _) = number_key(table, path, key.trim_start_matches("depth."), key)?;
        *slot = value as f32;
    }
    let [fx, fy, cx, cy, tx, ty, tz] = v;
    Ok(DepthCamera { fx, fy, cx, cy, t_m: [tx, ty, tz] })
}

/// The distortion keys of `calibration.toml`, in [`Distortion`]'s field order.
const DISTORTION_KEYS: [&str; 5] = ["k1", "k2", "p1", "p2", "k3"];

/// TUM's names of the distortion keys, and what to write instead.
const TUM_DISTORTION_KEYS: [(&str, &str); 5] = [
    ("d0", "is TUM's name of k1: write the distortion as k1, k2, p1, p2, k3"),
    ("d1", "is TUM's name of k2: write the distortion as k1, k2, p1, p2, k3"),
    ("d2", "is TUM's name of p1: write the distortion as k1, k2, p1, p2, k3"),
    ("d3", "is TUM's name of p2: write the distortion as k1, k2, p1, p2, k3"),
    ("d4", "is TUM's name of k3: write the distortion as k1, k2, p1, p2, k3"),
];

/// The largest distortion coefficient taken as real: real lenses stay far below it, so a larger
/// value is a typing mistake.
const MAX_DISTORTION: f64 = 100.0;

/// The optional distortion keys (each 0 when absent). TUM's names `d0..d4` are refused rather than
/// ignored: a distortion silently dropped would bend every trajectory.
fn distortion(table: &toml::Table, path: &Path) -> Result<Distortion, DatasetError> {
    for (key, reason) in TUM_DISTORTION_KEYS {
        if let Some(value) = table.get(key) {
            return Err(wrong_type(path, key, value, reason));
        }
    }
    let mut k = [0.0f32; 5];
    for (slot, key) in k.iter_mut().zip(DISTORTION_KEYS) {
        if table.contains_key(key) {
            let (v, value) = number_key(table, path, key, key)?;
            if !(v.is_finite() && v.abs() < MAX_DISTORTION) {
                return Err(wrong_type(path, key, value, "must be a finite number within +-100"));
            }
            *slot = v as f32;
        }
    }
    let [k1, k2, p1, p2, k3] = k;
    Ok(Distortion { k1, k2, p1, p2, k3 })
}

/// The number (a TOML float or integer) under `name` in `table`, and its TOML value; `key` is
/// what errors call it (the name with its table, e.g. `depth.fx`).
fn number_key<'t>(
    table: &'t toml::Table,
    path: &Path,
    name: &str,
    key: &'static str,
) -> Result<(f64, &'t toml::Value), DatasetError> {
    let value = table
        .get(name)
        .ok_or_else(|| DatasetError::CalibrationMissingKey { path: path.to_owned(), key })?;
    match value {
        toml::Value::Float(f) => Ok((*f, value)),
        toml::Value::Integer(i) => Ok((*i as f64, value)),
        other => Err(wrong_type(path, key, other, "must be a number")),
    }
}

/// A float key (a TOML float or integer), as a finite positive `f32`.
fn float_key(table: &toml::Table, path: &Path, key: &'static str) -> Result<f32, DatasetError> {
    let (v, value) = number_key(table, path, key, key)?;
    if !v.is_finite() {
        return Err(wrong_type(path, key, value, "must be a finite number"));
    }
    if v <= 0.0 {
        return Err(wrong_type(path, key, value, "must be positive"));
    }
    // Values beyond f32's range would become infinite.
    let f = v as f32;
    if !f.is_finite() {
        return Err(wrong_type(path, key, value, "must be a finite number"));
    }
    Ok(f)
}

/// An integer key, as a positive `u32`.
fn int_key(table: &toml::Table, path: &Path, key: &'static str) -> Result<u32, DatasetError> {
    let value = table
        .get(key)
        .ok_or_else(|| DatasetError::CalibrationMissingKey { path: path.to_owned(), key })?;
    let toml::Value::Integer(i) = value else {
        return Err(wrong_type(path, key, value, "must be an integer number of pixels"));
    };
    match u32::try_from(*i) {
        Ok(v) if v > 0 => Ok(v),
        _ => Err(wrong_type(path, key, value, "must be a positive integer below 2^32")),
    }
}

fn wrong_type(
    path: &Path,
    key: &'static str,
    v: &toml::Value,
    reason: &'static str,
) -> DatasetError {
    DatasetError::CalibrationValue { path: path.to_owned(), key, value: v.to_string(), reason }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "fx = 585.0\nfy = 585\ncx = 320.0\ncy = 240.0\nwidth = 640\nheight = 480\n\
                        depth_scale = 1000.0 # a comment\n";

    #[test]
    fn a_valid_file_parses() {
        let c = Calibration::from_toml_str(GOOD, Path::new("calibration.toml")).unwrap();
        assert_eq!(c.fx, 585.0);
        assert_eq!(c.fy, 585.0);
        assert_eq!((c.width, c.height), (640, 480));
        assert_eq!(c.depth_scale, 1000.0);
    }

    #[test]
    fn bad_values_name_the_file_and_key() {
        let path = Path::new("x/calibration.toml");
        let cases = [
            ("fx = 585.0", "fx = nan", "fx"),
            ("fy = 585", "fy = inf", "fy"),
            ("cx = 320.0", "cx = 0.0", "cx"),
            ("cy = 240.0", "cy = -240.0", "cy"),
            ("depth_scale = 1000.0", "depth_scale = -inf", "depth_scale"),
            ("width = 640", "width = 0", "width"),
            ("height = 480", "height = -480", "height"),
            ("height = 480", "height = 480.0", "height"),
            ("fx = 585.0", "fx = \"585\"", "fx"),
            ("cx = 320.0", "cx = 700.0", "cx"),
            ("fx = 585.0", "fx = 1e300", "fx"),
            ("width = 640", "width = 8193", "width"),
            ("width = 640\nheight = 480", "width = 4294967294\nheight = 4294967294", "width"),
            ("height = 480", "height = 65536", "height"),
        ];
        for (from, to, key) in cases {
            let text = GOOD.replace(from, to);
            let err = Calibration::from_toml_str(&text, path).unwrap_err();
            let msg = err.to_string();
            assert!(
                matches!(&err, DatasetError::CalibrationValue { key: k, .. } if *k == key),
                "{to}: {msg}"
            );
            assert!(msg.starts_with("x/calibration.toml: key '"), "{msg}");
        }
        let err = Calibration::from_toml_str(&GOOD.replace("fy = 585\n", ""), path).unwrap_err();
        assert_eq!(err.to_string(), "x/calibration.toml: missing key 'fy'");
        let err = Calibration::from_toml_str("fx = = 1", path).unwrap_err();
        assert!(matches!(err, DatasetError::CalibrationSyntax { .. }), "{err}");
    }

    #[test]
    fn a_depth_table_gives_the_depth_camera_and_bad_values_name_their_key() {
        let path = Path::new("c.toml");
        let with_depth = format!(
            "{GOOD}[depth]\nfx = 585.0\nfy = 585\ncx = 320.0\ncy = 240.0\ntx = -0.03\nty = 0.006\n\
             tz = 0\n"
        );
        let c = Calibration::from_toml_str(&with_depth, path).unwrap();
        let d = c.depth.unwrap();
        assert_eq!((d.fx, d.fy, d.cx, d.cy), (585.0, 585.0, 320.0, 240.0));
        assert_eq!(d.t_m, [-0.03, 0.006, 0.0]);
        assert_eq!(Calibration::from_toml_str(GOOD, path).unwrap().depth, None);
        let cases = [
            ("fx = 585.0\nfy", "fx = -585.0\nfy", "depth.fx"),
            ("cy = 240.0\ntx", "cy = 480.0\ntx", "depth.cy"),
            ("tx = -0.03", "tx = 30", "depth.tx"),
            ("tz = 0", "tz = nan", "depth.tz"),
            ("ty = 0.006", "ty = \"a\"", "depth.ty"),
        ];
        for (from, to, key) in cases {
            let (head, tail) = with_depth.split_once("[depth]").unwrap();
            let text = format!("{head}[depth]{}", tail.replacen(from, to, 1));
            let err = Calibration::from_toml_str(&text, path).unwrap_err();
            assert!(
                matches!(&err, DatasetError::CalibrationValue { key: k, .. } if *k == key),
                "{to}: {err}"
            );
        }
        let missing = with_depth.replace("tz = 0\n", "");
        let err = Calibration::from_toml_str(&missing, path).unwrap_err();
        assert_eq!(err.to_string(), "c.toml: missing key 'depth.tz'");
        let err = Calibration::from_toml_str(&format!("{GOOD}depth = 3\n"), path).unwrap_err();
        assert!(matches!(err, DatasetError::CalibrationValue { key: "depth", .. }), "{err}");
    }

    #[test]
    fn distortion_keys_are_optional_and_checked() {
        let path = Path::new("c.toml");
        let c = Calibration::from_toml_str(GOOD, path).unwrap();
        assert_eq!(c.distortion, Distortion::NONE);
        let text = format!("{GOOD}k1 = 0.25\nk2 = -1\np1 = -0.005\np2 = 0.002\nk3 = 1.1\n");
        let d = Calibration::from_toml_str(&text, path).unwrap().distortion;
        assert_eq!(d, Distortion { k1: 0.25, k2: -1.0, p1: -0.005, p2: 0.002, k3: 1.1 });
        for (line, key) in [("k2 = nan", "k2"), ("p1 = 1e3", "p1"), ("k3 = \"1\"", "k3")] {
            let err = Calibration::from_toml_str(&format!("{GOOD}{line}\n"), path).unwrap_err();
            assert!(
                matches!(&err, DatasetError::CalibrationValue { key: k, .. } if *k == key),
                "{line}: {err}"
            );
        }
        // TUM's names are refused, not ignored.
        let err = Calibration::from_toml_str(&format!("{GOOD}d0 = 0.26\n"), path).unwrap_err();
        assert!(err.to_string().contains("TUM's name of k1"), "{err}");
    }

    #[test]
    fn unknown_keys_are_refused_with_their_line_and_the_nearest_key() {
        let path = Path::new("x/calibration.toml");
        let depth =
            "[depth]\nfx = 585.0\nfy = 585\ncx = 320.0\ncy = 240.0\ntx = 0\nty = 0\ntz = 0\n";
        let cases = [
            // A misspelt distortion key would have left the distortion in the images.
            (
                format!("{GOOD}k_1 = 0.26\n"),
                "x/calibration.toml:8: unknown key `k_1`; did you mean `k1`?",
            ),
            // A misspelt table would have left the depth unregistered.
            (
                format!("{GOOD}{}", depth.replace("[depth]", "[depht]")),
                "x/calibration.toml:8: unknown key `depht`; did you mean `depth`?",
            ),
            (
                format!("{GOOD}{depth}fxx = 1\n"),
                "x/calibration.toml:16: unknown key `fxx` in the [depth] table; did you mean `fx`?",
            ),
            (
                format!("{GOOD}depth_noise = 0.001\n"),
                "x/calibration.toml:8: unknown key `depth_noise`; did you mean \
                 `depth_noise_coeff_per_m`?",
            ),
            (
                format!("FX = 525.0\n{GOOD}"),
                "x/calibration.toml:1: unknown key `FX`; did you mean `fx`?",
            ),
            // A top-level key written after the [depth] line belongs to that table.
            (
                format!("{GOOD}{depth}k1 = 0.2\n"),
                "x/calibration.toml:16: unknown key `k1` in the [depth] table; `k1` is a top-level \
                 key: write it above the [depth] line (every key after a [table] line belongs to \
                 that table)",
            ),
            (
                format!("{GOOD}tx = 0.01\n"),
                "x/calibration.toml:8: unknown key `tx`; `tx` is a key of the [depth] table: write \
                 it below a [depth] line",
            ),
            (
                format!("{GOOD}rig = \"kinect\"\n"),
                "x/calibration.toml:8: unknown key `rig`; the keys here are fx, fy, cx, cy, width, \
                 height, depth_scale, k1, k2, p1, p2, k3, depth_noise_coeff_per_m, depth",
            ),
            // The first in the file, not in key order.
            (format!("zz = 1\n{GOOD}aa = 1\n"), "x/calibration.toml:1: unknown key `zz`; "),
        ];
        for (text, message) in cases {
            let err = Calibration::from_toml_str(&text, path).unwrap_err();
            assert!(matches!(err, DatasetError::CalibrationUnknownKey { .. }), "{text}: {err}");
            assert!(err.to_string().starts_with(message), "{text}: {err}");
        }
        // Every key the format defines is accepted.
        let all = format!(
            "{GOOD}k1 = 0.1\nk2 = 0\np1 = 0\np2 = 0\nk3 = 0\n\
             depth_noise_coeff_per_m = 0.002\n{depth}"
        );
        assert!(Calibration::from_toml_str(&all, path).is_ok());
    }

    #[test]
    fn presets_are_tums_published_calibrations() {
        let c = Calibration::preset("tum3").unwrap();
        assert_eq!((c.fx, c.fy, c.cx, c.cy), (535.4, 539.2, 320.1, 247.6));
        assert_eq!(c.distortion, Distortion::NONE);
        let d = Calibration::preset("tum1").unwrap().distortion;
        assert_eq!(d, Distortion { k1: 0.2624, k2: -0.9531, p1: -0.0054, p2: 0.0026, k3: 1.1633 });
        assert_eq!((c.width, c.height, c.depth_scale), (640, 480, 5000.0));
        assert!(Calibration::preset("tum1").unwrap().validate(Path::new("p")).is_ok());
        assert!(Calibration::preset("tum2").unwrap().validate(Path::new("p")).is_ok());
        let err = Calibration::preset("fr4").unwrap_err();
        assert!(err.to_string().contains("\"fr4\""), "{err}");
    }

    #[test]
    fn downsampling_keeps_pixel_centres() {
        let c = Calibration::preset("tum1").unwrap();
        assert_eq!(c.downsampled(0), c);
        let h = c.downsampled(1);
        assert_eq!((h.fx, h.fy, h.width, h.height), (258.65, 258.25, 320, 240));
        assert_eq!(h.cx, (318.6 + 0.5) / 2.0 - 0.5);
        assert_eq!(h.cy, (255.3 + 0.5) / 2.0 - 0.5);
        // A principal point at the exact image centre stays at the centre.
        let centred = Calibration { cx: 319.5, cy: 239.5, ..c }.downsampled(2);
        assert_eq!((centred.cx, centred.cy), (79.5, 59.5));
        assert_eq!(h.depth_scale, c.depth_scale);
    }
}
