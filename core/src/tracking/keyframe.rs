//! The front end's reference keyframe: a copy of its gray image, its pose and the landmarks
//! back-projected from its depth-carrying features.

use heapless::Vec;
use nalgebra::Point3;

use crate::features::FeatureVec;
use crate::frame::RgbdFrame;
use crate::geometry::{PinholeCamera, Pose};
use crate::image::{DepthView, GrayView, ImageError};

/// Most landmarks one keyframe holds (one per detected feature at most).
pub const MAX_KEYFRAME_LANDMARKS: usize = crate::config::capacity::MAX_FEATURES_PER_FRAME;

/// A 3D point created from a keyframe feature with valid depth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KeyframeLandmark {
    /// Position in the world frame, metres.
    pub p_w: Point3<f32>,
    /// Where the keyframe saw it, pixels (pixel-centre convention).
    pub uv_kf: (f32, f32),
    /// Its depth in the keyframe, metres.
    pub depth_kf_m: f32,
}

/// Which features may become landmarks.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LandmarkFilter {
    /// Nearest accepted depth, metres.
    pub depth_min_m: f32,
    /// Farthest accepted depth, metres.
    pub depth_max_m: f32,
    /// A feature is dropped when a neighbour `discontinuity_radius_px` away (4-neighbourhood)
    /// has no depth or differs by more than this fraction of its depth (an occlusion edge).
    pub max_relative_depth_step: f32,
    /// Distance of the neighbours checked for discontinuities, pixels.
    pub discontinuity_radius_px: usize,
    /// Features closer than this to the image border are dropped (the matching template must fit).
    pub border_px: f32,
    /// Landmarks kept at most (features are taken in the detector's bucketed order, so a prefix
    /// still spreads over the image).
    pub max_landmarks: usize,
}

/// The reference keyframe, with its gray image stored in a `W` x `H` buffer.
///
/// Size: `W * H` bytes of image plus `MAX_KEYFRAME_LANDMARKS * 24` bytes of landmarks, a pose and
/// the image size: 89,144 bytes for QVGA (320 x 240), 319,544 bytes for VGA on a 64-bit host
/// (unit-tested; a few bytes less on 32-bit targets).
#[derive(Debug, Clone)]
pub struct Keyframe<const W: usize, const H: usize> {
    image: [[u8; W]; H],
    width: usize,
    height: usize,
    t_wc: Pose,
    landmarks: Vec<KeyframeLandmark, MAX_KEYFRAME_LANDMARKS>,
}

impl<const W: usize, const H: usize> Default for Keyframe<W, H> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const W: usize, const H: usize> Keyframe<W, H> {
    /// An empty keyframe (no image, no landmarks, identity pose); `const` for `static` use.
    pub const fn new() -> Self {
        Self {
            image: [[0; W]; H],
            width: 0,
            height: 0,
            t_wc: Pose::from_parts(
                nalgebra::Translation3::new(0.0, 0.0, 0.0),
                nalgebra::UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(
                    1.0, 0.0, 0.0, 0.0,
                )),
            ),
            landmarks: Vec::new(),
        }
    }

    /// The keyframe's camera-to-world pose.
    pub fn t_wc(&self) -> &Pose {
        &self.t_wc
    }

    /// Its landmarks.
    pub fn landmarks(&self) -> &[KeyframeLandmark] {
        &self.landmarks
    }

    /// A view of the stored gray image (`None` before the first [`Self::rebuild`]).
    pub fn image(&self) -> Option<GrayView<'_>> {
        GrayView::new(self.image.as_flattened(), self.width, self.height, W).ok()
    }

    /// Replaces this keyframe by `frame` at `t_wc` with the landmarks of `features` that pass
    /// `filter`, when at least `min_landmarks` do; otherwise leaves it unchanged. Returns the
    /// number of landmarks the frame offers.
    ///
    /// # Errors
    /// [`ImageError::ZeroSize`] when the frame is larger than `W` x `H` (the caller checks sizes
    /// first, so this is a guard, not an expected path).
    pub fn rebuild(
        &mut self,
        frame: &RgbdFrame<'_>,
        cam: &PinholeCamera,
        t_wc: &Pose,
        features: &FeatureVec,
        filter: &LandmarkFilter,
        min_landmarks: usize,
    ) -> Result<usize, ImageError> {
        let (width, height) = frame.gray.size();
        if width > W || height > H {
            return Err(ImageError::ZeroSize);
        }
        let accepted = |f: &&crate::features::Feature| landmark_depth(frame, cam, f, filter);
        let offered = features.iter().filter(|f| accepted(f).is_some()).count();
        let offered = offered.min(filter.max_landmarks).min(MAX_KEYFRAME_LANDMARKS);
        if offered < min_landmarks {
            return Ok(offered);
        }
        for (dst, src) in self.image.iter_mut().zip(frame.gray.rows()) {
            if let (Some(d), Some(s)) = (dst.get_mut(..width), src.get(..width)) {
                d.copy_from_slice(s);
            }
        }
        (self.width, self.height, self.t_wc) = (width, height, *t_wc);
        self.landmarks.clear();
        for f in features {
            if self.landmarks.len() >= offered {
                break;
            }
            let Some(z) = landmark_depth(frame, cam, f, filter) else { continue };
            let p_w = t_wc * cam.back_project(f.x, f.y, z);
            let lm = KeyframeLandmark { p_w, uv_kf: (f.x, f.y), depth_kf_m: z };
            // Cannot fail: `offered <= MAX_KEYFRAME_LANDMARKS`.
            if self.landmarks.push(lm).is_err() {
                break;
            }
        }
        Ok(self.landmarks.len())
    }
}

/// The depth of feature `f` if it may become a landmark: inside the border, depth in range and
/// no depth discontinuity around it.
fn landmark_depth(
    frame: &RgbdFrame<'_>,
    cam: &PinholeCamera,
    f: &crate::features::Feature,
    filter: &LandmarkFilter,
) -> Option<f32> {
    if !cam.in_image(&nalgebra::Point2::new(f.x, f.y), filter.border_px) {
        return None;
    }
    let (x, y) = (libm::roundf(f.x) as usize, libm::roundf(f.y) as usize);
    let z = depth_in_range(&frame.depth, x, y, filter.depth_min_m, filter.depth_max_m)?;
    let r = filter.discontinuity_radius_px;
    let neighbours = [(x + r, y), (x.wrapping_sub(r), y), (x, y + r), (x, y.wrapping_sub(r))];
    for (nx, ny) in neighbours {
        let zn = frame.depth.depth_m(nx, ny)?;
        if (zn - z).abs() > filter.max_relative_depth_step * z {
            return None;
        }
    }
    Some(z)
}

/// The depth at `(x, y)` when it is a reading within `[min_m, max_m]`.
pub(crate) fn depth_in_range(
    depth: &DepthView<'_>,
    x: usize,
    y: usize,
    min_m: f32,
    max_m: f32,
) -> Option<f32> {
    depth.depth_m(x, y).filter(|&z| z >= min_m && z <= max_m)
}
