//! The ground floor: every capacity, the profiles, the sensor's measurement model and the
//! defaults that more than one module reads. It imports nothing of the core.
//!
//! Capacities are compile-time constants because they size fixed arrays (`heapless::Vec<T, N>`,
//! `[T; N]`): nothing in the core grows at run time. A [`Profile`] names one set of them with
//! the resolution the pipeline runs at: [`Qvga`] is the reference board's (Cortex-M7F, 1 MB
//! SRAM), [`Vga`] the same map at full resolution, [`HostQvga`] and [`HostVga`] the host-scale
//! map. Tunables are run-time values: each algorithm's parameters (`FrontendParams`,
//! `BackendParams`, ...) keep their own defaults beside their fields; the values several of them
//! share are here.

/// Capacities that size the core's fixed arrays. Changing one changes RAM use: see
/// `memory-budget.md`, which CI checks. Why the map's are what they are: docs/decisions.md,
/// "Board RAM: depth level, map and BA capacities".
pub mod capacity {
    /// Widest image the core accepts, in pixels (the sensor's VGA width).
    pub const MAX_WIDTH: usize = 640;
    /// Tallest image the core accepts, in pixels (the sensor's VGA height).
    pub const MAX_HEIGHT: usize = 480;
    /// Features kept per frame after grid bucketing.
    pub const MAX_FEATURES_PER_FRAME: usize = 512;
    /// Observations one keyframe records at most (landmarks tracked into it plus new ones).
    pub const MAX_OBSERVATIONS_PER_KEYFRAME: usize = 128;
    /// Landmarks the tracker keeps a template for and tracks each frame (its local map).
    pub const MAX_TRACKED_LANDMARKS: usize = 256;
    /// Hard cap on the local bundle-adjustment window, in keyframes (the paper's 50-65 average).
    pub const LOCAL_WINDOW_MAX: usize = 65;
    /// Keyframes per segment of the segmented global bundle adjustment.
    pub const SEGMENT_MAX_KEYFRAMES: usize = 16;
    /// Keyframes the board's map holds at once, with their observations (the policy when it is
    /// full is in `map`).
    pub const MAX_KEYFRAMES: usize = super::BOARD_MAP.keyframes;
    /// Landmarks the board's map holds at once.
    pub const MAX_LANDMARKS: usize = super::BOARD_MAP.landmarks;
    /// Verification points a remembered keyframe keeps (3D point and descriptor each).
    pub const PLACE_POINTS: usize = 48;
    /// Width of a keyframe's place key, cells (a 16 x 12 thumbnail of the frame).
    pub const PLACE_KEY_W: usize = 16;
    /// Height of a keyframe's place key, cells.
    pub const PLACE_KEY_H: usize = 12;
    /// Bytes of one remembered keyframe in the long-term store (a fixed-size record).
    pub const PLACE_RECORD_BYTES: usize = 1024;
    /// Keyframes the board's long-term store holds: 500 records of 1 KiB, in
    /// [`BOARD_STORE_FLASH_BYTES`] of flash with the store's tables and spare units.
    pub const BOARD_STORE_KEYFRAMES: usize = 500;
    /// Bytes of flash the board's long-term store takes: 512 KiB (the persistence layer checks
    /// that its tables, the records and its spare units fill it).
    pub const BOARD_STORE_FLASH_BYTES: usize = 512 * 1024;
    /// Virtual objects placed at once (`ar::Anchors`).
    pub const MAX_ANCHORS: usize = 8;
}

/// The capacities of a map and of the back end that adjusts it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MapCapacity {
    /// Keyframes held at once.
    pub keyframes: usize,
    /// Landmarks held at once.
    pub landmarks: usize,
    /// Words of a bitset over the landmark slots: `landmarks / 32`, rounded up.
    pub landmark_words: usize,
    /// Rigs (pose variables) of the back end's bundle adjuster: a local window plus its fixed
    /// neighbours, or one per segment in a global adjustment.
    pub ba_rigs: usize,
    /// Points of the back end's bundle adjuster.
    pub ba_points: usize,
    /// Observations of the back end's bundle adjuster.
    pub ba_observations: usize,
}

impl MapCapacity {
    /// Segments of global bundle adjustment the map spans at most.
    pub const fn segments(&self) -> usize {
        self.keyframes.div_ceil(capacity::SEGMENT_MAX_KEYFRAMES)
    }
}

