//! The parser and decoder targets: each runs one input through the public API that reads such
//! bytes in the product, and checks the properties that must hold of what it accepted. A panic
//! is caught by the runner; a broken property is returned as `Err(what)`.
//!
//! - `map-file`: `check_map_file`, `PlaceMemory::load` (the host's place memory: a RAM store of
//!   the board's capacity) and `MapFile::from_bytes` agree on every input; a loaded map saves
//!   back to the same bytes; an accepted file's summary and PLY export run, and the file it
//!   writes back reads back to the same bytes.
//! - `flash-mount`: `FlashStore::mount` over the bytes (padded with erased bytes to whole 1 KiB
//!   sectors, at most [`MAX_REGION_BYTES`]), a place memory attached and saved; when the records
//!   it held decode, the map less its last record is loaded into it and committed, and the next
//!   boot of the same flash finds exactly that map. The same again on the bytes as flash of
//!   4 KiB sectors and 32-byte words ([`SECTOR_MODE_SECTOR`]: the store's sector mode).
//! - `wire`: `decode_capture`; its counts add up; every message it decoded encodes, and the
//!   encoded stream decodes to the same messages (bit for bit).
//! - `calibration`: `Calibration::from_toml_str`; an accepted calibration validates again, and
//!   the loader's next steps (downsampling, the undistortion map) run on it.
//! - `lists`: the dataset's list readers on the text (`parse_image_list` for `rgb.txt` and
//!   `depth.txt`, `Trajectory::parse_tum` as `groundtruth.txt` is read): accepted lists have
//!   finite, strictly increasing timestamps.
//! - `trajectory`: `Trajectory::parse_tum`: accepted poses are finite with unit quaternions and
//!   strictly increasing timestamps; writing them runs.
//! - `image`: the dataset loader's colour (to 8-bit gray) and depth (16-bit PNG) decoders on the
//!   bytes, expecting the seeds' [`IMAGE_SIZE`].

use std::path::Path;

use ferroslam_core::ar::{SavedWorld, World};
use ferroslam_core::loops::PlaceMemory;
use ferroslam_core::map::RamStore;
use ferroslam_core::persist::{
    FlashStore, MAP_VERSION, MapFileError, SECTOR_BYTES, SliceFlash, check_map_file,
    flash_bytes_for,
};
use ferroslam_core::wire::{MAX_FRAME_ON_WIRE, Message, encode};
use ferroslam_sim::dataset::undistort::Undistorter;
use ferroslam_sim::dataset::{Calibration, depth_from_bytes, gray_from_bytes, parse_image_list};
use ferroslam_sim::map_file::{MAX_MAP_RECORDS, MapFault, MapFile, encode_map_file};
use ferroslam_sim::run::slam::HostPlaces;
use ferroslam_sim::serial::decode_capture;
use ferroslam_sim::trajectory::Trajectory;

use super::Outcome;

/// The size of the image seeds (and what the `image` target expects), pixels.
pub const IMAGE_SIZE: (u32, u32) = (8, 6);

/// The largest flash region the `flash-mount` target mounts, bytes (a store of 8 records:
/// tables, records and spare units).
pub const MAX_REGION_BYTES: usize = flash_bytes_for(8);

/// The undistortion map is built for calibrations of at most this many pixels: the loader's
/// largest (8192 pixels a side) takes a second and a gigabyte, too slow an input for a fuzzer.
const MAX_UNDISTORT_PIXELS: u64 = 1 << 18;

/// The variant name of an error (its `Debug` up to the first non-identifier character): what
/// tells one refusal from another in the report and in the choice of inputs kept.
pub fn class_of(e: &impl std::fmt::Debug) -> String {
    format!("{e:?}").chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect()
}

/// A boxed place memory over a fresh RAM store of the board's capacity (half a megabyte, made
/// in a frame of its own as host-sim makes it).
#[inline(never)]
fn host_places() -> Box<HostPlaces> {
    Box::new(PlaceMemory::new(RamStore::new(), 1))
}

