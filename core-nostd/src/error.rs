//! The one error type of the core.
//!
//! Every fallible entry point returns [`Error`]. A call that fails leaves the structure it was
//! called on as it was before the call, unless its documentation says otherwise.

use core::fmt;

/// Names a buffer or fixed capacity, so that a [`Error::Capacity`] or [`Error::Length`] says
/// which one was too small or of the wrong length.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Resource {
    /// Column pointers of a compressed-column structure (length `n + 1`).
    ColumnPointers,
    /// Entries (row indices or values) of a sparse matrix `A`.
    MatrixEntries,
    /// Entries of the factor `L`.
    FactorEntries,
    /// Entries of an adjacency graph (both triangles, no diagonal).
    GraphEntries,
    /// A permutation of `0..n`.
    Permutation,
    /// Index (`u32`) storage handed to a constructor.
    IndexStorage,
    /// Scalar storage handed to a constructor.
    RealStorage,
    /// A scratch workspace.
    Workspace,
    /// A dense vector (right-hand side, solution, diagonal).
    Vector,
    /// Mesh nodes.
    Nodes,
    /// Tetrahedra.
    Tetrahedra,
    /// Boundary (surface) triangles.
    SurfaceTriangles,
    /// Tracked features.
    Features,
    /// Observations of one frame.
    Observations,
    /// Neighbour pairs of the cut detection.
    Pairs,
    /// Vertices of the cut line.
    CutVertices,
    /// Unknowns of the linear system (three per free node).
    Unknowns,
    /// Internal targets carried by the model.
    Targets,
}

impl fmt::Display for Resource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = match self {
            Resource::ColumnPointers => "column pointers",
            Resource::MatrixEntries => "matrix entries",
            Resource::FactorEntries => "factor entries",
            Resource::GraphEntries => "graph entries",
            Resource::Permutation => "permutation",
            Resource::IndexStorage => "index storage",
            Resource::RealStorage => "scalar storage",
            Resource::Workspace => "workspace",
            Resource::Vector => "vector",
            Resource::Nodes => "nodes",
            Resource::Tetrahedra => "tetrahedra",
            Resource::SurfaceTriangles => "surface triangles",
            Resource::Features => "features",
            Resource::Observations => "observations",
            Resource::Pairs => "neighbour pairs",
            Resource::CutVertices => "cut-line vertices",
            Resource::Unknowns => "unknowns",
            Resource::Targets => "internal targets",
        };
        f.write_str(s)
    }
}

/// A configuration parameter, named in [`Error::InvalidParameter`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Parameter {
    /// Young's modulus (must be positive and finite).
    YoungModulus,
    /// Poisson ratio (must lie in `(-1, 0.5)`).
    PoissonRatio,
    /// Spring stiffness of the feature coupling (positive, finite).
    SpringStiffness,
    /// Damping ratio (non-negative, finite).
    Damping,
    /// Depth prior (non-negative, finite).
    DepthPrior,
    /// Camera intrinsics (positive focal lengths, finite centre, positive image size).
    Intrinsics,
    /// Camera pose (finite, rotation orthonormal with determinant 1).
    Pose,
    /// Iteration counts of the solver (Newton, line search, PCG): positive and bounded.
    Iterations,
    /// Image margin beyond which an observation is rejected (non-negative).
    ImageMargin,
    /// Cut detection parameters (positive thresholds, `α` in `(0, 90]` degrees, steps ordered).
    Detection,
}

impl fmt::Display for Parameter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = match self {
            Parameter::YoungModulus => "Young's modulus must be positive and finite",
            Parameter::PoissonRatio => "Poisson ratio must lie in (-1, 0.5)",
            Parameter::SpringStiffness => "spring stiffness must be positive and finite",
            Parameter::Damping => "damping must be non-negative and finite",
            Parameter::DepthPrior => "the depth prior must be non-negative and finite",
            Parameter::Intrinsics => {
                "camera intrinsics need positive focal lengths, a finite centre and a positive image size"
            }
            Parameter::Pose => "camera pose must be finite with an orthonormal rotation",
            Parameter::Iterations => "iteration counts must be positive and within their bounds",
            Parameter::ImageMargin => "image margin must be non-negative and finite",
            Parameter::Detection => {
                "detection needs positive thresholds, an angle in (0, 90] degrees and min step <= max step"
            }
        };
        f.write_str(s)
    }
}

/// What is wrong with a sparse pattern handed to [`crate::sparse::UpperCsc::new`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum PatternProblem {
    /// Column pointers do not start at 0, decrease, or do not end at the number of entries.
    ColumnPointers,
    /// A row index is larger than its column (the pattern must be the upper triangle).
    BelowDiagonal,
    /// Row indices of a column are not strictly increasing.
    Unsorted,
    /// The diagonal entry of a column is missing.
    MissingDiagonal,
    /// A dimension or entry count does not fit the `u32` indices.
    TooLarge,
}