/// Fixed neighbours a local window can have besides its keyframes, at most.
const FIXED_NEIGHBOURS: usize = 31;

/// The board's map: 32 keyframes and 1,024 landmarks, sized for the RAM budget. Its adjuster
/// holds every keyframe of the map (a local window can therefore never reach
/// [`capacity::LOCAL_WINDOW_MAX`] on the board).
pub const BOARD_MAP: MapCapacity = MapCapacity {
    keyframes: 32,
    landmarks: 1024,
    landmark_words: 1024 / 32,
    ba_rigs: min(32, capacity::LOCAL_WINDOW_MAX + FIXED_NEIGHBOURS),
    ba_points: 1024,
    ba_observations: 6144,
};

/// The host-scale map: room for the paper's local window of 50-65 keyframes in a map of over 120
/// (about 1 MB of map and 380 KB of back end: host only). Its adjuster holds a full window plus
/// its fixed neighbours, with every observation of each.
pub const HOST_MAP: MapCapacity = MapCapacity {
    keyframes: 256,
    landmarks: 16_384,
    landmark_words: 16_384 / 32,
    ba_rigs: capacity::LOCAL_WINDOW_MAX + FIXED_NEIGHBOURS,
    ba_points: 4096,
    ba_observations: (capacity::LOCAL_WINDOW_MAX + FIXED_NEIGHBOURS)
        * capacity::MAX_OBSERVATIONS_PER_KEYFRAME,
};

const fn min(a: usize, b: usize) -> usize {
    if a < b { a } else { b }
}

/// The resolution the pipeline runs at, derived from the sensor's VGA frames by 2x downsampling.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Resolution {
    /// Short name used in reports (`"qvga"`, `"vga"`).
    pub name: &'static str,
    /// How many times the sensor frame is halved before processing (0 = full resolution).
    pub downsample_levels: u8,
    /// How many times more the depth is halved than the gray image, as the frame store keeps it
    /// (the `DepthView` level: one depth reading per `2^l` x `2^l` processing pixels, read in
    /// processing pixels).
    pub depth_level: u8,
}

impl Resolution {
    /// The processing width for a sensor frame `sensor_width` pixels wide.
    pub const fn width(&self, sensor_width: usize) -> usize {
        sensor_width >> self.downsample_levels
    }

    /// The processing height for a sensor frame `sensor_height` pixels tall.
    pub const fn height(&self, sensor_height: usize) -> usize {
        sensor_height >> self.downsample_levels
    }

    /// The widest processing frame: the sensor's [`capacity::MAX_WIDTH`] brought to it.
    pub const fn max_width(&self) -> usize {
        self.width(capacity::MAX_WIDTH)
    }

    /// The tallest processing frame.
    pub const fn max_height(&self) -> usize {
        self.height(capacity::MAX_HEIGHT)
    }
}

/// The reference board's resolution: 640x480 sensor frames halved once to 320x240, the depth
/// halved once more, to 160x120 (level 1): 38,400 bytes of depth instead of 153,600, which is
/// what lets the board's RAM budget hold a map. Why level 1: docs/decisions.md, "Board RAM:
/// depth level, map and BA capacities".
pub const QVGA: Resolution = Resolution { name: "qvga", downsample_levels: 1, depth_level: 1 };

/// The full resolution, for hosts with memory to spare (depth at full resolution too).
pub const VGA: Resolution = Resolution { name: "vga", downsample_levels: 0, depth_level: 0 };

/// The processing width the front end's pixel parameters (template and search sizes, distances
/// between features) are stated for: the reference board's QVGA.
pub const REFERENCE_WIDTH_PX: usize = 320;

/// The pyramid level the front end tracks on for frames `width` pixels wide: 1 (the frame halved
/// once) when halving brings the width nearer [`REFERENCE_WIDTH_PX`] than it is (in ratio: above
/// `sqrt 2` times it), else 0. A front end without room for the halved frame tracks on level 0.
/// Why: the templates the front end keeps are 16 x 16 pixels at any resolution, so tracking on
/// the level nearest the reference keeps what they cover of the scene; docs/decisions.md,
/// "Tracking on the pyramid level nearest the reference".
pub const fn tracking_level(width: usize) -> u8 {
    // width > sqrt(2) x 320, in integers: width^2 > 2 x 320^2.
    if width * width > 2 * REFERENCE_WIDTH_PX * REFERENCE_WIDTH_PX { 1 } else { 0 }
}

