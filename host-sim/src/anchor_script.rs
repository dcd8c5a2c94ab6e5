//! Anchor scripts (`--anchors FILE`): what a user does with virtual objects during a run, frame
//! by frame, as a TOML file of `[[step]]` tables:
//!
//! ```toml
//! [[step]]          # at frame 10 place object 0 at pixel (320, 240), scale 1
//! frame = 10
//! action = "place"
//! object = 0
//! pixel = [320.0, 240.0]
//! scale = 1.0       # optional for a place (default 1)
//!
//! [[step]]          # at frame 200 make it twice as big
//! frame = 200
//! action = "scale"
//! object = 0
//! scale = 2.0
//!
//! [[step]]          # at frame 250 remove it
//! frame = 250
//! action = "remove"
//! object = 0
//! ```
//!
//! Frames are 0-based as played (after `--skip-frames` and `--frames`); pixels are the
//! recording's (the sensor's resolution, centres at integers), brought to the processing
//! resolution as the calibration is. Steps of one frame apply in file order, before that frame is
//! drawn. Unknown keys, a missing or extra key for the action, and out-of-range values are refused
//! with the file and the step's line.

use std::path::{Path, PathBuf};

use ferroslam_core::ar::{Anchor, AnchorCommand};
use serde::Deserialize;

/// A script step: at frame `frame` (0-based, as played), `command`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScriptStep {
    /// The frame it applies in.
    pub frame: usize,
    /// What it does, pixels at the processing resolution.
    pub command: AnchorCommand,
    /// Its `[[step]]` line in the file (1-based), for messages.
    pub line: usize,
}

/// A script's steps in the order they apply (by frame, file order within a frame).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AnchorScript {
    /// The steps.
    pub steps: Vec<ScriptStep>,
}

/// Why a script was refused.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScriptError {
    /// The file could not be read.
    #[error("reading anchor script {}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Not TOML, or not the script's keys and types (the message has the line).
    #[error("anchor script {}: {message}", path.display())]
    Syntax {
        /// The file.
        path: PathBuf,
        /// The parser's message.
        message: String,
    },
    /// A step that does not say a valid command.
    #[error("anchor script {}, step at line {line}: {problem}", path.display())]
    Step {
        /// The file.
        path: PathBuf,
        /// The step's `[[step]]` line.
        line: usize,
        /// What is wrong.
        problem: String,
    },
}

/// A `[[step]]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct StepToml {
    frame: usize,
    action: Action,
    object: u16,
    pixel: Option<[f32; 2]>,
    scale: Option<f32>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "lowercase")]