/// The error type of every fallible call in the core.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Error {
    /// A caller-sized buffer or a fixed capacity is too small: `needed` entries were required,
    /// `available` were provided.
    Capacity {
        /// Which buffer or capacity.
        resource: Resource,
        /// Entries required.
        needed: usize,
        /// Entries available.
        available: usize,
    },
    /// An input slice has the wrong length.
    Length {
        /// Which input.
        resource: Resource,
        /// Length required.
        expected: usize,
        /// Length given.
        found: usize,
    },
    /// A sparse pattern breaks an invariant in `column`.
    Pattern {
        /// The offending column.
        column: usize,
        /// What is wrong.
        problem: PatternProblem,
    },
    /// An index is out of range: `index` at position `position` of the input, which must be
    /// below `bound`.
    IndexOutOfRange {
        /// What the index refers to.
        resource: Resource,
        /// Position of the index in its input slice.
        position: usize,
        /// The index.
        index: usize,
        /// Exclusive upper bound.
        bound: usize,
    },
    /// A permutation repeats the value at `position`.
    NotAPermutation {
        /// Position of the repeated value.
        position: usize,
    },
    /// The pivot of `column` (in the permuted order of the factorization) is zero or negative:
    /// the matrix is not positive definite.
    NotPositiveDefinite {
        /// Column of the permuted matrix.
        column: usize,
    },
    /// The pivot of `column` (permuted order) is NaN or infinite: the matrix holds a
    /// non-finite value.
    NotFinite {
        /// Column of the permuted matrix.
        column: usize,
    },
    /// A solve was asked of a factor that holds no successful factorization.
    NotFactored,
    /// The factor was computed for another symbolic analysis (different sizes).
    SymbolicMismatch,
    /// A configuration parameter is out of its range.
    InvalidParameter {
        /// Which parameter.
        parameter: Parameter,
    },
    /// A rest tetrahedron has (almost) no volume.
    DegenerateElement {
        /// Index of the tetrahedron.
        tet: usize,
    },
    /// A rest tetrahedron is inverted (negative volume for its node order).
    InvertedElement {
        /// Index of the tetrahedron.
        tet: usize,
    },
    /// A coordinate or value given as input is NaN or infinite.
    NonFiniteInput {
        /// What the value belongs to.
        resource: Resource,
        /// Its position in the input.
        position: usize,
    },
    /// The boundary surface is not a closed 2-manifold: the edge `(a, b)` is shared by a number
    /// of boundary triangles other than two, or a face by more than two tetrahedra.
    NonManifold {
        /// First node of the edge or face.
        a: usize,
        /// Second node of the edge or face.
        b: usize,
    },
    /// No node is fixed: with the features only constraining the image plane, the problem
    /// would be singular.
    NoFixedNodes,
    /// A point lies at or behind the camera's plane of projection.
    BehindCamera {
        /// Index of the point (node or feature, per the call).
        index: usize,
    },
    /// A frame names a feature id that was not registered at frame 0.
    UnknownFeature {
        /// The id.
        id: u32,
    },
    /// A frame names the same feature id twice.
    DuplicateFeature {
        /// The id.
        id: u32,
    },
    /// An observation lies farther outside the image than the configured margin.
    OutsideImage {
        /// The feature id.
        id: u32,
    },
    /// A frame holds no observation at all.
    EmptyFrame,
    /// No feature has been embedded yet (or none hit the model).
    NoFeatures,
    /// The solve produced a non-finite value; the state was rolled back.
    Diverged,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::Capacity {
                resource,
                needed,
                available,
            } => write!(
                f,
                "capacity exceeded: {resource} needs {needed} entries, {available} available"
            ),
            Error::Length {
                resource,
                expected,
                found,
            } => write!(f, "{resource} has length {found}, expected {expected}"),
            Error::Pattern { column, problem } => {
                let what = match problem {
                    PatternProblem::ColumnPointers => "column pointers are inconsistent",
                    PatternProblem::BelowDiagonal => "a row index lies below the diagonal",
                    PatternProblem::Unsorted => "row indices are not strictly increasing",
                    PatternProblem::MissingDiagonal => "the diagonal entry is missing",
                    PatternProblem::TooLarge => "the size does not fit 32-bit indices",
                };
                write!(f, "invalid sparse pattern in column {column}: {what}")
            }
            Error::IndexOutOfRange {
                resource,
                position,
                index,
                bound,
            } => write!(
                f,
                "{resource} index {index} at position {position} is out of range (bound {bound})"
            ),
            Error::NotAPermutation { position } => {
                write!(f, "not a permutation: value at position {position} repeats")
            }
            Error::NotPositiveDefinite { column } => write!(
                f,
                "matrix is not positive definite: pivot of column {column} is not positive"
            ),
            Error::NotFinite { column } => {
                write!(f, "non-finite value reached the pivot of column {column}")
            }
            Error::NotFactored => f.write_str("no successful factorization to solve with"),
            Error::SymbolicMismatch => {
                f.write_str("factor storage was sized for another symbolic analysis")
            }
            Error::InvalidParameter { parameter } => write!(f, "invalid parameter: {parameter}"),
            Error::DegenerateElement { tet } => {
                write!(f, "tetrahedron {tet} is degenerate (no volume)")
            }
            Error::InvertedElement { tet } => write!(f, "tetrahedron {tet} is inverted"),
            Error::NonFiniteInput { resource, position } => {
                write!(f, "non-finite value in {resource} at position {position}")
            }
            Error::NonManifold { a, b } => write!(
                f,
                "boundary surface is not a closed manifold near nodes {a} and {b}"
            ),
            Error::NoFixedNodes => {
                f.write_str("no fixed node: the registration problem would be singular")
            }
            Error::BehindCamera { index } => {
                write!(f, "point {index} lies at or behind the camera")
            }
            Error::UnknownFeature { id } => write!(f, "unknown feature id {id}"),
            Error::DuplicateFeature { id } => write!(f, "feature id {id} appears twice"),
            Error::OutsideImage { id } => {
                write!(f, "feature {id} lies too far outside the image")
            }
            Error::EmptyFrame => f.write_str("the frame holds no observation"),
            Error::NoFeatures => f.write_str("no feature is embedded in the model"),
            Error::Diverged => {
                f.write_str("the solve produced a non-finite value; the state was rolled back")
            }
        }
    }
}

impl core::error::Error for Error {}
