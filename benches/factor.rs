//! Numeric factorization and triangular solves of the core against faer's supernodal ones, on
//! the stiffness patterns of box meshes (3 unknowns per node, the face `x = 0` fixed) with
//! random SPD values, measured in the same run, single thread.
//!
//! The core factors under its own ordering (minimum degree or nested dissection, whichever fills
//! less), faer under its own AMD; both are timed on the numeric phase only (fastest of repeated
//! runs). faer's peer is the faster of its supernodal LLᵀ and LDLᵀ. Prints markdown tables.
//!
//! Last, the same on SOFA's fine liver (`../shared/data/liver/liverFine.vtu`, 4293 nodes, read
//! where it lies, its nodes within 5 mm of its smallest `x` fixed), when the file is there.
//!
//! Then the arithmetic rates of the machine in the same run: separate multiplies and adds as
//! safe Rust compiles them for the build's target (the ceiling of the core's kernels, which
//! cannot fuse them), and faer's dense product; the factorization table sets the core against
//! the first.
//!
//! `cargo bench --bench factor` (`-- --quick` for fewer repetitions).

use std::hint::black_box;
use std::time::Instant;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::{Conj, Mat, Par, Side};
use incise_core::sparse::{LdlFactor, Symbolic, analyse_work_len};
use incise_validation::oracle::{faer_amd_nnz_l, to_faer};
use incise_validation::rng::Rng;
use incise_validation::system::StiffnessPattern;
use incise_validation::testmesh::{TetMesh, box_mesh};

/// Cells per axis of the box meshes: 250, 500, 1000, 2000 and 4000 nodes.
const CASES: [[usize; 3]; 5] = [[9, 4, 4], [9, 9, 4], [9, 9, 9], [19, 9, 9], [19, 19, 9]];

/// Fastest seconds of `f` over runs until `budget` seconds have passed (at least `min_runs`
/// times): on a machine shared with other jobs the minimum is the estimate least disturbed by
/// them (medians moved by ±50 % between runs here).
fn best_seconds(min_runs: usize, budget: f64, mut f: impl FnMut()) -> f64 {
    let mut times = vec![];
    let start = Instant::now();
    while times.len() < min_runs || start.elapsed().as_secs_f64() < budget {
        let t = Instant::now();
        f();
        times.push(t.elapsed().as_secs_f64());
        if times.len() >= 10_000 {
            break;
        }
    }
    times.into_iter().fold(f64::INFINITY, f64::min)
}

struct Row {
    nodes: String,
    n: usize,
    supernodes: usize,
    flops: u64,
    simplicial: f64,
    supernodal: f64,
    faer_llt: f64,
    faer_ldlt: f64,
    solve_simplicial: f64,
    solve_supernodal: f64,
    faer_solve: f64,
    nnz_ours: usize,
    nnz_stored: usize,
    nnz_md: usize,
    nnz_nd: usize,
    nnz_faer_amd: usize,
}

fn faer_supernodal(a: &faer::sparse::SparseColMat<usize, f64>) -> SymbolicCholesky<usize> {
    let params = CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
        ..Default::default()
    };
    factorize_symbolic_cholesky(a.symbolic(), Side::Upper, SymmetricOrdering::Amd, params)
        .expect("faer symbolic")
}

/// A box mesh of `cells` with its face `x = 0` fixed.
fn box_case(cells: [usize; 3]) -> (String, TetMesh, Vec<u32>) {
    let mesh = box_mesh(cells, [2.0, 1.0, 1.0]);
    let fixed: Vec<u32> = (0..mesh.nodes.len() as u32)
        .filter(|&v| mesh.nodes[v as usize][0] == 0.0)
        .collect();
    (mesh.nodes.len().to_string(), mesh, fixed)
}

