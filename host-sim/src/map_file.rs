//! Saved map files ([`ferroslam_core::persist`]) on the host: read and checked whole, as
//! `PlaceMemory::load` checks them (header, length, record count, checksum, every record), then
//! summarized ([`MapSummary`], what `ferroslam-sim map info` prints) or written out as an ASCII
//! PLY point cloud ([`MapFile::write_ply`], what `map export --ply` writes).

use std::fmt;
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};

use ferroslam_core::ar::{SavedWorld, WORLD_UNITS};
use ferroslam_core::config::capacity::{BOARD_STORE_KEYFRAMES, PLACE_RECORD_BYTES};
use ferroslam_core::loops::INDEXED_RECORDS;
use ferroslam_core::map::{PlaceRecord, RecordBytes, RecordError};
use ferroslam_core::persist::{
    MAP_HEADER_BYTES, MAP_LAYOUT, MAP_VERSION, MapFileError, MapHeader, RecordLayout,
    RecordsChecksum, check_map_file, map_records, map_world,
};

/// Records a map file may hold: what the host's place memory (a store of
/// [`BOARD_STORE_KEYFRAMES`] slots, as the board's, [`WORLD_UNITS`] of them kept for the planes
/// and anchors) takes on `replay --load-map`.
pub const MAX_MAP_RECORDS: usize =
    if BOARD_STORE_KEYFRAMES < INDEXED_RECORDS { BOARD_STORE_KEYFRAMES } else { INDEXED_RECORDS }
        - WORLD_UNITS;

/// Colour of the verification points in an exported PLY (red, green, blue): light grey.
pub const PLY_POINT_RGB: [u8; 3] = [170, 170, 170];

/// Colour of the keyframes' camera positions in an exported PLY: red.
pub const PLY_CAMERA_RGB: [u8; 3] = [255, 40, 40];

/// Colour of the saved planes' centroids in an exported PLY: blue.
pub const PLY_PLANE_RGB: [u8; 3] = [40, 110, 255];

/// Colour of the saved anchors (the placed objects' positions) in an exported PLY: green.
pub const PLY_ANCHOR_RGB: [u8; 3] = [40, 200, 60];

/// What is wrong with a map file's bytes; the file is refused whole.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MapFault {
    /// The header, the length, the record count or the checksum (the core's error).
    #[error(transparent)]
    File(#[from] MapFileError),
    /// A record does not decode although the checksum over the records matches.
    #[error("record {index} does not decode: {source}")]
    Record {
        /// Its index in the file, from 0.
        index: u32,
        /// Why (the core's).
        source: RecordError,
    },
}

/// Why a map file could not be read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MapReadError {
    /// The file could not be opened or read.
    #[error("cannot read the map {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: io::Error,
    },
    /// The file is not a map this build reads, or is damaged.
    #[error("map {}: {source}", path.display())]
    Damaged {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        source: MapFault,
    },
}

/// A map file, checked whole: its header and its records, in file order.
#[derive(Debug, Clone)]
pub struct MapFile {
    /// The header.
    pub header: MapHeader,
    /// Bytes of the file.
    pub file_bytes: usize,
    /// The format version it was written in.
    pub version: u8,
    /// The records (remembered keyframes), decoded.
    pub records: Vec<PlaceRecord>,
    /// The planes and anchors after them (`None`: a file without them, as version 2 wrote).
    pub world: Option<SavedWorld>,
    /// The world units' bytes, as read (written back by [`Self::to_bytes`]).
    world_units: Vec<u8>,
}

impl MapFile {
    /// The map file at `path`. A file whose first bytes are not a map header is refused before
    /// the rest is read.
    ///
    /// # Errors
    /// [`MapReadError::Io`] when the file cannot be read; [`MapReadError::Damaged`] (what is
    /// wrong, as [`MapFile::from_bytes`]) otherwise.
    pub fn read(path: &Path) -> Result<Self, MapReadError> {
        let io = |source| MapReadError::Io { path: path.to_owned(), source };
        let damaged = |source| MapReadError::Damaged { path: path.to_owned(), source };
        let mut file = std::fs::File::open(path).map_err(io)?;
        let mut bytes = Vec::new();
        (&mut file).take(MAP_HEADER_BYTES as u64).read_to_end(&mut bytes).map_err(io)?;
        MapHeader::decode(&bytes).map_err(|e| damaged(e.into()))?;
        file.read_to_end(&mut bytes).map_err(io)?;
        Self::from_bytes(&bytes).map_err(damaged)
    }

