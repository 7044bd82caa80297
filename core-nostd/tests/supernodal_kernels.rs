//! The supernodal factorization against the column-by-column one on the core alone: the same
//! `L` and `D` to rounding on the stiffness patterns of node grids, in `f64` and in `f32`.
//!
//! The column-by-column factorization has no kernel that depends on the target (its loops run
//! over one column at a time), and `tests/sparse_ldl.rs` holds both to faer. This test builds
//! with nothing but the core, so that CI can run it quickly in a build for another target
//! (`.ci/run` builds it for AVX, where the supernodal micro-kernel takes 8-row tiles instead of
//! 4 and packs its target coefficients once instead of twice).

#![cfg(feature = "f64")]

use incise_core::Real;
use incise_core::sparse::{
    Graph, LdlFactor, Symbolic, analyse_work_len, block_upper_len, block_upper_pattern,
    expand_block_permutation, fill_reducing_order, fill_reducing_order_work_len,
};

/// The node graph of a box of `nx × ny × nz` nodes in which every node is joined to the up to
/// 26 nodes around it (the nodes of a hexahedral mesh that share an element): in compressed
/// form, each list sorted.
fn grid_graph(nx: usize, ny: usize, nz: usize) -> (Vec<u32>, Vec<u32>) {
    let index = |x: usize, y: usize, z: usize| (x + nx * (y + ny * z)) as u32;
    let (mut ptr, mut adj) = (vec![0u32], vec![]);
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let mut around = vec![];
                for dz in -1i64..=1 {
                    for dy in -1i64..=1 {
                        for dx in -1i64..=1 {
                            let (u, v, w) = (x as i64 + dx, y as i64 + dy, z as i64 + dz);
                            let inside = (0..nx as i64).contains(&u)
                                && (0..ny as i64).contains(&v)
                                && (0..nz as i64).contains(&w);
                            if inside && (dx, dy, dz) != (0, 0, 0) {
                                around.push(index(u as usize, v as usize, w as usize));
                            }
                        }
                    }
                }
                around.sort_unstable();
                adj.extend(around);
                ptr.push(adj.len() as u32);
            }
        }
    }
    (ptr, adj)
}

/// A fixed stream of numbers in `[0, 1)` (a linear congruential generator).
struct Stream(u64);

impl Stream {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Values on the upper pattern `col_ptr`/`row_idx` of a symmetric matrix with negative
/// off-diagonal entries and each diagonal entry above the sum of its row's others: positive
/// definite by Gershgorin's theorem, and as well conditioned as `margin` makes it.
fn dominant_values(col_ptr: &[u32], row_idx: &[u32], margin: f64, stream: &mut Stream) -> Vec<f64> {
    let n = col_ptr.len() - 1;
    let mut values = vec![0.0; row_idx.len()];
    let mut row_sums = vec![0.0; n];
    for j in 0..n {
        for k in col_ptr[j] as usize..col_ptr[j + 1] as usize {
            let i = row_idx[k] as usize;
            if i != j {
                values[k] = -stream.next();
                row_sums[i] -= values[k];
                row_sums[j] -= values[k];
            }
        }
    }
    for j in 0..n {
        let diagonal = col_ptr[j + 1] as usize - 1;
        assert_eq!(
            row_idx[diagonal] as usize, j,
            "the diagonal ends each column"
        );
        values[diagonal] = row_sums[j] + margin;
    }
    values
}

/// The largest difference of `a` from `b` relative to `b`'s largest entry.
fn relative_difference<T: Real>(a: &[T], b: &[T]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.to_f64().abs()));
    let most = a
        .iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x.to_f64() - y.to_f64()).abs()));
    most / scale.max(f64::MIN_POSITIVE)
}

