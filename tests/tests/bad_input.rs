//! Bad input to the dataset loader: every case gives a `DatasetError` (never a panic) whose message
//! names the file, and the 1-based line for list files.
//!
//! Each test builds a small valid TUM folder in a temporary directory (8x6 images, PNGs written by
//! the tiny encoder below so that this crate needs no image library), breaks one thing, and checks
//! the error.

// The helpers below are test code too (clippy only exempts `#[test]` functions themselves).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::fs;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use ferroslam_core::config::{QVGA, VGA};
use ferroslam_core::frame::FrameSource;
use ferroslam_sim::dataset::{
    CalibrationSource, Dataset, DatasetError, DatasetOptions, SkipReason,
};
use ferroslam_tests::shared_dataset;

const W: usize = 8;
const H: usize = 6;
const CALIBRATION: &str =
    "fx = 10.0\nfy = 10.0\ncx = 3.5\ncy = 2.5\nwidth = 8\nheight = 6\ndepth_scale = 5000.0\n";

// ---- a minimal PNG encoder (stored deflate blocks), enough for test images ----

fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 { 0xEDB8_8320 ^ (crc >> 1) } else { crc >> 1 };
        }
    }
    !crc
}

fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend_from_slice(&(data.len() as u32).to_be_bytes());
    let start = out.len();
    out.extend_from_slice(kind);
    out.extend_from_slice(data);
    let crc = crc32(&out[start..]);
    out.extend_from_slice(&crc.to_be_bytes());
}

/// A PNG of `width` x `height` with `color_type` (0 gray, 2 RGB) and `bit_depth` (8 or 16) holding
/// `samples` (big-endian for 16-bit) row after row.
fn png(width: usize, height: usize, color_type: u8, bit_depth: u8, samples: &[u8]) -> Vec<u8> {
    let row_bytes = samples.len() / height;
    let mut raw = Vec::new();
    for row in samples.chunks(row_bytes) {
        raw.push(0); // filter: none
        raw.extend_from_slice(row);
    }
    let mut zlib = vec![0x78, 0x01];
    let blocks: Vec<&[u8]> = raw.chunks(65535).collect();
    for (i, block) in blocks.iter().enumerate() {
        zlib.push(u8::from(i + 1 == blocks.len()));
        let len = block.len() as u16;
        zlib.extend_from_slice(&len.to_le_bytes());
        zlib.extend_from_slice(&(!len).to_le_bytes());
        zlib.extend_from_slice(block);
    }
    let (mut a, mut b) = (1u32, 0u32);
    for &x in &raw {
        a = (a + u32::from(x)) % 65521;
        b = (b + a) % 65521;
    }
    zlib.extend_from_slice(&((b << 16) | a).to_be_bytes());
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&(width as u32).to_be_bytes());
    ihdr.extend_from_slice(&(height as u32).to_be_bytes());
    ihdr.extend_from_slice(&[bit_depth, color_type, 0, 0, 0]);
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    chunk(&mut out, b"IHDR", &ihdr);
    chunk(&mut out, b"IDAT", &zlib);
    chunk(&mut out, b"IEND", &[]);
    out
}

fn gray8_png(w: usize, h: usize) -> Vec<u8> {
    png(w, h, 0, 8, &(0..w * h).map(|i| i as u8).collect::<Vec<_>>())
}

fn depth16_png(w: usize, h: usize) -> Vec<u8> {
    let samples: Vec<u8> = (0..w * h).flat_map(|i| (1000 + i as u16).to_be_bytes()).collect();
    png(w, h, 0, 16, &samples)
}

// ---- fixtures ----

/// A valid folder with `n` frames at 30 Hz, depth 5 ms after colour, ground truth, calibration.
fn fixture(n: usize) -> tempfile::TempDir {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    fs::create_dir_all(dir.join("rgb")).unwrap();
    fs::create_dir_all(dir.join("depth")).unwrap();
    let (mut rgb, mut depth) = ("# colour\n".to_owned(), "# depth\n".to_owned());
    let mut gt = "# timestamp tx ty tz qx qy qz qw\n".to_owned();
    for k in 0..n {
        let t = 100.0 + k as f64 / 30.0;
        rgb += &format!("{t:.6} rgb/{k}.png\n");
        depth += &format!("{:.6} depth/{k}.png\n", t + 0.005);
        gt += &format!("{t:.6} 0 0 {} 0 0 0 1\n", k as f64 * 0.01);
        fs::write(dir.join(format!("rgb/{k}.png")), gray8_png(W, H)).unwrap();
        fs::write(dir.join(format!("depth/{k}.png")), depth16_png(W, H)).unwrap();
    }
    fs::write(dir.join("rgb.txt"), rgb).unwrap();
    fs::write(dir.join("depth.txt"), depth).unwrap();
    fs::write(dir.join("groundtruth.txt"), gt).unwrap();
    fs::write(dir.join("calibration.toml"), CALIBRATION).unwrap();
    tmp
}

