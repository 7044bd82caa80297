//! Sparse symmetric positive definite systems in fixed, caller-sized storage.
//!
//! The stiffness matrix of a tetrahedral mesh keeps one sparsity pattern until the mesh is cut,
//! so the work splits into phases, each with its storage reported before anything runs (the
//! faer habit) and each a plain loop over index arrays (the QDLDL habit):
//!
//! 1. **Pattern** ([`pattern`]): the node adjacency [`Graph`] of a mesh, and the upper triangle
//!    of the matrix in compressed-column form ([`UpperCsc`]) with `3 × 3` blocks per node pair.
//! 2. **Ordering** ([`order`]): a fill-reducing permutation (minimum degree on the quotient
//!    graph, or nested dissection on large meshes) inside a fixed workspace, postordered so
//!    that every subtree of its elimination tree is a run of columns.
//! 3. **Symbolic** ([`symbolic`]): the permuted pattern, the elimination tree, the column counts,
//!    the full row and column patterns of `L` and its relaxed supernodes (small ones merged,
//!    storing a few explicit zeros), stored so that the numeric phase is a straight pass.
//! 4. **Numeric** ([`ldl`], [`supernodal`]): the LDLᵀ factorization into fixed buffers, either
//!    up-looking column by column or left-looking supernode by supernode with dense
//!    register-blocked kernels (same storage, same layout; the model uses the supernodal one,
//!    faster at every size measured, 2× at 250 nodes), with forward, diagonal and backward
//!    solves over the supernodes. A failed factorization names its column and leaves the
//!    previous factor in service.
//!
//! A firmware build can skip phases 2 and 3 at start-up: [`precomputed`] checks an analysis
//! generated ahead of time and [`Symbolic::load`] takes it in.
//!
//! All indices are `u32` ([`NONE`] marks "no index"); dimensions and entry counts must fit.
//!
//! ```
//! use incise_core::sparse::{Graph, LdlFactor, Symbolic, UpperCsc, minimum_degree, minimum_degree_work_len};
//! // A = [[4, 1, 0], [1, 4, 1], [0, 1, 4]], upper triangle in compressed columns.
//! let col_ptr = [0u32, 1, 3, 5];
//! let row_idx = [0u32, 0, 1, 1, 2];
//! let values = [4.0f64, 1.0, 4.0, 1.0, 4.0];
//! let a = UpperCsc::new(3, &col_ptr, &row_idx)?;
//!
//! // Ordering on the adjacency graph of the pattern.
//! let (mut g_ptr, mut g_adj, mut w) = ([0u32; 4], [0u32; 4], [0u32; 3]);
//! let graph = Graph::from_upper(&a, &mut g_ptr, &mut g_adj, &mut w)?;
//! let (mut perm, mut work) = ([0u32; 3], [0u32; 64]);
//! assert!(minimum_degree_work_len(3, graph.nnz()) <= work.len());
//! minimum_degree(&graph, &mut perm, &mut work)?;
//!
//! // Symbolic analysis, then the numeric factorization and a solve.
//! let mut awork = [0u32; 64];
//! let size = Symbolic::size(&a, &perm, &mut awork)?;
//! let mut sym_storage = [0u32; 64];
//! assert!(size.index_len() <= sym_storage.len());
//! let sym = Symbolic::new(&a, &perm, &mut sym_storage, &mut awork)?;
//! let mut fstore = [0.0f64; 16];
//! let mut factor = LdlFactor::new(&size, &mut fstore)?;
//! let (mut y, mut cursor) = ([0.0f64; 3], [0u32; 3]);
//! factor.factorize(&sym, &values, &mut y, &mut cursor)?;
//! let mut x = [5.0, 6.0, 5.0]; // A · [1, 1, 1]
//! factor.solve_in_place(&sym, &mut x, &mut y)?;
//! assert!(x.iter().all(|v| (v - 1.0).abs() < 1e-14));
//! # Ok::<(), incise_core::Error>(())
//! ```

pub mod dissect;
pub mod ldl;
pub mod order;
pub mod pattern;
pub mod precomputed;
pub mod supernodal;
pub mod symbolic;

pub use dissect::{DISSECTION_LEAF, nested_dissection, nested_dissection_work_len};
pub use ldl::{LdlFactor, relative_residual, sym_matvec};
pub use order::{
    DISSECTION_FROM, elimination_fill, elimination_fill_work_len, expand_block_permutation,
    fill_reducing_order, fill_reducing_order_work_len, minimum_degree, minimum_degree_work_len,
    postorder, postorder_work_len,
};
pub use pattern::{Graph, UpperCsc, block_upper_len, block_upper_pattern, tet_graph_work_len};
pub use precomputed::{PrecomputedAnalysis, check_work_len};
pub use symbolic::{Symbolic, SymbolicSize, analyse_work_len};

/// The "no index" marker in `u32` index arrays.
pub const NONE: u32 = u32::MAX;

/// Converts a validated index to `usize`.
#[inline(always)]
pub(crate) fn ux(i: u32) -> usize {
    i as usize
}