    /// The map file whose bytes are `bytes`, checked as `PlaceMemory::load` checks it
    /// ([`check_map_file`]: the header, the length, at most [`MAX_MAP_RECORDS`] records, the
    /// checksum over the records, then every record).
    ///
    /// # Errors
    /// The first check that fails.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, MapFault> {
        let decode = |chunk: &[u8]| {
            let mut buf: RecordBytes = [0; PLACE_RECORD_BYTES];
            buf.copy_from_slice(chunk);
            PlaceRecord::decode(&buf)
        };
        let header = match check_map_file(bytes, MAX_MAP_RECORDS) {
            Ok(h) => h,
            Err(MapFileError::Record { index }) => {
                // The core names the record; its reason is the record decoder's.
                let chunk = map_records(bytes).nth(index as usize).unwrap_or(&[]);
                let source = decode(chunk).err().unwrap_or(RecordError::Corrupt);
                return Err(MapFault::Record { index, source });
            }
            Err(e) => return Err(e.into()),
        };
        let records = map_records(bytes)
            .zip(0u32..)
            .map(|(chunk, index)| {
                decode(chunk).map_err(|source| MapFault::Record { index, source })
            })
            .collect::<Result<_, _>>()?;
        let world = map_world(bytes)?;
        let records_end = MAP_HEADER_BYTES + header.records as usize * PLACE_RECORD_BYTES;
        let world_units = bytes.get(records_end..);
        let world_units = world_units.filter(|_| world.is_some()).unwrap_or(&[]).to_vec();
        let version = bytes.get(4).copied().unwrap_or(MAP_VERSION);
        Ok(Self { header, file_bytes: bytes.len(), version, records, world, world_units })
    }

    /// The file's bytes: the header, then the records in order, then the world units (what
    /// `PlaceMemory::save` writes for a memory holding these records and this world), in the
    /// format this build writes.
    pub fn to_bytes(&self) -> Vec<u8> {
        encode_map_file_with(&self.records, &self.world_units)
    }

    /// What the file holds, in figures.
    pub fn summary(&self) -> MapSummary {
        let mut counts: Vec<usize> = self.records.iter().map(|r| r.points.len()).collect();
        counts.sort_unstable();
        let points = PointCounts::of_sorted(&counts);
        let mut timestamps_s: Option<(f64, f64)> = None;
        let mut extent_m: Option<Extent> = None;
        for r in &self.records {
            let t = r.timestamp_s;
            timestamps_s = Some(timestamps_s.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
            let p: [f32; 3] = r.t_wc.translation.vector.into();
            extent_m = Some(extent_m.map_or(Extent { min: p, max: p }, |e| e.grown(p)));
        }
        MapSummary {
            version: self.version,
            planes: self.world.as_ref().map(|w| w.planes().len()),
            anchors: self.world.as_ref().map(|w| w.anchors().len()),
            file_bytes: self.file_bytes,
            layout: MAP_LAYOUT,
            keyframes: self.records.len(),
            checksum: self.header.checksum,
            points,
            timestamps_s,
            extent_m,
        }
    }

    /// Writes the map as an ASCII PLY point cloud (any viewer opens it: MeshLab, CloudCompare):
    /// every record's verification points in the world frame (`t_wc * p_c`, metres), coloured
    /// [`PLY_POINT_RGB`], then each keyframe's camera position (the translation of `t_wc`),
    /// coloured [`PLY_CAMERA_RGB`], then each saved plane's centroid ([`PLY_PLANE_RGB`]) and each
    /// saved anchor's position ([`PLY_ANCHOR_RGB`]); the header's comments say which is which. A
    /// vertex with a non-finite coordinate (a record whose rotation is far from a unit
    /// quaternion) is left out and counted.
    ///
    /// # Errors
    /// A failed write.
    pub fn write_ply(&self, out: impl Write) -> io::Result<PlyCounts> {
        let world_points = self
            .records
            .iter()
            .flat_map(|r| r.points.iter().map(|p| <[f32; 3]>::from((r.t_wc * p.p_c).coords)));
        let cameras = self.records.iter().map(|r| <[f32; 3]>::from(r.t_wc.translation.vector));
        let world = self.world.as_ref();
        let planes = world.into_iter().flat_map(|w| w.planes().iter().map(|m| m.plane.centroid));
        let anchors = world.into_iter().flat_map(|w| w.anchors().iter().map(|a| a.p_w));
        let (points, points_all) = finite_only(world_points);
        let (cameras, cameras_all) = finite_only(cameras);
        // Saved planes and anchors are finite (the loader checks them).
        let (planes, anchors): (Vec<_>, Vec<_>) = (planes.collect(), anchors.collect());
        let counts = PlyCounts {
            points: points.len(),
            cameras: cameras.len(),
            planes: planes.len(),
            anchors: anchors.len(),
            skipped: points_all - points.len() + cameras_all - cameras.len(),
        };
        let mut out = io::BufWriter::new(out);
        let rgb = |[r, g, b]: [u8; 3]| format!("{r} {g} {b}");
        writeln!(out, "ply\nformat ascii 1.0")?;
        writeln!(
            out,
            "comment ferroslam map (format version {}): {} keyframes",
            self.version,
            self.records.len()
        )?;
        writeln!(out, "comment world frame, metres; points are t_wc * p_c of each keyframe")?;
        writeln!(
            out,
            "comment {} verification points coloured {} (grey), then {} keyframe camera \
             positions coloured {} (red), then {} plane centroids coloured {} (blue), then {} \
             anchors coloured {} (green)",
            counts.points,
            rgb(PLY_POINT_RGB),
            counts.cameras,
            rgb(PLY_CAMERA_RGB),
            counts.planes,
            rgb(PLY_PLANE_RGB),
            counts.anchors,
            rgb(PLY_ANCHOR_RGB)
        )?;
        writeln!(out, "element vertex {}", counts.vertices())?;
        for axis in ["x", "y", "z"] {
            writeln!(out, "property float {axis}")?;
        }
        for channel in ["red", "green", "blue"] {
            writeln!(out, "property uchar {channel}")?;
        }
        writeln!(out, "end_header")?;
        let lists = [
            (&points, PLY_POINT_RGB),
            (&cameras, PLY_CAMERA_RGB),
            (&planes, PLY_PLANE_RGB),
            (&anchors, PLY_ANCHOR_RGB),
        ];
        for (list, colour) in lists {
            for [x, y, z] in list {
                writeln!(out, "{x:.4} {y:.4} {z:.4} {}", rgb(colour))?;
            }
        }
        out.flush()?;
        Ok(counts)
    }
}

