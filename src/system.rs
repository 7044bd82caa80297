//! The core's sparse pipeline driven from `Vec` storage: what a host does with the caller-sized
//! API, packaged for tests and benchmarks.

use incise_core::sparse::{
    Graph, LdlFactor, NONE, Symbolic, SymbolicSize, UpperCsc, analyse_work_len, block_upper_len,
    block_upper_pattern, elimination_fill, expand_block_permutation, fill_reducing_order,
    fill_reducing_order_work_len, minimum_degree, nested_dissection, tet_graph_work_len,
};
use incise_core::{Error, Real};

use crate::rng::Rng;
use crate::testmesh::TetMesh;

/// Entries of the strictly lower factor (exact: no explicit zeros of relaxed supernodes) under
/// each of the core's orderings, from [`StiffnessPattern::ordering_fills`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OrderingFills {
    /// Under [`minimum_degree`].
    pub minimum_degree: usize,
    /// Under [`nested_dissection`].
    pub nested_dissection: usize,
    /// Under [`fill_reducing_order`], the ordering the core factors under.
    pub kept: usize,
}

/// The stiffness pattern of a mesh (3 unknowns per free node) with the fill-reducing ordering of
/// its unknowns computed on the node graph.
#[derive(Clone, Debug)]
pub struct StiffnessPattern {
    /// Free-node map used (`NONE` for fixed nodes).
    pub free: Vec<u32>,
    /// Column pointers of the upper triangle.
    pub col_ptr: Vec<u32>,
    /// Row indices of the upper triangle.
    pub row_idx: Vec<u32>,
    /// Fill-reducing ordering of the unknowns (`fill_reducing_order` on the node graph,
    /// expanded).
    pub perm: Vec<u32>,
}

impl StiffnessPattern {
    /// Builds the pattern of `mesh` with the nodes in `fixed` left out.
    pub fn new(mesh: &TetMesh, fixed: &[u32]) -> Result<Self, Error> {
        let mut free = vec![0u32; mesh.nodes.len()];
        for &f in fixed {
            free[f as usize] = NONE;
        }
        let mut next = 0;
        for f in free.iter_mut() {
            if *f != NONE {
                *f = next;
                next += 1;
            }
        }
        let n_free = next as usize;
        let mut work = vec![0u32; tet_graph_work_len(n_free, mesh.tets.len())];
        let nnz_g = Graph::tets_nnz(&mesh.tets, &free, &mut work)?;
        let (mut gp, mut ga) = (vec![0u32; n_free + 1], vec![0u32; nnz_g]);
        let graph = Graph::from_tets(&mesh.tets, &free, &mut gp, &mut ga, &mut work)?;
        let mut node_perm = vec![0u32; n_free];
        let mut mwork = vec![0u32; fill_reducing_order_work_len(n_free, nnz_g)];
        fill_reducing_order(&graph, &mut node_perm, &mut mwork)?;
        let mut perm = vec![0u32; 3 * n_free];
        expand_block_permutation(&node_perm, 3, &mut perm)?;
        let nnz = block_upper_len(&graph, 3);
        let (mut col_ptr, mut row_idx) = (vec![0u32; 3 * n_free + 1], vec![0u32; nnz]);
        block_upper_pattern(&graph, 3, &mut col_ptr, &mut row_idx)?;
        Ok(StiffnessPattern {
            free,
            col_ptr,
            row_idx,
            perm,
        })
    }

    /// Entries of the strictly lower factor (scalars) under each of the two orderings
    /// `fill_reducing_order` chooses between, and under the one it keeps.
    pub fn ordering_fills(&self, mesh: &TetMesh) -> Result<OrderingFills, Error> {
        let n_free = self.n() / 3;
        let mut work = vec![0u32; tet_graph_work_len(n_free, mesh.tets.len())];
        let nnz_g = Graph::tets_nnz(&mesh.tets, &self.free, &mut work)?;
        let (mut gp, mut ga) = (vec![0u32; n_free + 1], vec![0u32; nnz_g]);
        let graph = Graph::from_tets(&mesh.tets, &self.free, &mut gp, &mut ga, &mut work)?;
        let mut perm = vec![0u32; n_free];
        let mut work = vec![0u32; fill_reducing_order_work_len(n_free, nnz_g)];
        // A node-level entry is a 3 × 3 block; a diagonal block has 3 entries below its diagonal.
        let scalars = |perm: &[u32], work: &mut [u32]| {
            elimination_fill(&graph, perm, work).map(|f| 9 * f as usize + 3 * n_free)
        };
        minimum_degree(&graph, &mut perm, &mut work)?;
        let minimum_degree = scalars(&perm, &mut work)?;
        nested_dissection(&graph, &mut perm, &mut work)?;
        let nested_dissection = scalars(&perm, &mut work)?;
        fill_reducing_order(&graph, &mut perm, &mut work)?;
        let kept = scalars(&perm, &mut work)?;
        Ok(OrderingFills {
            minimum_degree,
            nested_dissection,
            kept,
        })
    }

    /// Dimension.
    pub fn n(&self) -> usize {
        self.col_ptr.len() - 1
    }

