//! A heap-free program over incise-core: everything lives on the stack, there is no global
//! allocator, and `tests/no_heap.rs` checks that no allocator symbol is linked. The entry point
//! returns 0 when the computation checks out, so a C `main` can run it.
#![no_std]
#![no_main]

use incise_core::sparse::{
    Graph, LdlFactor, Symbolic, analyse_work_len, block_upper_len, block_upper_pattern,
    expand_block_permutation, minimum_degree, minimum_degree_work_len, relative_residual,
    tet_graph_work_len,
};

#[panic_handler]
fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
    loop {}
}

/// Cells per side of the test box.
const C: usize = 2;
const NODES: usize = (C + 1) * (C + 1) * (C + 1);
const TETS: usize = 6 * C * C * C;
const N: usize = 3 * NODES;

/// Factorizes a stiffness-like matrix of a small box mesh and solves with it; 0 on success.
#[unsafe(no_mangle)]
pub extern "C" fn incise_nostd_check_sparse() -> i32 {
    match sparse() {
        Ok(true) => 0,
        Ok(false) => 2,
        Err(_) => 1,
    }
}

fn sparse() -> Result<bool, incise_core::Error> {
    let id = |i: usize, j: usize, k: usize| (i + (C + 1) * (j + (C + 1) * k)) as u32;
    let mut tets = [[0u32; 4]; TETS];
    let mut t = 0;
    for k in 0..C {
        for j in 0..C {
            for i in 0..C {
                for path in [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]] {
                    let mut c = [i, j, k];
                    tets[t][0] = id(i, j, k);
                    for (s, axis) in path.into_iter().enumerate() {
                        c[axis] += 1;
                        tets[t][s + 1] = id(c[0], c[1], c[2]);
                    }
                    t += 1;
                }
            }
        }
    }
    let mut free = [0u32; NODES];
    for (v, f) in free.iter_mut().enumerate() {
        *f = v as u32;
    }
    let mut work = [0u32; 4096];
    let mut gp = [0u32; NODES + 1];
    let mut ga = [0u32; 512];
    let _ = tet_graph_work_len(NODES, TETS);
    let graph = Graph::from_tets(&tets, &free, &mut gp, &mut ga, &mut work)?;
    let mut node_perm = [0u32; NODES];
    let _ = minimum_degree_work_len(NODES, graph.nnz());
    minimum_degree(&graph, &mut node_perm, &mut work)?;
    let mut perm = [0u32; N];
    expand_block_permutation(&node_perm, 3, &mut perm)?;
    let mut cp = [0u32; N + 1];
    let mut ri = [0u32; 2048];
    let nnz = block_upper_len(&graph, 3);
    let a = block_upper_pattern(&graph, 3, &mut cp, &mut ri)?;
    // A diagonally dominant matrix on the pattern: SPD.
    let mut values = [0.0f64; 2048];
    for j in 0..a.n() {
        for p in a.column_range(j) {
            values[p] = if a.row_idx()[p] as usize == j { 64.0 } else { -0.5 };
        }
    }
    let values = &values[..nnz];
    let _ = analyse_work_len(N, nnz);
    let size = Symbolic::size(&a, &perm, &mut work)?;
    let mut sstore = [0u32; 8192];
    let sym = Symbolic::new(&a, &perm, &mut sstore, &mut work)?;
    let mut fstore = [0.0f64; 8192];
    let mut factor = LdlFactor::new(&size, &mut fstore)?;
    let (mut y, mut cursor) = ([0.0f64; N], [0u32; N]);
    factor.factorize(&sym, values, &mut y, &mut cursor)?;
    let b = [1.0f64; N];
    let mut x = b;
    factor.solve_in_place(&sym, &mut x, &mut y)?;
    let res = relative_residual(&a, values, &x, &b, &mut y)?;
    Ok(res < 1e-12)
}

/// The negative control: with the `heap-control` feature this program does use a heap, and the
/// symbol check of `tests/no_heap.rs` must see it.
#[cfg(feature = "heap-control")]
mod heap_control {
    extern crate alloc;

    struct NoMemory;

    // SAFETY: returning null is the documented way for an allocator to report failure.
    unsafe impl core::alloc::GlobalAlloc for NoMemory {
        unsafe fn alloc(&self, _: core::alloc::Layout) -> *mut u8 {
            core::ptr::null_mut()
        }
        unsafe fn dealloc(&self, _: *mut u8, _: core::alloc::Layout) {}
    }

    #[global_allocator]
    static ALLOCATOR: NoMemory = NoMemory;

    #[unsafe(no_mangle)]
    pub extern "C" fn incise_nostd_check_heap(n: usize) -> usize {
        alloc::vec![1u8; n].len()
    }
}
