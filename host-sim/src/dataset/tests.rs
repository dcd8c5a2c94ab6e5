//! Dataset tests on small folders written to a temporary directory.

use std::fs;
use std::path::Path;

use ferroslam_core::config::{QVGA, Resolution, VGA};
use ferroslam_core::frame::FrameSource;
use image::{ImageBuffer, Luma, LumaA, Rgb};

use super::*;

const W: u32 = 8;
const H: u32 = 6;

fn write(dir: &Path, name: &str, text: &str) {
    fs::write(dir.join(name), text).unwrap();
}

/// Gray value of colour frame `k` at pixel `i`.
fn gray_at(k: usize, i: usize) -> u8 {
    (k * 40 + i * 3) as u8
}

/// Raw depth of frame `k` at pixel `i` (0 every 7th pixel: no reading).
fn depth_at(k: usize, i: usize) -> u16 {
    if i.is_multiple_of(7) { 0 } else { 1000 + (k * 100 + i) as u16 }
}

fn save_gray(path: &Path, k: usize) {
    let px = (0..(W * H) as usize).map(|i| gray_at(k, i)).collect();
    ImageBuffer::<Luma<u8>, Vec<u8>>::from_raw(W, H, px).unwrap().save(path).unwrap();
}

fn save_depth(path: &Path, k: usize) {
    let px = (0..(W * H) as usize).map(|i| depth_at(k, i)).collect();
    ImageBuffer::<Luma<u16>, Vec<u16>>::from_raw(W, H, px).unwrap().save(path).unwrap();
}

/// A TUM-like folder: colour at 30 Hz from t0, depth 7 ms later on its own clock, a depth frame
/// listed but absent, a colour frame with no depth partner, 100 Hz ground truth.
fn tum_like(dir: &Path, n: usize) {
    fs::create_dir_all(dir.join("rgb")).unwrap();
    fs::create_dir_all(dir.join("depth")).unwrap();
    let t0 = 1305031102.175304;
    let mut rgb = String::from("# color images\n# timestamp filename\n");
    let mut depth = String::from("# depth maps\n\n");
    for k in 0..n {
        let t = t0 + k as f64 / 30.0;
        rgb += &format!("{t:.6} rgb/{k}.png\n");
        save_gray(&dir.join(format!("rgb/{k}.png")), k);
        if k == n - 1 {
            continue; // the last colour frame has no depth at all
        }
        depth += &format!("{:.6} depth/{k}.png\n", t + 0.007);
        if k != 1 {
            save_depth(&dir.join(format!("depth/{k}.png")), k);
        }
    }
    let mut gt = String::from("# timestamp tx ty tz qx qy qz qw\n");
    for k in 0..(n * 10 / 3) {
        gt += &format!("{:.4} {} 0 0 0 0 0 1\n", t0 - 0.05 + k as f64 * 0.01, k as f64 * 0.001);
    }
    write(dir, "rgb.txt", &rgb);
    write(dir, "depth.txt", &depth);
    write(dir, "groundtruth.txt", &gt);
    write(
        dir,
        "calibration.toml",
        "fx = 10.0\nfy = 11.0\ncx = 3.5\ncy = 2.5\nwidth = 8\nheight = 6\ndepth_scale = 5000.0\n",
    );
}

fn opts(profile: Resolution) -> DatasetOptions {
    DatasetOptions { profile, ..DatasetOptions::default() }
}

#[test]
fn open_associates_skips_missing_and_reads_groundtruth() {
    let tmp = tempfile::tempdir().unwrap();
    tum_like(tmp.path(), 6);
    let ds = Dataset::open(tmp.path(), &opts(VGA)).unwrap();
    // Frames 0, 2, 3, 4: depth 1 is missing, colour 5 has no depth; colour 1 is then unpaired.
    assert_eq!(ds.len(), 4);
    assert!(
        ds.frames().iter().all(|f| (f.depth_timestamp_s - f.rgb_timestamp_s - 0.007).abs() < 1e-6)
    );
    assert!(ds.frames()[1].rgb_path.ends_with("rgb/2.png"));
    let reasons: Vec<_> = ds.skipped().iter().map(|s| (s.line, s.reason)).collect();
    // Sorted by list path (depth.txt before rgb.txt), then line.
    assert_eq!(
        reasons,
        vec![
            (4, SkipReason::Missing),
            (4, SkipReason::Unassociated),
            (8, SkipReason::Unassociated)
        ]
    );
    let msg = ds.skipped()[0].to_string();
    assert!(msg.contains("depth.txt:4: ") && msg.contains("depth/1.png does not exist"), "{msg}");
    // The frames skipped are the colour images: colour 1 lost its depth image, which is missing,
    // and colour 5 has none; with the four played they are the six listed.
    let frames: Vec<_> = ds.skipped_frames().collect();
    assert_eq!((ds.listed_frames(), frames.len()), (6, 2));
    assert_eq!(
        frames[0].why(),
        format!(
            "no depth image within 0.02 s ({} is listed but does not exist)",
            tmp.path().join("depth/1.png").display()
        )
    );
    assert_eq!(frames[1].why(), "no depth image within 0.02 s");
    assert!(frames[1].to_string().contains("rgb.txt:8: "), "{}", frames[1]);
    assert_eq!(ds.groundtruth().map(<[_]>::len), Some(20));
    assert_eq!(ds.calibration(), ds.sensor_calibration());
}