fn vga() -> DatasetOptions {
    DatasetOptions { profile: VGA, ..DatasetOptions::default() }
}

/// Opens `dir`, asserting that it neither panics nor succeeds; returns the error.
fn open_err(dir: &Path, opts: &DatasetOptions) -> DatasetError {
    match catch_unwind(AssertUnwindSafe(|| Dataset::open(dir, opts))) {
        Ok(Ok(ds)) => panic!("opened with {} frames, expected an error", ds.len()),
        Ok(Err(e)) => e,
        Err(_) => panic!("Dataset::open panicked"),
    }
}

/// Loads frame `index`, asserting that it neither panics nor succeeds; returns the error.
fn load_err(ds: &Dataset, index: usize) -> DatasetError {
    match catch_unwind(AssertUnwindSafe(|| ds.load_frame(index))) {
        Ok(Ok(_)) => panic!("frame {index} loaded, expected an error"),
        Ok(Err(e)) => e,
        Err(_) => panic!("load_frame panicked"),
    }
}

/// Asserts that the error's message contains every one of `parts`.
fn assert_mentions(err: &DatasetError, parts: &[&str]) {
    let msg = err.to_string();
    for part in parts {
        assert!(msg.contains(part), "message {msg:?} does not mention {part:?}");
    }
}

fn write(dir: &Path, name: &str, text: &str) {
    fs::write(dir.join(name), text).unwrap();
}

fn path_str(dir: &Path, name: &str) -> String {
    dir.join(name).display().to_string()
}

// ---- missing and unreadable files ----

#[test]
fn missing_lists_and_calibration_name_the_path() {
    for name in ["rgb.txt", "depth.txt"] {
        let tmp = fixture(2);
        fs::remove_file(tmp.path().join(name)).unwrap();
        let err = open_err(tmp.path(), &vga());
        assert!(matches!(err, DatasetError::NoList { list, .. } if list == name), "{err}");
        let folder = tmp.path().display().to_string();
        assert_mentions(&err, &[&format!("{folder} has no {name}"), "not a TUM RGB-D folder"]);
    }
    // A folder without calibration.toml (and no TUM sensor in its name): the error names the
    // folder and says how to give a calibration.
    let tmp = fixture(2);
    fs::remove_file(tmp.path().join("calibration.toml")).unwrap();
    let err = open_err(tmp.path(), &vga());
    assert!(matches!(err, DatasetError::NoCalibration { .. }), "{err}");
    let folder = tmp.path().display().to_string();
    assert_mentions(&err, &[&folder, "no calibration.toml", "--calibration", "--preset"]);
    // A folder that is not there is said so, not as the first file that cannot be read in it.
    let err = open_err(Path::new("/nonexistent/ferroslam/dataset"), &vga());
    assert!(matches!(err, DatasetError::NoFolder { .. }), "{err}");
    assert_mentions(&err, &["dataset folder /nonexistent/ferroslam/dataset does not exist"]);
}

#[test]
fn unreadable_lists_name_the_path() {
    let tmp = fixture(2);
    // A folder where a list should be, then a list that is not UTF-8 text.
    fs::remove_file(tmp.path().join("rgb.txt")).unwrap();
    fs::create_dir(tmp.path().join("rgb.txt")).unwrap();
    let err = open_err(tmp.path(), &vga());
    assert_mentions(&err, &[&path_str(tmp.path(), "rgb.txt")]);
    fs::write(tmp.path().join("depth.txt"), b"\xff\xfe 1.0 depth/0.png\n").unwrap();
    fs::remove_dir(tmp.path().join("rgb.txt")).unwrap();
    write(tmp.path(), "rgb.txt", "100.0 rgb/0.png\n");
    let err = open_err(tmp.path(), &vga());
    assert_mentions(&err, &[&path_str(tmp.path(), "depth.txt")]);
}

// ---- malformed list lines ----

