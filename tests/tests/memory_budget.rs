#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! `memory-budget.md` must not lie: every structure row of its core table names a type whose
//! `size_of` this test knows, and the bytes written there are the bytes measured here.

use std::collections::BTreeMap;
use std::mem::size_of;

use ferroslam_core::config::{
    Config, QvgaDepthBuffer, QvgaGrayBuffer, VgaDepthBuffer, VgaGrayBuffer,
};
use ferroslam_core::features::{FeatureVec, QvgaHessianDetector, VgaHessianDetector};
use ferroslam_core::frame::RgbdFrame;
use ferroslam_core::geometry::{PinholeCamera, Pose};
use ferroslam_core::image::{DepthView, GrayView};
use ferroslam_core::map::{BoardMap, KeyFrame, Landmark, Observation};
use ferroslam_core::tracking::sbi::SmallImage;
use ferroslam_core::tracking::{
    BoardLocalMap, InlierMask, MotionModel, PoseEstimate, QvgaFrontend, TrackedLandmark,
    VgaFrontend,
};

/// `size_of` of every type the budget table may name.
fn measured() -> BTreeMap<&'static str, usize> {
    BTreeMap::from([
        ("config::QvgaGrayBuffer", size_of::<QvgaGrayBuffer>()),
        ("config::QvgaDepthBuffer", size_of::<QvgaDepthBuffer>()),
        ("config::VgaGrayBuffer", size_of::<VgaGrayBuffer>()),
        ("config::VgaDepthBuffer", size_of::<VgaDepthBuffer>()),
        ("config::Config", size_of::<Config>()),
        ("image::GrayView", size_of::<GrayView<'static>>()),
        ("image::DepthView", size_of::<DepthView<'static>>()),
        ("frame::RgbdFrame", size_of::<RgbdFrame<'static>>()),
        ("geometry::PinholeCamera", size_of::<PinholeCamera>()),
        ("geometry::Pose", size_of::<Pose>()),
        ("features::QvgaHessianDetector", size_of::<QvgaHessianDetector>()),
        ("features::VgaHessianDetector", size_of::<VgaHessianDetector>()),
        ("features::FeatureVec", size_of::<FeatureVec>()),
        ("tracking::InlierMask", size_of::<InlierMask>()),
        ("tracking::PoseEstimate", size_of::<PoseEstimate>()),
        ("tracking::MotionModel", size_of::<MotionModel>()),
        ("tracking::QvgaFrontend", size_of::<QvgaFrontend>()),
        ("tracking::VgaFrontend", size_of::<VgaFrontend>()),
        ("tracking::TrackedLandmark", size_of::<TrackedLandmark>()),
        ("tracking::BoardLocalMap", size_of::<BoardLocalMap>()),
        ("tracking::sbi::SmallImage", size_of::<SmallImage>()),
        ("map::Observation", size_of::<Observation>()),
        ("map::Landmark", size_of::<Landmark>()),
        ("map::KeyFrame", size_of::<KeyFrame>()),
        ("map::BoardMap", size_of::<BoardMap>()),
    ])
}

/// The `(type, bytes)` rows of the table under the heading "Core structures".
fn documented(text: &str) -> Vec<(String, usize)> {
    let section = text.split("## Core structures").nth(1).unwrap_or("");
    let table = section.split("\n## ").next().unwrap_or("");
    table
        .lines()
        .filter(|l| l.starts_with("| `"))
        .map(|l| {
            let cells: Vec<&str> = l.split('|').map(str::trim).collect();
            let name = cells[1].trim_matches('`').to_string();
            let bytes = cells[3].replace(',', "").parse().unwrap_or_else(|_| {
                panic!("memory-budget.md: row {l:?} has no byte count in its third column")
            });
            (name, bytes)
        })
        .collect()
}

#[test]
fn core_structure_sizes_match_the_budget_file() {
    for (name, bytes) in measured() {
        println!("{name}: {bytes}");
    }
    // The table documents the host (64-bit) sizes; views and frames hold pointers and are smaller on
    // the 32-bit Cortex-M, buffers are the same.
    let path = ferroslam_tests::workspace_root().join("memory-budget.md");
    let text = std::fs::read_to_string(&path).expect("memory-budget.md is readable");
    let rows = documented(&text);
    let known = measured();
    assert_eq!(rows.len(), known.len(), "the table must list exactly the known structures");
    for (name, bytes) in rows {
        let actual = known.get(name.as_str()).unwrap_or_else(|| panic!("unknown type {name}"));
        assert_eq!(
            *actual, bytes,
            "memory-budget.md says {name} is {bytes} bytes, size_of is {actual}"
        );
    }
}