#[test]
fn max_frames_and_profile_calibration() {
    let tmp = tempfile::tempdir().unwrap();
    tum_like(tmp.path(), 6);
    let o = DatasetOptions { max_frames: Some(2), ..opts(QVGA) };
    let ds = Dataset::open(tmp.path(), &o).unwrap();
    assert_eq!(ds.len(), 2);
    let c = ds.calibration();
    assert_eq!((c.fx, c.fy, c.cx, c.cy, c.width, c.height), (5.0, 5.5, 1.5, 1.0, 4, 3));
    assert_eq!(ds.sensor_calibration().width, 8);
}

#[test]
fn skip_frames_drops_the_first_frames_before_max_frames() {
    let tmp = tempfile::tempdir().unwrap();
    tum_like(tmp.path(), 6);
    let all = Dataset::open(tmp.path(), &opts(QVGA)).unwrap();
    assert_eq!(all.len(), 4);
    let o = DatasetOptions { skip_frames: 1, max_frames: Some(2), ..opts(QVGA) };
    let ds = Dataset::open(tmp.path(), &o).unwrap();
    assert_eq!(ds.frames(), &all.frames()[1..3]);
    // Skipping every frame leaves an empty dataset, an error that names the option.
    let o = DatasetOptions { skip_frames: 4, ..opts(QVGA) };
    let err = Dataset::open(tmp.path(), &o).unwrap_err().to_string();
    assert!(err.contains("4 skipped at the start"), "{err}");
}

#[test]
fn load_frame_decodes_and_halves() {
    let tmp = tempfile::tempdir().unwrap();
    tum_like(tmp.path(), 4);
    let vga = Dataset::open(tmp.path(), &opts(VGA)).unwrap();
    let f = vga.load_frame(1).unwrap(); // colour 2 with depth 2
    assert_eq!((f.width, f.height, f.depth_scale), (8, 6, 5000.0));
    assert_eq!(f.timestamp_s, vga.frames()[1].rgb_timestamp_s);
    assert!(f.gray.iter().enumerate().all(|(i, &g)| g == gray_at(2, i)));
    assert!(f.depth.iter().enumerate().all(|(i, &d)| d == depth_at(2, i)));
    assert!(f.view().is_ok());

    let qvga = Dataset::open(tmp.path(), &opts(QVGA)).unwrap();
    let h = qvga.load_frame(1).unwrap();
    // The depth at the profile's level 1: one reading per 2 x 2 gray pixels.
    assert_eq!((h.width, h.height, h.gray.len(), h.depth.len()), (4, 3, 12, 2));
    assert_eq!((h.depth_level, h.depth_size()), (1, (2, 1)));
    let o = DatasetOptions { depth_level: Some(0), ..opts(QVGA) };
    let h0 = Dataset::open(tmp.path(), &o).unwrap().load_frame(1).unwrap();
    assert_eq!((h0.depth_level, h0.depth.len()), (0, 12));
    // Top-left block: pixels 0, 1, 8, 9 of the full image.
    let mean = [0, 1, 8, 9].iter().map(|&i| u16::from(gray_at(2, i))).sum::<u16>();
    assert_eq!(u16::from(h.gray[0]), (mean + 2) / 4);
    assert!(matches!(qvga.load_frame(9), Err(DatasetError::FrameIndex { index: 9, len: 2 })));
}

