//! The cost of a cut event next to the steady frame, on the committed cut scenes, run as
//! `incise run` runs them (their own settings).
//!
//! A frame that cuts does the steady work (observe, solve, detect, grow the line) and then the
//! cut event: the geometry (level set, snapping, splitting, separating, re-embedding) and the
//! rebuild of the linear system in the spare storage (pattern, ordering, symbolic analysis,
//! assembly and factorization). Two measures, neither a bare wall-clock time:
//! - wall time of the steady frame (median) and of each frame that cuts, as ratios to the
//!   steady frame and to faer's numeric Cholesky of the new matrix measured in the same run;
//! - instructions counted by callgrind (deterministic): the steady frame (median) and each
//!   frame that cuts, and the cut event alone (the frame minus the steady median).
//!
//!
//! A third table (callgrind too) splits a steady frame's instructions by stage: assembly,
//! factorization, triangular solves, PCG products, line search, detection and the cut line,
//! averaged over the run with the cut events taken out, for each scene's own setting and, on
//! `liver-lobe`, for `Refactor` (a factorization at every Newton step) and for the quasi-Newton
//! strategy (no tangent after the frozen one) as comparisons.
//!
//! `cargo bench --bench cut_event` runs all (the callgrind ones only if valgrind is installed);
//! `-- --no-callgrind` skips them, `-- --split-only` runs only the split. The binary re-runs itself under callgrind with
//! `--instructions <scene>` to count one scene, and `--stages <scene> <strategy>` to split one.

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use faer::Par;
use faer::Side;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymmetricOrdering, factorize_symbolic_cholesky,
};
use incise::scene::{Scene, read_points_csv};
use incise::storage::ModelStorage;
use incise_core::{Material, MeshInput, Model, ModelConfig, Observation, StepReport, Strategy};
use incise_validation::callgrind;
use incise_validation::oracle::to_faer;

const SCENES: [&str; 3] = ["band-side-cut", "band-middle-cut", "liver-lobe"];

fn scene(name: &str) -> Scene {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(name);
    Scene::load(&dir).expect("scene")
}