/// The `map-file` target (see the module documentation).
pub fn map_file(input: &[u8]) -> Result<Outcome, String> {
    let checked = check_map_file(input, MAX_MAP_RECORDS);
    let mut memory = host_places();
    let loaded = memory.load(input);
    let world = loaded.as_ref().ok().and_then(Option::as_ref);
    let file = MapFile::from_bytes(input);
    if checked.is_ok() != loaded.is_ok() || checked.is_ok() != file.is_ok() {
        return Err(format!(
            "the readers disagree: check_map_file {checked:?}, PlaceMemory::load {loaded:?}, \
             MapFile::from_bytes {:?}",
            file.as_ref().err()
        ));
    }
    if loaded.is_ok() {
        let saved = save_with(memory.as_mut(), world)
            .map_err(|e| format!("a loaded map does not save: {e}"))?;
        same_map_saved(&saved, input)?;
    }
    if let Ok(file) = &file {
        let _ = file.summary().to_string();
        file.write_ply(std::io::sink()).map_err(|e| format!("PLY export failed: {e}"))?;
        let written = file.to_bytes();
        let again = MapFile::from_bytes(&written)
            .map_err(|e| format!("the file MapFile writes back is refused: {e}"))?;
        if again.to_bytes() != written {
            return Err("MapFile's bytes do not read back to the same bytes".into());
        }
    }
    Ok(match checked {
        Ok(h) => Outcome::accepted(format!("accepted, {} records", h.records.min(3))),
        Err(MapFileError::Record { .. }) => match file {
            Err(MapFault::Record { source, .. }) => {
                Outcome::refused(format!("Record {}", class_of(&source)))
            }
            _ => Outcome::refused("Record".into()),
        },
        Err(e) => Outcome::refused(class_of(&e)),
    })
}

/// Whether `saved`, what a memory that loaded the map file `input` saves, is `input`: `Err` when
/// it is not (the known issue `map-header-reserved-bytes` when only those bytes differ). A
/// version 2 file saves as this build's version, byte 4 the only difference.
fn same_map_saved(saved: &[u8], input: &[u8]) -> Result<(), String> {
    let mut upgraded = input.to_vec();
    if upgraded.get(4) == Some(&2)
        && let Some(v) = upgraded.get_mut(4)
    {
        *v = MAP_VERSION;
    }
    if saved == upgraded {
        return Ok(());
    }
    Err(format!(
        "a loaded map saves to other bytes ({} bytes, {} loaded)",
        saved.len(),
        input.len()
    ))
}

/// Sector bytes of the `flash-mount` target's second geometry, which runs the store in sector
/// mode (4 records a sector).
pub const SECTOR_MODE_SECTOR: usize = 4096;
/// Word bytes of that geometry, programmed once each (as the STM32H743's).
pub const SECTOR_MODE_WORD: usize = 32;

/// The `flash-mount` target (see the module documentation): the outcome of the 1 KiB-sector
/// geometry, or of the sector mode's when only it found a committed table.
pub fn flash_mount(input: &[u8]) -> Result<Outcome, String> {
    let sectors = flash_mount_on::<SECTOR_MODE_SECTOR, SECTOR_MODE_WORD>(input)
        .map_err(|e| format!("sector mode: {e}"))?;
    let units = flash_mount_on::<SECTOR_BYTES, 4>(input)?;
    if units.accepted > 0 || sectors.accepted == 0 {
        return Ok(units);
    }
    Ok(Outcome { class: format!("sector mode: {}", sectors.class), ..sectors })
}

