//! What a model holds at most, and the storage that follows from it.
//!
//! Everything is a `const fn` of the scene's [`Capacities`], so a firmware build can size its
//! buffers at compile time; a host asks [`ModelSize::new`] and allocates. Nothing depends on the
//! mesh itself except the initial fill of the factor, which [`analyse_mesh`] reports to help
//! choose [`Capacities::factor_entries`].

use crate::embed::Embedding;
use crate::error::{Error, Resource};
use crate::features::Features;
use crate::mesh::{MeshCapacity, MeshInput};
use crate::real::Real;
use crate::solve::{KeptElements, SecantMemory};
use crate::sparse::pattern::MAX_INDEX;
use crate::sparse::{
    Graph, LdlFactor, NONE, Symbolic, SymbolicSize, UpperCsc, analyse_work_len, block_upper_len,
    block_upper_pattern, expand_block_permutation, fill_reducing_order,
    fill_reducing_order_work_len, tet_graph_work_len,
};
use crate::storage::{Slab, ensure_len, sum, times};

#[cfg(feature = "cut")]
use crate::cut;
#[cfg(feature = "detect")]
use crate::cutline::CutLine;
#[cfg(feature = "detect")]
use crate::detect::Detector;

/// The scalar the storage lengths are computed with: they are the same for every scalar type
/// (scalars and indices are counted, not bytes), so any one the build has will do.
#[cfg(feature = "f64")]
type AnyReal = f64;
#[cfg(all(feature = "f32", not(feature = "f64")))]
type AnyReal = f32;

/// The most a model holds, fixed when it is built. A cut adds nodes, tetrahedra and fill; it
/// must fit these or it is refused with [`Error::Capacity`] (and the model stays as it was).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Capacities {
    /// Nodes, tetrahedra and boundary triangles, after every cut.
    pub mesh: MeshCapacity,
    /// Tracked features.
    pub features: usize,
    /// Internal targets the model carries ([`crate::Model::embed_targets`]).
    pub targets: usize,
    /// Entries of the factor `L` (strictly lower triangle), after every cut: the fill a
    /// topology needs depends on its ordering, so it is stated, not derived. [`analyse_mesh`]
    /// gives the initial mesh's.
    pub factor_entries: usize,
    /// Neighbour pairs of the cut detection (`cut` feature; the paper's liver had 18 503).
    pub pairs: usize,
    /// Vertices of the cut line (`cut` feature).
    pub cut_vertices: usize,
}

/// One part of a model's storage ([`ModelSize::parts`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct StoragePart {
    /// What it holds.
    pub name: &'static str,
    /// The capacities (and mesh sizes) it grows with.
    pub grows_with: &'static str,
    /// Scalars.
    pub reals: usize,
    /// Indices.
    pub indices: usize,
    /// The feature of the core that brings it (`"detect"` or `"cut"`; 0 entries without
    /// it), or `None` for a part every build has.
    pub feature: Option<&'static str>,
}

impl StoragePart {
    /// Bytes for scalar type `T`, saturated.
    pub const fn bytes<T>(&self) -> usize {
        sum(&[
            times(self.reals, core::mem::size_of::<T>()),
            times(self.indices, 4),
        ])
    }
}

/// Storage sizes of a model, all functions of its [`Capacities`], which [`ModelSize::new`] has
/// checked: every count fits the core's `u32` indices and every storage length fits a slice,
/// so the lengths below are exact and a model built from them cannot overflow its indices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ModelSize {
    capacities: Capacities,
    nnz_a: usize,
    unknowns: usize,
}

/// Most entries [`ModelSize::new`] lets [`ModelSize::real_len`] or [`ModelSize::index_len`]
/// reach: the longest slice of `f64` the address space allows (`isize::MAX` bytes).
pub const MAX_STORAGE_LEN: usize = isize::MAX as usize / 8;

/// Halves of the topology-dependent storage: the one in service and, when the mesh can be
/// cut, the spare a cut is built into.
const HALVES: usize = if cfg!(feature = "cut") { 2 } else { 1 };

const fn max(a: usize, b: usize) -> usize {
    if a > b { a } else { b }
}

