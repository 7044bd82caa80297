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

/// Builds a model of a small box held at one end, embeds features seen from above and runs
/// registration steps pulling its free end; 0 when every step lowers the gradient.
#[unsafe(no_mangle)]
pub extern "C" fn incise_nostd_check_step() -> i32 {
    match step() {
        Ok(true) => 0,
        Ok(false) => 2,
        Err(_) => 1,
    }
}

fn step() -> Result<bool, incise_core::Error> {
    use incise_core::nalgebra::{Matrix3, Vector3};
    use incise_core::{
        Camera, Capacities, Coupling, Intrinsics, Law, Material, MeshCapacity, MeshInput, Model, ModelBuffers,
        ModelConfig, ModelSize, Observation, SolverConfig, Strategy,
    };
    const CX: usize = 4;
    const NN: usize = (CX + 1) * 3 * 3;
    const NT: usize = 6 * CX * 2 * 2;
    let (lx, ly, lz) = (0.04f64, 0.01, 0.01);
    let mut rest = [[0.0f64; 3]; NN];
    let mut tets = [[0u32; 4]; NT];
    box_mesh([CX, 2, 2], [lx, ly, lz], &mut rest, &mut tets);
    let id = |i: usize, j: usize, k: usize| (i + (CX + 1) * (j + 3 * k)) as u32;
    let fixed = [
        id(0, 0, 0),
        id(0, 1, 0),
        id(0, 2, 0),
        id(0, 0, 1),
        id(0, 1, 1),
        id(0, 2, 1),
        id(0, 0, 2),
        id(0, 1, 2),
        id(0, 2, 2),
    ];
    let mesh = MeshInput {
        rest: &rest,
        tets: &tets,
        fixed: &fixed,
    };

    // A camera 0.2 m above the box, looking down.
    let r = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);
    let eye = Vector3::new(0.02, 0.005, 0.2);
    let intr = Intrinsics {
        fx: 2000.0,
        fy: 2000.0,
        cx: 320.0,
        cy: 240.0,
        width: 640,
        height: 480,
    };
    let camera = Camera::new(intr, r, -(r * eye), 1e-4)?;
    let config = ModelConfig {
        material: Material {
            young: 3.0e4,
            poisson: 0.3,
            inversion_barrier: true,
            law: Law::SaintVenantKirchhoff,
        },
        camera,
        solver: SolverConfig {
            strategy: Strategy::Refactor,
            newton_iterations: 3,
            line_search_steps: 4,
            coupling: Coupling::Stiffness(2e-7),
            spring_threshold: incise_core::solve::DEFAULT_SPRING_THRESHOLD as _,
            damping: 1e-3,
            depth_prior: 0.0,
            image_margin: 50.0,
        },
        detection: incise_core::DetectionConfig::paper(),
    };
    // Every length is a `const fn` of the capacities: the buffers are sized at compile time.
    // A capacity the core cannot hold stops the build.
    const SIZE: ModelSize = match ModelSize::new(&Capacities {
        mesh: MeshCapacity {
            nodes: NN,
            tets: NT,
            surface_triangles: 4 * NT,
        },
        features: 16,
        targets: 4,
        factor_entries: 4096,
        pairs: 256,
        cut_vertices: 16,
    }) {
        Ok(size) => size,
        Err(_) => panic!("capacities too large for the core"),
    };
    let mut reals = [0.0f64; SIZE.real_len()];
    let mut indices = [0u32; SIZE.index_len()];
    let buffers = ModelBuffers::new(&SIZE, &mut reals, &mut indices)?;
    let mut model = Model::new(&mesh, &config, &SIZE, buffers)?;

    // Nine features on the top face near the free end.
    let mut frame = [Observation {
        id: 0,
        uv: [0.0; 2],
    }; 9];
    for (n, o) in frame.iter_mut().enumerate() {
        let p = Vector3::new(
            0.034 + 0.002 * (n % 3) as f64,
            0.003 + 0.002 * (n / 3) as f64,
            lz,
        );
        let uv = camera.project(&p, n)?;
        *o = Observation {
            id: n as u32,
            uv: [uv.x, uv.y],
        };
    }
    if model.embed_features(&frame)?.embedded != 9 {
        return Ok(false);
    }
    let mut ok = true;
    for step in 1..=4 {
        for o in frame.iter_mut() {
            o.uv[1] -= 2.0 * step as f64;
        }
        let report = model.step(&frame)?;
        ok &= report.gradient_norm_after < report.gradient_norm_before;
    }
    model.set_strategy(Strategy::Frozen { pcg_iterations: 10 })?;
    let report = model.step(&frame)?;
    ok &= report.gradient_norm_after <= report.gradient_norm_before;
    Ok(ok)
}