#[test]
fn colour_formats_convert_to_bt601_gray() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    tum_like(dir, 5); // frames: colour 0, 2, 3
    let rgb: Vec<u8> = (0..W * H).flat_map(|_| [255u8, 0, 0]).collect();
    ImageBuffer::<Rgb<u8>, Vec<u8>>::from_raw(W, H, rgb)
        .unwrap()
        .save(dir.join("rgb/0.png"))
        .unwrap();
    let rgb16: Vec<u16> = (0..W * H).flat_map(|_| [0u16, 65535, 0]).collect();
    let img16 = ImageBuffer::<Rgb<u16>, Vec<u16>>::from_raw(W, H, rgb16).unwrap();
    img16.save(dir.join("rgb/2.png")).unwrap();
    let ds = Dataset::open(dir, &opts(VGA)).unwrap();
    assert!(ds.load_frame(0).unwrap().gray.iter().all(|&g| g == 76));
    assert!(ds.load_frame(1).unwrap().gray.iter().all(|&g| g == 150));
    let la: Vec<u8> = (0..W * H).flat_map(|_| [33u8, 7]).collect();
    let la = ImageBuffer::<LumaA<u8>, Vec<u8>>::from_raw(W, H, la).unwrap();
    la.save(dir.join("rgb/0.png")).unwrap();
    assert!(ds.load_frame(0).unwrap().gray.iter().all(|&g| g == 33));
    // JPEG colour decodes too (lossy: only the size and a rough level are checked).
    let grey: Vec<u8> = vec![128; (W * H * 3) as usize];
    let jpg = ImageBuffer::<Rgb<u8>, Vec<u8>>::from_raw(W, H, grey).unwrap();
    jpg.save(dir.join("rgb/0.jpg")).unwrap();
    fs::rename(dir.join("rgb/0.jpg"), dir.join("rgb/0.png")).unwrap(); // content decides, not name
    let g = ds.load_frame(0).unwrap().gray;
    assert!(g.len() == (W * H) as usize && g.iter().all(|&v| v.abs_diff(128) < 4));
}

#[test]
fn reader_streams_in_order_and_delivers_errors_in_place() {
    let tmp = tempfile::tempdir().unwrap();
    tum_like(tmp.path(), 6);
    let ds = Dataset::open(tmp.path(), &opts(QVGA)).unwrap();
    let expected: Vec<_> = (0..ds.len()).map(|i| ds.load_frame(i).unwrap()).collect();
    // Corrupt frame 2's depth after opening: the reader must give an error in its place.
    let bad = ds.frames()[2].depth_path.clone();
    fs::write(&bad, b"not a png").unwrap();
    for read_ahead in [0, 1, 8] {
        let mut reader = ds.clone().into_reader(read_ahead);
        for (i, want) in expected.iter().enumerate() {
            match reader.next_frame() {
                Ok(Some(f)) => {
                    assert_ne!(i, 2);
                    assert_eq!(f.timestamp_s, want.timestamp_s);
                    assert_eq!(f.gray.row(0), Some(&want.gray[..want.width]));
                }
                Err(DatasetError::Decode { path, .. }) => assert!(i == 2 && path == bad),
                other => panic!("frame {i}: {other:?}"),
            }
        }
        assert!(matches!(reader.next_frame(), Ok(None)));
        assert!(matches!(reader.next_frame(), Ok(None)));
        assert_eq!(reader.position(), expected.len());
    }
}

#[test]
fn dropping_a_reader_mid_stream_stops_its_thread() {
    let tmp = tempfile::tempdir().unwrap();
    tum_like(tmp.path(), 30);
    let ds = Dataset::open(tmp.path(), &opts(VGA)).unwrap();
    let mut reader = ds.into_reader(2);
    assert!(reader.next_owned().unwrap().is_some());
    // The thread is blocked on a full channel; drop must close it and join without hanging.
    std::thread::sleep(std::time::Duration::from_millis(20));
    drop(reader);
}

#[test]
fn open_errors_name_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    tum_like(dir, 3);
    write(dir, "depth.txt", "1305031102.182304 depth/0.png\n1305031102.1 depth/1.png\n");
    let err = Dataset::open(dir, &opts(VGA)).unwrap_err();
    assert!(err.to_string().contains("depth.txt:2: timestamp"), "{err}");
    write(dir, "groundtruth.txt", "1 2 3\n");
    write(dir, "depth.txt", "1305031102.182304 depth/0.png\n");
    let err = Dataset::open(dir, &opts(VGA)).unwrap_err();
    assert!(matches!(err, DatasetError::Groundtruth { .. }), "{err}");
    assert!(err.to_string().contains("groundtruth.txt:1"), "{err}");
    fs::remove_file(dir.join("groundtruth.txt")).unwrap();
    assert!(Dataset::open(dir, &opts(VGA)).unwrap().groundtruth().is_none());
}

#[test]
fn errors_and_readers_cross_threads() {
    // The CLI wraps errors in anyhow (needs Send + Sync + 'static) and may move a reader to a
    // pipeline thread.
    fn send_sync<T: Send + Sync + 'static>() {}
    fn send<T: Send>() {}
    send_sync::<DatasetError>();
    send::<DatasetReader>();
    send_sync::<Dataset>();
}

