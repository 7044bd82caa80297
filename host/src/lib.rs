//! # incise (host)
//!
//! The `std` side of incise: it feeds the allocation-free core (`incise-core`) with tracked
//! features from fixture tracks or, with the `opencv` feature, from a video, validates it
//! against ground truth and reports.
#![forbid(unsafe_code)]

pub mod cli;
