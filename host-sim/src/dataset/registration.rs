//! Registering depth to colour: a depth image taken by a camera beside the colour camera (see
//! [`DepthCamera`]) redrawn as the colour camera would have measured it, so that the depth at a
//! colour pixel is the depth of what that pixel sees.
//!
//! Why it matters: the core back-projects a tracked colour pixel with the depth at the same pixel.
//! With the raw output of a Kinect v1 (Microsoft 7-Scenes), the depth camera has a longer focal
//! length than the colour camera (585 vs about 526 pixels) and sits about 3 cm to the side, so the
//! depth sample at a colour pixel belongs to a scene point up to 30 pixels away at the image edge
//! (the focal-length ratio) and several pixels away at the centre (the offset's parallax). A
//! sensor that registers in hardware, as the board's camera is meant to, delivers what this
//! module computes.
//!
//! Method: a forward warp. Every valid depth pixel is back-projected with the depth camera's
//! intrinsics, moved into the colour camera's frame, projected with the colour intrinsics and
//! rounded to the nearest colour pixel, which keeps the nearest depth landing on it (a z-buffer:
//! the nearer surface occludes the farther one). The depth written is the point's depth along the
//! colour camera's axis, in the same raw units. Colour pixels no depth sample lands on (the
//! occlusion shadow beside a foreground edge, the border the depth camera does not see) get 0,
//! "no reading", which the pipeline already handles. Deterministic: plain `f64` arithmetic in a
//! fixed order.

use super::calibration::{Calibration, DepthCamera};

/// `raw` (row-major, `colour.width` x `colour.height` depth samples in raw units, 0 = no reading)
/// taken by `depth`, registered to the colour camera `colour` (see the module documentation).
/// The result has the same size and units. A `raw` of another length gives an all-zero image
/// (the decoder checks sizes before this is called).
pub fn register_depth(raw: &[u16], colour: &Calibration, depth: &DepthCamera) -> Vec<u16> {
    let (w, h) = (colour.width as usize, colour.height as usize);
    let mut out = vec![0u16; w * h];
    if raw.len() != w * h {
        return out;
    }
    let scale = f64::from(colour.depth_scale);
    let [tx, ty, tz] = depth.t_m.map(f64::from);
    let (dfx, dfy, dcx, dcy) =
        (f64::from(depth.fx), f64::from(depth.fy), f64::from(depth.cx), f64::from(depth.cy));
    let (fx, fy, cx, cy) =
        (f64::from(colour.fx), f64::from(colour.fy), f64::from(colour.cx), f64::from(colour.cy));
    for (v, row) in raw.chunks_exact(w).enumerate() {
        for (u, &d) in row.iter().enumerate() {
            if d == 0 {
                continue;
            }
            let z = f64::from(d) / scale;
            let x = (u as f64 - dcx) * z / dfx + tx;
            let y = (v as f64 - dcy) * z / dfy + ty;
            let z = z + tz;
            if z <= 0.0 {
                continue;
            }
            let uc = (cx + fx * x / z + 0.5).floor();
            let vc = (cy + fy * y / z + 0.5).floor();
            let zq = (z * scale + 0.5).floor();
            let inside = (0.0..w as f64).contains(&uc) && (0.0..h as f64).contains(&vc);
            if !inside || !(1.0..=f64::from(u16::MAX)).contains(&zq) {
                continue;
            }
            // In range, so the casts are exact.
            let i = vc as usize * w + uc as usize;
            let zq = zq as u16;
            if let Some(o) = out.get_mut(i)
                && (*o == 0 || zq < *o)
            {
                *o = zq;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn colour(w: u32, h: u32) -> Calibration {
        Calibration {
            fx: 100.0,
            fy: 100.0,
            cx: (w as f32 - 1.0) / 2.0,
            cy: (h as f32 - 1.0) / 2.0,
            width: w,
            height: h,
            depth_scale: 1000.0,
            depth: None,
            distortion: crate::dataset::Distortion::NONE,
            depth_noise_coeff_per_m: None,
        }
    }

    #[test]
    fn identical_cameras_change_nothing() {
        let c = colour(8, 6);
        let d = DepthCamera { fx: c.fx, fy: c.fy, cx: c.cx, cy: c.cy, t_m: [0.0; 3] };
        let raw: Vec<u16> = (0..48).map(|i| if i % 7 == 0 { 0 } else { 1000 + i }).collect();
        assert_eq!(register_depth(&raw, &c, &d), raw);
    }

    #[test]
    fn an_offset_shifts_by_the_parallax_and_the_nearer_surface_wins() {
        // A depth camera 0.1 m to the left of the colour camera (a point at x in the depth frame
        // is at x - 0.1 in the colour frame): at 2 m a sample moves f * 0.1 / 2 = 5 pixels left.
        let c = colour(20, 3);
        let d = DepthCamera { fx: c.fx, fy: c.fy, cx: c.cx, cy: c.cy, t_m: [-0.1, 0.0, 0.0] };
        let mut raw = vec![0u16; 60];
        raw[20 + 12] = 2000;
        // At 1 m the same offset is 10 pixels: column 17 lands on column 7, where the 2 m sample
        // also lands; the nearer one (1 m) is kept.
        raw[20 + 17] = 1000;
        let out = register_depth(&raw, &c, &d);
        let nonzero: Vec<(usize, u16)> =
            out.iter().copied().enumerate().filter(|&(_, z)| z != 0).collect();
        assert_eq!(nonzero, vec![(20 + 7, 1000)]);
    }

    #[test]
    fn a_longer_depth_focal_length_pulls_samples_towards_the_centre() {
        // The depth camera sees a narrower field: its pixel 10 columns right of the centre is
        // 10 * 100 / 125 = 8 colour columns right of it.
        let c = colour(41, 1);
        let d = DepthCamera { fx: 125.0, fy: 125.0, cx: c.cx, cy: c.cy, t_m: [0.0, 0.0, 0.05] };
        let mut raw = vec![0u16; 41];
        raw[30] = 1500;
        let out = register_depth(&raw, &c, &d);
        // Also 5 cm along the axis: the colour camera sees the point at 1.55 m, 8 * 1.5 / 1.55
        // = 7.74 columns right of the centre, rounded to 8.
        assert_eq!(out[28], 1550);
        assert_eq!(out.iter().filter(|&&z| z != 0).count(), 1);
    }

    #[test]
    fn a_wrong_length_gives_no_depth() {
        let c = colour(4, 4);
        let d = DepthCamera { fx: 1.0, fy: 1.0, cx: 1.0, cy: 1.0, t_m: [0.0; 3] };
        assert_eq!(register_depth(&[1000; 3], &c, &d), vec![0; 16]);
    }
}
