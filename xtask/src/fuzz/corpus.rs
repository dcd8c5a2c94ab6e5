//! `cargo xtask fuzz --write-corpus`: the seed corpora of `fuzz/corpus/<target>/`, made from real
//! valid inputs (what `fuzz/README.md` describes), small enough to commit.
//!
//! - A run of the firmware's pipeline (`ferroslam_firmware::pipeline::run_frame`, the board's
//!   code) on the first [`DEMO_FRAMES`] frames of the built-in demo at QVGA, with a place memory:
//!   its UART bytes (pose and cost messages, then a status and a fault message) are the `wire`
//!   seeds, with the link's other direction (an anchor command, the anchor reported after it and
//!   a refused command's fault), and, as TUM lines, a `trajectory` seed; the map it saves is cut to one and two records
//!   and an empty map for `map-file`; a 2-record flash region after one and after two commits of
//!   those maps (`PlaceMemory::load` then `commit` on a `FlashStore`) are `flash-mount`'s.
//! - 7-Scenes (`../shared/datasets`): the head of `rgb.txt`, `depth.txt` and `groundtruth.txt`
//!   (`lists`, `trajectory`), its `calibration.toml` and `calibration/7scenes-kinect-v1.toml`
//!   without comments (`calibration`, with TUM's Freiburg 1 preset written as a file), and an
//!   8 x 6 crop of frame 0's colour and depth images re-encoded (`image`: RGB, RGBA and gray PNG,
//!   a JPEG, and the 16-bit depth PNG).
//! - `frames`: scripts of plausible sequences (a textured plane panned at 30 Hz; see
//!   [`super::frames`]), which the front end tracks.

use std::io::Cursor;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use ferroslam_core::ar::{AnchorCommand, SavedWorld, WORLD_UNITS, World};
use ferroslam_core::frame::TelemetrySink;
use ferroslam_core::loops::PlaceMemory;
use ferroslam_core::map::RamStore;
use ferroslam_core::persist::{FlashStore, SECTOR_BYTES, SliceFlash, flash_bytes_for};
use ferroslam_core::wire::{
    AnchorMessage, CommandMessage, FaultCode, FaultMessage, Message, TickUnit,
};
use ferroslam_firmware::commands::{Arrived, LinkCommands};
use ferroslam_firmware::pipeline::{FrameOutcome, Link, Pipeline, TickClock, run_frame};
use ferroslam_sim::dataset::{Calibration, parse_image_list};
use ferroslam_sim::map_file::{MapFile, encode_map_file};
use ferroslam_sim::serial::{TumPoseWriter, WireWriter, decode_capture};
use image::{DynamicImage, ImageFormat};

use super::frames::{FRAME_BYTES, MAX_FRAMES};
use super::targets::{MAX_REGION_BYTES, SECTOR_MODE_SECTOR, SECTOR_MODE_WORD};
use crate::paths::{SEVEN_SCENES, SEVEN_SCENES_CALIBRATION, root};

/// A target's seed files: names and bytes.
type Seeds = Vec<(String, Vec<u8>)>;

/// Frames of the demo the pipeline runs for the seeds.
const DEMO_FRAMES: usize = 45;

/// The demo frame the seeds' two objects are placed in.
const ANCHOR_FRAME: u32 = 40;

/// Data lines kept of each 7-Scenes list.
const LIST_LINES: usize = 6;

/// The crop of 7-Scenes frame 0 the image seeds hold: left, top (pixels) and the size.
const CROP: (u32, u32) = (316, 237);

