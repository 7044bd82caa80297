//! # incise (host)
//!
//! The `std` side of incise: it feeds the allocation-free core (`incise-core`) with tracked
//! features from fixture tracks or, with the `opencv` feature, from a video, validates it
//! against ground truth and reports.
//!
//! Modules, one per concern:
//! - [`msh`]: Gmsh mesh files (versions 1, 2.2 and 4.1, ASCII).
//! - [`vtu`]: VTK unstructured grids: output for ParaView, and input of tetrahedral meshes.
//! - [`render`]: rasterised silhouettes and overlay pictures.
//! - [`metrics`]: Dice, surface and target errors, polyline distances.
//! - [`generate`]: the synthetic-scene generator (`incise gen`) (the "real" object, its motion and its images).
//! - [`scene`]: the scene directory format (scene.toml, tracks, ground truth).
//! - [`limits`]: the bounds every size of a scene or scenario is checked against, and the
//!   memory budget.
//! - [`run`]: `incise run`, the frame loop over a scene and its metrics.
//! - [`rng`]: a small seeded random generator, so that everything generated is reproducible.
//! - [`report`]: human summaries, overview pictures, plots.
//! - [`eval`]: `incise eval`, scene families run end to end and summed up.
//! - [`cli`]: the `incise` command line.
//! - `video`, `track` (the `opencv` feature): video input and output, KLT tracking, camera
//!   calibration.
#![forbid(unsafe_code)]
// Geometry and image loops index several arrays with one variable; `!(x > 0.0)` is meant to
// be true for NaN.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

pub mod calibration;
pub mod cli;
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
