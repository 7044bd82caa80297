//! The core's sparse LDLᵀ against faer (solutions, residuals, fill) on stiffness patterns of
//! tetrahedral meshes, and its behaviour on the small and broken systems a user will hand it.

use incise_core::sparse::{
    Graph, LdlFactor, NONE, Symbolic, UpperCsc, analyse_work_len, block_upper_pattern,
    elimination_fill, elimination_fill_work_len, minimum_degree, minimum_degree_work_len,
    postorder, postorder_work_len, relative_residual, tet_graph_work_len,
};
use incise_core::{Error, Resource};
use incise_validation::oracle::{faer_amd_nnz_l, faer_solve};
use incise_validation::rng::Rng;
use incise_validation::system::{
    Method, StiffnessPattern, factor_and_solve, factor_and_solve_with, order_pattern,
};
use incise_validation::testmesh::{TetMesh, box_mesh, shuffle_nodes};

/// Box meshes of 144, 700 and 1859 nodes, node numbering shuffled; the nodes of the face
/// `x = 0` are fixed, as for a model held at one end.
fn meshes() -> Vec<(TetMesh, Vec<u32>)> {
    let mut rng = Rng::new(7);
    [[5, 5, 3], [9, 9, 6], [12, 12, 10]]
        .into_iter()
        .map(|cells| {
            let mesh = shuffle_nodes(&box_mesh(cells, [2.0, 1.0, 1.0]), &mut rng);
            let fixed = (0..mesh.nodes.len() as u32)
                .filter(|&v| mesh.nodes[v as usize][0] == 0.0)
                .collect();
            (mesh, fixed)
        })
        .collect()
}

fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
    let den: f64 = b.iter().map(|y| y * y).sum();
    (num / den).sqrt()
}

#[test]
fn f64_and_f32_solutions_agree_with_faer() {
    let mut rng = Rng::new(11);
    for (mesh, fixed) in meshes() {
        let pat = StiffnessPattern::new(&mesh, &fixed).unwrap();
        let a = pat.upper();
        let values: Vec<f64> = pat.random_spd(&mesh, &mut rng, 0.05);
        let b: Vec<f64> = (0..a.n()).map(|_| rng.range(-1.0, 1.0)).collect();
        let reference = faer_solve(&a, &values, &b);

        let ours = factor_and_solve(&a, &pat.perm, &values, &b).unwrap();
        let err = rel_diff(&ours.x, &reference);
        let mut work = vec![0.0; a.n()];
        let res = relative_residual(&a, &values, &ours.x, &b, &mut work).unwrap();
        eprintln!(
            "nodes {:5} unknowns {:5}: f64 relative error {err:.2e}, relative residual {res:.2e}",
            mesh.nodes.len(),
            a.n()
        );
        assert!(err <= 1e-10, "f64 relative error {err:e}");
        assert!(res <= 1e-12, "f64 relative residual {res:e}");

        let values32: Vec<f32> = values.iter().map(|&v| v as f32).collect();
        let b32: Vec<f32> = b.iter().map(|&v| v as f32).collect();
        let ours32 = factor_and_solve(&a, &pat.perm, &values32, &b32).unwrap();
        let x32: Vec<f64> = ours32.x.iter().map(|&v| f64::from(v)).collect();
        let err32 = rel_diff(&x32, &reference);
        eprintln!("                             f32 relative error {err32:.2e}");
        assert!(err32 <= 1e-4, "f32 relative error {err32:e}");
    }
}

/// The box meshes of the factorization benchmark (250 to 4000 nodes, the face `x = 0` fixed),
/// numbered as generated and shuffled, and SOFA's fine liver where the workplace keeps it.
fn ordering_cases() -> Vec<(String, TetMesh, Vec<u32>)> {
    let mut rng = Rng::new(5);
    let held = |mesh: &TetMesh| -> Vec<u32> {
        (0..mesh.nodes.len() as u32)
            .filter(|&v| mesh.nodes[v as usize][0] == 0.0)
            .collect()
    };
    let mut cases = vec![];
    for cells in [[9, 4, 4], [9, 9, 4], [9, 9, 9], [19, 9, 9], [19, 19, 9]] {
        let mesh = box_mesh(cells, [2.0, 1.0, 1.0]);
        let shuffled = shuffle_nodes(&mesh, &mut rng);
        let n = mesh.nodes.len();
        cases.push((format!("box {n}"), mesh.clone(), held(&mesh)));
        cases.push((
            format!("box {n}, shuffled"),
            shuffled.clone(),
            held(&shuffled),
        ));
    }
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/liver/liverFine.vtu");
    if let Ok(vtu) = incise::vtu::read_vtu(&path) {
        let x0 = vtu.nodes.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min);
        let fixed = (0..vtu.nodes.len() as u32)
            .filter(|&v| vtu.nodes[v as usize][0] <= x0 + 0.5)
            .collect();
        let mesh = TetMesh {
            nodes: vtu.nodes,
            tets: vtu.tets,
        };
        cases.push(("fine liver".into(), mesh, fixed));
    }
    cases
}

