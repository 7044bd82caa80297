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
        }
    }
}

impl core::error::Error for Error {}
