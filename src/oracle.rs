//! `faer`, the independent oracle: its sparse Cholesky solves the same systems, and its AMD
//! ordering is the yardstick for our fill.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, Mat, Par, Side};
use incise_core::sparse::UpperCsc;

/// The upper-triangle matrix as a faer matrix (f64).
pub fn to_faer(a: &UpperCsc<'_>, values: &[f64]) -> SparseColMat<usize, f64> {
    let mut trips = Vec::with_capacity(a.nnz());
    for j in 0..a.n() {
        for p in a.column_range(j) {
            trips.push(Triplet::new(a.row_idx()[p] as usize, j, values[p]));
        }
    }
    SparseColMat::try_new_from_triplets(a.n(), a.n(), &trips).expect("valid triplets")
}

fn simplicial(a: &SparseColMat<usize, f64>) -> SymbolicCholesky<usize> {
    let params = CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
        ..Default::default()
    };
    factorize_symbolic_cholesky(a.symbolic(), Side::Upper, SymmetricOrdering::Amd, params)
        .expect("faer symbolic")
}

/// Entries of the strictly lower triangle of `L` under faer's own AMD ordering (a simplicial
/// factor, so the count is exact structure, not supernodal blocks).
pub fn faer_amd_nnz_l(a: &UpperCsc<'_>) -> usize {
    let ones = vec![1.0; a.nnz()];
    let m = to_faer(a, &ones);
    let sym = simplicial(&m);
    match sym.raw() {
        SymbolicCholeskyRaw::Simplicial(s) => s.len_val() - a.n(),
        SymbolicCholeskyRaw::Supernodal(_) => unreachable!("forced simplicial"),
    }
}

/// Solves `A x = b` with faer's sparse LLᵀ (AMD ordering, sequential), in f64.
pub fn faer_solve(a: &UpperCsc<'_>, values: &[f64], b: &[f64]) -> Vec<f64> {
    let m = to_faer(a, values);
    let sym = simplicial(&m);
    let par = Par::Seq;
    let mut l_values = vec![0.0; sym.len_val()];
    let mut mem = MemBuffer::new(sym.factorize_numeric_llt_scratch::<f64>(par, Default::default()));
    let llt = sym
        .factorize_numeric_llt(
            &mut l_values,
            m.as_ref(),
            Side::Upper,
            Default::default(),
            par,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .expect("faer factorization");
    let mut x = Mat::<f64>::from_fn(b.len(), 1, |i, _| b[i]);
    let mut mem = MemBuffer::new(sym.solve_in_place_scratch::<f64>(1, par));
    llt.solve_in_place_with_conj(Conj::No, x.as_mut(), par, MemStack::new(&mut mem));
    (0..b.len()).map(|i| x[(i, 0)]).collect()
}
