//! `--mcap OUT`: a short demo's MCAP file read back with the `mcap` crate: every channel a
//! Foxglove schema in JSON, every message JSON with its schema's fields, one pose per posed
//! frame, the map's points; the same run gives the same bytes; a scripted object's place and
//! remove as scene updates and log lines; an unwritable file is named.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::BTreeMap;
use std::path::Path;

use ferroslam_sim::commands::demo::DemoArgs;
use ferroslam_sim::demo::{DemoOptions, demo};
use ferroslam_sim::report::RunOutputs;
use serde_json::Value;

/// Runs `demo ARGS --out DIR` as the command line would, without a progress bar.
fn run_demo(args: &[&str], out: &Path) -> anyhow::Result<RunOutputs> {
    let out_text = out.to_str().unwrap();
    let args = DemoArgs::from_args(args.iter().copied().chain(["--out", out_text])).unwrap();
    demo(&args.out, &DemoOptions { progress_bar: false, ..args.options()? })
}

/// Decodes standard base64 (what Foxglove's JSON carries bytes as).
fn base64_decode(text: &str) -> Vec<u8> {
    let value = |c: u8| match c {
        b'A'..=b'Z' => u32::from(c - b'A'),
        b'a'..=b'z' => u32::from(c - b'a') + 26,
        b'0'..=b'9' => u32::from(c - b'0') + 52,
        b'+' => 62,
        b'/' => 63,
        _ => panic!("not base64: {c}"),
    };
    let mut out = Vec::new();
    for chunk in text.as_bytes().chunks(4) {
        let digits: Vec<u32> = chunk.iter().filter(|&&c| c != b'=').map(|&c| value(c)).collect();
        let n = digits.iter().enumerate().fold(0, |n, (i, d)| n | (d << (18 - 6 * i)));
        out.extend(n.to_be_bytes()[1..digits.len()].iter());
    }
    out
}

/// Every property `schema` lists is in `message`; a `timestamp` is `{sec, nsec}`.
fn check_fields(topic: &str, schema: &Value, message: &Value) {
    let properties = schema["properties"].as_object().expect("an object schema");
    for name in properties.keys() {
        assert!(message.get(name).is_some(), "{topic}: no `{name}` in {message}");
    }
    if let Some(t) = message.get("timestamp") {
        assert!(t["sec"].is_u64() && t["nsec"].as_u64().is_some_and(|n| n < 1_000_000_000));
    }
}

/// The 3D view's points in report.html (what the page draws).
fn page_points(dir: &Path) -> usize {
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    let start = html.find("id=\"scene\">").unwrap() + "id=\"scene\">".len();
    let end = start + html[start..].find("</script>").unwrap();
    let scene: Value = serde_json::from_str(&html[start..end]).unwrap();
    scene["points"].as_array().unwrap().len()
}

#[test]
fn a_demo_mcap_reads_back_as_foxglove_messages() {
    let dir = tempfile::tempdir().unwrap();
    let (out, file) = (dir.path().join("run"), dir.path().join("run.mcap"));
    let args = ["--frames", "15", "--ar", "--mcap", file.to_str().unwrap()];
    let outputs = run_demo(&args, &out).unwrap();
    let bytes = std::fs::read(&file).unwrap();

    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    let mut last_time = 0;
    let mut points = None;
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        let channel = &message.channel;
        let schema = channel.schema.as_ref().expect("every channel has a schema");
        assert!(schema.name.starts_with("foxglove."), "{}: {}", channel.topic, schema.name);
        assert_eq!(schema.encoding, "jsonschema", "{}", channel.topic);
        assert_eq!(channel.message_encoding, "json", "{}", channel.topic);
        let schema_json: Value = serde_json::from_slice(&schema.data).unwrap();
        assert_eq!(schema_json["title"], schema.name.as_str());
        let body: Value = serde_json::from_slice(&message.data).unwrap();
        check_fields(&channel.topic, &schema_json, &body);
        if schema.name == "foxglove.SceneUpdate" {
            let entity = &schema_json["properties"]["entities"]["items"];
            for e in body["entities"].as_array().unwrap() {
                check_fields(&channel.topic, entity, e);
            }
        }
        assert!(message.log_time >= last_time, "messages in time order");
        last_time = message.log_time;
        if channel.topic == "/map/points" {
            assert_eq!(body["point_stride"], 12);
            points = Some(base64_decode(body["data"].as_str().unwrap()).len() / 12);
        }
        *counts.entry(channel.topic.clone()).or_default() += 1;
    }

    let camera = std::fs::read_to_string(out.join("CameraTrajectory.txt")).unwrap();
    let posed = camera.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty()).count();
    assert!(posed > 5, "the demo posed {posed} frames");
    assert_eq!(counts["/camera/pose"], posed, "{counts:?}");
    assert_eq!(counts["/tf"], posed);
    assert_eq!(counts["/trajectory"], 1);
    assert_eq!(counts["/map/keyframes"], outputs.report.keyframes);
    let matched = outputs.evaluation.as_ref().unwrap().matches.len();
    assert_eq!(counts["/groundtruth/pose"], matched);
    assert_eq!(points, Some(page_points(&out)), "the map's points");
    assert!(points.unwrap() > 100);
    assert!(counts.contains_key("/map/planes"), "{counts:?}");
    let objects = outputs.report.ar.as_ref().unwrap().objects;
    assert!(objects > 0, "the demo places its objects");
    assert_eq!(counts["/ar/anchors"], objects, "a cube per placement");

    // The same run, the same bytes.
    let again = dir.path().join("again.mcap");
    let args = ["--frames", "15", "--ar", "--mcap", again.to_str().unwrap()];
    run_demo(&args, &dir.path().join("again")).unwrap();
    assert!(std::fs::read(&again).unwrap() == bytes, "the file is reproducible");
}

