//! ferroslam-sim: the host side of ferroslam.
//!
//! It feeds recorded or synthetic RGB-D frames through `ferroslam-core` exactly as the firmware
//! does (through the core's [`ferroslam_core::frame::FrameSource`] port, never a side entrance), and
//! evaluates what comes out:
//!
//! - [`dataset`]: TUM RGB-D folders and MCAP recordings (lists, association, calibration, image
//!   decoding on a read-ahead thread);
//! - [`synth`]: a built-in synthetic RGB-D sequence with exact ground truth, rendered in code;
//! - [`trajectory`]: TUM trajectory files;
//! - [`eval`]: ATE and RPE as evo computes them;
//! - [`plot`]: trajectory and error plots;
//! - [`serial`]: the firmware's UART captures decoded, and host writers of the telemetry port;
//! - [`run`]: runs of the data path, odometry and SLAM over any frame source: the library API
//!   behind `replay` and `demo`, which xtask and the tests call;
//! - [`anchor_script`]: `--anchors` scripts (place, scale, remove virtual objects by frame);
//! - [`map_file`]: saved map files read and checked whole, summarized, written as PLY;
//! - [`report`]: what a run writes (report.json, trajectories, plots) and the console summary;
//! - [`page`]: report.html, the run's self-contained page with a 3D view of its map;
//! - [`mcap_out`]: a run's results as an MCAP file of Foxglove messages (`--mcap`);
//! - [`replay`] and [`demo`]: a recorded folder or the synthetic sequence opened, run and written
//!   out, returning the typed report: what `ferroslam-sim replay` and `demo` do, which xtask
//!   calls in process;
//! - [`commands`]: the CLI's subcommands, thin: arguments in, a run, its outputs.

pub mod anchor_script;
pub mod ar_files;
pub mod commands;
pub mod dataset;
pub mod demo;
pub mod eval;
pub mod faults;
pub mod frame;
pub mod map_file;
pub mod mcap_out;
pub mod page;
pub mod plane_truth;
pub mod plot;
pub mod replay;
pub mod report;
pub mod run;
pub mod serial;
pub mod synth;
pub mod trajectory;