/// `Err(TooLarge)` when `requested` exceeds `limit`.
const fn at_most(resource: Resource, requested: usize, limit: usize) -> Result<(), Error> {
    if requested > limit {
        Err(Error::TooLarge {
            resource,
            requested,
            limit,
        })
    } else {
        Ok(())
    }
}

/// `?` for a `const fn`.
macro_rules! check {
    ($e:expr) => {
        if let Err(e) = $e {
            return Err(e);
        }
    };
}

impl ModelSize {
    /// The sizes for `capacities`, once they are checked against what the core can hold.
    ///
    /// Node, tetrahedron, triangle, feature, target, pair, cut-vertex and factor-entry counts
    /// are stored in `u32` indices, so each, and the unknowns `3 n` and the stiffness entries
    /// `6 n + 54 t` that follow from the nodes `n` and tetrahedra `t`, must be at most
    /// [`MAX_INDEX`]; the storage lengths ([`ModelSize::real_len`], [`ModelSize::index_len`])
    /// must be at most [`MAX_STORAGE_LEN`]. The arithmetic saturates
    /// ([`crate::storage::times`]), so no capacity, however large, overflows on the way.
    ///
    /// # Errors
    /// [`Error::TooLarge`] naming the first count that does not fit: [`Resource::Nodes`],
    /// [`Resource::Unknowns`], [`Resource::Tetrahedra`], [`Resource::MatrixEntries`],
    /// [`Resource::SurfaceTriangles`], [`Resource::Features`], [`Resource::Targets`],
    /// [`Resource::FactorEntries`], [`Resource::Pairs`], [`Resource::CutVertices`], then
    /// [`Resource::RealStorage`] or [`Resource::IndexStorage`].
    pub const fn new(capacities: &Capacities) -> Result<Self, Error> {
        let c = capacities;
        let (unknowns, nnz_a) = match mesh_counts(c.mesh.nodes, c.mesh.tets) {
            Ok(counts) => counts,
            Err(e) => return Err(e),
        };
        let counts = [
            (Resource::SurfaceTriangles, c.mesh.surface_triangles),
            (Resource::Features, c.features),
            (Resource::Targets, c.targets),
            (Resource::FactorEntries, c.factor_entries),
            (Resource::Pairs, c.pairs),
            (Resource::CutVertices, c.cut_vertices),
        ];
        let mut rest: &[(Resource, usize)] = &counts;
        while let [(resource, count), tail @ ..] = rest {
            check!(at_most(*resource, *count, MAX_INDEX));
            rest = tail;
        }
        let size = ModelSize {
            capacities: *c,
            nnz_a,
            unknowns,
        };
        check!(at_most(
            Resource::RealStorage,
            size.real_len(),
            MAX_STORAGE_LEN
        ));
        check!(at_most(
            Resource::IndexStorage,
            size.index_len(),
            MAX_STORAGE_LEN
        ));
        Ok(size)
    }

    /// The capacities.
    pub const fn capacities(&self) -> &Capacities {
        &self.capacities
    }

    /// Capacity of stored entries of the stiffness matrix (upper triangle): its bound from the
    /// element count, `6 n + 54 t` (a node's diagonal block has 6 stored entries, a node pair
    /// 9, and a tetrahedron joins at most 6 pairs).
    pub const fn nnz_a(&self) -> usize {
        self.nnz_a
    }

    /// Capacity of unknowns: three per node.
    pub const fn unknowns(&self) -> usize {
        self.unknowns
    }

    /// Capacity of the symbolic analysis and the numeric factor.
    pub const fn symbolic_capacity(&self) -> SymbolicSize {
        SymbolicSize {
            n: self.unknowns,
            nnz_a: self.nnz_a,
            nnz_l: self.capacities.factor_entries,
        }
    }

    /// Scalars of one [`Discretization`](super::discretization) half.
    pub(crate) const fn half_real_len(&self) -> usize {
        let c = &self.capacities;
        let n = c.mesh.nodes;
        sum(&[
            c.mesh.real_len(),
            times(3, n), // positions
            times(3, n), // previous positions (damping reference)
            times(2, n), // damping and depth-prior weights
            Embedding::<AnyReal>::real_len(c.features),
            Embedding::<AnyReal>::real_len(c.targets),
        ])
    }