/// Writes every target's seeds under `dir` (each target's folder emptied first).
///
/// # Errors
/// The demo run, a missing 7-Scenes recording, or a file that cannot be written.
pub fn write_all(dir: &Path) -> Result<()> {
    let started = Instant::now();
    let demo = demo_run()?;
    let seven = root().join(SEVEN_SCENES);
    let seeds: Vec<(&str, Seeds)> = vec![
        ("map-file", map_seeds(&demo)?),
        ("flash-mount", flash_seeds(&demo)?),
        ("wire", wire_seeds(&demo)),
        ("calibration", calibration_seeds(&seven)?),
        ("lists", list_seeds(&seven)?),
        ("trajectory", trajectory_seeds(&seven, &demo)?),
        ("image", image_seeds(&seven)?),
        ("mcap", mcap_seeds()?),
        ("anchor-script", anchor_script_seeds()?),
        ("frames", frame_seeds()),
    ];
    for (target, files) in seeds {
        let folder = dir.join(target);
        if folder.exists() {
            std::fs::remove_dir_all(&folder)
                .with_context(|| format!("emptying {}", folder.display()))?;
        }
        std::fs::create_dir_all(&folder)
            .with_context(|| format!("creating {}", folder.display()))?;
        for (name, bytes) in files {
            let path = folder.join(name);
            std::fs::write(&path, &bytes).with_context(|| format!("writing {}", path.display()))?;
            eprintln!("{} ({} bytes)", path.display(), bytes.len());
        }
    }
    eprintln!("seed corpora written in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}

/// What the demo run gave.
struct DemoRun {
    /// The UART bytes of every frame (pose and cost messages).
    capture: Vec<u8>,
    /// The map saved at the end.
    map: Vec<u8>,
    /// The pipeline's status message at the end.
    status: Message,
}

/// The pipeline's tick clock for the seeds: 1000 cycles a reading, so that the cost messages
/// (and the corpus) are the same bytes on every run; their figures are not measurements.
struct CountingClock(u32);

impl TickClock for CountingClock {
    const UNIT: TickUnit = TickUnit::CoreCycle;

    fn now(&mut self) -> u32 {
        self.0 = self.0.wrapping_add(1000);
        self.0
    }
}

/// Runs the firmware's pipeline on the demo's first [`DEMO_FRAMES`] frames (see the module
/// documentation).
fn demo_run() -> Result<DemoRun> {
    let (mut source, cam, _) =
        ferroslam_tests::demo_frames::demo_frames((0..DEMO_FRAMES).collect());
    let mut pipeline = Box::new(Pipeline::new());
    let mut places = Box::new(PlaceMemory::new(RamStore::<64>::new(), 1));
    let mut sink = WireWriter::new(Vec::new());
    let mut clock = CountingClock(0);
    // Two objects placed (on the floor and a wall), so the saved map holds anchors too.
    let mut commands = WireWriter::new(Vec::new());
    for (object, pixel) in [(0, [80.0, 200.0]), (1, [60.0, 60.0])] {
        let command = AnchorCommand::Place { object, pixel, scale: 1.0 };
        let _ =
            commands.send(&Message::Command(CommandMessage { frame_index: ANCHOR_FRAME, command }));
    }
    let commands = commands.into_inner();
    let mut received = LinkCommands::new(Arrived(&commands[..]));
    loop {
        let outcome = run_frame(
            &mut source,
            pipeline.as_mut(),
            places.as_mut(),
            &cam,
            Link { tx: &mut sink, rx: &mut received },
            &mut clock,
            |_| 0,
        )?;
        match outcome {
            FrameOutcome::Processed { .. } => {}
            FrameOutcome::Fault(f) => bail!("the demo run faulted: {f:?}"),
            FrameOutcome::End => break,
        }
    }
    pipeline.remember_map_in(&cam, places.as_mut());
    let world = pipeline.slam().world();
    places.commit(Some(&world)).map_err(|e| anyhow!("commit: {e:?}"))?;
    let mut map = Vec::new();
    places
        .save(Some(&world), |b| {
            map.extend_from_slice(b);
            Ok::<(), std::convert::Infallible>(())
        })
        .map_err(|e| anyhow!("saving the demo's map: {e:?}"))?;
    let status = Message::Status(pipeline.status());
    Ok(DemoRun { capture: sink.into_inner(), map, status })
}

/// The demo's map with its first `n` records (at most as many as it has), without its planes and
/// anchors.
fn map_of(demo: &DemoRun, n: usize) -> Result<Vec<u8>> {
    let file = MapFile::from_bytes(&demo.map).context("the demo's map")?;
    if file.records.len() < 2 {
        bail!("the demo's map has {} records; the seeds need 2", file.records.len());
    }
    Ok(encode_map_file(file.records.get(..n).unwrap_or(&file.records)))
}

fn map_seeds(demo: &DemoRun) -> Result<Seeds> {
    Ok(vec![
        ("demo-0-records.fsmp".into(), map_of(demo, 0)?),
        ("demo-1-record.fsmp".into(), map_of(demo, 1)?),
        ("demo-2-records.fsmp".into(), map_of(demo, 2)?),
        ("demo-with-planes.fsmp".into(), demo.map.clone()),
    ])
}

fn flash_seeds(demo: &DemoRun) -> Result<Seeds> {
    let [first, second] = flash_images::<SECTOR_BYTES, 4>(demo, flash_bytes_for(2 + WORLD_UNITS))?;
    let [sectors_first, sectors_second] =
        flash_images::<SECTOR_MODE_SECTOR, SECTOR_MODE_WORD>(demo, MAX_REGION_BYTES)?;
    Ok(vec![
        ("demo-2-records-1-commit.flash".into(), first),
        ("demo-then-1-record-2-commits.flash".into(), second),
        ("demo-2-records-1-commit-4k-sectors.flash".into(), sectors_first),
        ("demo-then-1-record-2-commits-4k-sectors.flash".into(), sectors_second),
    ])
}

/// A region of `bytes` on flash of `SECTOR`-byte sectors and `WORD`-byte words after the demo's
/// map of 2 records was loaded and committed with its planes, then after its map of 1 record was
/// (without).
fn flash_images<const SECTOR: usize, const WORD: usize>(
    demo: &DemoRun,
    bytes: usize,
) -> Result<[Vec<u8>; 2]> {
    let saved = MapFile::from_bytes(&demo.map).context("the demo's map")?.world;
    let parts = saved.as_ref().map(SavedWorld::restored).context("the demo's map has planes")?;
    let world = World { planes: &parts.0, anchors: &parts.1 };
    let mut region = vec![0xFF; bytes];
    let mut images = Vec::new();
    for records in [2, 1] {
        let store = FlashStore::mount(SliceFlash::<SECTOR, WORD>::with_geometry(&mut region))
            .map_err(|e| anyhow!("mounting the seed region: {e:?}"))?;
        let mut memory =
            PlaceMemory::new(FlashStore::unmounted(SliceFlash::with_geometry(&mut [])), 1);
        memory.attach(store);
        memory.load(&map_of(demo, records)?).map_err(|e| anyhow!("loading the map: {e}"))?;
        let with = (records == 2).then_some(&world);
        memory.commit(with).map_err(|e| anyhow!("commit: {e:?}"))?;
        images.push(region.clone());
    }
    let second = images.pop().context("two images")?;
    let first = images.pop().context("two images")?;
    Ok([first, second])
}

/// The frames of a capture's first `n` frames (pose and cost messages each).
fn first_frames(capture: &[u8], n: usize) -> Vec<u8> {
    let end = capture
        .iter()
        .enumerate()
        .filter(|(_, b)| **b == 0)
        .nth(2 * n - 1)
        .map_or(capture.len(), |(i, _)| i + 1);
    capture.get(..end).unwrap_or(capture).to_vec()
}

fn wire_seeds(demo: &DemoRun) -> Seeds {
    let mut tail = WireWriter::new(Vec::new());
    // What the board sends for a frame it rejects (a repeated timestamp), and its status.
    let fault =
        FaultMessage { frame_index: DEMO_FRAMES as u32, code: FaultCode::FrameRejected, detail: 2 };
    for m in [Message::Fault(fault), demo.status] {
        // Writing to a Vec cannot fail.
        let _ = tail.send(&m);
    }
    // The link's other direction and the anchors: a command the host sends, the anchor the board
    // then reports, and a command it refused.
    let mut anchors = WireWriter::new(Vec::new());
    let command = AnchorCommand::Place { object: 1, pixel: [80.0, 200.0], scale: 1.5 };
    let anchor = AnchorMessage {
        frame_index: 7,
        object: 1,
        position_m: [0.25, -0.5, 1.75],
        up: [0.0, -1.0, 0.0],
        scale: 1.5,
    };
    let refused = FaultMessage { frame_index: 9, code: FaultCode::Command, detail: 3 };
    for m in [
        Message::Command(CommandMessage { frame_index: 7, command }),
        Message::Anchor(anchor),
        Message::Fault(refused),
    ] {
        let _ = anchors.send(&m);
    }
    vec![
        ("demo-3-frames.uart".into(), first_frames(&demo.capture, 3)),
        ("demo-fault-status.uart".into(), tail.into_inner()),
        ("anchors.uart".into(), anchors.into_inner()),
    ]
}

/// The first `LIST_LINES` data lines of `text` with the comment lines before them.
fn head(text: &str) -> Vec<u8> {
    let mut out = String::new();
    let mut data = 0;
    for line in text.lines() {
        if data == LIST_LINES {
            break;
        }
        if !line.trim_start().starts_with('#') {
            data += 1;
        }
        out.push_str(line);
        out.push('\n');
    }
    out.into_bytes()
}

fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path)
        .with_context(|| format!("reading {} (the 7-Scenes recording)", path.display()))
}

