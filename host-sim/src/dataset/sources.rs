//! Where a dataset's frames come from before association: a TUM folder's lists (images not on
//! disk left out) or an MCAP file's topics, with the calibration and ground truth of each.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use ferroslam_core::config::Resolution;

use super::mcap::{self, McapImages};
use super::skipped::keep_present;
use super::{
    Calibration, CalibrationOrigin, CalibrationSource, DatasetError, DatasetOptions, ListEntry,
    SkippedFrame, Stream, lists,
};
use crate::trajectory::Trajectory;

/// Where a dataset's images are.
#[derive(Debug, Clone)]
pub(super) enum ImageStore {
    /// Image files named by the lists.
    Files,
    /// Messages of an MCAP file.
    Mcap(Arc<McapImages>),
}

/// A recording's two image streams before association, its ground truth and calibration.
pub(super) struct Listed {
    pub(super) rgb_list: PathBuf,
    pub(super) rgb: Vec<ListEntry>,
    pub(super) depth_list: PathBuf,
    pub(super) depth: Vec<ListEntry>,
    /// The frames the recording lists (rgb.txt's data lines; the colour topic's messages).
    pub(super) listed_frames: usize,
    /// Listed images not there.
    pub(super) skipped: Vec<SkippedFrame>,
    pub(super) groundtruth: Option<Trajectory>,
    pub(super) sensor: Calibration,
    pub(super) calibration_origin: CalibrationOrigin,
    pub(super) images: ImageStore,
}

/// The sensor's calibration from `source`, and where it came from. A folder without
/// `calibration.toml` whose name names a TUM sensor gets that sensor's preset; otherwise the
/// missing file is an error that says how to give a calibration.
pub(super) fn open_calibration(
    dir: &Path,
    source: &CalibrationSource,
) -> Result<(Calibration, CalibrationOrigin), DatasetError> {
    Ok(match source {
        CalibrationSource::File => {
            let path = dir.join("calibration.toml");
            if !path.exists() {
                let Some(name) = Calibration::preset_for_folder(dir) else {
                    return Err(DatasetError::NoCalibration { dir: dir.to_owned() });
                };
                return Ok((Calibration::preset(name)?, CalibrationOrigin::FolderName(name)));
            }
            (Calibration::load(&path)?, CalibrationOrigin::File(path))
        }
        CalibrationSource::Preset(name) => {
            (Calibration::preset(name)?, CalibrationOrigin::Preset(name.clone()))
        }
        CalibrationSource::Path(path) => {
            (Calibration::load(path)?, CalibrationOrigin::File(path.clone()))
        }
    })
}

/// A TUM folder's lists (images not on disk left out and noted), ground truth and calibration.
pub(super) fn open_folder(dir: &Path, opts: &DatasetOptions) -> Result<Listed, DatasetError> {
    if opts.topics.any() {
        return Err(mcap::McapError::TopicsOnFolder { dir: dir.to_owned() }.into());
    }
    check_folder(dir)?;
    let (sensor, calibration_origin) = open_calibration(dir, &opts.calibration)?;
    check_profile(&sensor, opts.profile)?;
    let rgb_list = dir.join("rgb.txt");
    let depth_list = dir.join("depth.txt");
    let rgb = lists::parse_image_list(&rgb_list, &lists::read_text(&rgb_list)?, dir)?;
    let depth = lists::parse_image_list(&depth_list, &lists::read_text(&depth_list)?, dir)?;
    let groundtruth = read_groundtruth(&dir.join("groundtruth.txt"))?;
    let listed_frames = rgb.len();
    let mut skipped = Vec::new();
    let max_dt_s = opts.max_dt_s;
    let rgb = keep_present((&rgb_list, Stream::Rgb), rgb, max_dt_s, &mut skipped);
    let depth = keep_present((&depth_list, Stream::Depth), depth, max_dt_s, &mut skipped);
    Ok(Listed {
        rgb_list,
        rgb,
        depth_list,
        depth,
        listed_frames,
        skipped,
        groundtruth,
        sensor,
        calibration_origin,
        images: ImageStore::Files,
    })
}

/// An MCAP file's two image topics, ground truth and calibration (see [`mcap`]).
pub(super) fn open_mcap(path: &Path, opts: &DatasetOptions) -> Result<Listed, DatasetError> {
    let recording = mcap::recording::open(path, &opts.topics, &opts.calibration)?;
    check_profile(&recording.sensor, opts.profile)?;
    Ok(Listed {
        listed_frames: recording.rgb.len(),
        rgb_list: recording.rgb_list,
        rgb: recording.rgb,
        depth_list: recording.depth_list,
        depth: recording.depth,
        skipped: Vec::new(),
        groundtruth: recording.groundtruth,
        sensor: recording.sensor,
        calibration_origin: recording.origin,
        images: ImageStore::Mcap(Arc::new(recording.images)),
    })
}

/// Errors unless the calibrated size can be halved as often as `profile` asks.
pub(super) fn check_profile(sensor: &Calibration, profile: Resolution) -> Result<(), DatasetError> {
    let levels = profile.downsample_levels;
    let divisor = 1u32.checked_shl(u32::from(levels)).unwrap_or(0);
    if divisor == 0
        || !sensor.width.is_multiple_of(divisor)
        || !sensor.height.is_multiple_of(divisor)
    {
        return Err(DatasetError::ProfileSize {
            width: sensor.width,
            height: sensor.height,
            profile: profile.name,
            levels,
        });
    }
    Ok(())
}

/// Reads `groundtruth.txt` if it exists, with the trajectory module's TUM reader.
pub(super) fn read_groundtruth(path: &Path) -> Result<Option<Trajectory>, DatasetError> {
    match std::fs::read_to_string(path) {
        Ok(text) => {
            let trajectory = Trajectory::parse_tum(&text, path)?;
            Ok(if trajectory.is_empty() { None } else { Some(trajectory) })
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(source) => Err(DatasetError::Io { path: path.to_owned(), source }),
    }
}

/// The lists a dataset folder must hold.
const LISTS: [&str; 2] = ["rgb.txt", "depth.txt"];

/// Checks that `dir` is a folder holding both lists, so that a wrong path is said as such
/// rather than as the first file that cannot be read in it.
pub(super) fn check_folder(dir: &Path) -> Result<(), DatasetError> {
    match std::fs::metadata(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(DatasetError::NoFolder { dir: dir.to_owned() });
        }
        Err(source) => return Err(DatasetError::Io { path: dir.to_owned(), source }),
        Ok(m) if !m.is_dir() => return Err(DatasetError::NotAFolder { dir: dir.to_owned() }),
        Ok(_) => {}
    }
    for list in LISTS {
        // Only a list that is not there at all is said so; an unreadable one is an I/O error
        // when it is read.
        if let Err(e) = std::fs::metadata(dir.join(list))
            && e.kind() == std::io::ErrorKind::NotFound
        {
            return Err(DatasetError::NoList { dir: dir.to_owned(), list });
        }
    }
    Ok(())
}