    /// Indices of one half.
    pub(crate) const fn half_index_len(&self) -> usize {
        let c = &self.capacities;
        sum(&[
            c.mesh.index_len(),
            self.unknowns, // column pointers of the stiffness pattern
            1,
            self.nnz_a, // its row indices
            self.symbolic_capacity().index_len(),
            times(30, c.mesh.tets), // scatter map
            Embedding::<AnyReal>::index_len(c.features),
            Embedding::<AnyReal>::index_len(c.targets),
            Self::lips_len(c),
        ])
    }

    /// Scalars of the copies a failing call gives back (features, their embedding, the
    /// damping reference).
    const fn saved_real_len(c: &Capacities) -> usize {
        sum(&[
            Features::<AnyReal>::real_len(c.features),
            Embedding::<AnyReal>::real_len(c.features),
            times(3, c.mesh.nodes),
        ])
    }

    #[cfg(feature = "cut")]
    const fn lips_len(c: &Capacities) -> usize {
        times(2, c.mesh.nodes)
    }

    #[cfg(not(feature = "cut"))]
    const fn lips_len(_: &Capacities) -> usize {
        0
    }

    /// The unknowns the secant memory of [`crate::Strategy::QuasiNewton`] is sized for: all of
    /// them in a build with the `quasi-newton` feature, none without.
    pub(crate) const fn secant_unknowns(&self) -> usize {
        if cfg!(feature = "quasi-newton") {
            self.unknowns
        } else {
            0
        }
    }

    /// The model's storage part by part: what a firmware budget is spent on. Each part names
    /// the capacities it grows with; [`ModelSize::real_len`] and [`ModelSize::index_len`] are
    /// the sums of the parts.
    pub const fn parts(&self) -> [StoragePart; 10] {
        let c = &self.capacities;
        let (detection_reals, detection_indices) = Self::detection_lens(c);
        [
            StoragePart {
                name: "mesh and system in service (positions, boundary, pattern, analysis, scatter map, embeddings)",
                grows_with: "the mesh's nodes and tetrahedra, cut_nodes, cut_tets, factor_entries, features, targets",
                reals: self.half_real_len(),
                indices: self.half_index_len(),
                feature: None,
            },
            StoragePart {
                name: "spare half a cut is built into (cut feature)",
                grows_with: "the same capacities as the half in service",
                reals: times(HALVES - 1, self.half_real_len()),
                indices: times(HALVES - 1, self.half_index_len()),
                feature: Some("cut"),
            },
            StoragePart {
                name: "stiffness matrix values",
                grows_with: "the nodes and tetrahedra (6 n + 54 t entries)",
                reals: self.nnz_a,
                indices: 0,
                feature: None,
            },
            StoragePart {
                name: "factor values (L and D)",
                grows_with: "factor_entries",
                reals: LdlFactor::<AnyReal>::storage_len(&self.symbolic_capacity()),
                indices: 0,
                feature: None,
            },
            StoragePart {
                name: "solver vectors and factorization workspace",
                grows_with: "the nodes",
                reals: sum(&[
                    times(6, self.unknowns),                   // gradient, step, the PCG vectors
                    times(2, self.unknowns), // the solves' right-hand side and scratch
                    LdlFactor::<AnyReal>::SUPERNODAL_WORK_LEN, // packed blocks of the factorization
                    times(3, c.mesh.nodes),  // trial positions of the line search
                    times(6, c.mesh.nodes),  // camera rays through the nodes, what springs see
                ]),
                indices: LdlFactor::<AnyReal>::supernodal_index_work_len(self.unknowns),
                feature: None,
            },
            StoragePart {
                name: "secant pairs of the quasi-Newton strategy, the elements' gradient it keeps between frames, and their copies (quasi-newton feature)",
                grows_with: "the nodes",
                reals: sum(&[
                    SecantMemory::<AnyReal>::real_len(self.secant_unknowns()),
                    KeptElements::<AnyReal>::real_len(self.secant_unknowns()),
                ]),
                indices: 0,
                feature: Some("quasi-newton"),
            },
            StoragePart {
                name: "features' observations and the copies a failed call restores",
                grows_with: "features, the nodes",
                reals: sum(&[
                    Features::<AnyReal>::real_len(c.features),
                    Self::saved_real_len(c),
                ]),
                indices: sum(&[
                    Features::<AnyReal>::index_len(c.features),
                    Features::<AnyReal>::index_len(c.features), // saved copy
                    Embedding::<AnyReal>::index_len(c.features), // saved copy
                ]),
                feature: None,
            },
            StoragePart {
                name: "cut detection and cut line (detect feature)",
                grows_with: "features, pairs, cut_vertices",
                reals: detection_reals,
                indices: detection_indices,
                feature: Some("detect"),
            },
            StoragePart {
                name: "scratch of a cut (cut feature)",
                grows_with: "the nodes, cut_vertices",
                reals: Self::cut_lens(c).1,
                indices: 0,
                feature: Some("cut"),
            },
            StoragePart {
                name: "workspace (loading, ordering, analysis, cutting)",
                grows_with: "the nodes and tetrahedra",
                reals: 0,
                indices: self.work_len(),
                feature: None,
            },
        ]
    }

