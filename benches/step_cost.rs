//! Per-frame cost of `Model::step` for both strategies on box meshes of about 250, 500 and
//! 1000 nodes with 500 features over 100 frames.
//!
//! Two measures, neither a bare wall-clock time:
//! - wall time per frame (median and max) as a ratio to faer's numeric Cholesky of the same
//!   Hessian measured in the same run (the peer), with the absolute times alongside;
//! - instructions per frame counted by callgrind (`valgrind --tool=callgrind`, deterministic),
//!   median, max and max/median over the 100 frames, next to the worst-case work formula the
//!   model reports, and as a multiple of one triangular-solve pair (forward, diagonal, backward)
//!   on a factor of the same Hessian, counted the same way (issue 12 sets a `Frozen` frame with
//!   10 PCG steps against it).
//!
//! `cargo bench --bench step_cost` runs both (the second only if valgrind is installed);
//! `-- --no-callgrind` skips it. The binary re-runs itself under callgrind with
//! `--instructions <case>` to count one case, and with `--solve-pair <case>` to count one solve
//! pair.

use std::hint::black_box;
use std::process::Command;
use std::time::Instant;

use faer::Par;
use faer::Side;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymmetricOrdering, factorize_symbolic_cholesky,
};
use incise_core::sparse::{LdlFactor, Symbolic, analyse_work_len};
use incise_core::{
    Coupling, Law, Material, MeshInput, Model, ModelConfig, Observation, SolverConfig, StepReport,
    Strategy,
};
use incise_validation::callgrind;
use incise_validation::oracle::to_faer;
use incise_validation::scene::{ModelStorage, camera, nodes_where, observe};
use incise_validation::system::StiffnessPattern;
use incise_validation::testmesh::{TetMesh, box_mesh};

const FRAMES: usize = 100;
const FEATURES: usize = 500;
const CASES: [(&str, [usize; 3]); 3] = [
    ("250", [9, 4, 4]),
    ("500", [19, 4, 4]),
    ("1000", [15, 7, 7]),
];
const SIZE: [f64; 3] = [0.08, 0.02, 0.02];

struct Case {
    mesh: TetMesh,
    fixed: Vec<u32>,
    cam: incise_core::Camera<f64>,
    frames: Vec<Vec<Observation<f64>>>,
}

fn case(cells: [usize; 3]) -> Case {
    let mesh = box_mesh(cells, SIZE);
    let fixed = nodes_where(&mesh, 0, 0.0);
    let cam = camera(
        [0.04, 0.01, 0.3],
        [0.04, 0.01, 0.0],
        [0.0, 1.0, 0.0],
        2000.0,
        (800, 400),
    );
    // 500 points on the top face, 25 along x by 20 across.
    let mut pts = vec![];
    for i in 0..25 {
        for j in 0..20 {
            pts.push([
                SIZE[0] * (i as f64 + 0.5) / 25.0,
                SIZE[1] * (j as f64 + 0.5) / 20.0,
                SIZE[2],
            ]);
        }
    }
    assert_eq!(pts.len(), FEATURES);
    let base = observe(&cam, &pts);
    // The free end swings up and down in the image; every point moves in proportion to its
    // distance from the held end.
    let frames = (0..=FRAMES)
        .map(|f| {
            let s = (f as f64 * 0.15).sin();
            base.iter()
                .zip(&pts)
                .map(|(o, p)| {
                    let w = (p[0] / SIZE[0]).powi(2);
                    Observation {
                        id: o.id,
                        uv: [o.uv[0] + 6.0 * w * s, o.uv[1] - 30.0 * w * s],
                    }
                })
                .collect()
        })
        .collect();
    Case {
        mesh,
        fixed,
        cam,
        frames,
    }
}