#[test]
fn wrong_field_count_names_file_line_and_text() {
    let cases = [("rgb.txt", "100.0"), ("rgb.txt", "100.04 a.png b"), ("depth.txt", "\t1 2 3 4")];
    for (list, line) in cases {
        let tmp = fixture(3);
        let mut text = fs::read_to_string(tmp.path().join(list)).unwrap();
        // The fixture's line 3 is its second data line; replace it.
        let mut lines: Vec<&str> = text.lines().collect();
        lines[2] = line;
        text = lines.join("\n");
        write(tmp.path(), list, &text);
        let err = open_err(tmp.path(), &vga());
        assert!(matches!(err, DatasetError::FieldCount { line: 3, .. }), "{err}");
        let expected =
            format!("{}:3: expected 'timestamp path', got {line:?}", path_str(tmp.path(), list));
        assert_eq!(err.to_string(), expected);
    }
}

#[test]
fn unparsable_or_non_finite_timestamps_name_file_and_line() {
    for bad in ["1O0.0", "nan", "NaN", "inf", "-infinity", "1.0.0", "0x10"] {
        let tmp = fixture(3);
        write(tmp.path(), "depth.txt", &format!("# d\n100.005 depth/0.png\n{bad} depth/1.png\n"));
        let err = open_err(tmp.path(), &vga());
        assert!(matches!(err, DatasetError::BadNumber { line: 3, .. }), "{bad}: {err}");
        assert_mentions(&err, &[&format!("{}:3:", path_str(tmp.path(), "depth.txt")), bad]);
    }
}

#[test]
fn timestamps_going_backwards_name_file_and_line() {
    for list in ["rgb.txt", "depth.txt"] {
        let tmp = fixture(3);
        let folder = list.trim_end_matches(".txt");
        let text =
            format!("# x\n\n100.1 {folder}/0.png\n100.2 {folder}/1.png\n100.15 {folder}/2.png\n");
        write(tmp.path(), list, &text);
        let err = open_err(tmp.path(), &vga());
        assert!(
            matches!(err, DatasetError::TimestampNotIncreasing { line: 5, previous_line: 4, .. }),
            "{err}"
        );
        assert_mentions(&err, &[&format!("{}:5:", path_str(tmp.path(), list)), "100.15"]);
    }
    // A repeated timestamp is not an increase either.
    let tmp = fixture(3);
    write(tmp.path(), "rgb.txt", "100.0 rgb/0.png\n100.0 rgb/1.png\n");
    assert!(matches!(
        open_err(tmp.path(), &vga()),
        DatasetError::TimestampNotIncreasing { line: 2, .. }
    ));
}

#[test]
fn bad_groundtruth_lines_name_file_and_line() {
    let cases = [
        "100.0 0 0 0 0 0 1",     // 7 fields
        "100.0 0 0 x 0 0 0 1",   // not a number
        "100.0 0 0 nan 0 0 0 1", // NaN
        "100.0 0 0 0 0 0 0 0",   // zero quaternion
        "99.0 0 0 0 0 0 0 1",    // backwards
    ];
    for bad in cases {
        let tmp = fixture(2);
        write(tmp.path(), "groundtruth.txt", &format!("# gt\n99.5 0 0 0 0 0 0 1\n{bad}\n"));
        let err = open_err(tmp.path(), &vga());
        assert!(matches!(err, DatasetError::Groundtruth { .. }), "{bad}: {err}");
        assert_mentions(&err, &[&format!("{}:3", path_str(tmp.path(), "groundtruth.txt")), bad]);
    }
}

// ---- calibration ----

#[test]
fn bad_calibration_values_name_file_and_key() {
    let keys = ["fx", "fy", "cx", "cy", "width", "height", "depth_scale"];
    let values = ["nan", "inf", "-inf", "0", "0.0", "-1.0", "-5", "\"ten\""];
    for key in keys {
        for value in values {
            let tmp = fixture(1);
            let text: String = CALIBRATION
                .lines()
                .map(|l| {
                    if l.starts_with(&format!("{key} =")) {
                        format!("{key} = {value}\n")
                    } else {
                        format!("{l}\n")
                    }
                })
                .collect();
            write(tmp.path(), "calibration.toml", &text);
            let err = open_err(tmp.path(), &vga());
            assert!(matches!(err, DatasetError::CalibrationValue { .. }), "{key} = {value}: {err}");
            let file = path_str(tmp.path(), "calibration.toml");
            assert_mentions(&err, &[&file, &format!("key '{key}'")]);
        }
    }
}