/// [`flash_mount`] on flash of `SECTOR`-byte sectors and `WORD`-byte words.
fn flash_mount_on<const SECTOR: usize, const WORD: usize>(input: &[u8]) -> Result<Outcome, String> {
    let mut region = input.get(..MAX_REGION_BYTES).unwrap_or(input).to_vec();
    region.resize(region.len().next_multiple_of(SECTOR), 0xFF);
    let (generation, undecodable, held, first, world) = {
        let mut memory = boot::<SECTOR, WORD>(&mut region)?;
        let generation = memory.store().generation();
        let world = memory.held_world();
        let first = save(&mut memory).map_err(|e| format!("save after attach: {e}"))?;
        (generation, memory.stats().store_errors, memory.len(), first, world)
    };
    let class = match (generation, undecodable) {
        (0, _) => return Ok(Outcome::refused("no committed table".into())),
        (_, 0) => format!("table, {} records", held.min(3)),
        _ => "table, records that do not decode".into(),
    };
    let class = match &world {
        Some(Ok(_)) => format!("{class}, a world"),
        Some(Err(e)) => format!("{class}, a world refused ({})", class_of(e)),
        None => class,
    };
    // The world it held, if it read whole: committed again with the records, found again.
    let kept = world.and_then(Result::ok);
    let parts = kept.as_ref().map(SavedWorld::restored);
    let with = parts.as_ref().map(|(planes, anchors)| World { planes, anchors });
    // The map it held, less its last record, loaded (written anew) and committed: the next boot
    // must find exactly that map.
    let Ok(file) = MapFile::from_bytes(&first) else { return Ok(Outcome::accepted(class)) };
    let fewer = encode_map_file(file.records.get(..held.saturating_sub(1)).unwrap_or(&[]));
    {
        let mut memory = boot::<SECTOR, WORD>(&mut region)?;
        memory
            .load(&fewer)
            .map_err(|e| format!("a map saved from this store does not load: {e}"))?;
        if memory.stats().store_errors > 0 {
            return Ok(Outcome::accepted(format!("{class}, store full")));
        }
        if memory.commit(with.as_ref()).is_err() {
            return Ok(Outcome::accepted(format!("{class}, commit failed")));
        }
    }
    let mut memory = boot::<SECTOR, WORD>(&mut region)?;
    let world_again = memory.held_world().and_then(Result::ok);
    if world_again != kept {
        return Err(format!(
            "a world committed with the records is not what the next boot finds: {} planes, \
             {} anchors committed, {:?} found",
            kept.as_ref().map_or(0, |w| w.planes().len()),
            kept.as_ref().map_or(0, |w| w.anchors().len()),
            world_again.as_ref().map(|w| (w.planes().len(), w.anchors().len()))
        ));
    }
    let found = save(&mut memory).map_err(|e| format!("save after the second boot: {e}"))?;
    if found != fewer {
        return Err(format!(
            "{} records loaded and committed over a store mounted at generation {generation} \
             ({held} records held); the next boot finds {} records (generation {}){}",
            held.saturating_sub(1),
            memory.len(),
            memory.store().generation(),
            if memory.len() == held.saturating_sub(1) { ", other bytes" } else { "" }
        ));
    }
    Ok(Outcome::accepted(format!("{class}, reloaded")))
}

/// The place memory a board boots with on `region`: the store mounted, a memory made before it
/// attached to it (as the firmware does).
#[allow(clippy::type_complexity)]
fn boot<const SECTOR: usize, const WORD: usize>(
    region: &mut [u8],
) -> Result<PlaceMemory<FlashStore<SliceFlash<'_, SECTOR, WORD>>>, String> {
    let store = FlashStore::mount(SliceFlash::with_geometry(region))
        .map_err(|e| format!("mount failed on a region the flash holds: {e:?}"))?;
    let mut memory = PlaceMemory::new(FlashStore::unmounted(SliceFlash::with_geometry(&mut [])), 1);
    memory.attach(store);
    Ok(memory)
}

/// The map file `memory` saves (its records only).
pub fn save<S: ferroslam_core::map::KeyframeStore>(
    memory: &mut PlaceMemory<S>,
) -> Result<Vec<u8>, String> {
    save_with(memory, None)
}

/// What [`save`] writes, with `world`'s planes and anchors after the records.
fn save_with<S: ferroslam_core::map::KeyframeStore>(
    memory: &mut PlaceMemory<S>,
    world: Option<&SavedWorld>,
) -> Result<Vec<u8>, String> {
    crate::replay::saved_map(memory, world).map_err(|e| format!("{e:#}"))
}