/// Factors the grid's matrix (three unknowns per node, the core's fill-reducing ordering, its
/// relaxed supernodes) both ways in `T` and returns how far the supernodal `L` and `D` lie
/// from the column-by-column ones, and the number of supernodes.
fn both_ways<T: Real>(nodes: [usize; 3], margin: f64) -> (f64, f64, usize) {
    let (ptr, adj) = grid_graph(nodes[0], nodes[1], nodes[2]);
    let graph = Graph::new(ptr.len() - 1, &ptr, &adj).unwrap();
    let mut node_perm = vec![0u32; graph.n()];
    let mut work = vec![0u32; fill_reducing_order_work_len(graph.n(), graph.nnz())];
    fill_reducing_order(&graph, &mut node_perm, &mut work).unwrap();
    let mut perm = vec![0u32; 3 * graph.n()];
    expand_block_permutation(&node_perm, 3, &mut perm).unwrap();
    let n = perm.len();
    let (mut col_ptr, mut row_idx) = (vec![0u32; n + 1], vec![0u32; block_upper_len(&graph, 3)]);
    let a = block_upper_pattern(&graph, 3, &mut col_ptr, &mut row_idx).unwrap();
    let values = dominant_values(a.col_ptr(), a.row_idx(), margin, &mut Stream(7));
    let values: Vec<T> = values.iter().map(|&v| T::of(v)).collect();
    let mut awork = vec![0u32; analyse_work_len(n, a.nnz())];
    let size = Symbolic::size(&a, &perm, &mut awork).unwrap();
    let mut index_storage = vec![0u32; size.index_len()];
    let sym = Symbolic::new(&a, &perm, &mut index_storage, &mut awork).unwrap();
    let mut storage = vec![T::zero(); LdlFactor::<T>::storage_len(&size)];
    let mut factor = LdlFactor::new(&size, &mut storage).unwrap();
    let (mut y, mut cursor) = (vec![T::zero(); n], vec![0u32; n]);
    factor
        .factorize(&sym, &values, &mut y, &mut cursor)
        .unwrap();
    let (l, d) = (
        factor.l_values().unwrap().to_vec(),
        factor.d_values().unwrap().to_vec(),
    );
    let mut work = vec![T::zero(); LdlFactor::<T>::SUPERNODAL_WORK_LEN];
    let mut iwork = vec![0u32; LdlFactor::<T>::supernodal_index_work_len(n)];
    factor
        .factorize_supernodal(&sym, &values, &mut work, &mut iwork)
        .unwrap();
    (
        relative_difference(factor.l_values().unwrap(), &l),
        relative_difference(factor.d_values().unwrap(), &d),
        sym.supernodes(),
    )
}

/// Grids from a few hundred unknowns (supernodes narrower than one packed block) to about two
/// thousand (supernodes wider than a block of source columns and of target columns, and row
/// blocks of every remainder against the micro-kernel's tile).
const GRIDS: [[usize; 3]; 3] = [[5, 4, 4], [8, 6, 5], [10, 9, 7]];

#[test]
fn supernodal_factor_is_the_column_by_column_one_in_f64() {
    use incise_core::sparse::supernodal::{DUP, MR, NR};
    eprintln!("micro-kernel tile {MR} × {NR}, target coefficients packed {DUP} times");
    for nodes in GRIDS {
        let (l, d, supernodes) = both_ways::<f64>(nodes, 0.5);
        eprintln!("{nodes:?}: {supernodes} supernodes, L {l:.1e}, D {d:.1e} apart");
        assert!(l <= 1e-12 && d <= 1e-12, "{nodes:?}: L {l:e}, D {d:e}");
    }
}

#[cfg(feature = "f32")]
#[test]
fn supernodal_factor_is_the_column_by_column_one_in_f32() {
    for nodes in GRIDS {
        let (l, d, supernodes) = both_ways::<f32>(nodes, 0.5);
        eprintln!("{nodes:?}: {supernodes} supernodes, L {l:.1e}, D {d:.1e} apart");
        assert!(l <= 1e-4 && d <= 1e-4, "{nodes:?}: L {l:e}, D {d:e}");
    }
}