#[test]
fn missing_key_and_bad_toml_name_the_file() {
    let tmp = fixture(1);
    write(tmp.path(), "calibration.toml", &CALIBRATION.replace("depth_scale = 5000.0\n", ""));
    let err = open_err(tmp.path(), &vga());
    let file = path_str(tmp.path(), "calibration.toml");
    assert_eq!(err.to_string(), format!("{file}: missing key 'depth_scale'"));
    write(tmp.path(), "calibration.toml", "fx = 10.0\nfy = \n");
    let err = open_err(tmp.path(), &vga());
    assert!(matches!(err, DatasetError::CalibrationSyntax { .. }), "{err}");
    assert_mentions(&err, &[&file, "line 2"]);
}

#[test]
fn unknown_preset_and_unhalvable_size_are_errors() {
    let tmp = fixture(1);
    let opts = DatasetOptions { calibration: CalibrationSource::Preset("tum9".into()), ..vga() };
    assert_mentions(&open_err(tmp.path(), &opts), &["\"tum9\"", "tum1, tum2, tum3"]);
    write(tmp.path(), "calibration.toml", &CALIBRATION.replace("height = 6", "height = 5"));
    let qvga = DatasetOptions { profile: QVGA, ..vga() };
    let err = open_err(tmp.path(), &qvga);
    assert!(matches!(err, DatasetError::ProfileSize { width: 8, height: 5, .. }), "{err}");
}

// ---- empty datasets and missing frames ----

#[test]
fn datasets_without_usable_frames_are_errors() {
    let tmp = fixture(3);
    let dir = tmp.path();
    let empty = |err: DatasetError, dir: &Path| {
        assert!(matches!(err, DatasetError::EmptyDataset { .. }), "{err}");
        assert_mentions(&err, &["no usable frames", &dir.display().to_string()]);
    };
    // Only comments and blank lines.
    write(dir, "rgb.txt", "# nothing\n\n");
    empty(open_err(dir, &vga()), dir);
    // Every listed colour image missing on disk.
    write(dir, "rgb.txt", "100.0 rgb/x.png\n100.1 rgb/y.png\n");
    empty(open_err(dir, &vga()), dir);
    // Present images whose clocks never come within 0.02 s.
    write(dir, "rgb.txt", "200.0 rgb/0.png\n200.1 rgb/1.png\n");
    empty(open_err(dir, &vga()), dir);
    // Asking for zero frames.
    let tmp2 = fixture(3);
    let err = open_err(tmp2.path(), &DatasetOptions { max_frames: Some(0), ..vga() });
    assert_mentions(&err, &["3 associated", "at most 0 kept (--max-frames)"]);
    empty(err, tmp2.path());
}

#[test]
fn listed_but_absent_frames_are_skipped_and_counted() {
    let tmp = fixture(5);
    fs::remove_file(tmp.path().join("rgb/1.png")).unwrap();
    fs::remove_file(tmp.path().join("depth/3.png")).unwrap();
    let ds = Dataset::open(tmp.path(), &vga()).unwrap();
    assert_eq!(ds.len(), 3);
    let missing: Vec<_> =
        ds.skipped().iter().filter(|s| s.reason == SkipReason::Missing).map(|s| s.line).collect();
    assert_eq!(missing, vec![5, 3]); // depth.txt line 5 (depth 3), rgb.txt line 3 (rgb 1)
    let warnings: Vec<String> = ds.skipped().iter().map(ToString::to_string).collect();
    assert!(warnings.iter().any(|w| w.contains("rgb.txt:3:") && w.contains("does not exist")));
}

// ---- images ----

/// A dataset of `fixture(2)` whose frame 0 has `rgb` / `depth` replaced by the given bytes.
fn with_images(rgb: Option<Vec<u8>>, depth: Option<Vec<u8>>) -> (tempfile::TempDir, Dataset) {
    let tmp = fixture(2);
    if let Some(bytes) = rgb {
        fs::write(tmp.path().join("rgb/0.png"), bytes).unwrap();
    }
    if let Some(bytes) = depth {
        fs::write(tmp.path().join("depth/0.png"), bytes).unwrap();
    }
    let ds = Dataset::open(tmp.path(), &vga()).unwrap();
    (tmp, ds)
}