#[test]
fn fill_is_within_5_percent_of_faer_amd_at_every_size() {
    for (label, mesh, fixed) in ordering_cases() {
        let pat = StiffnessPattern::new(&mesh, &fixed).unwrap();
        let a = pat.upper();
        let mut work = vec![0u32; analyse_work_len(a.n(), a.nnz())];
        let ours = Symbolic::exact_nnz_l(&a, &pat.perm, &mut work).unwrap();
        let faer = faer_amd_nnz_l(&a);
        let ratio = ours as f64 / faer as f64;
        eprintln!(
            "{label:>20}: nnz(L) strictly lower, ours {ours:8}, faer AMD {faer:8}, ratio {ratio:.3}"
        );
        // Minimum degree alone (with supervariables and external degrees) was within a few
        // percent up to 2000 nodes but 1.075 at 4000; nested dissection, kept where it has
        // less fill, brings the larger boxes below AMD.
        assert!(ratio <= 1.05, "{label}: fill ratio {ratio}");
    }
}

#[test]
fn the_node_graph_fill_counts_the_factor_entries() {
    // Each node-level entry of `L` is a 3 × 3 block, each diagonal block has 3 entries below
    // its diagonal: the count the ordering compares is the symbolic analysis's, exactly.
    for (mesh, fixed) in meshes() {
        let pat = StiffnessPattern::new(&mesh, &fixed).unwrap();
        let a = pat.upper();
        let n = a.n() / 3;
        let mut work = vec![0u32; tet_graph_work_len(n, mesh.tets.len())];
        let nnz_g = Graph::tets_nnz(&mesh.tets, &pat.free, &mut work).unwrap();
        let (mut gp, mut ga) = (vec![0u32; n + 1], vec![0u32; nnz_g]);
        let graph = Graph::from_tets(&mesh.tets, &pat.free, &mut gp, &mut ga, &mut work).unwrap();
        let node_perm: Vec<u32> = pat.perm.iter().step_by(3).map(|&u| u / 3).collect();
        let mut fwork = vec![0u32; elimination_fill_work_len(n)];
        let nodes = elimination_fill(&graph, &node_perm, &mut fwork).unwrap() as usize;
        let mut awork = vec![0u32; analyse_work_len(a.n(), a.nnz())];
        let scalars = Symbolic::exact_nnz_l(&a, &pat.perm, &mut awork).unwrap();
        assert_eq!(9 * nodes + 3 * n, scalars);
    }
}

#[test]
fn the_postorder_keeps_the_fill_and_makes_every_subtree_a_run_of_columns() {
    for (mesh, fixed) in meshes() {
        let pat = StiffnessPattern::new(&mesh, &fixed).unwrap();
        let n = pat.n() / 3;
        let mut work = vec![0u32; tet_graph_work_len(n, mesh.tets.len())];
        let nnz_g = Graph::tets_nnz(&mesh.tets, &pat.free, &mut work).unwrap();
        let (mut gp, mut ga) = (vec![0u32; n + 1], vec![0u32; nnz_g]);
        let graph = Graph::from_tets(&mesh.tets, &pat.free, &mut gp, &mut ga, &mut work).unwrap();
        let mut perm = vec![0u32; n];
        minimum_degree(
            &graph,
            &mut perm,
            &mut vec![0u32; minimum_degree_work_len(n, nnz_g)],
        )
        .unwrap();
        let mut fwork = vec![0u32; elimination_fill_work_len(n)];
        let before = elimination_fill(&graph, &perm, &mut fwork).unwrap();
        let mut post = perm.clone();
        postorder(&graph, &mut post, &mut vec![0u32; postorder_work_len(n)]).unwrap();
        let mut sorted = post.clone();
        sorted.sort_unstable();
        assert!(sorted.iter().copied().eq(0..n as u32), "not a permutation");
        assert_eq!(elimination_fill(&graph, &post, &mut fwork).unwrap(), before);
        // The model's ordering is postordered: in the elimination tree of its unknowns, the
        // columns between a column and its parent all descend from that parent.
        let a = pat.upper();
        let mut awork = vec![0u32; analyse_work_len(a.n(), a.nnz())];
        let size = Symbolic::size(&a, &pat.perm, &mut awork).unwrap();
        let mut store = vec![0u32; size.index_len()];
        let sym = Symbolic::new(&a, &pat.perm, &mut store, &mut awork).unwrap();
        let parent = sym.etree();
        for (j, &p) in parent.iter().enumerate() {
            if p == NONE {
                continue;
            }
            for i in j + 1..p as usize {
                let mut up = i;
                while up < p as usize {
                    up = parent[up] as usize;
                }
                assert_eq!(up, p as usize, "column {i} between {j} and its parent {p}");
            }
        }
    }
}

