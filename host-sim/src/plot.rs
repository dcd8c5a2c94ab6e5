//! Trajectory and error plots as SVG (plotters), for `replay` and `eval` reports.
//!
//! Output is deterministic: the same inputs give the same bytes (no clock, no system fonts; text is
//! left to the SVG viewer).

use std::path::{Path, PathBuf};

use nalgebra::Point3;
use plotters::prelude::*;

use crate::eval::EvalReport;

/// Canvas size of the trajectory top view, in pixels (square, so both axes get the same scale).
const TOP_VIEW_PX: (u32, u32) = (800, 800);
/// Canvas size of the error-over-time plot, in pixels.
const ERROR_PLOT_PX: (u32, u32) = (1000, 400);

/// A plot could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlotError {
    /// Nothing to plot.
    #[error("{}: nothing to plot", path.display())]
    Empty {
        /// The plot file.
        path: PathBuf,
    },
    /// Input slices that must be parallel differ in length.
    #[error("{}: {times} times but {errors} errors", path.display())]
    LengthMismatch {
        /// The plot file.
        path: PathBuf,
        /// Number of times.
        times: usize,
        /// Number of errors.
        errors: usize,
    },
    /// A value is NaN or infinite.
    #[error("{}: {what} {index} is not finite", path.display())]
    NonFinite {
        /// The plot file.
        path: PathBuf,
        /// Which input: `"point"`, `"time"` or `"error"`.
        what: &'static str,
        /// Index of the first non-finite value in that input.
        index: usize,
    },
    /// Drawing or writing the file failed.
    #[error("{}: cannot draw: {reason}", path.display())]
    Draw {
        /// The plot file.
        path: PathBuf,
        /// The plotting library's message.
        reason: String,
    },
}

/// The plane a top view shows: two world axes (0 = x, 1 = y, 2 = z), horizontal first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlotPlane {
    /// World axis drawn horizontally.
    pub horizontal: usize,
    /// World axis drawn vertically.
    pub vertical: usize,
}

impl PlotPlane {
    /// The plane spanned by the two axes along which `points` extend most (ties to the lower
    /// axis), horizontal = the lower axis index (so x-y, x-z or y-z).
    pub fn of_largest_extent<'a>(points: impl IntoIterator<Item = &'a Point3<f64>>) -> Self {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in points {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let extent = |k: usize| if hi[k] >= lo[k] { hi[k] - lo[k] } else { 0.0 };
        // Drop the axis with the smallest extent (the highest index on ties).
        let drop = (0..3).rev().min_by(|&a, &b| extent(a).total_cmp(&extent(b))).unwrap_or(1);
        let (horizontal, vertical) = match drop {
            0 => (1, 2),
            1 => (0, 2),
            _ => (0, 1),
        };
        Self { horizontal, vertical }
    }

    fn label(axis: usize) -> &'static str {
        match axis {
            0 => "x [m]",
            1 => "y [m]",
            _ => "z [m]",
        }
    }
}

fn draw_error(path: &Path) -> impl Fn(DrawingAreaErrorKind<std::io::Error>) -> PlotError + '_ {
    move |e| PlotError::Draw { path: path.to_path_buf(), reason: e.to_string() }
}

fn check_finite(
    path: &Path,
    what: &'static str,
    finite: impl IntoIterator<Item = bool>,
) -> Result<(), PlotError> {
    match finite.into_iter().position(|ok| !ok) {
        Some(index) => Err(PlotError::NonFinite { path: path.to_path_buf(), what, index }),
        None => Ok(()),
    }
}

/// A range `[lo, hi]` of the values with a 5 % margin (and at least `min_span`).
fn padded_range(values: impl Iterator<Item = f64>, min_span: f64) -> (f64, f64) {
    let (lo, hi) =
        values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    let (lo, hi) = if lo <= hi { (lo, hi) } else { (0.0, 0.0) };
    let span = (hi - lo).max(min_span);
    let mid = 0.5 * (lo + hi);
    (mid - 0.55 * span, mid + 0.55 * span)
}