/// The model's storage as a firmware build holds it: `static`, sized at compile time by the
/// capacities' `const fn`s, handed out once.
#[cfg(feature = "cut")]
mod static_storage {
    use core::cell::UnsafeCell;
    use core::sync::atomic::{AtomicBool, Ordering};

    use incise_core::{Capacities, MeshCapacity, ModelSize};

    /// Cells of the box along x, y, z.
    pub const CELLS: [usize; 3] = [4, 2, 2];
    pub const NODES: usize = (CELLS[0] + 1) * (CELLS[1] + 1) * (CELLS[2] + 1);
    pub const TETS: usize = 6 * CELLS[0] * CELLS[1] * CELLS[2];
    /// Checked at compile time: a capacity the core cannot hold stops the build.
    pub const SIZE: ModelSize = match ModelSize::new(&Capacities {
        mesh: MeshCapacity {
            nodes: NODES + 64,
            tets: TETS + 256,
            surface_triangles: 4 * (TETS + 256),
        },
        features: 16,
        targets: 4,
        factor_entries: 8192,
        pairs: 256,
        cut_vertices: 16,
    }) {
        Ok(size) => size,
        Err(_) => panic!("capacities too large for the core"),
    };

    struct Buffers {
        reals: UnsafeCell<[f64; SIZE.real_len()]>,
        indices: UnsafeCell<[u32; SIZE.index_len()]>,
    }

    // SAFETY: the buffers are only reached through `take`, which hands them out once.
    unsafe impl Sync for Buffers {}

    static BUFFERS: Buffers = Buffers {
        reals: UnsafeCell::new([0.0; SIZE.real_len()]),
        indices: UnsafeCell::new([0; SIZE.index_len()]),
    };
    static TAKEN: AtomicBool = AtomicBool::new(false);

    /// The static buffers, the first time only.
    pub fn take() -> Option<(&'static mut [f64], &'static mut [u32])> {
        if TAKEN.swap(true, Ordering::AcqRel) {
            return None;
        }
        // SAFETY: `TAKEN` lets this run once, so these are the only references ever made.
        let (reals, indices) = unsafe { (&mut *BUFFERS.reals.get(), &mut *BUFFERS.indices.get()) };
        Some((&mut reals[..], &mut indices[..]))
    }
}

/// Builds a model of a box held at one end in static storage, embeds features and a target,
/// cuts it across along a line in the image (the whole cut pipeline: snapping, splitting,
/// separating, rebuilding the ordering, the symbolic analysis and the factor in place), checks
/// the cut took and the target stayed inside its element, and steps once more; 0 on success.
#[cfg(feature = "cut")]
#[unsafe(no_mangle)]
pub extern "C" fn incise_nostd_check_cut() -> i32 {
    match cut() {
        Ok(true) => 0,
        Ok(false) => 2,
        Err(_) => 1,
    }
}