/// The map file of `records` without planes or anchors, in this order: the header (record count,
/// checksum), then each record's bytes ([`PlaceRecord::encode`]).
pub fn encode_map_file(records: &[PlaceRecord]) -> Vec<u8> {
    encode_map_file_with(records, &[])
}

/// The map file of `records`, then `world_units` (the bytes of [`WORLD_UNITS`] world units, or
/// none).
fn encode_map_file_with(records: &[PlaceRecord], world_units: &[u8]) -> Vec<u8> {
    let mut body = Vec::with_capacity(records.len() * PLACE_RECORD_BYTES + world_units.len());
    let mut buf: RecordBytes = [0; PLACE_RECORD_BYTES];
    for r in records {
        r.encode(&mut buf);
        body.extend_from_slice(&buf);
    }
    body.extend_from_slice(world_units);
    let mut checksum = RecordsChecksum::default();
    checksum.add(&body);
    let header = MapHeader {
        records: u32::try_from(records.len()).unwrap_or(u32::MAX),
        world_units: (world_units.len() / PLACE_RECORD_BYTES) as u8,
        checksum: checksum.value(),
    };
    let mut file = header.encode().to_vec();
    file.extend_from_slice(&body);
    file
}

/// The points of `all` whose coordinates are finite, and how many points there were.
fn finite_only(all: impl Iterator<Item = [f32; 3]>) -> (Vec<[f32; 3]>, usize) {
    let mut seen = 0;
    let kept = all.inspect(|_| seen += 1).filter(|p| p.iter().all(|v| v.is_finite())).collect();
    (kept, seen)
}

/// Vertices of an exported PLY.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlyCounts {
    /// Verification points written.
    pub points: usize,
    /// Keyframe camera positions written.
    pub cameras: usize,
    /// Saved planes' centroids written.
    pub planes: usize,
    /// Saved anchors written.
    pub anchors: usize,
    /// Vertices left out for a non-finite coordinate.
    pub skipped: usize,
}

impl PlyCounts {
    /// Vertices written.
    pub fn vertices(&self) -> usize {
        self.points + self.cameras + self.planes + self.anchors
    }
}

