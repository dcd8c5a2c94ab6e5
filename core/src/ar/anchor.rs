//! Anchors: virtual objects placed on a plane by a pixel of a frame ([`Anchor::place`]), drawn at
//! the pixel a camera pose projects them to ([`Anchor::pixel`]).

use nalgebra::{Point3, Vector3};

use super::planes::Plane;
use crate::geometry::{PinholeCamera, Pose};
use crate::image::DepthView;

/// Why [`Anchor::place`] placed nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum AnchorError {
    /// The pixel is outside the image or not finite.
    OutsideImage,
    /// The frame has no depth at the pixel: nothing says which surface is under it.
    NoDepth,
    /// No plane of the frame passes within [`Anchor::MAX_GAP_M`] of the point under the pixel.
    NoPlane,
    /// The pixel's ray meets the plane behind the camera (it cannot, for a plane the frame saw;
    /// kept for a caller's own planes).
    Behind,
    /// The scale is not finite and positive.
    InvalidScale,
    /// The frame was not tracked: its pose says nothing about where the pixel is.
    NotTracked,
    /// Every anchor slot holds another object (`capacity::MAX_ANCHORS`).
    Full,
    /// No object with that id is placed.
    UnknownObject,
}

impl AnchorError {
    /// A number naming the variant (1 up, in declaration order), for a fault message's detail.
    pub fn code(&self) -> u32 {
        match self {
            Self::OutsideImage => 1,
            Self::NoDepth => 2,
            Self::NoPlane => 3,
            Self::Behind => 4,
            Self::InvalidScale => 5,
            Self::NotTracked => 6,
            Self::Full => 7,
            Self::UnknownObject => 8,
        }
    }
}

/// A virtual object on a plane: its position, the plane's normal (its up) in the world frame, and
/// its scale.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Anchor {
    /// The caller's object id.
    pub object: u16,
    /// Where it stands, in the world frame, metres.
    pub p_w: [f32; 3],
    /// The plane's unit normal in the world frame: the object's up.
    pub up_w: [f32; 3],
    /// Its scale (1: the object's own size).
    pub scale: f32,
}

impl Anchor {
    /// A plane is the one under a pixel when the point the pixel's depth gives is within this
    /// distance of it, metres (a few depth sigmas at 3 m; planes a box's height apart are told
    /// apart).
    pub const MAX_GAP_M: f32 = 0.05;

    /// The depth step [`Self::place`] reads the pixel's depth with: the plane detector's default
    /// (a reading across an edge is no surface).
    pub const MAX_RELATIVE_STEP: f32 = super::PlaneParams::DEFAULT.max_relative_step;

    /// Whether `scale` is one an anchor can have: finite and positive.
    pub fn is_valid_scale(scale: f32) -> bool {
        scale.is_finite() && scale > 0.0
    }

    /// Places `object` at `scale` where the ray of pixel `(u, v)` (the frame's pixel
    /// coordinates, centres at integers) meets the plane under it: of `planes` (the frame's, in
    /// its camera's frame, as `PlaneDetector::detect` gives them), the nearest to the point the
    /// frame's depth gives at that pixel, within [`Self::MAX_GAP_M`]. `t_wc` is the frame's
    /// camera-to-world pose. The ray, not the depth, gives the point: a plane fitted on
    /// thousands of samples is better than one reading.
    ///
    /// # Errors
    /// [`AnchorError`]: nothing is placed.
    #[allow(clippy::too_many_arguments)]
    pub fn place(
        object: u16,
        scale: f32,
        (u, v): (f32, f32),
        depth: &DepthView<'_>,
        cam: &PinholeCamera,
        t_wc: &Pose,
        planes: &[Plane],
    ) -> Result<Self, AnchorError> {
        if !Self::is_valid_scale(scale) {
            return Err(AnchorError::InvalidScale);
        }
        if !cam.in_image(&nalgebra::Point2::new(u, v), 0.0) {
            return Err(AnchorError::OutsideImage);
        }
        let z = depth.depth_at(u, v, Self::MAX_RELATIVE_STEP).ok_or(AnchorError::NoDepth)?;
        let seen = cam.back_project(u, v, z);
        let plane = planes
            .iter()
            .map(|p| (p, p.distance(&seen).abs()))
            .filter(|(_, gap)| *gap <= Self::MAX_GAP_M)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(p, _)| p)
            .ok_or(AnchorError::NoPlane)?;
        let ray = cam.back_project(u, v, 1.0).coords;
        let n = plane.normal();
        let along = n.dot(&ray);
        let t = -plane.offset_m / along;
        if !(t.is_finite() && t > 0.0) {
            return Err(AnchorError::Behind);
        }
        let p_w = t_wc * Point3::from(ray * t);
        let up_w: Vector3<f32> = t_wc.rotation * n;
        Ok(Self { object, p_w: p_w.coords.into(), up_w: up_w.into(), scale })
    }

    /// The pixel a camera at `t_wc` draws the anchor at, `None` when it is behind the camera.
    /// (Inside the image or not: the caller clips.)
    pub fn pixel(&self, t_wc: &Pose, cam: &PinholeCamera) -> Option<[f32; 2]> {
        let p_c = t_wc.inverse_transform_point(&Point3::from(self.p_w));
        cam.project(&p_c).map(|uv| [uv.x, uv.y])
    }
}
