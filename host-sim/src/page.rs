//! `report.html`: one self-contained page per run (no network: its script, data and plots are
//! inline) with the run's summary, the trajectory and error plots, and a 3D view of the map drawn
//! by a small canvas script of our own: the map's points (grey), the points new in the last
//! keyframe (red, the paper's colours), the trajectory (blue) and the aligned ground truth
//! (green), the keyframes (orange, each a stroke along its optical axis), the frames where a loop
//! closed (magenta), the planes (a translucent square around each centroid) and the AR objects
//! (cubes). Drag to orbit, wheel to zoom. Everything is in the run's world frame (the first
//! keyframe's camera: x right, y down, z forward), metres.
//!
//! The page records in `<body data-drawn="N">` how many items the view drew, and in
//! `data-error` any script error, so a headless browser can check it (`cargo xtask ci`).

use std::path::Path;

use anyhow::{Context, Result};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;

use crate::eval::EvalReport;
use crate::report::Report;
use crate::run::TrackingRun;
use crate::trajectory::StampedPose;

/// The 3D view's data: what a run's page draws.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Scene {
    /// Camera positions, in frame order.
    pub trajectory: Vec<[f32; 3]>,
    /// Ground-truth positions moved into the run's world by the evaluation's alignment.
    pub ground_truth: Vec<[f32; 3]>,
    /// Keyframes: position and optical axis (unit).
    pub keyframes: Vec<[f32; 6]>,
    /// The map's points, and those new in the last keyframe.
    pub points: Vec<[f32; 3]>,
    /// Points of the last keyframe.
    pub newest: Vec<[f32; 3]>,
    /// Camera positions of the frames where a loop closed.
    pub loops: Vec<[f32; 3]>,
    /// Planes: centroid and unit normal.
    pub planes: Vec<[f32; 6]>,
    /// AR objects: position, up, scale and object id.
    pub anchors: Vec<[f32; 8]>,
}

/// `p` as three f32 (the page's precision).
fn f32x3(p: &Vector3<f64>) -> [f32; 3] {
    [p.x as f32, p.y as f32, p.z as f32]
}

impl Scene {
    /// The scene of `run`, with the ground truth of `evaluation` when there is one.
    pub fn of(run: &TrackingRun, evaluation: Option<&EvalReport>) -> Self {
        let position = |t: &Isometry3<f64>| f32x3(&t.translation.vector);
        let trajectory: Vec<[f32; 3]> =
            run.camera.poses.iter().map(|p| position(&p.t_wc)).collect();
        let ground_truth = evaluation
            .map(|e| ground_truth_in_run_world(e).iter().map(|p| position(&p.t_wc)).collect())
            .unwrap_or_default();
        let keyframes = run
            .keyframes
            .poses
            .iter()
            .map(|p| {
                let [x, y, z] = position(&p.t_wc);
                let axis = f32x3(&(p.t_wc.rotation * Vector3::z()));
                [x, y, z, axis[0], axis[1], axis[2]]
            })
            .collect();
        let loops = run
            .per_frame
            .iter()
            .filter(|f| f.loop_closed)
            .filter_map(|f| run.camera.poses.iter().find(|p| p.timestamp_s == f.timestamp_s))
            .map(|p| position(&p.t_wc))
            .collect();
        let planes = run.planes.as_ref().map_or_else(Vec::new, |p| {
            p.planes
                .iter()
                .map(|p| {
                    let ([x, y, z], [a, b, c]) = (p.centroid_m, p.normal);
                    [x, y, z, a, b, c]
                })
                .collect()
        });
        let anchors = run.ar.as_ref().map_or_else(Vec::new, |ar| {
            ar.anchors
                .iter()
                .map(|a| {
                    let ([x, y, z], [u, v, w]) = (a.position_m, a.up);
                    [x, y, z, u, v, w, a.scale, f32::from(a.object)]
                })
                .collect()
        });
        let (points, newest) = run
            .map_points
            .as_ref()
            .map_or_else(Default::default, |c| (c.points.clone(), c.newest.clone()));
        Self { trajectory, ground_truth, keyframes, points, newest, loops, planes, anchors }
    }
}

/// The ground-truth poses `evaluation` matched, moved into the run's world by the inverse of
/// its alignment (which takes the estimate onto the ground truth), in time order.
pub fn ground_truth_in_run_world(evaluation: &EvalReport) -> Vec<StampedPose> {
    let a = &evaluation.alignment;
    let [qx, qy, qz, qw] = a.quaternion_xyzw;
    let [x, y, z] = a.translation_m;
    let t_gt_est = Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_quaternion(Quaternion::new(qw, qx, qy, qz)),
    );
    let t_est_gt = t_gt_est.inverse();
    let moved = |m: &crate::eval::MatchedPose| StampedPose {
        timestamp_s: m.gt.timestamp_s,
        t_wc: t_est_gt * m.gt.t_wc,
    };
    evaluation.matches.iter().map(moved).collect()
}

