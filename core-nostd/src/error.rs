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
    /// Slots of the embedded features (`0..` the number embedded), as opposed to their ids.
    FeatureSlots,
    /// Segments of the cut line (quadrilaterals of the separation surface).
    CutSegments,
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
            Resource::FeatureSlots => "feature slots",
            Resource::CutSegments => "cut-line segments",
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
    /// The material's strain energy law: this core was built without it (feature
    /// `neo-hookean`).
    Law,
    /// Poisson ratio (must lie in `(-1, 0.5)`).
    PoissonRatio,
    /// Spring stiffness of the feature coupling, given or derived from the scene (positive,
    /// finite).
    SpringStiffness,
    /// Damping ratio (non-negative, finite).
    Damping,
    /// Depth prior (non-negative, finite).
    DepthPrior,
    /// Threshold of the springs' robust loss (positive; infinite for quadratic springs).
    SpringThreshold,
    /// Camera intrinsics (positive focal lengths, finite centre, positive image size).
    Intrinsics,
    /// Camera pose (finite, rotation orthonormal with determinant 1).
    Pose,
    /// Camera projection: this core was built without it (features `perspective`,
    /// `orthographic`).
    Projection,
    /// Newton iterations per frame (1 to [`crate::solve::MAX_NEWTON_ITERATIONS`]).
    NewtonIterations,
    /// Line-search trials per Newton step (1 to [`crate::solve::MAX_LINE_SEARCH_STEPS`]).
    LineSearchSteps,
    /// The linear strategy: this core was built without it (features `refactor`, `frozen`,
    /// `factor-once`).
    Strategy,
    /// PCG iterations of [`crate::Strategy::Frozen`] (1 to [`crate::solve::MAX_PCG_ITERATIONS`]).
    PcgIterations,
    /// Image margin beyond which an observation is rejected (non-negative).
    ImageMargin,
    /// Cut detection, `radius_px`: neighbour radius in pixels (finite, non-negative; 0 derives it).
    RadiusPx,
    /// Cut detection, `radius_spacings`: neighbour radius in feature spacings (positive, finite).
    RadiusSpacings,
    /// Cut detection, `max_surface_ratio`: surface-to-image distance ratio of a pair (0, or finite and at least 1).
    MaxSurfaceRatio,
    /// Cut detection, `outlier_sigmas`: outlier threshold of a pair, robust deviations (positive, finite).
    OutlierSigmas,
    /// Cut detection, `temporal_sigmas`: threshold of the temporal filter, robust deviations (positive; infinite turns the filter off).
    TemporalSigmas,
    /// Cut detection, `min_difference_px`: floor of an outlier difference, pixels (finite, non-negative).
    MinDifferencePx,
    /// Cut detection, `persistence`: frames a pair must stay an outlier (1 to 254).
    Persistence,
    /// Cut detection, `init_points`: separation points that start the cut line (at least 2).
    InitPoints,
    /// Cut detection, `alpha_degrees`: angular restriction of a front, degrees (in `(0, 90]`).
    AlphaDegrees,
    /// Cut detection, `min_step`: shortest advance of a front, spacings (finite, non-negative, at most `max_step`).
    MinStep,
    /// Cut detection, `max_step`: longest advance of a front, spacings (positive, finite).
    MaxStep,
    /// Cut detection, `min_support`: separation points needed to advance a front (at least 1).
    MinSupport,
    /// Cut detection, `line_tolerance`: distance of a point counted for the line fit, spacings (positive, finite).
    LineTolerance,
    /// Cut detection, `max_outlier_fraction`: fraction of outlier pairs that makes a feature a tracking failure (positive, finite).
    MaxOutlierFraction,
    /// Cut detection, `depth`: extrusion direction of the cut (finite, not zero).
    Depth,
    /// [`crate::Model::cut_along`]'s `extension_px`: how far the cut reaches past the line's
    /// ends, pixels (finite, non-negative).
    CutExtension,
}