#[test]
fn relaxed_supernodes_store_explicit_zeros_that_factor_to_exactly_zero() {
    let mut rng = Rng::new(5);
    let mut relaxed_somewhere = false;
    for (mesh, fixed) in meshes() {
        let pat = StiffnessPattern::new(&mesh, &fixed).unwrap();
        let a = pat.upper();
        let mut work = vec![0u32; analyse_work_len(a.n(), a.nnz())];
        let stored = Symbolic::size(&a, &pat.perm, &mut work).unwrap().nnz_l;
        let exact = Symbolic::exact_nnz_l(&a, &pat.perm, &mut work).unwrap();
        assert!(stored >= exact);
        relaxed_somewhere |= stored > exact;
        let values: Vec<f64> = pat.random_spd(&mesh, &mut rng, 0.05);
        let b: Vec<f64> = (0..a.n()).map(|_| rng.range(-1.0, 1.0)).collect();
        for method in [Method::Simplicial, Method::Supernodal] {
            let solved = factor_and_solve_with(method, &a, &pat.perm, &values, &b).unwrap();
            assert_eq!(solved.l.len(), stored);
            // Random values leave no entry of the factor's own pattern at zero.
            let zeros = solved.l.iter().filter(|&&v| v == 0.0).count();
            assert_eq!(zeros, stored - exact, "{method:?}");
        }
    }
    assert!(relaxed_somewhere, "no supernode was merged");
}

/// A small dense symmetric matrix as an upper pattern with all entries stored.
struct Dense {
    n: usize,
    col_ptr: Vec<u32>,
    row_idx: Vec<u32>,
}

impl Dense {
    fn new(n: usize) -> Self {
        let mut col_ptr = vec![0u32];
        let mut row_idx = vec![];
        for j in 0..n {
            row_idx.extend(0..=j as u32);
            col_ptr.push(row_idx.len() as u32);
        }
        Dense {
            n,
            col_ptr,
            row_idx,
        }
    }
    fn upper(&self) -> UpperCsc<'_> {
        UpperCsc::new(self.n, &self.col_ptr, &self.row_idx).unwrap()
    }
}

#[test]
fn indefinite_matrix_names_the_column_and_keeps_the_previous_factor() {
    let dense = Dense::new(2);
    let a = dense.upper();
    let perm = [0u32, 1];
    let mut awork = vec![0u32; analyse_work_len(2, a.nnz())];
    let size = Symbolic::size(&a, &perm, &mut awork).unwrap();
    let mut sstore = vec![0u32; size.index_len()];
    let sym = Symbolic::new(&a, &perm, &mut sstore, &mut awork).unwrap();
    let mut fstore = vec![0.0f64; LdlFactor::<f64>::storage_len(&size)];
    let mut factor = LdlFactor::new(&size, &mut fstore).unwrap();
    let (mut y, mut cursor) = ([0.0; 2], [0u32; 2]);

    // [[2, 1], [1, 2]] is positive definite.
    factor
        .factorize(&sym, &[2.0, 1.0, 2.0], &mut y, &mut cursor)
        .unwrap();
    let d_before = factor.d_values().unwrap().to_vec();
    // [[1, 2], [2, 1]] has eigenvalues 3 and −1: the second pivot is 1 − 4 = −3.
    assert_eq!(
        factor.factorize(&sym, &[1.0, 2.0, 1.0], &mut y, &mut cursor),
        Err(Error::NotPositiveDefinite { column: 1 })
    );
    assert_eq!(factor.d_values().unwrap(), &d_before[..]);
    let mut x = [3.0, 3.0];
    factor.solve_in_place(&sym, &mut x, &mut y).unwrap();
    assert!((x[0] - 1.0).abs() < 1e-15 && (x[1] - 1.0).abs() < 1e-15);

    // A NaN reaches the pivot of the column it sits in.
    assert_eq!(
        factor.factorize(&sym, &[4.0, f64::NAN, 4.0], &mut y, &mut cursor),
        Err(Error::NotFinite { column: 1 })
    );
    assert_eq!(
        factor.factorize(&sym, &[f64::INFINITY, 0.0, 4.0], &mut y, &mut cursor),
        Err(Error::NotFinite { column: 0 })
    );
    // Still the first factor.
    assert_eq!(factor.d_values().unwrap(), &d_before[..]);
    let mut x = [3.0, 3.0];
    factor.solve_in_place(&sym, &mut x, &mut y).unwrap();
    assert!((x[0] - 1.0).abs() < 1e-15);
}