enum Action {
    Place,
    Scale,
    Remove,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ScriptToml {
    #[serde(default)]
    step: Vec<toml::Spanned<StepToml>>,
}

impl AnchorScript {
    /// Reads the script at `path`; its pixels are brought to a processing resolution
    /// `downsample_levels` halvings below the recording's.
    ///
    /// # Errors
    /// [`ScriptError`].
    pub fn load(path: &Path, downsample_levels: u8) -> Result<Self, ScriptError> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| ScriptError::Read { path: path.to_owned(), source })?;
        Self::from_toml_str(&text, path, downsample_levels)
    }

    /// [`Self::load`] of `text`, read from `path` (for messages).
    ///
    /// # Errors
    /// [`ScriptError`].
    pub fn from_toml_str(
        text: &str,
        path: &Path,
        downsample_levels: u8,
    ) -> Result<Self, ScriptError> {
        let script: ScriptToml = toml::from_str(text).map_err(|e| ScriptError::Syntax {
            path: path.to_owned(),
            message: e.to_string().trim_end().to_owned(),
        })?;
        // Pixel centres kept: u' = (u + 0.5) / 2^L - 0.5, as the calibration's principal point.
        let factor = 1.0 / f32::from(1u8 << downsample_levels.min(7));
        let mut steps = Vec::with_capacity(script.step.len());
        for spanned in script.step {
            let line = 1 + text.bytes().take(spanned.span().start).filter(|&b| b == b'\n').count();
            let step = spanned.into_inner();
            let problem = |problem: &str| ScriptError::Step {
                path: path.to_owned(),
                line,
                problem: problem.to_owned(),
            };
            let command = match (step.action, step.pixel, step.scale) {
                (Action::Place, None, _) => return Err(problem("a place needs `pixel = [u, v]`")),
                (Action::Place, Some(p), scale) => {
                    if !p.iter().all(|c| c.is_finite() && *c >= 0.0) {
                        return Err(problem("`pixel` must be two finite, non-negative numbers"));
                    }
                    let scale = scale.unwrap_or(1.0);
                    if !Anchor::is_valid_scale(scale) {
                        return Err(problem("`scale` must be finite and positive"));
                    }
                    let pixel = p.map(|c| (c + 0.5) * factor - 0.5);
                    AnchorCommand::Place { object: step.object, pixel, scale }
                }
                (Action::Scale, Some(_), _) => {
                    return Err(problem("a scale takes no `pixel` (place the object again)"));
                }
                (Action::Scale, None, None) => return Err(problem("a scale needs `scale`")),
                (Action::Scale, None, Some(scale)) if !Anchor::is_valid_scale(scale) => {
                    return Err(problem("`scale` must be finite and positive"));
                }
                (Action::Scale, None, Some(scale)) => {
                    AnchorCommand::Scale { object: step.object, scale }
                }
                (Action::Remove, None, None) => AnchorCommand::Remove { object: step.object },
                (Action::Remove, ..) => {
                    return Err(problem("a remove takes no `pixel` or `scale`"));
                }
            };
            steps.push(ScriptStep { frame: step.frame, command, line });
        }
        // Stable: steps of one frame keep their file order.
        steps.sort_by_key(|s| s.frame);
        Ok(Self { steps })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<AnchorScript, ScriptError> {
        AnchorScript::from_toml_str(text, Path::new("anchors.toml"), 1)
    }

    #[test]
    fn steps_are_read_in_frame_order_with_pixels_at_the_processing_resolution() {
        let script = parse(
            "[[step]]\nframe = 30\naction = \"remove\"\nobject = 2\n\n\
             [[step]]\nframe = 3\naction = \"place\"\nobject = 2\npixel = [319.5, 0.0]\n\n\
             [[step]]\nframe = 3\naction = \"scale\"\nobject = 2\nscale = 2.5\n",
        )
        .unwrap();
        let got: Vec<_> = script.steps.iter().map(|s| (s.frame, s.command, s.line)).collect();
        let place = AnchorCommand::Place { object: 2, pixel: [159.5, -0.25], scale: 1.0 };
        assert_eq!(
            got,
            [
                (3, place, 6),
                (3, AnchorCommand::Scale { object: 2, scale: 2.5 }, 12),
                (30, AnchorCommand::Remove { object: 2 }, 1),
            ]
        );
        assert!(parse("").unwrap().steps.is_empty());
    }

    #[test]
    fn bad_steps_are_refused_with_their_line() {
        let step = |body: &str| format!("# a script\n[[step]]\nframe = 1\nobject = 0\n{body}");
        for (body, says) in [
            ("action = \"place\"\n", "needs `pixel"),
            ("action = \"place\"\npixel = [1.0, -2.0]\n", "non-negative"),
            ("action = \"place\"\npixel = [1.0, 2.0]\nscale = 0.0\n", "positive"),
            ("action = \"scale\"\n", "needs `scale`"),
            ("action = \"scale\"\nscale = -1.0\n", "positive"),
            ("action = \"scale\"\nscale = 2.0\npixel = [1.0, 2.0]\n", "no `pixel`"),
            ("action = \"remove\"\nscale = 2.0\n", "no `pixel` or `scale`"),
        ] {
            let e = parse(&step(body)).unwrap_err().to_string();
            assert!(e.contains("anchors.toml, step at line 2") && e.contains(says), "{e}");
        }
        for (text, says) in [
            (step("action = \"place\"\npixle = [1.0, 2.0]\n"), "pixle"),
            (step("action = \"move\"\n"), "move"),
            ("[[stp]]\nframe = 1\n".to_owned(), "stp"),
            (step("action = \"remove\"\nobject = 3\n"), "duplicate"),
            ("[[step]]\nframe = -1\naction = \"remove\"\nobject = 0\n".to_owned(), "frame"),
        ] {
            let e = parse(&text).unwrap_err().to_string();
            assert!(e.contains("anchors.toml") && e.contains(says), "{e}");
        }
        let missing = AnchorScript::load(Path::new("/nonexistent/anchors.toml"), 1).unwrap_err();
        assert!(missing.to_string().contains("/nonexistent/anchors.toml"), "{missing}");
    }
}