    /// Scalars of storage a model needs (the same count for `f32` and `f64`): the sum of
    /// [`ModelSize::parts`], [`ModelSize::factor_real_len`] included.
    pub const fn real_len(&self) -> usize {
        self.totals().0
    }

    /// Scalars of the factor's values and of the workspace of its factorization and solves
    /// (parts of two of [`ModelSize::parts`]): the part of [`ModelSize::real_len`] in the
    /// factor's scalar type, which a mixed-precision model ([`ModelBuffers::new_mixed`]) takes
    /// in a slice of its own.
    pub const fn factor_real_len(&self) -> usize {
        sum(&[
            LdlFactor::<AnyReal>::storage_len(&self.symbolic_capacity()),
            LdlFactor::<AnyReal>::SUPERNODAL_WORK_LEN, // packed blocks of the factorization
            times(2, self.unknowns),                   // the solves' right-hand side and scratch
        ])
    }

    /// Scalars of storage in the model's scalar type: [`ModelSize::real_len`] but the
    /// factor's part ([`ModelSize::factor_real_len`]).
    pub const fn model_real_len(&self) -> usize {
        self.real_len().saturating_sub(self.factor_real_len())
    }

    /// Indices of storage a model needs, its workspace included: the sum of
    /// [`ModelSize::parts`].
    pub const fn index_len(&self) -> usize {
        self.totals().1
    }

    /// The scalars and the indices of [`ModelSize::parts`], each summed (saturating).
    const fn totals(&self) -> (usize, usize) {
        let parts = self.parts();
        let (mut reals, mut indices) = (0usize, 0usize);
        let mut rest: &[StoragePart] = &parts;
        while let [part, tail @ ..] = rest {
            reals = reals.saturating_add(part.reals);
            indices = indices.saturating_add(part.indices);
            rest = tail;
        }
        (reals, indices)
    }

    /// Indices of the workspace the model keeps for rebuilding its mesh and factor (part of
    /// [`ModelSize::index_len`]): the largest of what loading the mesh, ordering and analysing
    /// it, and cutting it need.
    pub const fn work_len(&self) -> usize {
        let c = &self.capacities;
        let (n, t) = (c.mesh.nodes, c.mesh.tets);
        let graph = times(12, t);
        let phases = max(
            max(
                tet_graph_work_len(n, t),
                fill_reducing_order_work_len(n, graph),
            ),
            analyse_work_len(self.unknowns, self.nnz_a),
        );
        let rebuild = sum(&[n, 1, graph, n, self.unknowns, phases]);
        max(max(c.mesh.work_len(), rebuild), Self::cut_lens(c).0)
    }