#[test]
fn a_fresh_factor_refuses_to_solve() {
    let dense = Dense::new(1);
    let a = dense.upper();
    let mut awork = vec![0u32; analyse_work_len(1, 1)];
    let size = Symbolic::size(&a, &[0], &mut awork).unwrap();
    let mut sstore = vec![0u32; size.index_len()];
    let sym = Symbolic::new(&a, &[0], &mut sstore, &mut awork).unwrap();
    let mut fstore = vec![0.0f64; LdlFactor::<f64>::storage_len(&size)];
    let mut factor = LdlFactor::new(&size, &mut fstore).unwrap();
    let (mut y, mut cursor) = ([0.0; 1], [0u32; 1]);
    assert_eq!(
        factor.solve_in_place(&sym, &mut [1.0], &mut y),
        Err(Error::NotFactored)
    );
    assert_eq!(
        factor.factorize(&sym, &[-1.0], &mut y, &mut cursor),
        Err(Error::NotPositiveDefinite { column: 0 })
    );
    assert!(!factor.is_factored());
}

#[test]
fn one_by_one_and_empty_systems() {
    let one = Dense::new(1);
    let s = factor_and_solve(&one.upper(), &[0], &[4.0f64], &[10.0]).unwrap();
    assert_eq!(s.x, vec![2.5]);
    assert_eq!(s.size.nnz_l, 0);

    let empty = Dense::new(0);
    let s = factor_and_solve::<f64>(&empty.upper(), &[], &[], &[]).unwrap();
    assert!(s.x.is_empty());
    assert_eq!(order_pattern(&empty.upper()).unwrap(), Vec::<u32>::new());
}

#[test]
fn diagonal_matrix_has_no_fill() {
    let n = 50;
    let col_ptr: Vec<u32> = (0..=n as u32).collect();
    let row_idx: Vec<u32> = (0..n as u32).collect();
    let a = UpperCsc::new(n, &col_ptr, &row_idx).unwrap();
    let d: Vec<f64> = (1..=n).map(|k| k as f64).collect();
    let b: Vec<f64> = (0..n).map(|k| 3.0 * (k + 1) as f64).collect();
    let perm = order_pattern(&a).unwrap();
    let s = factor_and_solve(&a, &perm, &d, &b).unwrap();
    assert_eq!(s.size.nnz_l, 0);
    assert!(s.x.iter().all(|&x| (x - 3.0).abs() < 1e-15));
}

#[test]
fn dense_matrix_matches_closed_form_factor() {
    // The 3 × 3 matrix with L = [[1, 0, 0], [2, 1, 0], [3, 4, 1]], D = diag(1, 2, 3):
    // A = L D Lᵀ = [[1, 2, 3], [2, 6, 14], [3, 14, 44]].
    let dense = Dense::new(3);
    let a = dense.upper();
    let values = [1.0f64, 2.0, 6.0, 3.0, 14.0, 44.0];
    let perm = [0u32, 1, 2];
    let mut awork = vec![0u32; analyse_work_len(3, a.nnz())];
    let size = Symbolic::size(&a, &perm, &mut awork).unwrap();
    let mut sstore = vec![0u32; size.index_len()];
    let sym = Symbolic::new(&a, &perm, &mut sstore, &mut awork).unwrap();
    let mut fstore = vec![0.0f64; LdlFactor::<f64>::storage_len(&size)];
    let mut factor = LdlFactor::new(&size, &mut fstore).unwrap();
    let (mut y, mut cursor) = ([0.0; 3], [0u32; 3]);
    factor
        .factorize(&sym, &values, &mut y, &mut cursor)
        .unwrap();
    assert_eq!(factor.d_values().unwrap(), &[1.0, 2.0, 3.0]);
    // Column-major strictly lower L: (1,0), (2,0), (2,1).
    assert_eq!(factor.l_values().unwrap(), &[2.0, 3.0, 4.0]);
}

