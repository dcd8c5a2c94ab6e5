//! Every capacity and tunable of the core, in one place.
//!
//! Capacities are compile-time constants because they size fixed arrays (`heapless::Vec<T, N>`,
//! `[T; N]`): nothing in the core grows at run time. Tunables are run-time values with defaults, so a
//! user can adjust thresholds without a rebuild. The two [`Profile`]s say at which resolution the
//! pipeline runs: [`QVGA`] on the reference board (Cortex-M7F, 1 MB SRAM), [`VGA`] on the host.

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
    /// Keyframes held in the map arena at once, with their observations (the policy when it is
    /// full is in [`crate::map`]).
    pub const MAX_KEYFRAMES: usize = 32;
    /// Landmarks held in the map arena at once.
    pub const MAX_LANDMARKS: usize = 1024;
    /// Observations one keyframe records at most (landmarks tracked into it plus new ones).
    pub const MAX_OBSERVATIONS_PER_KEYFRAME: usize = 128;
    /// Landmarks the tracker keeps a template for and tracks each frame (its local map).
    pub const MAX_TRACKED_LANDMARKS: usize = 256;
    /// Hard cap on the local bundle-adjustment window, in keyframes (the paper's 50-65 average).
    pub const LOCAL_WINDOW_MAX: usize = 65;
    /// Keyframes per segment of the segmented global bundle adjustment.
    pub const SEGMENT_MAX_KEYFRAMES: usize = 16;
    /// Segments held at once.
    pub const MAX_SEGMENTS: usize = MAX_KEYFRAMES / 4;
}

/// The resolution the pipeline runs at, derived from the sensor's VGA frames by 2x downsampling.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Profile {
    /// Short name used in reports (`"qvga"`, `"vga"`).
    pub name: &'static str,
    /// How many times the sensor frame is halved before processing (0 = full resolution).
    pub downsample_levels: u8,
    /// How many times more the depth is halved than the gray image, as the frame store keeps it
    /// (the [`DepthView`](crate::image::DepthView) level: one depth reading per `2^l` x `2^l`
    /// processing pixels, read in processing pixels).
    pub depth_level: u8,
}

impl Profile {
    /// The processing width for a sensor frame `sensor_width` pixels wide.
    pub const fn width(&self, sensor_width: usize) -> usize {
        sensor_width >> self.downsample_levels
    }

    /// The processing height for a sensor frame `sensor_height` pixels tall.
    pub const fn height(&self, sensor_height: usize) -> usize {
        sensor_height >> self.downsample_levels
    }
}

/// The reference board's profile: 640x480 sensor frames halved once to 320x240, the depth
/// halved once more, to 160x120 (level 1).
///
/// The coarser depth is what lets the board's RAM budget hold a map: it keeps 38,400 bytes of
/// depth instead of 153,600. Why: docs/decisions.md, "Board RAM: depth level, map and BA
/// capacities".
pub const QVGA: Profile = Profile { name: "qvga", downsample_levels: 1, depth_level: 1 };

/// The full-resolution profile for hosts with memory to spare (depth at full resolution too).
pub const VGA: Profile = Profile { name: "vga", downsample_levels: 0, depth_level: 0 };

/// A gray frame buffer at the QVGA profile (320x240), owned by whoever holds the frame.
pub type QvgaGrayBuffer = [u8; (capacity::MAX_WIDTH / 2) * (capacity::MAX_HEIGHT / 2)];
/// A raw depth frame buffer at the QVGA profile: 160x120, one reading per 2x2 block of the
/// 320x240 gray image ([`QVGA`]`.depth_level` = 1).
pub type QvgaDepthBuffer = [u16; (capacity::MAX_WIDTH
    >> (QVGA.downsample_levels + QVGA.depth_level))
    * (capacity::MAX_HEIGHT >> (QVGA.downsample_levels + QVGA.depth_level))];
/// A gray frame buffer at the VGA profile (640x480).
pub type VgaGrayBuffer = [u8; capacity::MAX_WIDTH * capacity::MAX_HEIGHT];
/// A raw depth frame buffer at the VGA profile (640x480).
pub type VgaDepthBuffer = [u16; capacity::MAX_WIDTH * capacity::MAX_HEIGHT];

/// Run-time thresholds of the pipeline.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Tunables {
    /// Depth readings nearer than this are discarded, in metres (Kinect-class sensors read ~0.4 m).
    pub depth_min_m: f32,
    /// Depth readings farther than this are discarded, in metres (structured-light noise grows with
    /// the square of depth; beyond ~4 m it dominates).
    pub depth_max_m: f32,
    /// Maximum timestamp difference when associating colour, depth and ground truth, in seconds
    /// (the TUM benchmark's and evo's 0.02 s).
    pub association_max_dt_s: f64,
    /// The depth sensor's noise as the standard deviation of inverse depth, in 1/m: a reading at
    /// `z` metres has `sigma_z = k z^2`. Pose estimation and bundle adjustment weigh their
    /// inverse-depth residuals by it ([`PoseParams::depth_noise_coeff_per_m`]). Default 3e-3,
    /// a Kinect v1-class structured-light sensor with a margin for its quantization and for
    /// depth read a fraction of a pixel off the tracked point; a sensor with better depth should
    /// say so, or its depth is under-weighted against the pixels.
    ///
    /// [`PoseParams::depth_noise_coeff_per_m`]: crate::tracking::PoseParams::depth_noise_coeff_per_m
    pub depth_noise_coeff_per_m: f32,
    /// The same coefficient as bundle adjustment weighs a keyframe's depth observation, in 1/m.
    /// Default [`BA_DEPTH_NOISE_COEFF_PER_M`], 6e-4 whatever the sensor (why it differs from the
    /// tracker's: docs/decisions.md, "Bundle adjustment depth weight").
    ///
    /// [`BA_DEPTH_NOISE_COEFF_PER_M`]: crate::backend::BA_DEPTH_NOISE_COEFF_PER_M
    pub ba_depth_noise_coeff_per_m: f32,
}

impl Default for Tunables {
    fn default() -> Self {
        Self {
            depth_min_m: 0.3,
            depth_max_m: 4.0,
            association_max_dt_s: 0.02,
            depth_noise_coeff_per_m: crate::tracking::PoseParams::DEFAULT.depth_noise_coeff_per_m,
            ba_depth_noise_coeff_per_m: crate::backend::BA_DEPTH_NOISE_COEFF_PER_M,
        }
    }
}

/// A complete configuration: the profile and the tunables.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Config {
    /// The processing resolution.
    pub profile: Profile,
    /// Run-time thresholds.
    pub tunables: Tunables,
}

impl Default for Config {
    /// The reference board's configuration: [`QVGA`] with default tunables.
    fn default() -> Self {
        Self { profile: QVGA, tunables: Tunables::default() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profiles_halve_the_sensor_frame() {
        assert_eq!((QVGA.width(640), QVGA.height(480)), (320, 240));
        assert_eq!((VGA.width(640), VGA.height(480)), (640, 480));
        assert_eq!(core::mem::size_of::<QvgaGrayBuffer>(), 320 * 240);
    }

    #[test]
    fn default_tunables_are_ordered() {
        let t = Tunables::default();
        assert!(t.depth_min_m > 0.0 && t.depth_min_m < t.depth_max_m);
    }
}