fn calibration_seeds(seven: &Path) -> Result<Seeds> {
    let registered = read_text(&root().join(SEVEN_SCENES_CALIBRATION))?;
    let registered: String = registered
        .lines()
        .filter(|l| !l.trim_start().starts_with('#') && !l.trim().is_empty())
        .map(|l| format!("{l}\n"))
        .collect();
    let c = Calibration::preset("tum1")?;
    let d = c.distortion;
    let tum1 = format!(
        "fx = {:?}\nfy = {:?}\ncx = {:?}\ncy = {:?}\nwidth = {}\nheight = {}\ndepth_scale = {:?}\n\
         k1 = {:?}\nk2 = {:?}\np1 = {:?}\np2 = {:?}\nk3 = {:?}\ndepth_noise_coeff_per_m = 0.003\n",
        c.fx, c.fy, c.cx, c.cy, c.width, c.height, c.depth_scale, d.k1, d.k2, d.p1, d.p2, d.k3
    );
    Ok(vec![
        ("7scenes-nominal.toml".into(), read_text(&seven.join("calibration.toml"))?.into_bytes()),
        ("7scenes-kinect-v1-registered.toml".into(), registered.into_bytes()),
        ("tum1-preset.toml".into(), tum1.into_bytes()),
    ])
}

fn list_seeds(seven: &Path) -> Result<Seeds> {
    ["rgb.txt", "depth.txt", "groundtruth.txt"]
        .into_iter()
        .map(|name| Ok((format!("7scenes-{name}"), head(&read_text(&seven.join(name))?))))
        .collect()
}