/// Builds the scene's model as `incise run` does and hands it to `f`.
fn with_model<R>(s: &Scene, f: impl FnOnce(&mut Model<'_, f64>) -> R) -> R {
    let toml = s.dir.join("scene.toml");
    let config = ModelConfig {
        material: Material {
            young: s.file.model.young,
            poisson: s.file.model.poisson,
            inversion_barrier: s.file.model.inversion_barrier,
            law: s.file.model.law.core(),
        },
        camera: s.file.camera(&toml).expect("camera"),
        solver: s.file.solver(&toml).expect("solver"),
        detection: s.file.detection.config(),
    };
    let input = MeshInput {
        rest: &s.rest,
        tets: &s.tets,
        fixed: &s.file.model.fixed,
    };
    let mut storage = ModelStorage::new(&input, &s.file.capacities).expect("size");
    let mut model = storage.model(&input, &config).expect("model");
    model.embed_features(&s.frames[0]).expect("embed");
    let path = s.dir.join("gt").join("targets.csv");
    let text = std::fs::read_to_string(&path).expect("targets");
    let targets = read_points_csv(&text, Path::new(&path)).expect("targets");
    model.embed_targets(&targets[0]).expect("targets");
    f(&mut model)
}

fn known(model: &Model<'_, f64>, frame: &[Observation<f64>]) -> Vec<Observation<f64>> {
    frame
        .iter()
        .copied()
        .filter(|o| model.features().slot_of(o.id).is_some())
        .collect()
}

#[inline(never)]
fn bench_frame_step(model: &mut Model<'_, f64>, frame: &[Observation<f64>]) -> StepReport<f64> {
    model.step(frame).expect("step")
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[s.len() / 2]
}

/// faer's numeric Cholesky of the system the model assembles now, seconds (median of 9).
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
    let par = Par::Seq;
    let mut l = vec![0.0; sym.len_val()];
    let mut mem = MemBuffer::new(sym.factorize_numeric_llt_scratch::<f64>(par, Default::default()));
    let mut times = vec![];
    for _ in 0..9 {
        let t = Instant::now();
        black_box(
            sym.factorize_numeric_llt(
                &mut l,
                a.as_ref(),
                Side::Upper,
                Default::default(),
                par,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .expect("faer"),
        );
        times.push(t.elapsed().as_secs_f64());
    }
    median(&times)
}

fn timing() {
    println!("## Wall time: the steady frame and the frames that cut the mesh\n");
    println!(
        "| scene | steady ms (median) | cutting frame | ms | / steady | faer factor ms (new matrix) | cut event / faer | nodes | tetrahedra |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |");
    for name in SCENES {
        let s = scene(name);
        with_model(&s, |model| {
            let (mut steady, mut cuts) = (vec![], vec![]);
            let mut peers = vec![];
            for (f, frame) in s.frames.iter().enumerate().skip(1) {
                let obs = known(model, frame);
                let t = Instant::now();
                let report = black_box(bench_frame_step(model, &obs));
                let ms = t.elapsed().as_secs_f64() * 1e3;
                if report.cut.applied {
                    let mesh = (model.mesh().n_nodes(), model.mesh().n_tets());
                    cuts.push((f, ms, mesh));
                    peers.push(faer_factor_seconds(model) * 1e3);
                } else {
                    steady.push(ms);
                }
            }
            let m = median(&steady);
            for ((f, ms, (n, t)), peer) in cuts.iter().zip(&peers) {
                println!(
                    "| {name} | {m:.2} | {f} | {ms:.2} | {:.1} | {peer:.3} | {:.1} | {n} | {t} |",
                    ms / m,
                    (ms - m) / peer
                );
            }
        });
    }
    println!();
}

/// Runs one scene for callgrind, which dumps its counts after each `Model::step`, and prints
/// which frames cut.
fn instructions_child(name: &str) {
    let s = scene(name);
    with_model(&s, |model| {
        let mut cutting = vec![];
        for (f, frame) in s.frames.iter().enumerate().skip(1) {
            let obs = known(model, frame);
            let report = black_box(bench_frame_step(model, &obs));
            if report.cut.applied {
                cutting.push(f.to_string());
                let (w, g) = (report.cut.work, report.cut.event.work);
                println!(
                    "CUT {f} {} {} {} {} {} {} {}",
                    w.factor_flops,
                    g.node_tests,
                    g.element_tests,
                    g.faces_sorted,
                    g.star_entries,
                    g.segment_tests,
                    g.triangle_tests
                );
            }
        }
    });
}

fn instructions() {
    if Command::new("valgrind").arg("--version").output().is_err() {
        println!("valgrind not found: instruction counts skipped\n");
        return;
    }
    let exe = std::env::current_exe().expect("exe");
    let dir = std::env::temp_dir().join(format!("incise-cut-callgrind-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("tmp dir");
    println!("## Instructions (callgrind): the steady frame and the cut events\n");
    println!(
        "| scene | steady frame (median) | cutting frame | instructions | cut event alone | / steady | factor flops of the rebuild | node tests | element visits | faces sorted | star entries | segment tests | boundary triangle tests |"
    );
    println!(
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
    );
    for name in SCENES {
        let out = dir.join(format!("cg-{name}"));
        let stdout = callgrind::run(
            &exe,
            "--dump-after=*incise_core*Model*step*",
            &out,
            &["--instructions", name],
        );
        let cuts: Vec<Vec<u64>> = stdout
            .lines()
            .filter_map(|l| l.strip_prefix("CUT "))
            .map(|l| l.split_whitespace().map(|x| x.parse().unwrap()).collect())
            .collect();
        // One dump per step, `<out>.<n>` (n from 1, frame n), with the instructions since the
        // last dump.
        let mut counts = vec![];
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            let fname = path.file_name().unwrap().to_string_lossy().to_string();
            if let Some(n) = fname.strip_prefix(&format!("cg-{name}.")) {
                let text = std::fs::read_to_string(&path).unwrap();
                if let (Ok(n), Some(total)) = (
                    n.parse::<usize>(),
                    text.lines().find_map(|l| {
                        l.strip_prefix("summary: ")
                            .or_else(|| l.strip_prefix("totals: "))
                    }),
                ) {
                    let ir: f64 = total.split_whitespace().next().unwrap().parse().unwrap();
                    counts.push((n, ir));
                }
            }
        }
        counts.sort_by_key(|c| c.0);
        // The first dump also holds the set-up; frame n is dump n.
        let is_cut = |n: usize| cuts.iter().any(|c| c[0] as usize == n);
        let steady: Vec<f64> = counts
            .iter()
            .filter(|c| c.0 > 1 && !is_cut(c.0))
            .map(|c| c.1)
            .collect();
        let m = median(&steady);
        for c in &cuts {
            let f = c[0] as usize;
            let ir = counts.iter().find(|x| x.0 == f).map_or(f64::NAN, |x| x.1);
            println!(
                "| {name} | {m:.3e} | {f} | {ir:.3e} | {:.3e} | {:.1} | {:.3e} | {} | {} | {} | {} | {} | {} |",
                ir - m,
                ir / m,
                c[1] as f64,
                c[2],
                c[3],
                c[4],
                c[5],
                c[6],
                c[7]
            );
        }
        for entry in std::fs::read_dir(&dir).unwrap() {
            let _ = std::fs::remove_file(entry.unwrap().path());
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    println!();
}

/// The stages of a frame, each with the functions whose inclusive instructions callgrind gives
/// for it, summed (`Model::step` calls each of them, and none calls another of its stage; the
/// rest of the frame is "other": observing, the Newton loop's vector updates, the secant
/// recursion, copies for the all-or-nothing step). A trial the line search assembles (one
/// trial per step) counts as assembly; "line search" is the energy-only evaluations.
const STAGES: [(&str, &[&str]); 7] = [
    (
        "assembly",
        &[
            "assembly::Problem<T>::assemble",
            "assembly::Problem<T>::assemble_keeping",
            "assembly::Problem<T>::assemble_reusing",
        ],
    ),
    ("factorization", &["LdlFactor<T>::factorize_supernodal"]),
    ("solves", &["LdlFactor<T>::solve_converting"]),
    ("PCG products", &["sym_matvec"]),
    ("line search", &["assembly::Problem<T>::energy"]),
    ("detection", &["Detector<T>::update"]),
    ("cut line", &["CutLine<T>::update"]),
];

/// The settings the split runs: each scene's own, and on the liver `Refactor` and the
/// quasi-Newton strategy with one step of one line-search trial (the cheapest setting the
/// report runs) and with two.
const SPLITS: [(&str, &str); 6] = [
    ("band-side-cut", "own"),
    ("band-middle-cut", "own"),
    ("liver-lobe", "own"),
    ("liver-lobe", "refactor"),
    ("liver-lobe", QUASI_NEWTON[0].0),
    ("liver-lobe", QUASI_NEWTON[1].0),
];

/// The quasi-Newton settings of [`SPLITS`], with their Newton steps (one trial each).
const QUASI_NEWTON: [(&str, u32); 2] = [
    ("quasi-newton, 1 step, 1 trial", 1),
    ("quasi-newton, 2 steps, 1 trial", 2),
];

/// Runs one scene's frames (with `strategy` unless it is "own") for callgrind.
fn stages_child(name: &str, strategy: &str) {
    let mut s = scene(name);
    if let Some(&(_, steps)) = QUASI_NEWTON
        .iter()
        .find(|(setting, _)| *setting == strategy)
    {
        let solver = &mut s.file.solver;
        solver.strategy = "quasi-newton".to_string();
        solver.newton_iterations = steps;
        solver.line_search_steps = 1;
    }
    with_model(&s, |model| {
        if strategy == "refactor" {
            model.set_strategy(Strategy::Refactor).expect("strategy");
        }
        for frame in s.frames.iter().skip(1) {
            let obs = known(model, frame);
            black_box(bench_frame_step(model, &obs));
        }
    });
}

/// Instructions callgrind counted inside the functions that `toggle` names, in total and per
/// stage (the largest inclusive count of an entry naming the stage's function: callgrind
/// lists a function once per source file its inlined code comes from, the whole function
/// being the largest).
fn counted(exe: &Path, out: &Path, toggle: &str, args: &[&str]) -> (f64, Vec<f64>) {
    callgrind::run(exe, &format!("--toggle-collect={toggle}"), out, args);
    let annotated = Command::new("callgrind_annotate")
        .args(["--inclusive=yes", "--threshold=100"])
        .arg(out)
        .output()
        .expect("callgrind_annotate runs");
    let text = String::from_utf8_lossy(&annotated.stdout);
    let entries: Vec<(f64, &str)> = text
        .lines()
        .filter_map(|l| {
            let l = l.trim_start();
            let (n, rest) = l.split_once(' ')?;
            let n: f64 = n.replace(',', "").parse().ok()?;
            Some((n, rest))
        })
        .collect();
    let total = entries
        .iter()
        .find(|e| e.1.contains("PROGRAM TOTALS"))
        .map_or(0.0, |e| e.0);
    // The function an entry names: `file:function [binary]` (callgrind's form).
    let function = |rest: &str| -> String {
        let named = rest.split(" [").next().unwrap_or(rest);
        named.split_once(':').map_or(named, |(_, f)| f).to_string()
    };
    let stages = STAGES
        .iter()
        .map(|(_, functions)| {
            functions
                .iter()
                .map(|f| {
                    entries
                        .iter()
                        .filter(|e| function(e.1).ends_with(f))
                        .map(|e| e.0)
                        .fold(0.0, f64::max)
                })
                .sum::<f64>()
        })
        .collect();
    (total, stages)
}

fn stage_split() {
    if Command::new("callgrind_annotate")
        .arg("--version")
        .output()
        .is_err()
    {
        println!("callgrind_annotate not found: stage split skipped\n");
        return;
    }
    let exe = std::env::current_exe().expect("exe");
    let dir = std::env::temp_dir().join(format!("incise-stages-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("tmp dir");
    println!(
        "## Where a steady frame's instructions go (callgrind, mean over the run, cut events taken out)\n"
    );
    let names: Vec<&str> = STAGES.iter().map(|s| s.0).collect();
    println!(
        "| scene | setting | instructions / frame | {} | other |",
        names.join(" | ")
    );
    println!("| --- | --- | ---: |{}", " ---: |".repeat(STAGES.len() + 1));
    for (name, strategy) in SPLITS {
        let s = scene(name);
        let frames = (s.frames.len() - 1) as f64;
        let setting = if strategy == "own" {
            s.file.solver.strategy.clone()
        } else {
            strategy.to_string()
        };
        let args = ["--stages", name, strategy];
        let out = dir.join("cg");
        let (all, in_steps) = counted(&exe, &out, "*bench_frame_step*", &args);
        let (cut, in_cuts) = counted(&exe, &out, "*Model*apply_cut*", &args);
        let per_frame = (all - cut) / frames;
        let mut cells = vec![];
        let mut staged = 0.0;
        for (a, c) in in_steps.iter().zip(&in_cuts) {
            let v = (a - c) / frames;
            staged += v;
            cells.push(format!("{:.0}%", 100.0 * v / per_frame));
        }
        cells.push(format!("{:.0}%", 100.0 * (per_frame - staged) / per_frame));
        println!(
            "| {name} | {setting} | {per_frame:.3e} | {} |",
            cells.join(" | ")
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
    println!();
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--instructions") {
        instructions_child(&args[i + 1]);
        return;
    }
    if let Some(i) = args.iter().position(|a| a == "--stages") {
        stages_child(&args[i + 1], &args[i + 2]);
        return;
    }
    if args.iter().any(|a| a == "--split-only") {
        stage_split();
        return;
    }
    timing();
    if !args.iter().any(|a| a == "--no-callgrind") {
        instructions();
        stage_split();
    }
}
