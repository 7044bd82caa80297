//! # incise-core
//!
//! The `no_std`, allocation-free heart of incise: it keeps a coarse tetrahedral model of an organ
//! aligned with tracked image features (Paulus et al., MICCAI 2015) at a fixed, bounded cost per
//! frame.
//!
//! The core never allocates, never reads files and never prints. Every structure is built inside
//! storage the caller hands over (plain slices, sized up front by a `*_len` / `*size` function),
//! in the manner of smoltcp and QDLDL; capacities are fixed at construction and an overflow is an
//! [`Error`], never a panic or a silent truncation.
//!
//! Modules, one per concern:
//! - [`sparse`]: symmetric sparse patterns, a minimum-degree ordering, the symbolic analysis and
//!   the numeric LDLᵀ factorization with its solves.
//! - [`storage`]: carving caller-owned slices into the pieces a structure needs.
//! - [`real`]: the scalar trait (`f32` and `f64`).
//! - [`error`]: the one error type of the crate.
#![no_std]
#![forbid(unsafe_code)]

pub mod error;
pub mod real;
pub mod sparse;
pub mod storage;

pub use error::{Error, Parameter, Resource};
pub use real::Real;