fn config(cam: incise_core::Camera<f64>, strategy: Strategy) -> ModelConfig<f64> {
    ModelConfig {
        material: Material {
            young: 3.0e4,
            poisson: 0.3,
            inversion_barrier: true,
            law: Law::SaintVenantKirchhoff,
        },
        camera: cam,
        solver: SolverConfig {
            strategy,
            newton_iterations: 2,
            line_search_steps: 3,
            coupling: Coupling::Stiffness(1e-7),
            spring_threshold: incise_core::solve::DEFAULT_SPRING_THRESHOLD,
            damping: 1e-3,
            depth_prior: 0.0,
            image_margin: 50.0,
        },
        detection: incise_core::DetectionConfig {
            enabled: false,
            ..incise_core::DetectionConfig::paper()
        },
    }
}

const STRATEGIES: [(&str, Strategy); 2] = [
    ("refactor", Strategy::Refactor),
    ("frozen", Strategy::Frozen { pcg_iterations: 10 }),
];

#[inline(never)]
fn bench_frame_step(model: &mut Model<'_, f64>, frame: &[Observation<f64>]) -> StepReport<f64> {
    model.step(black_box(frame)).expect("step")
}

fn with_model<R>(c: &Case, strategy: Strategy, f: impl FnOnce(&mut Model<'_, f64>) -> R) -> R {
    let input = MeshInput {
        rest: &c.mesh.nodes,
        tets: &c.mesh.tets,
        fixed: &c.fixed,
    };
    let mut storage = ModelStorage::with_features(&input, FEATURES).expect("size");
    let mut model = storage
        .model(&input, &config(c.cam, strategy))
        .expect("model");
    let report = model.embed_features(&c.frames[0]).expect("embed");
    assert_eq!(report.embedded, FEATURES);
    f(&mut model)
}

fn percentile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// Median time of faer's numeric Cholesky of the model's current Hessian.
fn faer_factor_seconds(model: &mut Model<'_, f64>) -> f64 {
    let lin = model.linearize().expect("linearize");
    let a = to_faer(&lin.pattern, lin.hessian);
    let sym = factorize_symbolic_cholesky(
        a.symbolic(),
        Side::Upper,
        SymmetricOrdering::Amd,
        CholeskySymbolicParams::default(),
    )
    .expect("faer symbolic");
    let mut l = vec![0.0; sym.len_val()];
    let mut mem =
        MemBuffer::new(sym.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()));
    let mut times = vec![];
    for _ in 0..15 {
        let t = Instant::now();
        sym.factorize_numeric_llt(
            &mut l,
            a.as_ref(),
            Side::Upper,
            Default::default(),
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .expect("faer factor");
        times.push(t.elapsed().as_secs_f64());
    }
    percentile(&mut times, 0.5)
}

fn timing() {
    println!(
        "## Wall time per frame ({FRAMES} frames, {FEATURES} features, 2 Newton steps, 3 line-search trials)\n"
    );
    println!(
        "| nodes | unknowns | strategy | median ms | max ms | faer factor ms | median / faer | max / median |"
    );
    println!("| ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: |");
    for (name, cells) in CASES {
        let c = case(cells);
        for (sname, strategy) in STRATEGIES {
            with_model(&c, strategy, |model| {
                let mut times = vec![];
                for frame in &c.frames[1..] {
                    let t = Instant::now();
                    black_box(bench_frame_step(model, frame));
                    times.push(t.elapsed().as_secs_f64() * 1e3);
                }
                let peer = faer_factor_seconds(model) * 1e3;
                let max = times.iter().cloned().fold(0.0, f64::max);
                let median = percentile(&mut times, 0.5);
                println!(
                    "| {} ({name}) | {} | {sname} | {median:.2} | {max:.2} | {peer:.3} | {:.1} | {:.2} |",
                    c.mesh.nodes.len(),
                    model.n_unknowns(),
                    median / peer,
                    max / median
                );
            });
        }
    }
    println!();
}

/// Runs one case for callgrind, which dumps its counts after each `Model::step`; the last
/// `FRAMES` dumps hold exactly one frame each.
fn instructions_child(case_name: &str, strategy_name: &str) {
    let cells = CASES.iter().find(|c| c.0 == case_name).expect("case").1;
    let strategy = STRATEGIES
        .iter()
        .find(|s| s.0 == strategy_name)
        .expect("strategy")
        .1;
    let c = case(cells);
    with_model(&c, strategy, |model| {
        let w = model.worst_case_work();
        println!(
            "WORST {} {} {} {}",
            w.factor_flops, w.solve_flops, w.matvec_flops, w.element_tangents
        );
        // A warm-up step: callgrind's first dump also holds the set-up.
        black_box(bench_frame_step(model, &c.frames[1]));
        for frame in &c.frames[1..] {
            black_box(bench_frame_step(model, frame));
        }
    });
}

/// Solve pairs counted per callgrind run: their mean is the table's "solve pair".
const SOLVE_PAIRS: usize = 10;

/// `SOLVE_PAIRS` solve pairs on `factor`, the only code callgrind counts in a
/// `--solve-pair` run.
#[inline(never)]
fn bench_solve_pairs(factor: &LdlFactor<'_, f64>, sym: &Symbolic<'_>, b: &[f64], y: &mut [f64]) {
    let mut x = b.to_vec();
    for _ in 0..SOLVE_PAIRS {
        x.copy_from_slice(b);
        factor
            .solve_in_place(sym, black_box(&mut x), y)
            .expect("solve");
    }
    black_box(&x);
}

/// Runs one case for callgrind: two frames (not counted), then a factor of the model's Hessian
/// under the core's ordering, as the model factors it (supernodal), and [`bench_solve_pairs`]
/// on it. A solve pair costs the same whatever the values, so one count per mesh serves both
/// strategies.
fn solve_pair_child(case_name: &str) {
    let cells = CASES.iter().find(|c| c.0 == case_name).expect("case").1;
    let c = case(cells);
    with_model(&c, Strategy::Refactor, |model| {
        for frame in &c.frames[1..3] {
            black_box(bench_frame_step(model, frame));
        }
        let lin = model.linearize().expect("linearize");
        let pat = StiffnessPattern::new(&c.mesh, &c.fixed).expect("pattern");
        assert_eq!(
            lin.pattern.col_ptr(),
            &pat.col_ptr[..],
            "the model's pattern"
        );
        assert_eq!(
            lin.pattern.row_idx(),
            &pat.row_idx[..],
            "the model's pattern"
        );
        let a = pat.upper();
        let n = a.n();
        let mut awork = vec![0u32; analyse_work_len(n, a.nnz())];
        let size = Symbolic::size(&a, &pat.perm, &mut awork).expect("size");
        let mut sstore = vec![0u32; size.index_len()];
        let sym = Symbolic::new(&a, &pat.perm, &mut sstore, &mut awork).expect("symbolic");
        let mut fstore = vec![0.0f64; LdlFactor::<f64>::storage_len(&size)];
        let mut factor = LdlFactor::new(&size, &mut fstore).expect("factor");
        let mut work = vec![0.0; LdlFactor::<f64>::SUPERNODAL_WORK_LEN];
        let mut iwork = vec![0u32; LdlFactor::<f64>::supernodal_index_work_len(n)];
        factor
            .factorize_supernodal(&sym, lin.hessian, &mut work, &mut iwork)
            .expect("factor");
        let b: Vec<f64> = (0..n)
            .map(|i| ((i * 7919) % 1000) as f64 / 500.0 - 1.0)
            .collect();
        let mut y = vec![0.0; n];
        bench_solve_pairs(&factor, &sym, &b, &mut y);
    });
}

/// Instructions of one solve pair on case `name` (the mean over [`SOLVE_PAIRS`]), counted by
/// callgrind in a child run.
fn solve_pair_instructions(exe: &std::path::Path, dir: &std::path::Path, name: &str) -> f64 {
    let out = dir.join(format!("cg-solve-{name}"));
    callgrind::run(
        exe,
        "--toggle-collect=*bench_solve_pairs*",
        &out,
        &["--solve-pair", name],
    );
    let text = std::fs::read_to_string(&out).expect("callgrind output");
    let total: f64 = text
        .lines()
        .find_map(|l| {
            l.strip_prefix("summary: ")
                .or_else(|| l.strip_prefix("totals: "))
        })
        .and_then(|t| t.split_whitespace().next()?.parse().ok())
        .expect("callgrind totals");
    total / SOLVE_PAIRS as f64
}

fn instructions() {
    if Command::new("valgrind").arg("--version").output().is_err() {
        println!("valgrind not found: instruction counts skipped\n");
        return;
    }
    let exe = std::env::current_exe().expect("exe");
    let dir = std::env::temp_dir().join(format!("incise-callgrind-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("tmp dir");
    println!("## Instructions per frame (callgrind, {FRAMES} frames)\n");
    println!(
        "| nodes | strategy | median | max | max / median | factor flops (formula) | solve flops | matvec flops | one solve pair | median / solve pair |"
    );
    println!("| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |");
    for (name, _) in CASES {
        let solve_pair = solve_pair_instructions(&exe, &dir, name);
        for (sname, _) in STRATEGIES {
            let out = dir.join(format!("cg-{name}-{sname}"));
            let stdout = callgrind::run(
                &exe,
                "--dump-after=*incise_core*Model*step*",
                &out,
                &["--instructions", name, sname],
            );
            let worst: Vec<u64> = stdout
                .lines()
                .find_map(|l| l.strip_prefix("WORST "))
                .expect("worst-case line")
                .split_whitespace()
                .map(|x| x.parse().unwrap())
                .collect();
            // One dump file per call, `<out>.<n>`, each with the instructions since the last.
            let mut counts = vec![];
            for entry in std::fs::read_dir(&dir).unwrap() {
                let path = entry.unwrap().path();
                let fname = path.file_name().unwrap().to_string_lossy().to_string();
                let prefix = format!("cg-{name}-{sname}.");
                if let Some(n) = fname.strip_prefix(&prefix) {
                    let text = std::fs::read_to_string(&path).unwrap();
                    if let Some(total) = text.lines().find_map(|l| {
                        l.strip_prefix("summary: ")
                            .or_else(|| l.strip_prefix("totals: "))
                    }) {
                        let ir: f64 = total.split_whitespace().next().unwrap().parse().unwrap();
                        if let Ok(n) = n.parse::<usize>()
                            && n > 1
                        {
                            counts.push((n, ir));
                        }
                    }
                }
            }
            counts.sort_by_key(|c| c.0);
            // The last FRAMES dumps are the measured frames.
            assert!(
                counts.len() >= FRAMES,
                "expected a dump per frame, got {}",
                counts.len()
            );
            let mut ir: Vec<f64> = counts[counts.len() - FRAMES..]
                .iter()
                .map(|c| c.1)
                .collect();
            let max = ir.iter().cloned().fold(0.0, f64::max);
            let median = percentile(&mut ir, 0.5);
            println!(
                "| {name} | {sname} | {:.3e} | {:.3e} | {:.4} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {:.1} |",
                median,
                max,
                max / median,
                worst[0] as f64,
                worst[1] as f64,
                worst[2] as f64,
                solve_pair,
                median / solve_pair
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    println!();
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--instructions") {
        instructions_child(&args[i + 1], &args[i + 2]);
        return;
    }
    if let Some(i) = args.iter().position(|a| a == "--solve-pair") {
        solve_pair_child(&args[i + 1]);
        return;
    }
    timing();
    if !args.iter().any(|a| a == "--no-callgrind") {
        instructions();
    }
}
