//! # incise (host)
//!
//! The `std` side of incise: it feeds the allocation-free core (`incise-core`) with tracked
//! features from fixture tracks or, with the `opencv` feature, from a video, validates it
//! against ground truth and reports.
//!
//! Modules, one per concern:
//! - [`scene`]: the scene directory format: `scene.toml` and its sections (`scene/file.rs`),
//!   tracks and ground-truth files (`scene/formats.rs`), loading a scene and the core's model
//!   configuration built from it (`scene/mod.rs`).
//! - [`msh`]: Gmsh mesh files (versions 1, 2.2 and 4.1, ASCII): the reader and writer
//!   (`msh/mod.rs`), the line reader (`msh/lines.rs`), node and element sections of every
//!   version driven by one element table (`msh/sections.rs`).
//! - [`vtu`]: VTK unstructured grids: output for ParaView, and input of tetrahedral meshes.
//! - [`calibration`]: the camera calibration file (OpenCV's YAML/XML), and with the `opencv`
//!   feature the undistortion of tracked points.
//! - [`limits`]: the bounds every size of a scene or scenario is checked against, and the
//!   memory budget.
//! - [`storage`]: a model's storage: owned buffers sized for a scene's capacities, checked
//!   against the limits first.
//! - [`run`]: `incise run`: the frame loop (`run/mod.rs`), where frames come from
//!   (`run/sources.rs`: tracks, a tracked video), the ground truth and per-frame measures
//!   (`run/truth.rs`), where outputs go (`run/sinks.rs`), what a pass records and its summary
//!   (`run/trace.rs`).
//! - [`render`]: rasterised silhouettes, the drawing canvas (`render/mod.rs`) and the overlay
//!   picture of a frame (`render/overlay.rs`).
//! - [`metrics`]: Dice, surface and target errors, polyline distances.
//! - [`report`]: human summaries, overview pictures, plots, and the files of a run (VTU per
//!   frame, `frames.csv`).
//! - [`generate`]: the synthetic-scene generator (`incise gen`) (the "real" object, its motion
//!   and its images).
//! - [`codegen`]: `incise codegen`: one scene as a Rust module for a firmware build
//!   (`codegen/mod.rs`), and the firmware program built and measured (`codegen/footprint.rs`).
//! - [`eval`]: `incise eval`, scene families run end to end and summed up.
//! - [`rng`]: a small seeded random generator, so that everything generated is reproducible.
//! - [`cli`]: the `incise` command line: its arguments and dispatch (`cli/mod.rs`), one function
//!   per command (`cli/commands.rs`).
//! - `video`, `track` (the `opencv` feature): video input and output, and KLT tracking.
#![forbid(unsafe_code)]
#![warn(missing_docs)]
// Every fallible public function says what it returns on error.
#![warn(clippy::missing_errors_doc)]
// Geometry and image loops index several arrays with one variable; `!(x > 0.0)` is meant to
// be true for NaN.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

pub mod calibration;
pub mod cli;
pub mod codegen;
pub mod eval;
pub mod generate;
pub mod limits;
pub mod metrics;
pub mod msh;
pub mod render;
pub mod report;
pub mod rng;
pub mod run;
pub mod scene;
pub mod storage;
pub mod vtu;

// The OpenCV video driver.
#[cfg(feature = "opencv")]
pub mod track;
#[cfg(feature = "opencv")]
pub mod video;