/// Pixels of the buffer a front end for frames up to `width` x `height` needs to track on its
/// level: the halved frame's when [`tracking_level`] is 1, else none.
pub const fn tracking_buffer_pixels(width: usize, height: usize) -> usize {
    if tracking_level(width) == 1 { (width / 2) * (height / 2) } else { 0 }
}

/// How much larger the front end's pixel parameters are at a tracking level `width` pixels wide
/// than at [`REFERENCE_WIDTH_PX`] (1 at QVGA, and at VGA tracked on level 1).
pub fn pixel_scale(width: usize) -> f32 {
    width as f32 / REFERENCE_WIDTH_PX as f32
}

/// A profile: the resolution the pipeline runs at and the capacities of its map, named once by
/// a type (`Slam<Qvga>`). The core's types for a profile are chosen from these values in
/// `system`.
pub trait Profile: 'static {
    /// The processing resolution.
    const RESOLUTION: Resolution;
    /// The map's and the back end's capacities.
    const MAP: MapCapacity;
}

/// The reference board: QVGA with the board's map ([`BOARD_MAP`]); what the firmware runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Qvga {}

/// Full resolution with the board's map.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Vga {}

/// QVGA with the host-scale map ([`HOST_MAP`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HostQvga {}

/// Full resolution with the host-scale map.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HostVga {}

impl Profile for Qvga {
    const RESOLUTION: Resolution = QVGA;
    const MAP: MapCapacity = BOARD_MAP;
}

impl Profile for Vga {
    const RESOLUTION: Resolution = VGA;
    const MAP: MapCapacity = BOARD_MAP;
}

impl Profile for HostQvga {
    const RESOLUTION: Resolution = QVGA;
    const MAP: MapCapacity = HOST_MAP;
}

impl Profile for HostVga {
    const RESOLUTION: Resolution = VGA;
    const MAP: MapCapacity = HOST_MAP;
}

/// A gray frame buffer at the QVGA resolution (320x240), owned by whoever holds the frame.
pub type QvgaGrayBuffer = [u8; QVGA.max_width() * QVGA.max_height()];
/// A raw depth frame buffer at the QVGA resolution: 160x120, one reading per 2x2 block of the
/// 320x240 gray image ([`QVGA`]`.depth_level` = 1).
pub type QvgaDepthBuffer =
    [u16; (QVGA.max_width() >> QVGA.depth_level) * (QVGA.max_height() >> QVGA.depth_level)];
/// A gray frame buffer at the VGA resolution (640x480).
pub type VgaGrayBuffer = [u8; capacity::MAX_WIDTH * capacity::MAX_HEIGHT];
/// A raw depth frame buffer at the VGA resolution (640x480).
pub type VgaDepthBuffer = [u16; capacity::MAX_WIDTH * capacity::MAX_HEIGHT];

/// The sensor's measurement model: how far a pixel position and a depth reading are trusted,
/// and which depths are read at all. Pose estimation and bundle adjustment both take it (each
/// residual is whitened by it), so the front end and the back end weigh the same data alike.
///
/// Depth of the Kinect class has `sigma_z = k z^2`; since `d(1/z) = dz / z^2`, inverse depth has
/// the constant standard deviation `k`, which is why the depth residuals are in inverse depth.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorModel {
    /// Standard deviation of a feature's pixel position, pixels. Reprojection residuals are
    /// divided by it. Default 1.
    pub pixel_sigma_px: f32,
    /// Huber threshold on the reprojection error, pixels; the depth term uses the same threshold
    /// in standard deviations (`huber_delta_px / pixel_sigma_px`). Default 2.4477 (`sqrt(5.991)`,
    /// the 95% chi-square quantile of 2 DOF).
    pub huber_delta_px: f32,
    /// The depth noise `k`, in 1/m: the standard deviation of inverse depth. Default 3e-3: a
    /// Kinect v1-class structured-light sensor (about 1.4e-3) with a margin for its quantization
    /// and for depth read a fraction of a pixel off the tracked point. A sensor with better depth
    /// should say so, or its depth is under-weighted against the pixels. The back end weighs a
    /// keyframe's depth with its own coefficient ([`BA_DEPTH_NOISE_COEFF_PER_M`]).
    pub depth_noise_coeff_per_m: f32,
    /// Depth readings nearer than this are not used, metres (Kinect-class sensors read from
    /// about 0.4 m). Default 0.3.
    pub depth_min_m: f32,
    /// Depth readings farther than this are not used, metres (structured-light noise grows with
    /// the square of depth; beyond about 4 m it dominates). Default 4.
    pub depth_max_m: f32,
}