impl fmt::Display for Parameter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // The ranges bounded by the solver's constants, which the message gives as numbers.
        let bounded = match self {
            Parameter::NewtonIterations => {
                Some(("newton_iterations", crate::solve::MAX_NEWTON_ITERATIONS))
            }
            Parameter::LineSearchSteps => {
                Some(("line_search_steps", crate::solve::MAX_LINE_SEARCH_STEPS))
            }
            Parameter::PcgIterations => Some(("pcg_iterations", crate::solve::MAX_PCG_ITERATIONS)),
            _ => None,
        };
        if let Some((name, max)) = bounded {
            return write!(f, "{name} must lie in 1..={max}");
        }
        let s = match self {
            Parameter::YoungModulus => "Young's modulus must be positive and finite",
            Parameter::Law => {
                "this material law is not built into the core: enable its feature (neo-hookean)"
            }
            Parameter::PoissonRatio => "Poisson ratio must lie in (-1, 0.5)",
            Parameter::SpringStiffness => {
                "spring coupling must be positive and finite (given, or derived from the scene)"
            }
            Parameter::Damping => "damping must be non-negative and finite",
            Parameter::DepthPrior => "the depth prior must be non-negative and finite",
            Parameter::SpringThreshold => {
                "the springs' robust threshold must be positive (infinite for quadratic springs)"
            }
            Parameter::Intrinsics => {
                "camera intrinsics need positive focal lengths, a finite centre and a positive image size"
            }
            Parameter::Pose => "camera pose must be finite with an orthonormal rotation",
            Parameter::Projection => {
                "this camera projection is not built into the core: enable its feature (perspective, orthographic)"
            }
            Parameter::Strategy => {
                "this strategy is not built into the core: enable its feature (refactor, frozen, factor-once)"
            }
            Parameter::ImageMargin => "image margin must be non-negative and finite",
            Parameter::RadiusPx => {
                "detection radius_px must be finite and non-negative (0 derives it from the features' density)"
            }
            Parameter::RadiusSpacings => "detection radius_spacings must be positive and finite",
            Parameter::MaxSurfaceRatio => {
                "detection max_surface_ratio must be 0 or finite and at least 1"
            }
            Parameter::OutlierSigmas => "detection outlier_sigmas must be positive and finite",
            Parameter::TemporalSigmas => {
                "detection temporal_sigmas must be positive (infinite turns the temporal filter off)"
            }
            Parameter::MinDifferencePx => {
                "detection min_difference_px must be finite and non-negative"
            }
            Parameter::Persistence => "detection persistence must lie in 1..=254",
            Parameter::InitPoints => "detection init_points must be at least 2",
            Parameter::AlphaDegrees => "detection alpha_degrees must lie in (0, 90] degrees",
            Parameter::MinStep => {
                "detection min_step must be finite, non-negative and at most max_step"
            }
            Parameter::MaxStep => "detection max_step must be positive and finite",
            Parameter::MinSupport => "detection min_support must be at least 1",
            Parameter::LineTolerance => "detection line_tolerance must be positive and finite",
            Parameter::MaxOutlierFraction => {
                "detection max_outlier_fraction must be positive and finite"
            }
            Parameter::Depth => "detection depth must be finite and not zero",
            Parameter::CutExtension => "the cut's extension must be finite and non-negative",
            Parameter::NewtonIterations | Parameter::LineSearchSteps | Parameter::PcgIterations => {
                ""
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

/// What is wrong with a precomputed symbolic analysis, in [`Error::Precomputed`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum PrecomputedProblem {
    /// An array's length does not follow from the stated sizes.
    Lengths,
    /// The checksum does not match the arrays: damaged or edited data.
    Checksum,
    /// It was computed for another matrix: another dimension, entry count or pattern (the mesh
    /// it was generated from is not the one loaded).
    Matrix,
    /// An index out of range, a list out of order, or the trees, rows, columns or supernodes
    /// disagree.
    Structure,
    /// The factor's pattern misses fill: a column's entries are not all in its parent's.
    Fill,
}

impl fmt::Display for PrecomputedProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PrecomputedProblem::Lengths => "an array's length does not match the stated sizes",
            PrecomputedProblem::Checksum => "its checksum does not match (damaged or edited)",
            PrecomputedProblem::Matrix => {
                "it was computed for another stiffness pattern (another mesh or fixed nodes)"
            }
            PrecomputedProblem::Structure => "its index arrays are inconsistent",
            PrecomputedProblem::Fill => "the factor's pattern misses fill",
        })
    }
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
    /// A capacity asks for more than the core can hold: `requested` of `resource` (or of what
    /// follows from it, such as the unknowns `3 n` of `n` nodes) where at most `limit` fit,
    /// because indices are `u32` ([`crate::sparse::pattern::MAX_INDEX`]) or because storage lengths must
    /// fit a slice ([`crate::model::MAX_STORAGE_LEN`]). A request too large to count is given as
    /// `usize::MAX`. Raised by [`crate::ModelSize::new`].
    TooLarge {
        /// What was asked for.
        resource: Resource,
        /// How many (saturated at `usize::MAX`).
        requested: usize,
        /// The most the core holds.
        limit: usize,
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
    /// A precomputed symbolic analysis ([`crate::sparse::PrecomputedAnalysis`]) does not fit
    /// the matrix it is loaded for, or is damaged.
    Precomputed {
        /// What does not hold.
        problem: PrecomputedProblem,
    },
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
        /// Index of the point, as the caller of [`crate::Camera::project`] numbered it (a
        /// virtual feature is reported as [`Error::FeatureBehindCamera`] instead).
        index: usize,
    },
    /// The virtual feature in `slot` (tracked as `id`) lies at or behind the camera's plane of
    /// projection, so its spring cannot be evaluated.
    FeatureBehindCamera {
        /// Slot of the feature in the model (see [`crate::features::Features::ids`]).
        slot: usize,
        /// Its id, as the frames name it.
        id: u32,
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
            Error::TooLarge {
                resource,
                requested,
                limit,
            } => write!(
                f,
                "too large: {requested} {resource} requested, the core holds at most {limit}"
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
            Error::Precomputed { problem } => {
                write!(f, "the precomputed symbolic analysis is refused: {problem}")
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
            Error::FeatureBehindCamera { slot, id } => write!(
                f,
                "virtual feature of id {id} (slot {slot}) lies at or behind the camera"
            ),
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