#[test]
fn capacity_overflow_is_an_error_not_a_panic() {
    let mesh = box_mesh([3, 3, 3], [1.0, 1.0, 1.0]);
    let free: Vec<u32> = (0..mesh.nodes.len() as u32).collect();
    let mut work = vec![0u32; 10_000];
    let nnz = Graph::tets_nnz(&mesh.tets, &free, &mut work).unwrap();
    // Adjacency storage one short.
    let (mut gp, mut ga) = (vec![0u32; free.len() + 1], vec![0u32; nnz - 1]);
    assert_eq!(
        Graph::from_tets(&mesh.tets, &free, &mut gp, &mut ga, &mut work).err(),
        Some(Error::Capacity {
            resource: Resource::GraphEntries,
            needed: nnz,
            available: nnz - 1
        })
    );
    let mut ga = vec![0u32; nnz];
    let g = Graph::from_tets(&mesh.tets, &free, &mut gp, &mut ga, &mut work).unwrap();
    // Matrix pattern storage too short.
    let (mut cp, mut ri) = (vec![0u32; 3 * g.n() + 1], vec![0u32; 100]);
    assert!(matches!(
        block_upper_pattern(&g, 3, &mut cp, &mut ri),
        Err(Error::Capacity {
            resource: Resource::MatrixEntries,
            ..
        })
    ));
    // Symbolic and numeric storage too short.
    let pat = StiffnessPattern::new(&mesh, &[]).unwrap();
    let a = pat.upper();
    let mut awork = vec![0u32; analyse_work_len(a.n(), a.nnz())];
    let size = Symbolic::size(&a, &pat.perm, &mut awork).unwrap();
    let mut short = vec![0u32; size.index_len() - 1];
    assert!(matches!(
        Symbolic::new(&a, &pat.perm, &mut short, &mut awork),
        Err(Error::Capacity {
            resource: Resource::IndexStorage,
            ..
        })
    ));
    let mut fshort = vec![0.0f64; LdlFactor::<f64>::storage_len(&size) - 1];
    assert!(matches!(
        LdlFactor::new(&size, &mut fshort),
        Err(Error::Capacity {
            resource: Resource::RealStorage,
            ..
        })
    ));
    // Workspace too short.
    let mut wshort = vec![0u32; 3];
    assert!(matches!(
        Symbolic::size(&a, &pat.perm, &mut wshort),
        Err(Error::Capacity {
            resource: Resource::Workspace,
            ..
        })
    ));
    // A permutation that repeats a value.
    let mut bad = pat.perm.clone();
    bad[1] = bad[0];
    assert_eq!(
        Symbolic::size(&a, &bad, &mut awork),
        Err(Error::NotAPermutation { position: 1 })
    );
}