    /// What the `cut` feature adds: the indices of its workspace and the scalars of its
    /// scratch; both 0 without it.
    #[cfg(feature = "cut")]
    const fn cut_lens(c: &Capacities) -> (usize, usize) {
        let (n, t) = (c.mesh.nodes, c.mesh.tets);
        (cut::work_len(n, t), cut::real_len(n, c.cut_vertices))
    }

    #[cfg(not(feature = "cut"))]
    const fn cut_lens(_: &Capacities) -> (usize, usize) {
        (0, 0)
    }

    /// What the `detect` feature adds: the scalars and the indices of the detector, the cut
    /// line and their scratch; both 0 without it.
    #[cfg(feature = "detect")]
    const fn detection_lens(c: &Capacities) -> (usize, usize) {
        let reals = sum(&[
            Detector::<AnyReal>::real_len(c.features, c.pairs),
            CutLine::<AnyReal>::real_len(c.cut_vertices),
            times(2, c.features),                      // residuals
            times(2, max(c.features, c.cut_vertices)), // projections
        ]);
        let indices = sum(&[
            Detector::<AnyReal>::index_len(c.features, c.pairs),
            CutLine::<AnyReal>::index_len(c.cut_vertices),
        ]);
        (reals, indices)
    }

    #[cfg(not(feature = "detect"))]
    const fn detection_lens(_: &Capacities) -> (usize, usize) {
        (0, 0)
    }

    /// Bytes of storage for scalar type `T` (scalars and indices), saturated at `usize::MAX`
    /// (where `usize` is narrower than 64 bits, `f64` storage of a valid size may not fit).
    pub const fn bytes<T>(&self) -> usize {
        self.bytes_mixed::<T, T>()
    }

    /// Bytes of storage for a model in scalar type `T` that factorizes in `F` (mixed
    /// precision), saturated as [`ModelSize::bytes`].
    pub const fn bytes_mixed<T, F>(&self) -> usize {
        sum(&[
            times(self.model_real_len(), core::mem::size_of::<T>()),
            times(self.factor_real_len(), core::mem::size_of::<F>()),
            times(self.index_len(), 4),
        ])
    }
}

/// The storage a model is built in: scalars and indices, of the lengths
/// [`ModelSize::real_len`] and [`ModelSize::index_len`] give (a mixed-precision model takes
/// the factor's scalars, [`ModelSize::factor_real_len`], in a slice of their own type). Made
/// only by [`ModelBuffers::new`] and [`ModelBuffers::new_mixed`], which check the lengths, so
/// that the slices cannot be swapped by mistake.
#[derive(Debug)]
pub struct ModelBuffers<'a, T, F = T> {
    /// Scalars in the model's type.
    pub(crate) reals: &'a mut [T],
    /// Scalars in the factor's type.
    pub(crate) factor_reals: &'a mut [F],
    /// Indices (the model's workspace included).
    pub(crate) indices: &'a mut [u32],
}

impl<'a, T> ModelBuffers<'a, T> {
    /// Wraps the two slices after checking their lengths against `size`.
    ///
    /// # Errors
    /// [`Error::Capacity`] naming [`Resource::RealStorage`] or [`Resource::IndexStorage`] for a
    /// slice that is too short.
    pub fn new(
        size: &ModelSize,
        reals: &'a mut [T],
        indices: &'a mut [u32],
    ) -> Result<Self, Error> {
        ensure_len(reals, size.real_len(), Resource::RealStorage)?;
        ensure_len(indices, size.index_len(), Resource::IndexStorage)?;
        // `real_len` counts `factor_real_len` among its parts, so the split holds after the
        // check; checked anyway, as everything reachable from the public API.
        let available = reals.len();
        let (factor_reals, reals) =
            reals
                .split_at_mut_checked(size.factor_real_len())
                .ok_or(Error::Capacity {
                    resource: Resource::RealStorage,
                    needed: size.factor_real_len(),
                    available,
                })?;
        Ok(ModelBuffers {
            reals,
            factor_reals,
            indices,
        })
    }
}

