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
use crate::sparse::{
    Graph, LdlFactor, NONE, Symbolic, SymbolicSize, UpperCsc, analyse_work_len, block_upper_len,
    block_upper_pattern, expand_block_permutation, minimum_degree, minimum_degree_work_len,
    tet_graph_work_len,
};
use crate::storage::{Slab, ensure_len};

#[cfg(feature = "cut")]
use crate::cut;
#[cfg(feature = "cut")]
use crate::cutline::CutLine;
#[cfg(feature = "cut")]
use crate::detect::Detector;

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

/// Storage sizes of a model, all functions of its [`Capacities`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ModelSize {
    /// The capacities.
    pub capacities: Capacities,
    /// Capacity of stored entries of the stiffness matrix (upper triangle): its bound from the
    /// element count, `6 n + 54 t` (a node's diagonal block has 6 stored entries, a node pair
    /// 9, and a tetrahedron joins at most 6 pairs).
    pub nnz_a: usize,
    /// Capacity of unknowns: three per node.
    pub unknowns: usize,
}

/// Halves of the topology-dependent storage: the one in service and, when the mesh can be
/// cut, the spare a cut is built into.
const HALVES: usize = if cfg!(feature = "cut") { 2 } else { 1 };

const fn max(a: usize, b: usize) -> usize {
    if a > b { a } else { b }
}

impl ModelSize {
    /// The sizes for `capacities`.
    pub const fn new(capacities: &Capacities) -> Self {
        let (n, t) = (capacities.mesh.nodes, capacities.mesh.tets);
        ModelSize {
            capacities: *capacities,
            nnz_a: 6 * n + 54 * t,
            unknowns: 3 * n,
        }
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
        c.mesh.real_len()
            + 3 * n // positions
            + 3 * n // previous positions (damping reference)
            + 2 * n // damping and depth-prior weights
            + Embedding::<f64>::real_len(c.features)
            + Embedding::<f64>::real_len(c.targets)
    }

    /// Indices of one half.
    pub(crate) const fn half_index_len(&self) -> usize {
        let c = &self.capacities;
        c.mesh.index_len()
            + (self.unknowns + 1) // column pointers of the stiffness pattern
            + self.nnz_a // its row indices
            + self.symbolic_capacity().index_len()
            + 30 * c.mesh.tets // scatter map
            + Embedding::<f64>::index_len(c.features)
            + Embedding::<f64>::index_len(c.targets)
            + Self::lips_len(c)
    }

    /// Scalars of the copies a failing call gives back (features, their embedding, the
    /// damping reference).
    const fn saved_real_len(c: &Capacities) -> usize {
        Features::<f64>::real_len(c.features)
            + Embedding::<f64>::real_len(c.features)
            + 3 * c.mesh.nodes
    }

    #[cfg(feature = "cut")]
    const fn lips_len(c: &Capacities) -> usize {
        2 * c.mesh.nodes
    }

    #[cfg(not(feature = "cut"))]
    const fn lips_len(_: &Capacities) -> usize {
        0
    }

    /// Scalars of storage a model needs (the same count for `f32` and `f64`).
    pub const fn real_len(&self) -> usize {
        let c = &self.capacities;
        HALVES * self.half_real_len()
            + self.nnz_a // Hessian values
            + LdlFactor::<f64>::storage_len(&self.symbolic_capacity())
            + 7 * self.unknowns // gradient, step, the PCG vectors, solve work
            + LdlFactor::<f64>::SUPERNODAL_WORK_LEN // packed blocks of the factorization
            + 3 * c.mesh.nodes // trial positions of the line search
            + Features::<f64>::real_len(c.features)
            + Self::saved_real_len(c)
            + Self::detection_real_len(c)
    }

    /// Indices of storage a model needs, its workspace included.
    pub const fn index_len(&self) -> usize {
        let c = &self.capacities;
        HALVES * self.half_index_len()
            + LdlFactor::<f64>::supernodal_index_work_len(self.unknowns) // factorization
            + Features::<f64>::index_len(c.features)
            + Features::<f64>::index_len(c.features) // saved copy
            + Embedding::<f64>::index_len(c.features) // saved copy
            + Self::detection_index_len(c)
            + self.work_len()
    }

    /// Indices of the workspace the model keeps for rebuilding its mesh and factor (part of
    /// [`ModelSize::index_len`]): the largest of what loading the mesh, ordering and analysing
    /// it, and cutting it need.
    pub const fn work_len(&self) -> usize {
        let c = &self.capacities;
        let (n, t) = (c.mesh.nodes, c.mesh.tets);
        let graph = 12 * t;
        let phases = max(
            max(tet_graph_work_len(n, t), minimum_degree_work_len(n, graph)),
            analyse_work_len(self.unknowns, self.nnz_a),
        );
        let rebuild = (n + 1) + graph + n + self.unknowns + phases;
        max(max(c.mesh.work_len(), rebuild), Self::cut_work_len(c))
    }

    #[cfg(feature = "cut")]
    const fn cut_work_len(c: &Capacities) -> usize {
        cut::work_len(c.mesh.nodes, c.mesh.tets)
    }