/// Verification points of a map: the total and their count per keyframe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointCounts {
    /// Points over all keyframes.
    pub total: usize,
    /// Fewest in one keyframe.
    pub min: usize,
    /// Median per keyframe (the mean of the two middle counts when there are an even number).
    pub median: f64,
    /// Most in one keyframe.
    pub max: usize,
}

impl PointCounts {
    /// The counts of `sorted` (per keyframe, ascending); `None` when it is empty.
    fn of_sorted(sorted: &[usize]) -> Option<Self> {
        let (&min, &max) = (sorted.first()?, sorted.last()?);
        let n = sorted.len();
        // The same element when `n` is odd.
        let lower = sorted.get((n - 1) / 2).copied().unwrap_or(min);
        let upper = sorted.get(n / 2).copied().unwrap_or(max);
        let median = (lower + upper) as f64 / 2.0;
        Some(Self { total: sorted.iter().sum(), min, median, max })
    }
}

/// An axis-aligned box, metres, world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extent {
    /// Smallest x, y, z.
    pub min: [f32; 3],
    /// Largest x, y, z.
    pub max: [f32; 3],
}

impl Extent {
    /// The box grown to hold `p`.
    fn grown(self, p: [f32; 3]) -> Self {
        let mut e = self;
        for ((lo, hi), v) in e.min.iter_mut().zip(e.max.iter_mut()).zip(p) {
            *lo = lo.min(v);
            *hi = hi.max(v);
        }
        e
    }

    /// Its size along x, y, z.
    pub fn size(&self) -> [f32; 3] {
        let [a, b, c] = self.min;
        let [x, y, z] = self.max;
        [x - a, y - b, z - c]
    }
}

/// What a map file holds, in figures ([`MapFile::summary`]); its `Display` is what
/// `ferroslam-sim map info` prints.
#[derive(Debug, Clone, PartialEq)]
pub struct MapSummary {
    /// The format version.
    pub version: u8,
    /// Bytes of the file.
    pub file_bytes: usize,
    /// The record layout (bytes, points and key size per record).
    pub layout: RecordLayout,
    /// Records: remembered keyframes.
    pub keyframes: usize,
    /// Planes saved with the map (`None`: the file holds no planes or anchors).
    pub planes: Option<usize>,
    /// Anchors saved with the map (`None` as for `planes`).
    pub anchors: Option<usize>,
    /// The header's FNV-1a checksum of the records and world units (checked against them).
    pub checksum: u32,
    /// Verification points; `None` for a map of no keyframes.
    pub points: Option<PointCounts>,
    /// Earliest and latest keyframe timestamps, seconds.
    pub timestamps_s: Option<(f64, f64)>,
    /// The box around the keyframes' camera positions (metres, world frame).
    pub extent_m: Option<Extent>,
}

impl fmt::Display for MapSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "format: version {}, {MAP_HEADER_BYTES}-byte header, {}",
            self.version, self.layout
        )?;
        writeln!(f, "file: {} bytes", self.file_bytes)?;
        writeln!(
            f,
            "checksum: {:#010x} (FNV-1a of the records and world: matches)",
            self.checksum
        )?;
        writeln!(f, "keyframes: {}", self.keyframes)?;
        match &self.points {
            Some(p) => writeln!(
                f,
                "verification points: {} (per keyframe: min {}, median {}, max {})",
                p.total, p.min, p.median, p.max
            )?,
            None => writeln!(f, "verification points: 0")?,
        }
        writeln!(f, "segments: not stored in this format")?;
        match (self.planes, self.anchors) {
            (Some(p), Some(a)) => writeln!(f, "planes: {p}, anchors: {a}")?,
            _ => writeln!(f, "planes and anchors: not in this file")?,
        }
        match self.timestamps_s {
            Some((a, b)) => writeln!(f, "timestamps: {a:.6} s to {b:.6} s ({:.3} s)", b - a)?,
            None => writeln!(f, "timestamps: none")?,
        }
        match &self.extent_m {
            Some(e) => {
                let ([x0, y0, z0], [x1, y1, z1]) = (e.min, e.max);
                let [sx, sy, sz] = e.size();
                write!(
                    f,
                    "keyframe positions (world frame, m): x {x0:.3} to {x1:.3}, y {y0:.3} to \
                     {y1:.3}, z {z0:.3} to {z1:.3} (extent {sx:.3} x {sy:.3} x {sz:.3})"
                )
            }
            None => write!(f, "keyframe positions: none"),
        }
    }
}

#[cfg(test)]
mod tests;