/// SOFA's fine liver, if it is where the workplace keeps it, with its nodes within 5 mm of its
/// smallest `x` fixed (the file is in centimetres).
fn fine_liver() -> Option<(String, TetMesh, Vec<u32>)> {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/liver/liverFine.vtu");
    let vtu = incise::vtu::read_vtu(&path).ok()?;
    let x0 = vtu.nodes.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min);
    let fixed: Vec<u32> = (0..vtu.nodes.len() as u32)
        .filter(|&v| vtu.nodes[v as usize][0] <= x0 + 0.5)
        .collect();
    let label = format!("{} (fine liver)", vtu.nodes.len());
    Some((
        label,
        TetMesh {
            nodes: vtu.nodes,
            tets: vtu.tets,
        },
        fixed,
    ))
}

fn measure((label, mesh, fixed): (String, TetMesh, Vec<u32>), budget: f64) -> Row {
    let pat = StiffnessPattern::new(&mesh, &fixed).expect("pattern");
    let a = pat.upper();
    let n = a.n();
    let mut rng = Rng::new(3);
    let values: Vec<f64> = pat.random_spd(&mesh, &mut rng, 0.05);
    let b: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();

    // The core.
    let fills = pat.ordering_fills(&mesh).expect("orderings");
    let mut awork = vec![0u32; analyse_work_len(n, a.nnz())];
    let size = Symbolic::size(&a, &pat.perm, &mut awork).expect("size");
    let mut sstore = vec![0u32; size.index_len()];
    let sym = Symbolic::new(&a, &pat.perm, &mut sstore, &mut awork).expect("symbolic");
    let mut fstore = vec![0.0f64; LdlFactor::<f64>::storage_len(&size)];
    let mut factor = LdlFactor::new(&size, &mut fstore).expect("factor");
    let (mut y, mut cursor) = (vec![0.0; n], vec![0u32; n]);
    let mut work = vec![0.0; LdlFactor::<f64>::SUPERNODAL_WORK_LEN];
    let mut iwork = vec![0u32; LdlFactor::<f64>::supernodal_index_work_len(n)];
    let simplicial = best_seconds(5, budget, || {
        factor
            .factorize(&sym, black_box(&values), &mut y, &mut cursor)
            .expect("simplicial");
    });
    let supernodal = best_seconds(5, budget, || {
        factor
            .factorize_supernodal(&sym, black_box(&values), &mut work, &mut iwork)
            .expect("supernodal");
    });
    let mut x = b.clone();
    let solve_supernodal = best_seconds(5, budget, || {
        x.copy_from_slice(&b);
        factor.solve_in_place(&sym, &mut x, &mut y).expect("solve");
    });
    // The column-by-column solves (the core's solves before the supernodal ones).
    let solve_simplicial = best_seconds(5, budget, || {
        for (wk, &p) in y.iter_mut().zip(sym.perm()) {
            *wk = b[p as usize];
        }
        factor.solve_lower_in_place(&sym, &mut y).expect("lower");
        factor
            .solve_diagonal_in_place(&sym, &mut y)
            .expect("diagonal");
        factor.solve_upper_in_place(&sym, &mut y).expect("upper");
        for (&wk, &p) in y.iter().zip(sym.perm()) {
            x[p as usize] = wk;
        }
        black_box(&x);
    });

    // faer, supernodal, its own AMD ordering.
    let fa = to_faer(&a, &values);
    let fsym = faer_supernodal(&fa);
    let mut l = vec![0.0; fsym.len_val()];
    let mut mem = MemBuffer::new(
        fsym.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default())
            .or(fsym.factorize_numeric_ldlt_scratch::<f64>(Par::Seq, Default::default())),
    );
    let faer_ldlt = best_seconds(5, budget, || {
        fsym.factorize_numeric_ldlt(
            &mut l,
            fa.as_ref(),
            Side::Upper,
            Default::default(),
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .expect("faer ldlt");
    });
    let faer_llt = best_seconds(5, budget, || {
        fsym.factorize_numeric_llt(
            &mut l,
            fa.as_ref(),
            Side::Upper,
            Default::default(),
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .expect("faer llt");
    });
    let llt = fsym
        .factorize_numeric_llt(
            &mut l,
            fa.as_ref(),
            Side::Upper,
            Default::default(),
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .expect("faer llt");
    let mut rhs = Mat::<f64>::from_fn(n, 1, |i, _| b[i]);
    let mut smem = MemBuffer::new(fsym.solve_in_place_scratch::<f64>(1, Par::Seq));
    let faer_solve = best_seconds(5, budget, || {
        for i in 0..n {
            rhs[(i, 0)] = b[i];
        }
        llt.solve_in_place_with_conj(Conj::No, rhs.as_mut(), Par::Seq, MemStack::new(&mut smem));
        black_box(&rhs);
    });
    // The two solutions agree (the benchmark measures the right thing).
    let err = (0..n)
        .map(|i| (x[i] - rhs[(i, 0)]).abs())
        .fold(0.0, f64::max);
    assert!(err < 1e-8, "solutions differ by {err:e}");

    Row {
        nodes: label,
        n,
        supernodes: sym.supernodes(),
        flops: sym.factor_flops(),
        simplicial,
        supernodal,
        faer_llt,
        faer_ldlt,
        solve_simplicial,
        solve_supernodal,
        faer_solve,
        nnz_ours: fills.kept,
        nnz_stored: size.nnz_l,
        nnz_md: fills.minimum_degree,
        nnz_nd: fills.nested_dissection,
        nnz_faer_amd: faer_amd_nnz_l(&a),
    }
}

/// Passes over the chains per timed run of the peak loop.
const PEAK_PASSES: usize = 20_000;

/// GFLOP/s of separate multiplies and adds on `C` independent chains of each, as safe Rust
/// compiles them for this target (the compiler vectorises the chains and, by Rust's
/// floating-point rules, never fuses a multiply with an add).
fn multiply_then_add_rate<const C: usize>(budget: f64) -> f64 {
    let (b, c) = (black_box(1.000_000_1f64), black_box(1e-9f64));
    let seconds = best_seconds(5, budget, || {
        let mut m = black_box([1.0f64; C]);
        let mut s = black_box([0.0f64; C]);
        for _ in 0..PEAK_PASSES {
            for (m, s) in m.iter_mut().zip(s.iter_mut()) {
                *m *= b;
                *s += c;
            }
        }
        black_box((m, s));
    });
    (2 * C * PEAK_PASSES) as f64 / seconds / 1e9
}

/// The most arithmetic the core's kernels can do per second here, whatever their blocking:
/// the best of [`multiply_then_add_rate`] over 8, 16 and 32 chains (too few leave units idle
/// while results are under way; too many spill out of the vector registers, fewer in some
/// builds than in others).
fn multiply_then_add_peak(budget: f64) -> f64 {
    multiply_then_add_rate::<8>(budget)
        .max(multiply_then_add_rate::<16>(budget))
        .max(multiply_then_add_rate::<32>(budget))
}

/// Order of the dense product that measures faer's own arithmetic rate.
const DENSE_ORDER: usize = 384;

/// GFLOP/s of faer's dense matrix product (`2 n³` flops), single thread: the rate of its
/// kernels, which dispatch at run time to the widest vector instructions this CPU has,
/// fused multiply-adds included.
fn faer_dense_product(budget: f64) -> f64 {
    let n = DENSE_ORDER;
    let mut rng = Rng::new(5);
    let a = Mat::<f64>::from_fn(n, n, |_, _| rng.range(-1.0, 1.0));
    let b = Mat::<f64>::from_fn(n, n, |_, _| rng.range(-1.0, 1.0));
    let mut c = Mat::<f64>::zeros(n, n);
    let seconds = best_seconds(3, budget, || {
        faer::linalg::matmul::matmul(
            c.as_mut(),
            faer::Accum::Replace,
            a.as_ref(),
            b.as_ref(),
            1.0,
            Par::Seq,
        );
        black_box(&c);
    });
    2.0 * (n * n * n) as f64 / seconds / 1e9
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let budget = if quick { 0.2 } else { 1.0 };
    let cases = CASES.iter().map(|&c| box_case(c)).chain(fine_liver());
    let rows: Vec<Row> = cases.map(|c| measure(c, budget)).collect();
    let peak = multiply_then_add_peak(budget);
    let dense = faer_dense_product(budget);

    println!("## Numeric factorization (single thread, fastest of repeated runs)\n");
    println!(
        "| nodes | unknowns | supernodes | core simplicial ms | core supernodal ms | faer supernodal ms | simplicial / faer | supernodal / faer | core GFLOP/s | core's share of the multiply-and-add rate | least supernodal / faer at that rate |"
    );
    println!("| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |");
    for r in &rows {
        let peer = r.faer_llt.min(r.faer_ldlt);
        let rate = 2.0 * r.flops as f64 / r.supernodal / 1e9;
        println!(
            "| {} | {} | {} | {:.3} | {:.3} | {:.3} | {:.2} | {:.2} | {:.1} | {:.0} % | {:.2} |",
            r.nodes,
            r.n,
            r.supernodes,
            r.simplicial * 1e3,
            r.supernodal * 1e3,
            peer * 1e3,
            r.simplicial / peer,
            r.supernodal / peer,
            rate,
            100.0 * rate / peak,
            2.0 * r.flops as f64 / peak / 1e9 / peer,
        );
    }
    println!(
        "\nfaer: the faster of its supernodal LLᵀ and LDLᵀ (AMD ordering). GFLOP/s: 2 × the \
         multiply-adds of the core's factorization over its supernodal time. The last two \
         columns set it against the multiply-and-add rate below, the most arithmetic per second \
         the core's kernels can do in this build: the share of it the factorization reaches, \
         and the ratio to faer it would have if every one of its multiply-adds ran at that rate \
         with nothing else to do (the least this build can reach on that matrix).\n"
    );

    println!("## Arithmetic rates of this machine (single thread, same run)\n");
    println!("| what | GFLOP/s |");
    println!("| --- | ---: |");
    println!(
        "| multiplies and adds on independent chains, safe Rust as this build compiles it (best of 8, 16 and 32 chains) | {peak:.1} |"
    );
    println!(
        "| faer's dense product, order {DENSE_ORDER} (its kernels: fused multiply-adds where the CPU has them) | {dense:.1} |"
    );
    println!(
        "\nRust never fuses a multiply and an add (a fused one rounds once, so it would change the \
         result), and safe `no_std` Rust has no stable way to ask for one: the core's kernels \
         issue the two, and the first row is their ceiling. faer's kernels are chosen at run \
         time for this CPU and fuse them.\n"
    );

    println!("## Triangular solve pair (forward, diagonal, backward; permutation included)\n");
    println!(
        "| nodes | core column-by-column µs | core supernodal µs | faer supernodal µs | column / faer | supernodal / faer |"
    );
    println!("| ---: | ---: | ---: | ---: | ---: | ---: |");
    for r in &rows {
        println!(
            "| {} | {:.1} | {:.1} | {:.1} | {:.2} | {:.2} |",
            r.nodes,
            r.solve_simplicial * 1e6,
            r.solve_supernodal * 1e6,
            r.faer_solve * 1e6,
            r.solve_simplicial / r.faer_solve,
            r.solve_supernodal / r.faer_solve,
        );
    }

    println!("\n## Fill: strictly lower nnz(L)\n");
    println!(
        "| nodes | core minimum degree | core nested dissection | core, kept | faer AMD | kept / AMD | stored (relaxed supernodes) |"
    );
    println!("| ---: | ---: | ---: | ---: | ---: | ---: | ---: |");
    for r in &rows {
        println!(
            "| {} | {} | {} | {} | {} | {:.3} | {} (+{:.1} %) |",
            r.nodes,
            r.nnz_md,
            r.nnz_nd,
            r.nnz_ours,
            r.nnz_faer_amd,
            r.nnz_ours as f64 / r.nnz_faer_amd as f64,
            r.nnz_stored,
            100.0 * (r.nnz_stored as f64 / r.nnz_ours as f64 - 1.0)
        );
    }
    println!(
        "\nThe core keeps the ordering with the smaller fill (`fill_reducing_order`); the \
         factorization and solves above run under it. The fill counts the factor's entries; \
         the factor stores a few more, the explicit zeros of its relaxed supernodes \
         (`Symbolic`), which the factorization's time includes."
    );
}