    #[cfg(not(feature = "cut"))]
    const fn cut_work_len(_: &Capacities) -> usize {
        0
    }

    #[cfg(feature = "cut")]
    const fn detection_real_len(c: &Capacities) -> usize {
        Detector::<f64>::real_len(c.features, c.pairs)
            + CutLine::<f64>::real_len(c.cut_vertices)
            + 2 * c.features // residuals
            + 2 * max(c.features, c.cut_vertices) // projections
            + cut::real_len(c.mesh.nodes, c.cut_vertices)
    }

    #[cfg(not(feature = "cut"))]
    const fn detection_real_len(_: &Capacities) -> usize {
        0
    }

    #[cfg(feature = "cut")]
    const fn detection_index_len(c: &Capacities) -> usize {
        Detector::<f64>::index_len(c.features, c.pairs) + CutLine::<f64>::index_len(c.cut_vertices)
    }

    #[cfg(not(feature = "cut"))]
    const fn detection_index_len(_: &Capacities) -> usize {
        0
    }

    /// Bytes of storage for scalar type `T` (scalars and indices).
    pub const fn bytes<T>(&self) -> usize {
        self.real_len() * core::mem::size_of::<T>() + self.index_len() * 4
    }
}

/// The storage a model is built in: one slice of scalars and one of indices, of the lengths
/// [`ModelSize::real_len`] and [`ModelSize::index_len`] give. Named fields, so the two cannot be
/// swapped by mistake; check them with [`ModelBuffers::new`].
#[derive(Debug)]
pub struct ModelBuffers<'a, T> {
    /// Scalars.
    pub reals: &'a mut [T],
    /// Indices (the model's workspace included).
    pub indices: &'a mut [u32],
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
        Ok(ModelBuffers { reals, indices })
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
/// tetrahedra.
pub const fn analyse_mesh_work_len(nodes: usize, tets: usize) -> usize {
    let size = ModelSize::new(&Capacities {
        mesh: MeshCapacity {
            nodes,
            tets,
            surface_triangles: 0,
        },
        features: 0,
        targets: 0,
        factor_entries: 0,
        pairs: 0,
        cut_vertices: 0,
    });
    let graph = 12 * tets;
    let phases = max(
        max(
            tet_graph_work_len(nodes, tets),
            minimum_degree_work_len(nodes, graph),
        ),
        analyse_work_len(size.unknowns, size.nnz_a),
    );
    // The free-node map, the pattern, then what ordering it leaves for the phases.
    nodes + (size.unknowns + 1) + size.nnz_a + (nodes + 1) + graph + nodes + size.unknowns + phases
}

/// Orders the free nodes of `mesh` as a model does and reports the sizes of its stiffness
/// matrix and factor: what [`Capacities::factor_entries`] must hold at least before any cut.
/// `work` needs [`analyse_mesh_work_len`] entries.
///
/// # Errors
/// [`Error::IndexOutOfRange`] for a bad node index, [`Error::Capacity`] for a short `work`.
pub fn analyse_mesh<T: Real>(
    mesh: &MeshInput<'_, T>,
    work: &mut [u32],
) -> Result<MeshAnalysis, Error> {
    let (n, t) = (mesh.rest.len(), mesh.tets.len());
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
    let mut n_free = 0u32;
    for f in free.iter_mut() {
        if *f != NONE {
            *f = n_free;
            n_free += 1;
        }
    }
    let n_free = n_free as usize;
    let col_ptr = slab.take(3 * n_free + 1)?;
    let row_idx = slab.take(6 * n_free + 54 * t)?;
    let ordered = order_free_nodes(mesh.tets, free, n_free, col_ptr, row_idx, &mut slab)?;
    let a = UpperCsc::new(
        3 * n_free,
        &col_ptr[..3 * n_free + 1],
        &row_idx[..ordered.nnz_a],
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

/// Builds the node graph of the free nodes (numbered by `free`), its minimum-degree ordering,
/// and the block pattern of the stiffness matrix into `col_ptr` / `row_idx`.
pub(crate) fn order_free_nodes<'w>(
    tets: &[[u32; 4]],
    free: &[u32],
    n_free: usize,
    col_ptr: &mut [u32],
    row_idx: &mut [u32],
    slab: &mut Slab<'w, u32>,
) -> Result<Ordered<'w>, Error> {
    let g_ptr = slab.take(n_free + 1)?;
    let g_adj = slab.take(12 * tets.len())?;
    let node_perm = slab.take(n_free)?;
    let perm = slab.take(3 * n_free)?;
    // The rest of the slab is scratch for each phase in turn.
    let scratch = slab.take(slab.remaining())?;
    let graph = Graph::from_tets(tets, free, g_ptr, g_adj, scratch)?;
    minimum_degree(&graph, node_perm, scratch)?;
    expand_block_permutation(node_perm, 3, perm)?;
    let nnz_a = block_upper_len(&graph, 3);
    block_upper_pattern(&graph, 3, col_ptr, row_idx)?;
    Ok(Ordered {
        perm,
        nnz_a,
        scratch,
    })
}