/// The messages of the MCAP file `bytes`: topic and JSON body, in the file's order.
fn topics_and_bodies(bytes: &[u8]) -> Vec<(String, Value)> {
    let stream = mcap::MessageStream::new(bytes).unwrap();
    let body = |m: mcap::Message| serde_json::from_slice(&m.data).unwrap();
    stream.map(|m| m.unwrap()).map(|m| (m.channel.topic.clone(), body(m))).collect()
}

#[test]
fn scripted_anchors_are_placed_and_removed_with_log_lines() {
    let dir = tempfile::tempdir().unwrap();
    let (script, file) = (dir.path().join("anchors.toml"), dir.path().join("run.mcap"));
    let step = |frame, action, extra| {
        format!("[[step]]\nframe = {frame}\naction = \"{action}\"\nobject = 0\n{extra}\n")
    };
    let text =
        [step(2, "place", "pixel = [320.0, 400.0]"), step(4, "remove", ""), step(5, "remove", "")]
            .concat();
    std::fs::write(&script, text).unwrap();
    let (script_text, file_text) = (script.to_str().unwrap(), file.to_str().unwrap());
    let args = ["--frames", "8", "--anchors", script_text, "--mcap", file_text];
    run_demo(&args, &dir.path().join("run")).unwrap();
    let messages = topics_and_bodies(&std::fs::read(&file).unwrap());
    let on = |topic: &str| -> Vec<&Value> {
        messages.iter().filter(|(t, _)| t == topic).map(|(_, b)| b).collect()
    };
    let anchors = on("/ar/anchors");
    assert_eq!(anchors.len(), 2, "placed, then removed: {anchors:?}");
    assert_eq!(anchors[0]["entities"][0]["id"], "object-0");
    assert_eq!(anchors[1]["deletions"][0]["id"], "object-0");
    assert_eq!(anchors[1]["deletions"][0]["type"], 0, "MATCHING_ID");
    let events: Vec<&str> = on("/events").iter().filter_map(|b| b["message"].as_str()).collect();
    assert_eq!(events.len(), 3, "{events:?}");
    assert!(events[0].starts_with("frame 2: anchor script line 1: place 0"), "{events:?}");
    assert!(events[1].ends_with("remove 0: done"), "{events:?}");
    assert!(events[2].contains("refused"), "the second remove has nothing to remove: {events:?}");
    assert_eq!(on("/events")[2]["level"], 3, "a refused step is a warning");
}

#[test]
fn an_mcap_file_that_cannot_be_written_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("no-such-folder").join("run.mcap");
    let args = ["--frames", "3", "--mode", "odometry", "--mcap", file.to_str().unwrap()];
    let error = run_demo(&args, &dir.path().join("run")).unwrap_err().to_string();
    assert!(error.contains("cannot write the MCAP file"), "{error}");
    assert!(error.contains(file.to_str().unwrap()), "{error}");
    let args = ["--frames", "3", "--mode", "data-path", "--mcap", file.to_str().unwrap()];
    let error = run_demo(&args, &dir.path().join("run")).unwrap_err().to_string();
    assert!(error.contains("--mcap") && error.contains("no poses"), "{error}");
}