fn trajectory_seeds(seven: &Path, demo: &DemoRun) -> Result<Seeds> {
    let mut tum = TumPoseWriter::new(Vec::new());
    for m in decode_capture(&demo.capture).messages.iter().take(2 * (LIST_LINES + 2)) {
        let _ = tum.send(m);
    }
    Ok(vec![
        ("7scenes-groundtruth.txt".into(), head(&read_text(&seven.join("groundtruth.txt"))?)),
        ("demo-estimate.txt".into(), tum.into_inner()),
    ])
}

/// `image` encoded as `format`.
fn encoded(image: &DynamicImage, format: ImageFormat) -> Result<Vec<u8>> {
    let mut out = Cursor::new(Vec::new());
    image.write_to(&mut out, format).with_context(|| format!("encoding a {format:?} seed"))?;
    Ok(out.into_inner())
}

fn image_seeds(seven: &Path) -> Result<Seeds> {
    let first = |list: &str| -> Result<std::path::PathBuf> {
        let path = seven.join(list);
        let entries = parse_image_list(&path, &read_text(&path)?, seven)?;
        entries
            .first()
            .map(|e| e.path.clone())
            .with_context(|| format!("{} is empty", path.display()))
    };
    let (w, h) = super::targets::IMAGE_SIZE;
    let crop = |path: &Path| -> Result<DynamicImage> {
        let image = image::open(path).with_context(|| format!("decoding {}", path.display()))?;
        Ok(image.crop_imm(CROP.0, CROP.1, w, h))
    };
    let colour = crop(&first("rgb.txt")?)?;
    let depth = crop(&first("depth.txt")?)?;
    if !matches!(depth, DynamicImage::ImageLuma16(_)) {
        bail!("7-Scenes depth is not 16-bit gray");
    }
    let rgb = DynamicImage::ImageRgb8(colour.to_rgb8());
    Ok(vec![
        ("7scenes-colour-rgb8.png".into(), encoded(&rgb, ImageFormat::Png)?),
        (
            "7scenes-colour-rgba8.png".into(),
            encoded(&DynamicImage::ImageRgba8(colour.to_rgba8()), ImageFormat::Png)?,
        ),
        (
            "7scenes-colour-gray8.png".into(),
            encoded(&DynamicImage::ImageLuma8(colour.to_luma8()), ImageFormat::Png)?,
        ),
        ("7scenes-colour.jpg".into(), encoded(&rgb, ImageFormat::Jpeg)?),
        ("7scenes-depth-gray16.png".into(), encoded(&depth, ImageFormat::Png)?),
    ])
}

