//! Shared helpers for the workspace integration tests under `tests/tests/`, and the list of core
//! structures whose size `memory-budget.md` states ([`structures`], also read by `cargo xtask
//! budgets`).

pub mod structures;

use std::path::PathBuf;

/// The workspace root (the folder holding the top-level `Cargo.toml`).
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `../shared/datasets/NAME` beside the workspace, where CI and tests read real recordings.
pub fn shared_dataset(name: &str) -> PathBuf {
    workspace_root().join("..").join("shared").join("datasets").join(name)
}

pub mod demo_frames {
    //! The demo's room played in any order of its frames, at the board's resolution (test code:
    //! it panics on a bad index).
    #![allow(clippy::expect_used)]

    use ferroslam_core::config::QVGA;
    use ferroslam_core::frame::{FrameSource, RgbdFrame};
    use ferroslam_core::geometry::PinholeCamera;
    use ferroslam_sim::run::ProfileSource;
    use ferroslam_sim::synth::{SynthError, SynthFrame, SynthOptions, SyntheticSequence};

    /// The demo's frames in the order `order` gives, renumbered 1/30 s apart from 0, at the
    /// sensor's resolution (wrap in [`ProfileSource`] for the board's).
    #[derive(Debug)]
    pub struct Played {
        sequence: SyntheticSequence,
        order: Vec<usize>,
        next: usize,
        frame: SynthFrame,
    }

    impl FrameSource for Played {
        type Error = SynthError;

        fn next_frame(&mut self) -> Result<Option<RgbdFrame<'_>>, SynthError> {
            let Some(&index) = self.order.get(self.next) else { return Ok(None) };
            self.sequence.render_into(index, &mut self.frame)?;
            self.frame.timestamp_s = self.next as f64 / 30.0;
            self.next += 1;
            Ok(Some(self.frame.view()?))
        }
    }

    /// The default demo's frames `order` at QVGA (what the board processes), the camera at that
    /// resolution, and each frame's camera-to-world ground truth in the frame of the demo's first
    /// camera (what a run from frame 0 calls its world).
    ///
    /// # Panics
    /// On an index past the demo's 300 frames (test code).
    pub fn demo_frames(
        order: Vec<usize>,
    ) -> (ProfileSource<Played>, PinholeCamera, Vec<nalgebra::Isometry3<f32>>) {
        let sequence = SyntheticSequence::new(SynthOptions::default()).expect("the demo");
        let k = sequence.intrinsics();
        let cam = PinholeCamera::new(
            k.fx as f32,
            k.fy as f32,
            k.cx as f32,
            k.cy as f32,
            k.width,
            k.height,
        )
        .and_then(|c| c.downscaled_2x())
        .expect("the demo's camera");
        let t_0w = sequence.ground_truth(0).expect("frame 0").t_wc.inverse();
        let truth = order
            .iter()
            .map(|&i| (t_0w * sequence.ground_truth(i).expect("a demo frame").t_wc).cast::<f32>())
            .collect();
        let frame = sequence.render(0).expect("frame 0");
        let played = Played { sequence, order, next: 0, frame };
        (ProfileSource::new(played, QVGA.downsample_levels, QVGA.depth_level), cam, truth)
    }

    /// Places objects 0, 1, ... at `pixels` of `frame` through `slam` as the board does
    /// (`Slam::command`, scale 1), `result` the frame's; returns where each belongs: the true
    /// point under its pixel (`t_true` the frame's ground truth, camera to world).
    ///
    /// # Panics
    /// When a place is refused or a pixel has no depth (test code).
    pub fn place_objects(
        slam: &mut ferroslam_core::system::QvgaSlam,
        (frame, cam, result): (
            &RgbdFrame<'_>,
            &PinholeCamera,
            &ferroslam_core::tracking::FrameResult,
        ),
        t_true: &nalgebra::Isometry3<f32>,
        pixels: &[(f32, f32)],
    ) -> Vec<nalgebra::Point3<f32>> {
        let mut placed = Vec::new();
        for (object, &(u, v)) in (0u16..).zip(pixels) {
            let place =
                ferroslam_core::ar::AnchorCommand::Place { object, pixel: [u, v], scale: 1.0 };
            slam.command(&place, frame, cam, result).expect("placed");
            let z = frame.depth.depth_at(u, v, 0.05).expect("depth under the pixel");
            placed.push(t_true * cam.back_project(u, v, z));
        }
        placed
    }
}
