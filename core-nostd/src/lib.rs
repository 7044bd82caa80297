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
//! The per-frame path, top to bottom, is [`model::Model::step`]: take the frame's observations
//! ([`features`]), then a fixed number of Newton steps ([`solve`]) on the elastic energy of the
//! mesh ([`mesh`], [`material`]) plus the springs to the observations through the camera
//! ([`camera`]), each solved with the sparse factorization ([`sparse`]); with the `detect`
//! feature, then detection and the cut line, and with the `cut` feature a cut of the mesh
//! where the line has grown.
//!
//! Modules, one per concern:
//! - [`model`]: the model built in caller storage, and the per-frame step.
//! - [`mesh`]: the tetrahedral mesh, its fixed nodes and its boundary surface.
//! - [`camera`]: the pinhole camera, projection, Jacobian and rays.
//! - [`features`]: virtual features embedded in the surface, and the frame's observations.
//! - [`solve`]: the per-frame minimisation: assembly, the Newton loop with the `Refactor`,
//!   `Frozen` and `FactorOnce` strategies, PCG and the line search.
//! - [`detect`]: cut detection from motion discontinuities (the detector needs the `detect`
//!   feature; its configuration is always there).
//! - `cutline` (`detect` feature): the cut polyline, its fronts, and the separation surface.
//! - `cut` (`cut` feature): cutting the volume mesh along the separation surface (snap, split,
//!   separate, re-embed), on a spare copy of the model's storage swapped in on success.
//! - [`material`]: Saint Venant–Kirchhoff elasticity on linear tetrahedra, in layers: the law
//!   (Lamé parameters, strain, stress), the element's rest geometry, and the element energy,
//!   forces and (optionally PSD-projected) 12 × 12 tangent with its 3 × 3 eigen-solve.
//! - [`sparse`]: symmetric sparse patterns, a minimum-degree ordering, the symbolic analysis and
//!   the numeric LDLᵀ factorization with its solves.
//! - [`storage`]: carving caller-owned slices into the pieces a structure needs.
//! - [`real`]: the scalar trait (`f32` and `f64`).
//! - [`error`]: the one error type of the crate.
#![no_std]
#![forbid(unsafe_code)]
// No panic reachable from the public API (issue 13): the panicking shortcuts and indexing
// (`x[i]`, `&x[a..b]`: every index goes through `get`, and a miss is a typed error) are denied
// outside the unit tests. Arithmetic is not linted (the README's "Reliability" section says
// how input-derived sizes are checked instead).
#![cfg_attr(
    not(test),
    deny(
        clippy::indexing_slicing,
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::todo,
        clippy::unimplemented,
        clippy::unreachable
    )
)]
// Numerical kernels index several arrays with one loop variable; iterator chains would hide
// which entries meet.
#![allow(clippy::needless_range_loop)]
// `!(x > 0)` is deliberate: it is true for NaN, which is exactly when we want to stop.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

#[cfg(not(any(
    feature = "refactor",
    feature = "frozen",
    feature = "factor-once",
    feature = "quasi-newton"
)))]
compile_error!(
    "incise-core needs at least one linear strategy: enable `refactor`, `frozen`, \
     `factor-once`, `quasi-newton` or all of them (`strategies`, a default feature)"
);

#[cfg(not(any(feature = "f32", feature = "f64")))]
compile_error!(
    "incise-core needs at least one scalar type: enable `f32`, `f64` or both (`scalars`, a \
     default feature)"
);

#[cfg(not(any(feature = "perspective", feature = "orthographic")))]
compile_error!(
    "incise-core needs at least one camera projection: enable `perspective`, `orthographic` or \
     both (`cameras`, a default feature)"
);

pub mod camera;
#[cfg(feature = "cut")]
pub mod cut;
#[cfg(feature = "detect")]
pub mod cutline;
pub mod detect;
pub mod embed;
pub mod error;
pub mod features;
pub mod material;
pub mod mesh;
pub mod model;
pub mod real;
pub mod robust;
pub mod solve;
pub mod sparse;
pub mod storage;

pub use error::{Error, Parameter, PrecomputedProblem, Resource};
pub use real::Real;
// The small matrices of the public API (camera pose) are nalgebra's; re-exported so that a user
// needs no version of their own.
pub use nalgebra;

pub use camera::{Camera, Intrinsics, Projection};
#[cfg(feature = "cut")]
pub use cut::{CutEvent, CutReport, CutWork};
#[cfg(feature = "detect")]
pub use cutline::LineWork;
pub use detect::{DetectionConfig, DetectionWork};
pub use features::{EmbedReport, Observation};
pub use material::Law;
pub use mesh::{MeshCapacity, MeshInput};
pub use model::{
    Capacities, Linearization, MAX_STORAGE_LEN, Material, MeshAnalysis, Model, ModelBuffers,
    ModelConfig, ModelSize, StepReport, StoragePart, analyse_mesh, analyse_mesh_work_len,
};
pub use solve::{Coupling, Energies, SolverConfig, Strategy, WorkCount};