/// Largest entry-wise difference relative to the largest entry of `b`.
fn max_rel(a: &[f64], b: &[f64]) -> f64 {
    let scale = b
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(f64::MIN_POSITIVE);
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

/// Checks the supernodal factor of `values` against the simplicial one (same `L` and `D` to
/// rounding) and its solution against faer's (and its residual).
fn check_supernodal(a: &UpperCsc<'_>, perm: &[u32], values: &[f64], b: &[f64], what: &str) {
    let simp = factor_and_solve_with(Method::Simplicial, a, perm, values, b).unwrap();
    let sup = factor_and_solve_with(Method::Supernodal, a, perm, values, b).unwrap();
    let (dl, dd) = (max_rel(&sup.l, &simp.l), max_rel(&sup.d, &simp.d));
    let reference = faer_solve(a, values, b);
    let err = rel_diff(&sup.x, &reference);
    let mut work = vec![0.0; a.n()];
    let res = relative_residual(a, values, &sup.x, b, &mut work).unwrap();
    eprintln!(
        "{what}: n {:5}, {:5} supernodes, L {dl:.1e}, D {dd:.1e} from simplicial; \
         error {err:.1e} against faer, residual {res:.1e}",
        a.n(),
        sup.supernodes
    );
    assert!(dl <= 1e-12 && dd <= 1e-12, "{what}: L {dl:e}, D {dd:e}");
    assert!(err <= 1e-10, "{what}: relative error {err:e}");
    assert!(res <= 1e-12, "{what}: relative residual {res:e}");
}

#[test]
fn supernodal_factor_matches_simplicial_and_faer_on_meshes() {
    let mut rng = Rng::new(21);
    for (mesh, fixed) in meshes() {
        let pat = StiffnessPattern::new(&mesh, &fixed).unwrap();
        let a = pat.upper();
        let values: Vec<f64> = pat.random_spd(&mesh, &mut rng, 0.05);
        let b: Vec<f64> = (0..a.n()).map(|_| rng.range(-1.0, 1.0)).collect();
        check_supernodal(&a, &pat.perm, &values, &b, "box mesh");

        // f32 as well.
        let values32: Vec<f32> = values.iter().map(|&v| v as f32).collect();
        let b32: Vec<f32> = b.iter().map(|&v| v as f32).collect();
        let ours32 =
            factor_and_solve_with(Method::Supernodal, &a, &pat.perm, &values32, &b32).unwrap();
        let x32: Vec<f64> = ours32.x.iter().map(|&v| f64::from(v)).collect();
        let err32 = rel_diff(&x32, &faer_solve(&a, &values, &b));
        assert!(err32 <= 1e-4, "f32 relative error {err32:e}");
    }
}

/// A random symmetric pattern of dimension `n` with about `per_col` off-diagonal entries per
/// column, and diagonally dominant values (so positive definite).
fn random_spd_pattern(n: usize, per_col: usize, rng: &mut Rng) -> (Vec<u32>, Vec<u32>, Vec<f64>) {
    let mut cols: Vec<Vec<(u32, f64)>> = vec![vec![]; n];
    let mut diag = vec![1.0f64; n];
    for j in 0..n {
        for _ in 0..per_col {
            let i = (rng.uniform() * j as f64) as usize;
            if i >= j || cols[j].iter().any(|&(r, _)| r as usize == i) {
                continue;
            }
            let v = rng.range(-1.0, 1.0);
            cols[j].push((i as u32, v));
            diag[i] += v.abs();
            diag[j] += v.abs();
        }
    }
    let (mut col_ptr, mut row_idx, mut values) = (vec![0u32], vec![], vec![]);
    for (j, col) in cols.iter_mut().enumerate() {
        col.push((j as u32, diag[j]));
        col.sort_by_key(|&(r, _)| r);
        for &(r, v) in col.iter() {
            row_idx.push(r);
            values.push(v);
        }
        col_ptr.push(row_idx.len() as u32);
    }
    (col_ptr, row_idx, values)
}

#[test]
fn supernodal_factor_matches_on_dense_and_random_patterns() {
    let mut rng = Rng::new(5);
    // Dense: one supernode wider than the column blocks and the packed depth, so every blocked
    // path of the kernels runs.
    for n in [1, 2, 5, 33, 150] {
        let dense = Dense::new(n);
        let a = dense.upper();
        let g: Vec<f64> = (0..n * n).map(|_| rng.range(-1.0, 1.0)).collect();
        let mut values = vec![];
        for j in 0..n {
            for i in 0..=j {
                let e: f64 = (0..n).map(|k| g[k * n + i] * g[k * n + j]).sum();
                values.push(e + if i == j { 0.1 * n as f64 } else { 0.0 });
            }
        }
        let b: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
        let perm: Vec<u32> = (0..n as u32).collect();
        check_supernodal(&a, &perm, &values, &b, "dense");
    }
    // Random patterns, natural order and minimum degree.
    for (n, per_col) in [(40, 2), (300, 3), (600, 6)] {
        let (col_ptr, row_idx, values) = random_spd_pattern(n, per_col, &mut rng);
        let a = UpperCsc::new(n, &col_ptr, &row_idx).unwrap();
        let b: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
        let natural: Vec<u32> = (0..n as u32).collect();
        check_supernodal(&a, &natural, &values, &b, "random, natural order");
        let md = order_pattern(&a).unwrap();
        check_supernodal(&a, &md, &values, &b, "random, minimum degree");
    }
}

#[test]
fn supernodal_failure_names_the_column_and_leaves_the_factor_bit_for_bit() {
    let mut rng = Rng::new(9);
    let (mesh, fixed) = meshes().swap_remove(1);
    let pat = StiffnessPattern::new(&mesh, &fixed).unwrap();
    let a = pat.upper();
    let n = a.n();
    let good: Vec<f64> = pat.random_spd(&mesh, &mut rng, 0.05);
    let mut awork = vec![0u32; analyse_work_len(n, a.nnz())];
    let size = Symbolic::size(&a, &pat.perm, &mut awork).unwrap();
    let mut sstore = vec![0u32; size.index_len()];
    let sym = Symbolic::new(&a, &pat.perm, &mut sstore, &mut awork).unwrap();
    let mut fstore = vec![0.0f64; LdlFactor::<f64>::storage_len(&size)];
    let mut factor = LdlFactor::new(&size, &mut fstore).unwrap();
    let mut simp_store = vec![0.0f64; LdlFactor::<f64>::storage_len(&size)];
    let mut simp = LdlFactor::new(&size, &mut simp_store).unwrap();
    let (mut y, mut cursor) = (vec![0.0; n], vec![0u32; n]);
    let mut work = vec![0.0; LdlFactor::<f64>::SUPERNODAL_WORK_LEN];
    let mut iwork = vec![0u32; LdlFactor::<f64>::supernodal_index_work_len(n)];
    factor
        .factorize_supernodal(&sym, &good, &mut work, &mut iwork)
        .unwrap();
    let bits = |f: &LdlFactor<'_, f64>| -> Vec<u64> {
        let l = f.l_values().unwrap().iter();
        l.chain(f.d_values().unwrap())
            .map(|v| v.to_bits())
            .collect()
    };
    let before = bits(&factor);
    let b: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
    let mut x_before = b.clone();
    factor.solve_in_place(&sym, &mut x_before, &mut y).unwrap();

    // Broken matrices: a negative diagonal entry at a column in the middle of the permuted
    // order, and a NaN off the diagonal; the supernodal factorization must name the column the
    // simplicial one names.
    // A column in the middle of the permuted order with an entry above its diagonal.
    let k = (n / 2..n)
        .find(|&k| a.column_range(pat.perm[k] as usize).len() > 1)
        .unwrap();
    let col = pat.perm[k] as usize;
    let mut negative = good.clone();
    negative[a.find(col, col).unwrap()] = -1.0;
    let mut nan = good.clone();
    let off = a
        .column_range(col)
        .find(|&p| a.row_idx()[p] as usize != col)
        .unwrap();
    nan[off] = f64::NAN;
    let mut infinite = good.clone();
    infinite[a.find(col, col).unwrap()] = f64::INFINITY;
    for (what, broken) in [
        ("negative", &negative),
        ("NaN", &nan),
        ("infinite", &infinite),
    ] {
        let expected = simp
            .factorize(&sym, broken, &mut y, &mut cursor)
            .unwrap_err();
        let got = factor
            .factorize_supernodal(&sym, broken, &mut work, &mut iwork)
            .unwrap_err();
        eprintln!("{what}: {got}");
        assert_eq!(got, expected, "{what}");
        assert!(matches!(
            got,
            Error::NotPositiveDefinite { .. } | Error::NotFinite { .. }
        ));
        assert_eq!(bits(&factor), before, "{what}: factor changed");
        let mut x = b.clone();
        factor.solve_in_place(&sym, &mut x, &mut y).unwrap();
        assert!(
            x.iter()
                .zip(&x_before)
                .all(|(p, q)| p.to_bits() == q.to_bits()),
            "{what}: solution changed"
        );
    }
    // A negative pivot shows at its own column or (through the updates it feeds) later.
    let Error::NotPositiveDefinite { column } = simp
        .factorize(&sym, &negative, &mut y, &mut cursor)
        .unwrap_err()
    else {
        panic!("a negative diagonal is not a non-finite pivot");
    };
    assert!(column >= k && column < n, "column {column}, broken {k}");
}