#[test]
fn a_distortion_is_removed_from_gray_and_sensor_registered_depth() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    tum_like(dir, 3);
    let pinhole = Dataset::open(dir, &opts(VGA)).unwrap();
    write(
        dir,
        "calibration.toml",
        "fx = 10.0\nfy = 11.0\ncx = 3.5\ncy = 2.5\nwidth = 8\nheight = 6\ndepth_scale = 5000.0\n\
         k1 = 0.3\np2 = 0.01\n",
    );
    let ds = Dataset::open(dir, &opts(VGA)).unwrap();
    let sensor = *ds.sensor_calibration();
    assert_eq!(sensor.distortion, Distortion { k1: 0.3, p2: 0.01, ..Distortion::NONE });
    // The core gets a pinhole camera with the same intrinsics.
    assert_eq!(ds.calibration(), pinhole.calibration());
    let raw = pinhole.load_frame(0).unwrap();
    let undistorter = Undistorter::new(&sensor).unwrap();
    let frame = ds.load_frame(0).unwrap();
    assert_eq!(frame.gray, undistorter.gray(&raw.gray));
    assert_eq!(frame.depth, undistorter.depth(&raw.depth));
    assert_ne!(frame.gray, raw.gray);
}

#[test]
fn a_folder_without_calibration_takes_the_tum_preset_its_name_gives() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("rgbd_dataset_freiburg3_tiny");
    tum_like(&dir, 3);
    fs::remove_file(dir.join("calibration.toml")).unwrap();
    // The preset's size (640 x 480) is not the images' (8 x 6): opening works, decoding says so.
    let ds = Dataset::open(&dir, &opts(VGA)).unwrap();
    assert_eq!(*ds.sensor_calibration(), Calibration::preset("tum3").unwrap());
    assert_eq!(*ds.calibration_origin(), CalibrationOrigin::FolderName("tum3"));
    assert!(ds.calibration_origin().to_string().starts_with("preset tum3 (the folder has no"));
    assert!(matches!(ds.load_frame(0), Err(DatasetError::ImageSize { .. })));
    let plain = tmp.path().join("recording");
    tum_like(&plain, 3);
    fs::remove_file(plain.join("calibration.toml")).unwrap();
    let err = Dataset::open(&plain, &opts(VGA)).unwrap_err();
    assert!(matches!(err, DatasetError::NoCalibration { .. }), "{err}");
    assert!(err.to_string().contains("--preset tum1|tum2|tum3"), "{err}");
    assert_eq!(Calibration::preset_for_folder(Path::new("a/freiburg1_freiburg2")), None);
    assert_eq!(
        Calibration::preset_for_folder(Path::new("rgbd_dataset_Freiburg2_xyz")),
        Some("tum2")
    );
}

/// Every calibration file the product ships (`calibration/`, the shared data set's) or writes
/// (`demo --write-dataset`, `calibrate-depth --out`, tested with its writer) is read without an
/// unknown key.
#[test]
fn every_calibration_file_shipped_or_written_is_accepted() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut files: Vec<_> = fs::read_dir(root.join("calibration"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    assert!(!files.is_empty());
    files.push(root.join("../shared/datasets/7scenes-redkitchen-1000/calibration.toml"));
    let tmp = tempfile::tempdir().unwrap();
    let options =
        crate::synth::SynthOptions { frames: 1, width: 32, height: 24, ..Default::default() };
    let sequence = crate::synth::SyntheticSequence::new(options).unwrap();
    crate::synth::write_tum_folder(&sequence, tmp.path(), "test", 2e-4).unwrap();
    files.push(tmp.path().join("calibration.toml"));
    for file in files {
        if let Err(e) = Calibration::load(&file) {
            panic!("{}: {e}", file.display());
        }
    }
}

#[test]
fn a_path_that_is_no_dataset_folder_is_said_so() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("nowhere");
    let err = Dataset::open(&missing, &opts(VGA)).unwrap_err();
    assert!(matches!(err, DatasetError::NoFolder { .. }), "{err}");
    assert_eq!(err.to_string(), format!("dataset folder {} does not exist", missing.display()));
    write(tmp.path(), "file", "");
    let err = Dataset::open(&tmp.path().join("file"), &opts(VGA)).unwrap_err();
    assert!(matches!(err, DatasetError::NotAFolder { .. }), "{err}");
    // Said before the calibration, which is missing too.
    let err = Dataset::open(tmp.path(), &opts(VGA)).unwrap_err();
    assert!(matches!(err, DatasetError::NoList { list: "rgb.txt", .. }), "{err}");
    write(tmp.path(), "rgb.txt", "");
    let err = Dataset::open(tmp.path(), &opts(VGA)).unwrap_err();
    assert!(matches!(err, DatasetError::NoList { list: "depth.txt", .. }), "{err}");
}
