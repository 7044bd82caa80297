//! Shared helpers for the fixture-based tests and benchmarks of incise: test meshes, a seeded
//! random generator, the whole sparse pipeline of the core driven from `Vec` storage, and the
//! `faer` oracle it is checked against. Not part of the product.

pub mod bench_model;
pub mod callgrind;
pub mod oracle;
pub use incise::rng;
pub mod cutcheck;
pub mod scene;
pub mod symbols;
pub mod system;
pub mod testmesh;