impl<'a, T, F> ModelBuffers<'a, T, F> {
    /// Wraps the storage of a mixed-precision model ([`crate::Model`] with a factor scalar `F`
    /// other than `T`): `reals` of [`ModelSize::model_real_len`] scalars, `factor_reals` of
    /// [`ModelSize::factor_real_len`], `indices` of [`ModelSize::index_len`].
    ///
    /// # Errors
    /// [`Error::Capacity`] naming [`Resource::RealStorage`] or [`Resource::IndexStorage`] for a
    /// slice that is too short.
    pub fn new_mixed(
        size: &ModelSize,
        reals: &'a mut [T],
        factor_reals: &'a mut [F],
        indices: &'a mut [u32],
    ) -> Result<Self, Error> {
        ensure_len(reals, size.model_real_len(), Resource::RealStorage)?;
        ensure_len(factor_reals, size.factor_real_len(), Resource::RealStorage)?;
        ensure_len(indices, size.index_len(), Resource::IndexStorage)?;
        Ok(ModelBuffers {
            reals,
            factor_reals,
            indices,
        })
    }
}

/// What the initial mesh needs of the linear algebra, from [`analyse_mesh`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MeshAnalysis {
    /// Unknowns: three per free node.
    pub unknowns: usize,
    /// Stored entries of the stiffness matrix (upper triangle).
    pub nnz_a: usize,
    /// Entries of the factor (strictly lower) under the model's ordering.
    pub nnz_l: usize,
}

/// Length of the workspace [`analyse_mesh`] needs for a mesh of `nodes` nodes and `tets`
/// tetrahedra (saturated at `usize::MAX`, see [`crate::storage::times`]).
pub const fn analyse_mesh_work_len(nodes: usize, tets: usize) -> usize {
    let unknowns = times(3, nodes);
    let nnz_a = stiffness_len(nodes, tets);
    let graph = times(12, tets);
    let phases = max(
        max(
            tet_graph_work_len(nodes, tets),
            fill_reducing_order_work_len(nodes, graph),
        ),
        analyse_work_len(unknowns, nnz_a),
    );
    // The free-node map, the pattern, then what ordering it leaves for the phases.
    sum(&[
        nodes, unknowns, 1, nnz_a, nodes, 1, graph, nodes, unknowns, phases,
    ])
}

/// Bound on the stored entries of the stiffness matrix of `nodes` nodes and `tets` tetrahedra
/// (see [`ModelSize::nnz_a`]), saturated.
const fn stiffness_len(nodes: usize, tets: usize) -> usize {
    sum(&[times(6, nodes), times(54, tets)])
}

/// Checks that a mesh of `nodes` nodes and `tets` tetrahedra fits the `u32` indices; returns
/// its unknowns and the bound on its stiffness entries.
const fn mesh_counts(nodes: usize, tets: usize) -> Result<(usize, usize), Error> {
    check!(at_most(Resource::Nodes, nodes, MAX_INDEX));
    let unknowns = times(3, nodes);
    check!(at_most(Resource::Unknowns, unknowns, MAX_INDEX));
    check!(at_most(Resource::Tetrahedra, tets, MAX_INDEX));
    let nnz_a = stiffness_len(nodes, tets);
    check!(at_most(Resource::MatrixEntries, nnz_a, MAX_INDEX));
    Ok((unknowns, nnz_a))
}