#[cfg(feature = "cut")]
fn cut() -> Result<bool, incise_core::Error> {
    use incise_core::nalgebra::{Matrix3, Vector3};
    use incise_core::{
        Camera, Coupling, Intrinsics, Law, Material, MeshInput, Model, ModelBuffers, ModelConfig, Observation,
        SolverConfig, Strategy,
    };
    use static_storage::{CELLS, NODES, SIZE, TETS};
    let (lx, ly, lz) = (0.04f64, 0.01, 0.01);
    let mut rest = [[0.0f64; 3]; NODES];
    let mut tets = [[0u32; 4]; TETS];
    box_mesh(CELLS, [lx, ly, lz], &mut rest, &mut tets);
    let id = |i: usize, j: usize, k: usize| (i + (CELLS[0] + 1) * (j + (CELLS[1] + 1) * k)) as u32;
    let mut fixed = [0u32; (CELLS[1] + 1) * (CELLS[2] + 1)];
    for k in 0..=CELLS[2] {
        for j in 0..=CELLS[1] {
            fixed[j + (CELLS[1] + 1) * k] = id(0, j, k);
        }
    }
    let mesh = MeshInput {
        rest: &rest,
        tets: &tets,
        fixed: &fixed,
    };
    let r = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);
    let eye = Vector3::new(0.02, 0.005, 0.2);
    let camera = Camera::new(
        Intrinsics {
            fx: 2000.0,
            fy: 2000.0,
            cx: 320.0,
            cy: 240.0,
            width: 640,
            height: 480,
        },
        r,
        -(r * eye),
        1e-4,
    )?;
    let config = ModelConfig {
        material: Material {
            young: 3.0e4,
            poisson: 0.3,
            inversion_barrier: true,
            law: Law::SaintVenantKirchhoff,
        },
        camera,
        solver: SolverConfig {
            strategy: Strategy::Refactor,
            newton_iterations: 2,
            line_search_steps: 4,
            coupling: Coupling::Stiffness(2e-7),
            spring_threshold: incise_core::solve::DEFAULT_SPRING_THRESHOLD as _,
            damping: 1e-3,
            depth_prior: 0.0,
            image_margin: 50.0,
        },
        detection: incise_core::DetectionConfig::paper(),
    };
    let Some((reals, indices)) = static_storage::take() else {
        return Ok(false);
    };
    let mut model = Model::new(
        &mesh,
        &config,
        &SIZE,
        ModelBuffers::new(&SIZE, reals, indices)?,
    )?;
    let mut frame = [Observation {
        id: 0,
        uv: [0.0; 2],
    }; 12];
    for (n, o) in frame.iter_mut().enumerate() {
        let p = Vector3::new(
            0.003 + 0.0065 * (n % 6) as f64,
            0.003 + 0.004 * (n / 6) as f64,
            lz,
        );
        let uv = camera.project(&p, n)?;
        *o = Observation {
            id: n as u32,
            uv: [uv.x, uv.y],
        };
    }
    if model.embed_features(&frame)?.embedded != frame.len() {
        return Ok(false);
    }
    model.embed_targets(&[[0.025, 0.005, 0.005]])?;
    let (nodes, tets_before) = (model.mesh().n_nodes(), model.mesh().n_tets());
    // A slit across the box at x = 2.3 cm from the far side (y = 0) to three quarters across.
    let a = camera.project(&Vector3::new(0.023, -0.002, lz), 0)?;
    let b = camera.project(&Vector3::new(0.023, 0.0075, lz), 0)?;
    let report = model.cut_along(&[[a.x, a.y], [b.x, b.y]], 5.0)?;
    let target_inside = model
        .target_embedding()
        .weights()
        .iter()
        .all(|w| w.iter().all(|&c| c >= 0.0));
    let grew = model.mesh().n_nodes() > nodes && model.mesh().n_tets() >= tets_before;
    // The cut model goes on registering: pull the features on the free end apart.
    for o in frame.iter_mut() {
        o.uv[0] += if o.uv[0] > a.x { 3.0 } else { 0.0 };
    }
    let step = model.step(&frame)?;
    Ok(report.applied
        && report.event.faces_cut > 0
        && grew
        && target_inside
        && step.gradient_norm_after < step.gradient_norm_before)
}

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
    let mut rest = [[0.0f64; 3]; NODES];
    let mut tets = [[0u32; 4]; TETS];
    box_mesh([C, C, C], [1.0, 1.0, 1.0], &mut rest, &mut tets);
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
            values[p] = if a.row_idx()[p] as usize == j {
                64.0
            } else {
                -0.5
            };
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

/// A box of `nx × ny × nz` cells, six positive tetrahedra per cell (Kuhn), into fixed arrays:
/// `rest` needs `(nx + 1)(ny + 1)(nz + 1)` entries, `tets` `6 nx ny nz`.
fn box_mesh(n: [usize; 3], size: [f64; 3], rest: &mut [[f64; 3]], tets: &mut [[u32; 4]]) {
    let [nx, ny, nz] = n;
    let id = |i: usize, j: usize, k: usize| (i + (nx + 1) * (j + (ny + 1) * k)) as u32;
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                rest[id(i, j, k) as usize] = [
                    size[0] * i as f64 / nx as f64,
                    size[1] * j as f64 / ny as f64,
                    size[2] * k as f64 / nz as f64,
                ];
            }
        }
    }
    let mut t = 0;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                for path in [
                    [0, 1, 2],
                    [0, 2, 1],
                    [1, 0, 2],
                    [1, 2, 0],
                    [2, 0, 1],
                    [2, 1, 0],
                ] {
                    let mut c = [i, j, k];
                    tets[t][0] = id(i, j, k);
                    for (s, axis) in path.into_iter().enumerate() {
                        c[axis] += 1;
                        tets[t][s + 1] = id(c[0], c[1], c[2]);
                    }
                    // Kuhn paths alternate in orientation: make every tetrahedron positive.
                    let p = |v: u32| rest[v as usize];
                    let (a, b, cc, d) =
                        (p(tets[t][0]), p(tets[t][1]), p(tets[t][2]), p(tets[t][3]));
                    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                    let v = [cc[0] - a[0], cc[1] - a[1], cc[2] - a[2]];
                    let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
                    let vol = u[0] * (v[1] * w[2] - v[2] * w[1])
                        - u[1] * (v[0] * w[2] - v[2] * w[0])
                        + u[2] * (v[0] * w[1] - v[1] * w[0]);
                    if vol < 0.0 {
                        tets[t].swap(2, 3);
                    }
                    t += 1;
                }
            }
        }
    }
}