/// Draws the ground truth and the aligned estimate (world positions of the camera, metres) seen
/// from above, in the plane of their two largest extents ([`PlotPlane::of_largest_extent`]), both
/// axes at the same scale, as an SVG file at `path`, with a circle on each point of `marks`
/// (estimate positions of an event, such as `relocalized`, named in the legend: blue, then green,
/// for each kind in turn). Returns the plane drawn; the axis labels say which (`x [m]`, `z [m]`,
/// ...).
pub fn plot_trajectory_top_view(
    path: &Path,
    gt: &[Point3<f64>],
    est_aligned: &[Point3<f64>],
    marks: &[Marks<'_>],
    title: &str,
) -> Result<PlotPlane, PlotError> {
    if gt.is_empty() && est_aligned.is_empty() {
        return Err(PlotError::Empty { path: path.to_path_buf() });
    }
    let finite = |p: &Point3<f64>| p.coords.iter().all(|c| c.is_finite());
    check_finite(path, "point", gt.iter().map(finite))?;
    check_finite(path, "point", est_aligned.iter().map(finite))?;
    let plane = PlotPlane::of_largest_extent(gt.iter().chain(est_aligned));
    let (h, v) = (plane.horizontal, plane.vertical);
    let all = || gt.iter().chain(est_aligned);
    let (h0, h1) = padded_range(all().map(|p| p[h]), 1e-3);
    let (v0, v1) = padded_range(all().map(|p| p[v]), 1e-3);
    // Same metres per pixel on both axes: widen the narrower range to the wider span.
    let half = 0.5 * (h1 - h0).max(v1 - v0);
    let (hc, vc) = (0.5 * (h0 + h1), 0.5 * (v0 + v1));

    let err = draw_error(path);
    let root = SVGBackend::new(path, TOP_VIEW_PX).into_drawing_area();
    root.fill(&WHITE).map_err(&err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(65)
        .build_cartesian_2d(hc - half..hc + half, vc - half..vc + half)
        .map_err(&err)?;
    chart
        .configure_mesh()
        .x_desc(PlotPlane::label(h))
        .y_desc(PlotPlane::label(v))
        .draw()
        .map_err(&err)?;
    let series = [(gt, BLACK, "ground truth"), (est_aligned, RED, "estimate (aligned)")];
    for (points, color, label) in series {
        chart
            .draw_series(LineSeries::new(
                points.iter().map(|p| (p[h], p[v])),
                color.stroke_width(2),
            ))
            .map_err(&err)?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    for (kind, color) in
        marks.iter().filter(|m| !m.points.is_empty()).zip([BLUE, GREEN].iter().cycle())
    {
        let mark = color.stroke_width(2);
        chart
            .draw_series(kind.points.iter().map(|p| Circle::new((p[h], p[v]), 6, mark)))
            .map_err(&err)?
            .label(kind.label)
            .legend(move |(x, y)| Circle::new((x + 10, y), 6, mark));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(&err)?;
    root.present().map_err(&err)?;
    Ok(plane)
}

/// Positions of one kind of event on a trajectory plot, named by `label` in its legend.
#[derive(Debug, Clone)]
pub struct Marks<'a> {
    /// The legend's name of the event.
    pub label: &'a str,
    /// Where it happened, metres.
    pub points: Vec<Point3<f64>>,
}

/// Draws an error curve (`errors_m[i]` in metres at `times_s[i]` in seconds) as an SVG file at
/// `path`; the time axis is in seconds since the first time.
pub fn plot_error_over_time(
    path: &Path,
    times_s: &[f64],
    errors_m: &[f64],
    title: &str,
) -> Result<(), PlotError> {
    if times_s.len() != errors_m.len() {
        return Err(PlotError::LengthMismatch {
            path: path.to_path_buf(),
            times: times_s.len(),
            errors: errors_m.len(),
        });
    }
    let Some(&t0) = times_s.first() else {
        return Err(PlotError::Empty { path: path.to_path_buf() });
    };
    check_finite(path, "time", times_s.iter().map(|t| t.is_finite()))?;
    check_finite(path, "error", errors_m.iter().map(|e| e.is_finite()))?;
    let (x0, x1) = padded_range(times_s.iter().map(|t| t - t0), 1e-3);
    let (_, y1) = padded_range(errors_m.iter().copied().chain([0.0]), 1e-4);

    let err = draw_error(path);
    let root = SVGBackend::new(path, ERROR_PLOT_PX).into_drawing_area();
    root.fill(&WHITE).map_err(&err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(x0.min(0.0)..x1, 0.0..y1)
        .map_err(&err)?;
    chart
        .configure_mesh()
        .x_desc("time since start [s]")
        .y_desc("error [m]")
        .draw()
        .map_err(&err)?;
    chart
        .draw_series(LineSeries::new(
            times_s.iter().zip(errors_m).map(|(t, e)| (t - t0, *e)),
            BLUE.stroke_width(2),
        ))
        .map_err(&err)?;
    root.present().map_err(&err)?;
    Ok(())
}

/// Writes both plots of an evaluation: the top view of ground truth and aligned estimate to
/// `top_view_svg`, with the estimate's poses at the timestamps of each event kind of `events`
/// (`(label, timestamps in seconds)`) circled, and the ATE of each match over time to `ate_svg`.
pub fn plot_report(
    report: &EvalReport,
    top_view_svg: &Path,
    ate_svg: &Path,
    events: &[(&str, Vec<f64>)],
) -> Result<(), PlotError> {
    let gt: Vec<Point3<f64>> =
        report.matches.iter().map(|m| Point3::from(m.gt.t_wc.translation.vector)).collect();
    let est: Vec<Point3<f64>> = report
        .matches
        .iter()
        .map(|m| Point3::from(m.est_aligned_t_wc.translation.vector))
        .collect();
    let marks: Vec<Marks<'_>> = events
        .iter()
        .map(|(label, at_s)| Marks {
            label,
            points: report
                .matches
                .iter()
                .filter(|m| at_s.contains(&m.est.timestamp_s))
                .map(|m| Point3::from(m.est_aligned_t_wc.translation.vector))
                .collect(),
        })
        .collect();
    let title = format!(
        "trajectory (ATE rmse {:.4} m, {} matched poses)",
        report.ate.rmse, report.matched_poses
    );
    plot_trajectory_top_view(top_view_svg, &gt, &est, &marks, &title)?;
    let (times, errors) = report.ate_over_time();
    plot_error_over_time(ate_svg, &times, &errors, "absolute trajectory error (SE(3)-aligned)")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spiral(n: usize, scale: f64) -> Vec<Point3<f64>> {
        (0..n)
            .map(|i| {
                let a = i as f64 * 0.1;
                Point3::new(scale * a.cos(), 0.05 * a.sin(), scale * a.sin() + 0.01 * a)
            })
            .collect()
    }

    fn assert_svg_with_polyline(path: &Path) -> String {
        let text = std::fs::read_to_string(path).unwrap();
        assert!(text.starts_with("<svg"), "{}", &text[..text.len().min(80)]);
        assert!(text.contains("<polyline"));
        assert!(text.trim_end().ends_with("</svg>"));
        text
    }

    #[test]
    fn top_view_is_valid_deterministic_svg_in_the_largest_plane() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.svg"), dir.path().join("b.svg"));
        let gt = spiral(200, 1.0);
        let est = spiral(200, 1.02);
        let plane = plot_trajectory_top_view(&a, &gt, &est, &[], "top view").unwrap();
        assert_eq!(plane, PlotPlane { horizontal: 0, vertical: 2 });
        let text = assert_svg_with_polyline(&a);
        assert!(text.contains("x [m]") && text.contains("z [m]"));
        plot_trajectory_top_view(&b, &gt, &est, &[], "top view").unwrap();
        assert_eq!(text, std::fs::read_to_string(&b).unwrap());
        // A relocalization and a loop are circled and named in the legend; an event kind that
        // did not happen is not.
        assert!(!text.contains("relocalized"));
        let c = dir.path().join("c.svg");
        let marks = |loops: usize| {
            [
                Marks { label: "relocalized", points: est[50..51].to_vec() },
                Marks { label: "loop closed", points: est[80..80 + loops].to_vec() },
            ]
        };
        plot_trajectory_top_view(&c, &gt, &est, &marks(1), "top view").unwrap();
        let marked = std::fs::read_to_string(&c).unwrap();
        assert!(marked.contains("relocalized") && marked.contains("loop closed"));
        assert!(marked.matches("<circle").count() >= 4, "two marks and two legend circles");
        plot_trajectory_top_view(&c, &gt, &est, &marks(0), "top view").unwrap();
        let marked = std::fs::read_to_string(&c).unwrap();
        assert!(marked.contains("relocalized") && !marked.contains("loop closed"));
    }

    #[test]
    fn error_plot_is_valid_svg() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("err.svg");
        let t: Vec<f64> = (0..100).map(|i| 1000.0 + i as f64 / 30.0).collect();
        let e: Vec<f64> = (0..100).map(|i| 0.01 + 0.001 * (i as f64 * 0.2).sin()).collect();
        plot_error_over_time(&path, &t, &e, "ATE").unwrap();
        assert_svg_with_polyline(&path);
    }

    #[test]
    fn bad_inputs_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.svg");
        assert!(matches!(plot_error_over_time(&p, &[], &[], "t"), Err(PlotError::Empty { .. })));
        assert!(matches!(
            plot_error_over_time(&p, &[0.0], &[], "t"),
            Err(PlotError::LengthMismatch { .. })
        ));
        assert!(matches!(
            plot_error_over_time(&p, &[0.0, 1.0], &[0.0, f64::NAN], "t"),
            Err(PlotError::NonFinite { what: "error", index: 1, .. })
        ));
        assert!(matches!(
            plot_trajectory_top_view(&p, &[], &[], &[], "t"),
            Err(PlotError::Empty { .. })
        ));
        let missing = dir.path().join("no/such/dir/x.svg");
        assert!(matches!(
            plot_error_over_time(&missing, &[0.0, 1.0], &[0.0, 1.0], "t"),
            Err(PlotError::Draw { .. })
        ));
    }

    #[test]
    fn plane_choice() {
        let flat_y = [Point3::new(0.0, 0.0, 0.0), Point3::new(2.0, 0.1, 1.0)];
        assert_eq!(PlotPlane::of_largest_extent(&flat_y), PlotPlane { horizontal: 0, vertical: 2 });
        let flat_z = [Point3::new(0.0, 0.0, 0.0), Point3::new(2.0, 1.0, 0.1)];
        assert_eq!(PlotPlane::of_largest_extent(&flat_z), PlotPlane { horizontal: 0, vertical: 1 });
        let flat_x = [Point3::new(0.0, 0.0, 0.0), Point3::new(0.1, 1.0, 2.0)];
        assert_eq!(PlotPlane::of_largest_extent(&flat_x), PlotPlane { horizontal: 1, vertical: 2 });
    }
}