/// Orders the free nodes of `mesh` as a model does and reports the sizes of its stiffness
/// matrix and factor: what [`Capacities::factor_entries`] must hold at least before any cut.
/// `work` needs [`analyse_mesh_work_len`] entries.
///
/// # Errors
/// [`Error::TooLarge`] for a mesh whose counts do not fit the `u32` indices (as
/// [`ModelSize::new`]); [`Error::IndexOutOfRange`] for a bad node index, [`Error::Capacity`]
/// for a short `work`.
pub fn analyse_mesh<T: Real>(
    mesh: &MeshInput<'_, T>,
    work: &mut [u32],
) -> Result<MeshAnalysis, Error> {
    let (n, t) = (mesh.rest.len(), mesh.tets.len());
    mesh_counts(n, t)?;
    ensure_len(work, analyse_mesh_work_len(n, t), Resource::Workspace)?;
    let mut slab = Slab::new(work, Resource::Workspace);
    let free = slab.take(n)?;
    free.fill(0);
    for (position, &f) in mesh.fixed.iter().enumerate() {
        let slot = free.get_mut(f as usize).ok_or(Error::IndexOutOfRange {
            resource: Resource::Nodes,
            position,
            index: f as usize,
            bound: n,
        })?;
        *slot = NONE;
    }
    // At most `n` free nodes, which fits `u32` (checked above).
    let mut n_free = 0u32;
    for f in free.iter_mut() {
        if *f != NONE {
            *f = n_free;
            n_free = n_free.saturating_add(1);
        }
    }
    let n_free = n_free as usize;
    // Both within the workspace checked above, so exact.
    let unknowns = times(3, n_free);
    let col_ptr = slab.take(sum(&[unknowns, 1]))?;
    let row_idx = slab.take(stiffness_len(n_free, t))?;
    let ordered = order_free_nodes(mesh.tets, free, n_free, col_ptr, row_idx, &mut slab)?;
    let a = UpperCsc::new(
        unknowns,
        col_ptr,
        row_idx.get(..ordered.nnz_a).ok_or(Error::Capacity {
            resource: Resource::MatrixEntries,
            needed: ordered.nnz_a,
            available: row_idx.len(),
        })?,
    )?;
    let size = Symbolic::size(&a, ordered.perm, ordered.scratch)?;
    Ok(MeshAnalysis {
        unknowns: size.n,
        nnz_a: size.nnz_a,
        nnz_l: size.nnz_l,
    })
}

/// The outcome of [`order_free_nodes`]: the ordering and what is left of the workspace.
pub(crate) struct Ordered<'w> {
    /// The fill-reducing permutation of the unknowns.
    pub perm: &'w mut [u32],
    /// Stored entries of the pattern written.
    pub nnz_a: usize,
    /// The rest of the workspace.
    pub scratch: &'w mut [u32],
}

/// Builds the node graph of the free nodes (numbered by `free`), its fill-reducing ordering,
/// and the block pattern of the stiffness matrix into `col_ptr` / `row_idx`.
pub(crate) fn order_free_nodes<'w>(
    tets: &[[u32; 4]],
    free: &[u32],
    n_free: usize,
    col_ptr: &mut [u32],
    row_idx: &mut [u32],
    slab: &mut Slab<'w, u32>,
) -> Result<Ordered<'w>, Error> {
    let (graph, nnz_a, rest) = free_node_pattern(tets, free, n_free, col_ptr, row_idx, slab)?;
    let mut rest = Slab::new(rest, Resource::Workspace);
    let node_perm = rest.take(n_free)?;
    let perm = rest.take(times(3, n_free))?;
    let scratch = rest.take(rest.remaining())?;
    fill_reducing_order(&graph, node_perm, scratch)?;
    expand_block_permutation(node_perm, 3, perm)?;
    Ok(Ordered {
        perm,
        nnz_a,
        scratch,
    })
}

/// Builds the node graph of the free nodes (numbered by `free`) in storage from `slab`, and
/// from it the block pattern of the stiffness matrix into `col_ptr` / `row_idx`: what both an
/// analysis and a precomputed one ([`crate::Model::from_precomputed`]) start from. Returns the
/// graph, the pattern's stored entries, and the rest of the slab (scratch, no meaning).
pub(crate) fn free_node_pattern<'w>(
    tets: &[[u32; 4]],
    free: &[u32],
    n_free: usize,
    col_ptr: &mut [u32],
    row_idx: &mut [u32],
    slab: &mut Slab<'w, u32>,
) -> Result<(Graph<'w>, usize, &'w mut [u32]), Error> {
    let g_ptr = slab.take(sum(&[n_free, 1]))?;
    let g_adj = slab.take(times(12, tets.len()))?;
    let rest = slab.take(slab.remaining())?;
    let graph = Graph::from_tets(tets, free, g_ptr, g_adj, rest)?;
    let nnz_a = block_upper_len(&graph, 3);
    block_upper_pattern(&graph, 3, col_ptr, row_idx)?;
    Ok((graph, nnz_a, rest))
}