#[test]
fn depth_that_is_not_16_bit_gray_png_names_file_and_format() {
    let rgb16: Vec<u8> = (0..W * H * 3).flat_map(|i| (i as u16).to_be_bytes()).collect();
    let cases = [(gray8_png(W, H), "8-bit gray PNG"), (png(W, H, 2, 16, &rgb16), "16-bit RGB PNG")];
    for (bytes, found) in cases {
        let (tmp, ds) = with_images(None, Some(bytes));
        let err = load_err(&ds, 0);
        assert!(matches!(err, DatasetError::DepthFormat { .. }), "{err}");
        assert_mentions(&err, &[&path_str(tmp.path(), "depth/0.png"), found]);
        assert!(ds.load_frame(1).is_ok(), "the next frame is unaffected");
    }
}

#[test]
fn jpeg_depth_is_rejected() {
    // A real JPEG, named by absolute path from the list (the shared dataset is only read).
    let jpeg = shared_dataset("7scenes-redkitchen-1000").join("rgb/frame-000000.color.jpg");
    let tmp = fixture(1);
    write(tmp.path(), "rgb.txt", &format!("100.0 {}\n", jpeg.display()));
    write(tmp.path(), "depth.txt", &format!("100.005 {}\n", jpeg.display()));
    write(
        tmp.path(),
        "calibration.toml",
        &CALIBRATION.replace("width = 8", "width = 640").replace("height = 6", "height = 480"),
    );
    let ds = Dataset::open(tmp.path(), &vga()).unwrap();
    let err = load_err(&ds, 0);
    assert!(matches!(err, DatasetError::DepthFormat { .. }), "{err}");
    assert_mentions(&err, &[&jpeg.display().to_string(), "8-bit RGB JPEG"]);
}

#[test]
fn wrong_image_sizes_name_file_and_both_sizes() {
    let (tmp, ds) = with_images(Some(gray8_png(10, 6)), None);
    let err = load_err(&ds, 0);
    assert!(matches!(err, DatasetError::ImageSize { width: 10, height: 6, .. }), "{err}");
    assert_mentions(&err, &[&path_str(tmp.path(), "rgb/0.png"), "10x6", "8x6"]);
    let (tmp, ds) = with_images(None, Some(depth16_png(8, 4)));
    let err = load_err(&ds, 0);
    assert_mentions(&err, &[&path_str(tmp.path(), "depth/0.png"), "8x4", "8x6"]);
}

#[test]
fn corrupt_or_vanished_images_name_the_file() {
    let mut truncated = gray8_png(W, H);
    truncated.truncate(40);
    for bytes in [b"garbage, not an image".to_vec(), truncated, Vec::new()] {
        let (tmp, ds) = with_images(Some(bytes), None);
        let err = load_err(&ds, 0);
        assert_mentions(&err, &[&path_str(tmp.path(), "rgb/0.png")]);
    }
    let (tmp, ds) = with_images(None, None);
    fs::remove_file(tmp.path().join("depth/1.png")).unwrap();
    let err = load_err(&ds, 1);
    assert!(matches!(err, DatasetError::Io { .. }), "{err}");
    assert_mentions(&err, &[&path_str(tmp.path(), "depth/1.png")]);
    assert!(matches!(load_err(&ds, 7), DatasetError::FrameIndex { index: 7, len: 2 }));
}

#[test]
fn reader_delivers_a_bad_frame_in_order_and_goes_on() {
    let tmp = fixture(4);
    fs::write(tmp.path().join("depth/2.png"), gray8_png(W, H)).unwrap();
    let ds = Dataset::open(tmp.path(), &vga()).unwrap();
    let mut reader = ds.into_reader(4);
    let mut seen: Vec<Result<f64, PathBuf>> = Vec::new();
    loop {
        match catch_unwind(AssertUnwindSafe(|| {
            reader.next_frame().map(|f| f.map(|f| f.timestamp_s))
        })) {
            Ok(Ok(Some(t))) => seen.push(Ok(t)),
            Ok(Ok(None)) => break,
            Ok(Err(DatasetError::DepthFormat { path, .. })) => seen.push(Err(path)),
            Ok(Err(e)) => panic!("unexpected error {e}"),
            Err(_) => panic!("the reader panicked"),
        }
    }
    assert_eq!(seen.len(), 4);
    assert!(seen[0].is_ok() && seen[1].is_ok() && seen[3].is_ok());
    assert_eq!(seen[2], Err(tmp.path().join("depth/2.png")));
}