/// A script of `frames` (see [`super::frames`]): header `places`, `texture`.
fn script(places: bool, texture: u8, frames: impl Iterator<Item = [u8; FRAME_BYTES]>) -> Vec<u8> {
    let mut out = vec![u8::from(places), texture];
    frames.take(MAX_FRAMES).for_each(|f| out.extend_from_slice(&f));
    out
}

fn frame_seeds() -> Seeds {
    let n = MAX_FRAMES as u8;
    vec![
        // 1 px right a frame, 34 ms apart, a plane at 1.5 m in TUM's depth units.
        ("pan-right.frames".into(), script(true, 7, (0..n).map(|i| [0, i, 4, 0, 33, 22, 0, 0]))),
        // Diagonal at 1/30 s, a slanted plane at 2 m in millimetres.
        (
            "pan-diagonal-slanted.frames".into(),
            script(false, 11, (0..n).map(|i| [1, i, 3, 2, 252, 32 | 0x80, 0, 1])),
        ),
        // Still, then a slow pan with the light changing, depth at full resolution.
        (
            "still-then-pan.frames".into(),
            script(
                true,
                23,
                (0..n)
                    .map(|i| [2, i, if i < 4 { 0 } else { 2 }, 0, 33, 14, (i as i8 * 8) as u8, 16]),
            ),
        ),
    ]
}

/// `mcap`: the built-in demo's first two frames at 16 x 16 written as a TUM folder, converted
/// (`ferroslam-sim convert`: zstd chunks, CameraInfo, ground truth, the calibration carried).
fn mcap_seeds() -> Result<Seeds> {
    use ferroslam_sim::dataset::CalibrationSource;
    use ferroslam_sim::demo::{DemoOptions, write_dataset};
    let scratch = root().join("target/fuzz/scratch/mcap-seeds");
    let folder = scratch.join("demo");
    let mut options = DemoOptions::new(None);
    options.synth.width = 16;
    options.synth.height = 16;
    options.synth.frames = 2;
    write_dataset(&folder, &options, "fuzz seeds")?;
    let file = scratch.join("demo.mcap");
    ferroslam_sim::dataset::mcap::convert_to_mcap(&folder, &file, &CalibrationSource::File)?;
    // A file cut before its footer is not a seed: the reader refuses it (the crate needs the
    // closing magic), and seeds must be accepted inputs.
    Ok(vec![("demo-2-frames.mcap".into(), std::fs::read(&file)?)])
}

/// `anchor-script`: the example script of `docs/anchor-scripts/demo-restart.toml`, and one
/// step of each action.
fn anchor_script_seeds() -> Result<Seeds> {
    let example = root().join("docs/anchor-scripts/demo-restart.toml");
    let mut seeds: Seeds = vec![("demo-restart.toml".into(), read_text(&example)?.into_bytes())];
    let each = "[[step]]\nframe = 2\naction = \"place\"\nobject = 5\npixel = [248.0, 426.0]\nscale = 1.5\n\n\
                [[step]]\nframe = 6\naction = \"scale\"\nobject = 5\nscale = 2.0\n\n\
                [[step]]\nframe = 10\naction = \"remove\"\nobject = 5\n";
    seeds.push(("each-action.toml".into(), each.as_bytes().to_vec()));
    Ok(seeds)
}