/// The wire frame of `m`.
fn frame_of(m: &Message) -> Result<Vec<u8>, String> {
    let mut buf = [0u8; MAX_FRAME_ON_WIRE];
    let n = encode(m, &mut buf).map_err(|e| format!("a decoded message does not encode: {e}"))?;
    Ok(buf.get(..n).unwrap_or(&[]).to_vec())
}

/// The `wire` target (see the module documentation). Counted in frames: decoded, or dropped.
pub fn wire(input: &[u8]) -> Result<Outcome, String> {
    let capture = decode_capture(input);
    let s = capture.stats;
    if s.bytes_received != input.len() as u64
        || s.bytes_delivered + s.bytes_skipped != s.bytes_received
        || s.frames_decoded != capture.messages.len() as u64
        || s.frames_dropped + s.frames_unknown_version != capture.dropped.len() as u64
    {
        return Err(format!(
            "the decoder's counts do not add up over {} bytes: {s:?}, {} messages, {} dropped",
            input.len(),
            capture.messages.len(),
            capture.dropped.len()
        ));
    }
    let frames = capture.messages.iter().map(frame_of).collect::<Result<Vec<_>, _>>()?;
    let again = decode_capture(&frames.concat());
    let again_frames = again.messages.iter().map(frame_of).collect::<Result<Vec<_>, _>>()?;
    if !again.dropped.is_empty() || again_frames != frames {
        return Err(format!(
            "{} messages encoded decode to {} others ({} frames dropped)",
            frames.len(),
            again_frames.iter().zip(&frames).filter(|(a, b)| a != b).count()
                + again_frames.len().abs_diff(frames.len()),
            again.dropped.len()
        ));
    }
    let class = match (capture.messages.first(), capture.dropped.first()) {
        (Some(m), _) => format!("decoded {}", class_of(m)),
        (None, Some((_, e))) => class_of(e),
        (None, None) => "no frame".into(),
    };
    Ok(Outcome { accepted: s.frames_decoded, refused: capture.dropped.len() as u64, class })
}

/// The `calibration` target (see the module documentation).
pub fn calibration(input: &[u8]) -> Result<Outcome, String> {
    let text = String::from_utf8_lossy(input);
    let path = Path::new("fuzz/calibration.toml");
    let c = match Calibration::from_toml_str(&text, path) {
        Ok(c) => c,
        Err(e) => return Ok(Outcome::refused(calibration_class(&e))),
    };
    c.validate(path).map_err(|e| format!("an accepted calibration does not validate: {e}"))?;
    for levels in 0..4 {
        let _ = c.downsampled(levels);
    }
    if u64::from(c.width) * u64::from(c.height) <= MAX_UNDISTORT_PIXELS
        && let Some(u) = Undistorter::new(&c)
    {
        let pixels = (c.width * c.height) as usize;
        let _ = u.gray(&vec![128; pixels]);
        let _ = u.depth(&vec![1000; pixels]);
    }
    let parts = [c.depth.is_some(), !c.distortion.is_none(), c.depth_noise_coeff_per_m.is_some()];
    Ok(Outcome::accepted(format!("accepted {parts:?}")))
}

/// A calibration error's class: its variant, and the key it names.
fn calibration_class(e: &ferroslam_sim::dataset::DatasetError) -> String {
    use ferroslam_sim::dataset::DatasetError as E;
    match e {
        E::CalibrationMissingKey { key, .. } | E::CalibrationValue { key, .. } => {
            format!("{} {key}", class_of(e))
        }
        _ => class_of(e),
    }
}

/// The `lists` target (see the module documentation). Counted in lists read: the input is read
/// as an image list and as a ground-truth file.
pub fn lists(input: &[u8]) -> Result<Outcome, String> {
    let text = String::from_utf8_lossy(input);
    let mut outcome = Outcome { accepted: 0, refused: 0, class: String::new() };
    match parse_image_list(Path::new("rgb.txt"), &text, Path::new("/data")) {
        Ok(entries) => {
            let mut previous = f64::NEG_INFINITY;
            for e in &entries {
                if !e.timestamp_s.is_finite() || e.timestamp_s <= previous {
                    return Err(format!(
                        "an accepted list has timestamp {} after {previous}",
                        e.timestamp_s
                    ));
                }
                previous = e.timestamp_s;
            }
            outcome.accepted += 1;
            outcome.class = format!("list of {}", entries.len().min(3));
        }
        Err(e) => {
            outcome.refused += 1;
            outcome.class = class_of(&e);
        }
    }
    match Trajectory::parse_tum(&text, Path::new("groundtruth.txt")) {
        Ok(t) => {
            check_trajectory(&t)?;
            outcome.accepted += 1;
            outcome.class.push_str(", ground truth");
        }
        Err(_) => outcome.refused += 1,
    }
    Ok(outcome)
}