/// The depth noise the back end's bundle adjustment weighs a keyframe's depth with, in 1/m,
/// whatever the sensor: 6e-4 (`sigma_z = k z^2`: 2.4 mm at 2 m). It checks each reading against
/// the landmark's other keyframes, so it can trust depth more than tracking does. Measured, not
/// derived: docs/decisions.md, "Bundle adjustment depth weight".
pub const BA_DEPTH_NOISE_COEFF_PER_M: f32 = 6.0e-4;

impl SensorModel {
    /// The defaults, documented per field (`const`, for a `static`).
    pub const DEFAULT: Self = Self {
        pixel_sigma_px: 1.0,
        huber_delta_px: 2.447_7,
        depth_noise_coeff_per_m: 3.0e-3,
        depth_min_m: 0.3,
        depth_max_m: 4.0,
    };

    /// Whether every value is finite and positive and the depth range not empty.
    pub fn is_valid(&self) -> bool {
        let pos = |x: f32| x.is_finite() && x > 0.0;
        pos(self.pixel_sigma_px)
            && pos(self.huber_delta_px)
            && pos(self.depth_noise_coeff_per_m)
            && pos(self.depth_min_m)
            && pos(self.depth_max_m)
            && self.depth_min_m < self.depth_max_m
    }
}

impl Default for SensorModel {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Back-end work units after each frame, in deterministic replay and on the board: every
/// back-end step stays under about 2 M Cortex-M4 instructions (see `memory-budget.md`). Why
/// this value: docs/decisions.md, "Back-end work quota per frame".
pub const DEFAULT_BACKEND_QUOTA: u32 = 2_500;

/// Back-end steps a run allows after its last frame, before its map is read or saved
/// (`Slam::drain_backend`: the work under way, then its newest keyframes settled): the host
/// replay's and the board's, so that both save the same map.
pub const DEFAULT_DRAIN_STEPS: u32 = 10_000;

/// Reads of a store's table or record before it is taken as damaged: a read that flipped a bit
/// (a read disturb) is transient, a damaged cell is not. Costs nothing on a good read.
pub const STORE_READ_TRIES: usize = 3;

/// Largest timestamp difference when associating colour, depth and ground truth, in seconds
/// (the TUM benchmark's and evo's 0.02 s).
pub const ASSOCIATION_MAX_DT_S: f64 = 0.02;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolutions_halve_the_sensor_frame() {
        assert_eq!((QVGA.width(640), QVGA.height(480)), (320, 240));
        assert_eq!((VGA.max_width(), VGA.max_height()), (640, 480));
        assert_eq!(core::mem::size_of::<QvgaGrayBuffer>(), 320 * 240);
        assert_eq!(core::mem::size_of::<QvgaDepthBuffer>(), 160 * 120 * 2);
    }

    #[test]
    fn the_tracking_level_is_the_one_nearest_the_reference() {
        assert_eq!([320, 424, 452, 453, 640, 848].map(tracking_level), [0, 0, 0, 1, 1, 1]);
        assert_eq!((pixel_scale(320), pixel_scale(424)), (1.0, 1.325));
    }

    #[test]
    fn map_capacities_agree() {
        for map in [BOARD_MAP, HOST_MAP] {
            assert!(map.landmark_words * 32 >= map.landmarks);
            assert!(map.ba_rigs <= map.keyframes && map.ba_rigs >= 1);
        }
        // The values the board's map had before they moved here.
        assert_eq!((BOARD_MAP.ba_rigs, BOARD_MAP.segments()), (32, 2));
        assert_eq!((HOST_MAP.ba_rigs, HOST_MAP.ba_observations), (96, 96 * 128));
    }

    #[test]
    fn the_default_sensor_is_valid_and_ordered() {
        let s = SensorModel::DEFAULT;
        assert!(s.is_valid());
        assert!(!SensorModel { depth_min_m: 5.0, ..s }.is_valid());
        assert!(!SensorModel { pixel_sigma_px: f32::NAN, ..s }.is_valid());
    }
}
