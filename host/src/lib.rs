//! # incise (host)
//!
//! The `std` side of incise: it feeds the allocation-free core (`incise-core`) with tracked
//! features from fixture tracks or, with the `opencv` feature, from a video, validates it
//! against ground truth and reports.
//!
//! Modules, one per concern:
//! - [`msh`]: Gmsh mesh files (versions 1, 2.2 and 4.1, ASCII).
//! - [`vtu`]: VTK unstructured-grid output for ParaView.
//! - [`render`]: rasterised silhouettes and overlay pictures.
//! - [`metrics`]: Dice, surface and target errors, polyline distances.
//! - [`generate`]: the synthetic-scene generator (`incise gen`) (the "real" object, its motion and its images).
//! - [`rng`]: a small seeded random generator, so that everything generated is reproducible.
//! - [`cli`]: the `incise` command line.
#![forbid(unsafe_code)]

pub mod cli;
pub mod generate;
pub mod metrics;
pub mod msh;
pub mod render;
pub mod rng;
pub mod vtu;