/// The `trajectory` target (see the module documentation).
pub fn trajectory(input: &[u8]) -> Result<Outcome, String> {
    let text = String::from_utf8_lossy(input);
    match Trajectory::parse_tum(&text, Path::new("trajectory.txt")) {
        Ok(t) => {
            check_trajectory(&t)?;
            let written = t.to_tum_string();
            if written.lines().count() != t.len() {
                return Err("the TUM text of a trajectory is not one line per pose".into());
            }
            Ok(Outcome::accepted(format!("accepted, {} poses", t.len().min(3))))
        }
        Err(ferroslam_sim::trajectory::TrajectoryError::Line { problem, .. }) => {
            Ok(Outcome::refused(class_of(&problem)))
        }
        Err(e) => Ok(Outcome::refused(class_of(&e))),
    }
}

/// What an accepted trajectory guarantees: finite poses, unit quaternions, increasing time.
fn check_trajectory(t: &Trajectory) -> Result<(), String> {
    if t.check_increasing().is_err() {
        return Err("an accepted trajectory's timestamps do not strictly increase".into());
    }
    for p in &t.poses {
        let q = p.t_wc.rotation.quaternion();
        let finite = p.t_wc.translation.vector.iter().chain(q.coords.iter()).all(|v| v.is_finite());
        if !finite || (q.norm() - 1.0).abs() > 1e-9 {
            return Err(format!("an accepted pose is not finite and unit: {p:?}"));
        }
    }
    Ok(())
}

/// The `image` target (see the module documentation). Counted in decodes: the input is decoded
/// as a colour image and as a depth image.
pub fn image(input: &[u8]) -> Result<Outcome, String> {
    let path = Path::new("fuzz.png");
    let pixels = (IMAGE_SIZE.0 * IMAGE_SIZE.1) as usize;
    let mut outcome = Outcome { accepted: 0, refused: 0, class: String::new() };
    let mut classes = Vec::new();
    match gray_from_bytes(input, path, IMAGE_SIZE) {
        Ok(gray) if gray.len() == pixels => {
            outcome.accepted += 1;
            classes.push("gray".to_owned());
        }
        Ok(gray) => return Err(format!("a gray image of {} pixels, not {pixels}", gray.len())),
        Err(e) => {
            outcome.refused += 1;
            classes.push(image_class(&e));
        }
    }
    match depth_from_bytes(input, path, IMAGE_SIZE) {
        Ok(depth) if depth.len() == pixels => {
            outcome.accepted += 1;
            classes.push("depth".to_owned());
        }
        Ok(depth) => return Err(format!("a depth image of {} pixels, not {pixels}", depth.len())),
        Err(e) => {
            outcome.refused += 1;
            classes.push(image_class(&e));
        }
    }
    outcome.class = classes.join(", ");
    Ok(outcome)
}

/// An image error's class: its variant, and for a decoding error, the image crate's.
fn image_class(e: &ferroslam_sim::dataset::DatasetError) -> String {
    match e {
        ferroslam_sim::dataset::DatasetError::Decode { source, .. } => {
            format!("Decode {}", class_of(source))
        }
        _ => class_of(e),
    }
}

impl Outcome {
    /// One input, accepted, of class `class`.
    pub fn accepted(class: String) -> Self {
        Self { accepted: 1, refused: 0, class }
    }

    /// One input, refused, of class `class`.
    pub fn refused(class: String) -> Self {
        Self { accepted: 0, refused: 1, class }
    }
}