    /// The checked pattern.
    pub fn upper(&self) -> UpperCsc<'_> {
        UpperCsc::new(self.n(), &self.col_ptr, &self.row_idx).expect("pattern is valid")
    }

    /// Random symmetric positive definite values on this pattern: a sum over tetrahedra of
    /// random positive semidefinite `12 × 12` element matrices `GᵀG` (restricted to the free
    /// unknowns), plus `shift` times the largest diagonal entry on the diagonal, which bounds the
    /// condition number by about `1 + 1/shift`.
    pub fn random_spd<T: Real>(&self, mesh: &TetMesh, rng: &mut Rng, shift: f64) -> Vec<T> {
        let a = self.upper();
        let mut v = vec![0.0f64; a.nnz()];
        for tet in &mesh.tets {
            let g: Vec<f64> = (0..144).map(|_| rng.range(-1.0, 1.0)).collect();
            let dof = |l: usize| {
                let f = self.free[tet[l / 3] as usize];
                (f != NONE).then(|| 3 * f as usize + l % 3)
            };
            for c in 0..12 {
                for r in 0..12 {
                    let (Some(i), Some(j)) = (dof(r), dof(c)) else {
                        continue;
                    };
                    if i > j {
                        continue;
                    }
                    let e: f64 = (0..12).map(|k| g[k * 12 + r] * g[k * 12 + c]).sum();
                    v[a.find(i, j).expect("entry in pattern")] += e;
                }
            }
        }
        let dmax = (0..a.n())
            .map(|j| v[a.find(j, j).unwrap()])
            .fold(0.0, f64::max);
        for j in 0..a.n() {
            v[a.find(j, j).unwrap()] += shift * dmax;
        }
        v.into_iter().map(T::of).collect()
    }
}

/// Result of [`factor_and_solve`].
#[derive(Clone, Debug)]
pub struct Solved<T> {
    /// The solution.
    pub x: Vec<T>,
    /// The sizes of the symbolic factorization.
    pub size: SymbolicSize,
    /// Multiply-adds of the numeric factorization.
    pub factor_flops: u64,
    /// Strictly lower values of `L` (column layout of the symbolic analysis).
    pub l: Vec<T>,
    /// Diagonal `D`.
    pub d: Vec<T>,
    /// Supernodes of the analysis.
    pub supernodes: usize,
}

/// Which numeric factorization of the core to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Up-looking, column by column ([`LdlFactor::factorize`]).
    Simplicial,
    /// Left-looking over supernodes ([`LdlFactor::factorize_supernodal`]).
    Supernodal,
}

/// Analyses `a` under `perm`, factorizes `values` (simplicial) and solves for `b`, all in `Vec`
/// storage sized by the core's own `*_len` functions.
pub fn factor_and_solve<T: Real>(
    a: &UpperCsc<'_>,
    perm: &[u32],
    values: &[T],
    b: &[T],
) -> Result<Solved<T>, Error> {
    factor_and_solve_with(Method::Simplicial, a, perm, values, b)
}

/// [`factor_and_solve`] with the numeric factorization `method`.
pub fn factor_and_solve_with<T: Real>(
    method: Method,
    a: &UpperCsc<'_>,
    perm: &[u32],
    values: &[T],
    b: &[T],
) -> Result<Solved<T>, Error> {
    let n = a.n();
    let mut awork = vec![0u32; analyse_work_len(n, a.nnz())];
    let size = Symbolic::size(a, perm, &mut awork)?;
    let mut sstore = vec![0u32; size.index_len()];
    let sym = Symbolic::new(a, perm, &mut sstore, &mut awork)?;
    let mut fstore = vec![T::zero(); LdlFactor::<T>::storage_len(&size)];
    let mut factor = LdlFactor::new(&size, &mut fstore)?;
    let mut y = vec![T::zero(); n];
    match method {
        Method::Simplicial => {
            let mut cursor = vec![0u32; n];
            factor.factorize(&sym, values, &mut y, &mut cursor)?;
        }
        Method::Supernodal => {
            let mut work = vec![T::zero(); LdlFactor::<T>::SUPERNODAL_WORK_LEN];
            let mut iwork = vec![0u32; LdlFactor::<T>::supernodal_index_work_len(n)];
            factor.factorize_supernodal(&sym, values, &mut work, &mut iwork)?;
        }
    }
    let mut x = b.to_vec();
    factor.solve_in_place(&sym, &mut x, &mut y)?;
    Ok(Solved {
        x,
        size,
        factor_flops: sym.factor_flops(),
        l: factor.l_values().unwrap_or_default().to_vec(),
        d: factor.d_values().unwrap_or_default().to_vec(),
        supernodes: sym.supernodes(),
    })
}

/// The fill-reducing ordering (`fill_reducing_order`) of any symmetric pattern, computed on its
/// own graph.
pub fn order_pattern(a: &UpperCsc<'_>) -> Result<Vec<u32>, Error> {
    let n = a.n();
    let off = a.nnz() - n;
    let (mut gp, mut ga, mut w) = (vec![0u32; n + 1], vec![0u32; 2 * off], vec![0u32; n]);
    let g = Graph::from_upper(a, &mut gp, &mut ga, &mut w)?;
    let mut perm = vec![0u32; n];
    let mut work = vec![0u32; fill_reducing_order_work_len(n, g.nnz())];
    fill_reducing_order(&g, &mut perm, &mut work)?;
    Ok(perm)
}