#[test]
fn supernodal_workspace_too_short_is_an_error() {
    let dense = Dense::new(4);
    let a = dense.upper();
    let perm = [0u32, 1, 2, 3];
    let values = [4.0, 1.0, 4.0, 0.0, 1.0, 4.0, 0.0, 0.0, 1.0, 4.0];
    let mut awork = vec![0u32; analyse_work_len(4, a.nnz())];
    let size = Symbolic::size(&a, &perm, &mut awork).unwrap();
    let mut sstore = vec![0u32; size.index_len()];
    let sym = Symbolic::new(&a, &perm, &mut sstore, &mut awork).unwrap();
    let mut fstore = vec![0.0f64; LdlFactor::<f64>::storage_len(&size)];
    let mut factor = LdlFactor::new(&size, &mut fstore).unwrap();
    let mut work = vec![0.0; LdlFactor::<f64>::SUPERNODAL_WORK_LEN];
    let mut iwork = vec![0u32; LdlFactor::<f64>::supernodal_index_work_len(4)];
    assert!(matches!(
        factor.factorize_supernodal(&sym, &values, &mut work[..10], &mut iwork),
        Err(Error::Capacity {
            resource: Resource::Workspace,
            ..
        })
    ));
    assert!(matches!(
        factor.factorize_supernodal(&sym, &values, &mut work, &mut iwork[..3]),
        Err(Error::Capacity {
            resource: Resource::Workspace,
            ..
        })
    ));
    assert!(!factor.is_factored());
    factor
        .factorize_supernodal(&sym, &values, &mut work, &mut iwork)
        .unwrap();
    assert_eq!(sym.supernodes(), 1);
}