/// Writes `dir/report.html`: `report`'s summary, the plots `dir` holds (trajectory.svg, ate.svg)
/// and `scene` in the 3D view.
///
/// # Errors
/// A file that cannot be read or written.
pub fn write_page(dir: &Path, report: &Report, scene: &Scene) -> Result<()> {
    let mut plots = String::new();
    for name in ["trajectory.svg", "ate.svg"] {
        let path = dir.join(name);
        if path.exists() {
            let svg = std::fs::read_to_string(&path)
                .with_context(|| format!("reading {}", path.display()))?;
            // The XML declaration is not allowed inside HTML; the rest is inline SVG.
            let body = svg.find("<svg").map_or("", |i| &svg[i..]);
            plots.push_str(&format!("<figure>{body}<figcaption>{name}</figcaption></figure>\n"));
        }
    }
    let value = serde_json::to_value(report)?;
    let summary = summary_rows(&value);
    let full = escape(&serde_json::to_string_pretty(&value)?);
    // `</` in the data would end the script element: JSON lets `/` be written `\/`.
    let data = serde_json::to_string(scene)?.replace("</", "<\\/");
    let html = format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n\
         <title>ferroslam report</title>\n<style>{STYLE}</style></head>\n<body>\n\
         <h1>ferroslam report</h1>\n<p>{note}</p>\n\
         <h2>Map</h2>\n<canvas id=\"view\" width=\"960\" height=\"600\"></canvas>\n{LEGEND}\n\
         <h2>Summary</h2>\n<table>{summary}</table>\n\
         <h2>Trajectory and error</h2>\n{plots}\
         <details><summary>report.json</summary><pre>{full}</pre></details>\n\
         <script type=\"application/json\" id=\"scene\">{data}</script>\n\
         <script>{SCRIPT}</script>\n</body></html>\n",
        note = escape(&report.note),
    );
    let path = dir.join("report.html");
    std::fs::write(&path, html).with_context(|| format!("writing {}", path.display()))
}

/// A table row per top-level scalar of the report, and per scalar of its objects one level down.
fn summary_rows(value: &serde_json::Value) -> String {
    let mut rows = String::new();
    let Some(top) = value.as_object() else { return rows };
    let scalar = |v: &serde_json::Value| match v {
        serde_json::Value::Number(n) => Some(n.to_string()),
        serde_json::Value::Bool(b) => Some(b.to_string()),
        serde_json::Value::String(s) => Some(s.clone()),
        _ => None,
    };
    for (key, v) in top {
        if key == "note" {
            continue;
        }
        if let Some(text) = scalar(v) {
            rows.push_str(&format!("<tr><th>{}</th><td>{}</td></tr>", escape(key), escape(&text)));
        } else if let Some(inner) = v.as_object() {
            for (k, v) in inner {
                if let Some(text) = scalar(v) {
                    let name = format!("{key}.{k}");
                    rows.push_str(&format!(
                        "<tr><th>{}</th><td>{}</td></tr>",
                        escape(&name),
                        escape(&text)
                    ));
                }
            }
        }
    }
    rows
}

/// `text` safe inside HTML elements and attributes.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

const STYLE: &str = "body{font-family:sans-serif;margin:1.5em;max-width:1000px}\
canvas{border:1px solid #ccc;cursor:grab;background:#fff}\
table{border-collapse:collapse;font-size:13px}th,td{border:1px solid #ddd;padding:2px 6px;\
text-align:left}figure{display:inline-block;margin:0 1em 1em 0}\
.legend span{display:inline-block;margin-right:1em}.legend i{display:inline-block;width:12px;\
height:12px;margin-right:4px;vertical-align:middle}pre{font-size:12px}";

const LEGEND: &str = "<p class=\"legend\">\
<span><i style=\"background:#999\"></i>map points</span>\
<span><i style=\"background:#e02020\"></i>points new in the last keyframe</span>\
<span><i style=\"background:#0050ff\"></i>trajectory</span>\
<span><i style=\"background:#20a040\"></i>ground truth (aligned)</span>\
<span><i style=\"background:#ff9900\"></i>keyframes</span>\
<span><i style=\"background:#d000d0\"></i>loops closed</span>\
<span><i style=\"background:#80b0ff\"></i>planes</span>\
<span>cubes: AR objects</span> (drag to orbit, wheel to zoom)</p>";

const SCRIPT: &str = include_str!("page_view.js");