/// Mixed precision at the level of the sparse phases: an `f32` factor computed from `f64`
/// values ([`LdlFactor::factorize_supernodal`] rounds them), `f64` right-hand sides solved
/// through it ([`LdlFactor::solve_converting`]); its factor equals the one of the values rounded
/// to `f32` first, bit for bit, and three steps of iterative refinement on the `f64` residual
/// take the solution to `f64`'s accuracy against faer. `solve_converting` in the factor's own
/// type is `solve_in_place`, bit for bit.
#[test]
fn an_f32_factor_of_an_f64_matrix_refines_to_f64_accuracy() {
    let mut rng = Rng::new(31);
    for (mesh, fixed) in meshes() {
        let pat = StiffnessPattern::new(&mesh, &fixed).unwrap();
        let a = pat.upper();
        let n = a.n();
        let values: Vec<f64> = pat.random_spd(&mesh, &mut rng, 0.05);
        let b: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
        let reference = faer_solve(&a, &values, &b);

        let mut awork = vec![0u32; analyse_work_len(n, a.nnz())];
        let size = Symbolic::size(&a, &pat.perm, &mut awork).unwrap();
        let mut sstore = vec![0u32; size.index_len()];
        let sym = Symbolic::new(&a, &pat.perm, &mut sstore, &mut awork).unwrap();
        let mut fstore = vec![0f32; LdlFactor::<f32>::storage_len(&size)];
        let mut factor = LdlFactor::new(&size, &mut fstore).unwrap();
        let mut work = vec![0f32; LdlFactor::<f32>::SUPERNODAL_WORK_LEN];
        let mut iwork = vec![0u32; LdlFactor::<f32>::supernodal_index_work_len(n)];
        factor
            .factorize_supernodal(&sym, &values, &mut work, &mut iwork)
            .unwrap();

        // The same factor as from the values rounded first.
        let values32: Vec<f32> = values.iter().map(|&v| v as f32).collect();
        let b32: Vec<f32> = b.iter().map(|&v| v as f32).collect();
        let rounded =
            factor_and_solve_with(Method::Supernodal, &a, &pat.perm, &values32, &b32).unwrap();
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(factor.l_values().unwrap()), bits(&rounded.l));
        assert_eq!(bits(factor.d_values().unwrap()), bits(&rounded.d));

        // In the factor's own type, `solve_in_place` bit for bit.
        let mut own = b32.clone();
        let mut scratch = vec![0f32; 2 * n];
        factor
            .solve_converting(&sym, &mut own, &mut scratch)
            .unwrap();
        assert_eq!(bits(&own), bits(&rounded.x));

        // Refinement in f64: x += A⁻¹ (b − A x), A⁻¹ through the f32 factor.
        let mut x = vec![0.0f64; n];
        let mut r = b.clone();
        let mut ax = vec![0.0f64; n];
        let mut errors = vec![];
        for _ in 0..4 {
            factor.solve_converting(&sym, &mut r, &mut scratch).unwrap();
            for (xi, ri) in x.iter_mut().zip(&r) {
                *xi += ri;
            }
            errors.push(rel_diff(&x, &reference));
            incise_core::sparse::sym_matvec(&a, &values, &x, &mut ax).unwrap();
            for ((ri, bi), axi) in r.iter_mut().zip(&b).zip(&ax) {
                *ri = bi - axi;
            }
        }
        eprintln!(
            "unknowns {n:5}: relative error through the f32 factor, refined 0 to 3 times: {}",
            errors
                .iter()
                .map(|e| format!("{e:.1e}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
        assert!(
            errors[0] > 1e-9,
            "one f32 solve is f32-accurate only: {errors:?}"
        );
        assert!(errors[3] <= 1e-10, "refined: {errors:?}");
    }
}
