//! `incise report`: for each scene, its error against run time over solver settings (with the
//! Pareto front and a recommended setting), its worst case (the core's counted work against
//! the formulas, and instructions per frame), and its memory; as one self-contained HTML page
//! (`index.html`, figures inline) beside the same figures as SVG and the data as CSV and JSON.
//!
//! A fourth section, the stability envelope (`stability`), runs each scene over grids of
//! material, spring stiffness, scalar type, track quality and deformation (elements pulled
//! inside out, a block squeezed to 60 %), and classifies every cell.
//!
//! The error against run time also has a mesh-resolution axis (`resolution`): the band and the
//! liver modelled by their own mesh, that mesh refined, and the real object's fine mesh.
//!
//! Every run of the report (settings, cells, cost-growth variants, model meshes) goes into one
//! pool of threads, one per core, the longest runs first: run phase after phase, each waiting
//! for its slowest run, the quick report took 66 s on two cores, and 51 s in one pool.

mod figures;
mod findings;
mod html;
mod instructions;
mod pareto;
mod resolution;
mod scaling;
mod stability;

use std::path::Path;

use serde::Serialize;

use incise_core::{CutWork, DetectionWork, LineWork, WorkCount};

use crate::run::{FrameWork, RunOptions, Summary, Trace, run_scene, scene_storage};
use crate::scene::{Precision, Scene, SolverSection};

use super::{SweepSetting, sweep_settings};

pub use instructions::{count_frames, per_frame as instructions_per_frame};

/// What `incise report` does.
#[derive(Clone, Copy, Debug)]
pub struct ReportOptions {
    /// Fewer settings and sampled frames: a check that the page is made, in about a minute.
    pub quick: bool,
    /// Show a progress bar.
    pub progress: bool,
}

/// Everything the page shows; `report.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Made with `--quick`.
    pub quick: bool,
    /// How instructions were counted, or why they were not.
    pub instructions: String,
    /// The rule that picks the recommended setting.
    pub recommendation_rule: &'static str,
    /// One entry per scene, in the order given.
    pub scenes: Vec<SceneReport>,
    /// How the cost grows with nodes and features (not with `--quick`, and only when
    /// `band-no-cut`, whose scenario the variants are made from, is among the scenes).
    pub scaling: Option<scaling::Scaling>,
    /// The mesh-resolution axis of `band-side-cut` and `liver-lobe` among the scenes (not with
    /// `--quick`).
    pub resolution: Vec<resolution::Resolution>,
}

/// One scene's part of the report.
#[derive(Clone, Debug, Serialize)]
pub struct SceneReport {
    /// Scene name.
    pub name: String,
    /// The settings tried, the scene's own first.
    pub settings: Vec<SettingResult>,
    /// Indices into `settings` of the Pareto front (cost, target error, Dice), cheapest first.
    pub front: Vec<usize>,
    /// Index into `settings` of the recommended setting.
    pub recommended: Option<usize>,
    /// The scene's own setting: each work counter of the steady frame, the detection and the
    /// cut line against its formula.
    pub worst_case: Vec<WorstCaseRow>,
    /// The same for the cut events (empty if none).
    pub cut_events: Vec<WorstCaseRow>,
    /// The scene's own setting: instructions of each stepped frame (frame 1 first), if counted.
    pub instructions_per_frame: Vec<u64>,
    /// Frames (numbers) that cut the mesh, with the scene's own setting.
    pub cut_frames: Vec<usize>,
    /// Steady frames (no cut event): largest instructions over the median within one
    /// topology, the largest over the run's topologies.
    pub steady_max_over_median: Option<f64>,
    /// The model's storage, part by part (f64).
    pub memory: Vec<MemoryRow>,
    /// The stability grid.
    pub stability: Vec<stability::Cell>,
}

/// One setting of one scene.
#[derive(Clone, Debug, Serialize)]
pub struct SettingResult {
    /// A short label.
    pub label: String,
    /// `"refactor"`, `"frozen"` or `"factor-once"`.
    pub strategy: &'static str,
    /// Newton steps per frame.
    pub newton: u32,
    /// PCG steps.
    pub pcg: u32,
    /// Line-search trials per Newton step.
    pub line_search: u32,
    /// The scalar type the core computed in.
    pub precision: Precision,
    /// The scene's own setting.
    pub own: bool,
    /// Dice of the last frame.
    pub dice_final: f64,
    /// Mean Dice after the cut opens (over all frames without a cut).
    pub dice_mean_after_cut: f64,
    /// Target error of the last frame, millimetres.
    pub tre_mm_final: f64,
    /// Surface error of the last frame, millimetres (RMS).
    pub surface_mm_final: f64,
    /// Nodes and tetrahedra of the mesh at the end (more than at rest where it was cut).
    pub mesh_final: [usize; 2],
    /// Wall time of a step, milliseconds: median and largest.
    pub ms_median: f64,
    /// Largest step time, milliseconds.
    pub ms_max: f64,
    /// Instructions of a steady frame (median over the counted frames without a cut event).
    pub instructions_median: Option<f64>,
    /// Frames counted.
    pub instructions_frames: usize,
}

/// One work counter against its formula.
#[derive(Clone, Debug, Serialize)]
pub struct WorstCaseRow {
    /// The stage that counts it.
    pub stage: &'static str,
    /// What it counts.
    pub counter: &'static str,
    /// The formula's value (the largest over the frames: it changes with the topology).
    pub formula: u64,
    /// The largest counted value.
    pub max: u64,
    /// The median counted value.
    pub median: f64,
    /// The largest ratio of the counted value to the frame's formula (≤ 1: the formula holds).
    pub max_over_formula: f64,
}

/// One part of a model's storage.
#[derive(Clone, Debug, Serialize)]
pub struct MemoryRow {
    /// What it holds.
    pub part: &'static str,
    /// What it grows with.
    pub grows_with: &'static str,
    /// Bytes (f64 scalars, u32 indices).
    pub bytes: usize,
}

/// Frames counted per setting: every frame of the scene's own setting (the worst case needs
/// them all) and, for the other settings, the first ten (five and three with `--quick`), whose
/// median is the steady cost.
fn frames_counted(own: bool, quick: bool) -> usize {
    match (own, quick) {
        (true, false) => usize::MAX,
        (true, true) => 5,
        (false, false) => 10,
        (false, true) => 3,
    }
}

/// The settings tried on a scene: its own first, then the sweep's but its two dearest (`--quick`: refactoring
/// once per frame, the cheapest).
fn settings_for(solver: &SolverSection, quick: bool) -> Vec<(SweepSetting, bool)> {
    let own = SweepSetting::of(solver);
    let others = if quick {
        vec![SweepSetting {
            strategy: "refactor",
            newton: 1,
            pcg: 10,
            precision: Precision::F64,
            line_search: crate::report::SWEEP_LINE_SEARCH,
        }]
    } else {
        // The report counts every setting under callgrind and must finish within ten minutes
        // on a 2-core machine: it leaves out the two dearest settings of the sweep to make
        // room for its line-search axis. Neither was on any scene's Pareto front (the report
        // after b043dfa).
        let dear = |s: &SweepSetting| {
            matches!(
                (s.strategy, s.newton, s.pcg),
                ("frozen", 3, 30) | ("factor-once", 2, 10)
            )
        };
        sweep_settings().into_iter().filter(|s| !dear(s)).collect()
    };
    let same = |s: &SweepSetting| {
        s.strategy == own.strategy
            && s.newton == own.newton
            && (matches!(s.strategy, "refactor" | "quasi-newton") || s.pcg == own.pcg)
            && s.line_search == own.line_search
    };
    // The scene's own setting in single and in mixed precision too: where each matches `f64`.
    let single = SweepSetting {
        precision: Precision::F32,
        ..own
    };
    let mixed = SweepSetting {
        precision: Precision::Mixed,
        ..own
    };
    std::iter::once((own, true))
        .chain([(single, false), (mixed, false)])
        .chain(others.into_iter().filter(|s| !same(s)).map(|s| (s, false)))
        .collect()
}

/// Runs the report over `scenes` and writes it into `out`.
///
/// # Errors
/// A message naming the scene and setting that failed, or the file that could not be written.
pub fn write_report(
    scenes: &[Scene],
    out: &Path,
    options: ReportOptions,
) -> Result<Report, String> {
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let counting = instructions::available();
    let runs: usize = scenes
        .iter()
        .map(|s| {
            settings_for(&s.file.solver, options.quick).len()
                + stability::grid(s, options.quick).len()
        })
        .sum();
    let scaling_base = (!options.quick)
        .then(|| scenes.iter().find(|s| s.file.name == scaling::BASE))
        .flatten();
    let runs = runs + scaling_base.map_or(0, |_| scaling::len());
    let resolution_bases: Vec<&Scene> = if options.quick {
        vec![]
    } else {
        scenes
            .iter()
            .filter(|s| resolution::BASES.contains(&s.file.name.as_str()))
            .collect()
    };
    let runs = runs + resolution_bases.len() * resolution::len();
    let bar = if options.progress {
        let bar = indicatif::ProgressBar::new(runs as u64);
        if let Ok(style) =
            indicatif::ProgressStyle::with_template("{prefix:>16} [{bar:30}] {pos}/{len} runs")
        {
            bar.set_style(style.progress_chars("=> "));
        }
        bar
    } else {
        indicatif::ProgressBar::hidden()
    };
    let mut report = Report {
        quick: options.quick,
        instructions: if counting {
            format!(
                "counted by callgrind inside Model::step, one dump per frame; the scene's own \
                 setting over {}, the others over the first {} frames (their median without \
                 cut events is the steady cost)",
                if options.quick {
                    "its first 5 frames"
                } else {
                    "every frame"
                },
                frames_counted(false, options.quick)
            )
        } else {
            "not counted: valgrind (callgrind) is not installed; the cost axis is wall time".into()
        },
        recommendation_rule: pareto::RULE,
        scenes: vec![],
        scaling: None,
        resolution: vec![],
    };
    // Every run of the report in one pool, one run per core at a time, the longest first: the
    // mesh-resolution models (largest first: the fine liver under callgrind is the longest
    // run of all), each scene's settings (each counted by callgrind in a process of its own),
    // the cost-growth variants, then the stability cells. The counts do not depend on what
    // else runs; the wall times, one run per core, hardly do.
    let settings: Vec<(usize, SweepSetting, bool)> = scenes
        .iter()
        .enumerate()
        .flat_map(|(i, s)| {
            settings_for(&s.file.solver, options.quick)
                .into_iter()
                .map(move |(setting, own)| (i, setting, own))
        })
        .collect();
    let cells: Vec<(usize, stability::CellSetting)> = scenes
        .iter()
        .enumerate()
        .flat_map(|(i, s)| {
            stability::grid(s, options.quick)
                .into_iter()
                .map(move |c| (i, c))
        })
        .collect();
    bar.set_prefix("preparing");
    let squeezed = stability::Squeezed::new(&cells)?;
    let models = resolution::prepare(&resolution_bases)?;
    let mut by_size: Vec<usize> = (0..models.jobs.len()).collect();
    by_size.sort_by_key(|&k| std::cmp::Reverse(models.jobs.get(k).map_or(0, |j| j.nodes())));
    let growth = scaling_base.map_or(0, |_| scaling::len());
    // The first cell of each squeezed variant first, one scene after another, so that the two
    // cores generate different variants instead of one waiting for the other's. A cell's rank:
    // squeezed before not, then how many cells of its scene and variant come before it, then
    // its scene (counted in one pass over the cells).
    let mut seen: std::collections::HashMap<(usize, Option<u64>), usize> = Default::default();
    let ranks: Vec<(bool, usize, usize)> = cells
        .iter()
        .map(|&(i, cell)| {
            let before = seen
                .entry((i, cell.compression.map(f64::to_bits)))
                .or_default();
            *before += 1;
            (cell.compression.is_none(), *before - 1, i)
        })
        .collect();
    let mut cell_order: Vec<usize> = (0..cells.len()).collect();
    cell_order.sort_by_key(|&k| ranks.get(k).copied());
    let jobs: Vec<Job> = (by_size.into_iter().map(Job::Model))
        .chain(
            settings
                .iter()
                .map(|&(i, setting, own)| Job::Setting(i, setting, own)),
        )
        .chain((0..growth).map(Job::Growth))
        .chain(cell_order.into_iter().map(Job::Cell))
        .collect();
    bar.set_prefix("runs");
    let done = on_every_core(&jobs, |job| {
        let done = match *job {
            Job::Setting(i, setting, own) => Done::Setting(Box::new(
                scenes
                    .get(i)
                    .ok_or_else(|| "no such scene".to_string())
                    .and_then(|scene| run_setting(scene, setting, own, counting, options.quick)),
            )),
            Job::Cell(k) => Done::Cell(Box::new(
                cells
                    .get(k)
                    .and_then(|&(i, cell)| Some((i, cell, scenes.get(i)?)))
                    .ok_or_else(|| "no such cell".to_string())
                    .and_then(|(i, cell, base)| Ok((cell, squeezed.scene_for(i, base, &cell)?)))
                    .map(|(cell, scene)| stability::run_cell(scene, cell)),
            )),
            Job::Growth(k) => Done::Growth(Box::new(
                scaling_base
                    .ok_or_else(|| "no cost-growth base".to_string())
                    .and_then(|base| scaling::measure_point(&base.dir, k, counting)),
            )),
            Job::Model(k) => Done::Model(Box::new(
                models
                    .jobs
                    .get(k)
                    .ok_or_else(|| "no such model".to_string())
                    .and_then(|job| resolution::run(job, &resolution_bases, counting)),
            )),
        };
        bar.inc(1);
        done
    });
    drop(squeezed);
    let mut per_scene: Vec<(Vec<SettingRun>, Vec<stability::Cell>)> =
        scenes.iter().map(|_| (vec![], vec![])).collect();
    let mut points = vec![];
    let mut cell_runs: Vec<Option<Result<stability::Cell, String>>> =
        cells.iter().map(|_| None).collect();
    let mut model_runs: Vec<Option<Result<resolution::Model, String>>> =
        models.jobs.iter().map(|_| None).collect();
    for (job, done) in jobs.iter().zip(done) {
        match (job, done) {
            (Job::Setting(i, ..), Done::Setting(run)) => {
                if let Some(slot) = per_scene.get_mut(*i) {
                    slot.0.push((*run)?);
                }
            }
            (Job::Cell(k), Done::Cell(cell)) => {
                if let Some(slot) = cell_runs.get_mut(*k) {
                    *slot = Some(*cell);
                }
            }
            (Job::Growth(_), Done::Growth(point)) => points.push(*point),
            (Job::Model(k), Done::Model(model)) => {
                if let Some(slot) = model_runs.get_mut(*k) {
                    *slot = Some(*model);
                }
            }
            _ => return Err("a report run lost its scene".into()),
        }
    }
    // The cells in the grid's order.
    for (&(i, _), run) in cells.iter().zip(cell_runs) {
        if let Some(slot) = per_scene.get_mut(i) {
            slot.1
                .push(run.unwrap_or_else(|| Err("a cell was not run".into()))?);
        }
    }
    for (scene, (runs, cells)) in scenes.iter().zip(per_scene) {
        let mut settings = vec![];
        let mut own_trace = None;
        let mut own_counts = vec![];
        for (setting, own, summary, trace, counts) in runs {
            settings.push(setting_result(&setting, own, &summary, &trace, &counts));
            if own {
                own_trace = Some(trace);
                own_counts = counts;
            }
        }
        let trace = own_trace.ok_or("no run with the scene's own setting")?;
        let mut scene_report = scene_report(scene, settings, &trace, own_counts, counting)?;
        scene_report.stability = cells;
        report.scenes.push(scene_report);
    }
    if scaling_base.is_some() {
        report.scaling = Some(scaling::assemble(points, counting)?);
    }
    let model_runs = model_runs
        .into_iter()
        .map(|m| m.unwrap_or_else(|| Err("a model was not run".into())))
        .collect();
    report.resolution = resolution::assemble(&resolution_bases, &models, model_runs)?;
    drop(models);
    bar.finish_and_clear();
    let largest = report
        .resolution
        .iter()
        .flat_map(|r| r.models.iter().map(move |m| (r, m)))
        .filter_map(|(r, m)| m.instructions.map(|v| (r, m, v)))
        .max_by_key(|(_, m, _)| m.nodes)
        .map(|(r, m, v)| scaling::LargestModel {
            scene: r.scene.clone(),
            mesh: m.mesh.to_string(),
            nodes: m.nodes,
            instructions: v,
        });
    if let Some(scaling) = &mut report.scaling {
        scaling.include_largest(largest);
    }
    html::write(&report, out)?;
    Ok(report)
}

/// One run of the report's pool: a setting of scene `i` (the scene's own when the flag is
/// set), stability cell `k` (of every scene's, in grid order), cost-growth variant `k`, or
/// mesh-resolution model `k`.
#[derive(Clone, Copy)]
enum Job {
    Setting(usize, SweepSetting, bool),
    Cell(usize),
    Growth(usize),
    Model(usize),
}

/// What a [`Job`] gives.
enum Done {
    Setting(Box<Result<SettingRun, String>>),
    Cell(Box<Result<stability::Cell, String>>),
    Growth(Box<Result<scaling::Point, String>>),
    Model(Box<Result<resolution::Model, String>>),
}

/// A setting's run: the setting, whether it is the scene's own, its summary and trace, and its
/// instructions per frame (empty when not counted).
type SettingRun = (SweepSetting, bool, Summary, Trace, Vec<u64>);

/// Runs `scene` with `setting`, then counts it under callgrind (when `counting`).
fn run_setting(
    scene: &Scene,
    setting: SweepSetting,
    own: bool,
    counting: bool,
    quick: bool,
) -> Result<SettingRun, String> {
    let name = &scene.file.name;
    let mut s = scene.clone();
    setting.apply(&mut s);
    let (summary, trace) = run_scene(&s, &RunOptions::default())
        .map_err(|e| format!("{name}, {}: {e}", setting.label()))?;
    let counts = if counting {
        instructions::per_frame(&scene.dir, &setting, frames_counted(own, quick))
            .map_err(|e| format!("{name}, {}: instructions: {e}", setting.label()))?
    } else {
        vec![]
    };
    Ok((setting, own, summary, trace, counts))
}

/// A fresh directory for the report's scratch files (generated variants, callgrind dumps),
/// named after `what`, removed with everything in it when the handle is dropped, on every
/// path out, errors and panics included.
///
/// # Errors
/// A message naming the directory that could not be made.
pub(super) fn scratch_dir(what: &str) -> Result<tempfile::TempDir, String> {
    tempfile::Builder::new()
        .prefix(&format!("incise-{what}-"))
        .tempdir()
        .map_err(|e| {
            format!(
                "a scratch directory in {}: {e}",
                std::env::temp_dir().display()
            )
        })
}

/// `job` on every item, on as many threads as the machine has cores, each taking the next
/// item not yet taken: the results in the items' order.
pub(super) fn on_every_core<I: Sync, R: Send>(items: &[I], job: impl Fn(&I) -> R + Sync) -> Vec<R> {
    let workers = std::thread::available_parallelism().map_or(1, |n| n.get());
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut results: Vec<(usize, R)> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..workers)
            .map(|_| {
                s.spawn(|| {
                    let mut mine = vec![];
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(item) = items.get(i) else {
                            break mine;
                        };
                        mine.push((i, job(item)));
                    }
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    });
    results.sort_by_key(|(i, _)| *i);
    results.into_iter().map(|(_, r)| r).collect()
}

/// Frame numbers of `trace` that cut the mesh.
fn cut_frames(trace: &Trace) -> Vec<usize> {
    trace
        .frames
        .iter()
        .filter(|r| r.work.is_some_and(|w| w.cut.is_some()))
        .map(|r| r.frame)
        .collect()
}

/// The counts of frames (count `k` is frame `k + 1`) that did not cut.
fn steady_counts(counts: &[u64], cuts: &[usize]) -> Vec<f64> {
    counts
        .iter()
        .enumerate()
        .filter(|(k, _)| !cuts.contains(&(k + 1)))
        .map(|(_, &c)| c as f64)
        .collect()
}

/// Largest over median of the steady frames' counts within each topology (the runs of frames
/// between two cut events: a cut adds nodes and elements, so the frames after it cost more
/// than those before, which says nothing of whether a frame's work follows its data), the
/// largest over the topologies; `None` without a steady frame.
fn steady_spread(counts: &[u64], cuts: &[usize]) -> Option<f64> {
    let mut ratios = vec![];
    let mut run: Vec<f64> = vec![];
    // Count `k` is frame `k + 1`; a cut frame ends the run before it.
    for (k, &c) in counts.iter().enumerate() {
        if cuts.contains(&(k + 1)) {
            ratios.extend(max_over_median(&run));
            run.clear();
        } else {
            run.push(c as f64);
        }
    }
    ratios.extend(max_over_median(&run));
    ratios.into_iter().reduce(f64::max)
}

/// Largest over median of `run`; `None` if empty.
fn max_over_median(run: &[f64]) -> Option<f64> {
    median(run).map(|m| run.iter().copied().fold(0.0, f64::max) / m)
}

/// The median of [`steady_counts`].
fn steady_median(counts: &[u64], cuts: &[usize]) -> Option<f64> {
    median(&steady_counts(counts, cuts))
}

/// The median (the mean of the two middle values for an even count); `None` if empty.
fn median(values: &[f64]) -> Option<f64> {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => None,
        _ if n % 2 == 1 => Some(v[n / 2]),
        _ => Some(0.5 * (v[n / 2 - 1] + v[n / 2])),
    }
}

fn setting_result(
    setting: &SweepSetting,
    own: bool,
    summary: &Summary,
    trace: &Trace,
    counts: &[u64],
) -> SettingResult {
    SettingResult {
        label: setting.label(),
        strategy: setting.strategy,
        newton: setting.newton,
        pcg: setting.pcg,
        line_search: setting.line_search,
        precision: setting.precision,
        own,
        dice_final: summary.dice_final,
        dice_mean_after_cut: summary.dice_mean_after_cut,
        tre_mm_final: summary.tre_mm_final,
        surface_mm_final: summary.surface_rmse_mm_final,
        mesh_final: [summary.nodes_final, summary.tets_final],
        ms_median: summary.ms_per_frame_median,
        ms_max: summary.ms_per_frame_max,
        instructions_median: steady_median(counts, &cut_frames(trace)),
        instructions_frames: counts.len(),
    }
}

fn scene_report(
    scene: &Scene,
    settings: Vec<SettingResult>,
    trace: &Trace,
    counts: Vec<u64>,
    counting: bool,
) -> Result<SceneReport, String> {
    let points: Vec<pareto::Point> = settings
        .iter()
        .map(|s| pareto::Point {
            cost: if counting {
                s.instructions_median.unwrap_or(f64::NAN)
            } else {
                s.ms_median
            },
            tre_mm: s.tre_mm_final,
            dice: s.dice_final,
        })
        .collect();
    let front = pareto::front(&points);
    let recommended = pareto::recommend(&points, &front);
    let cuts = cut_frames(trace);
    let steady_max_over_median = steady_spread(&counts, &cuts);
    let works: Vec<FrameWork> = trace.frames.iter().filter_map(|r| r.work).collect();
    let memory = scene_storage(scene)
        .map_err(|e| e.to_string())?
        .size()
        .parts()
        .iter()
        .map(|p| MemoryRow {
            part: p.name,
            grows_with: p.grows_with,
            bytes: p.bytes::<f64>(),
        })
        .collect();
    Ok(SceneReport {
        name: scene.file.name.clone(),
        settings,
        front,
        recommended,
        worst_case: worst_case_rows(&works, STEADY_COUNTERS),
        cut_events: worst_case_rows(
            &works
                .iter()
                .copied()
                .filter(|w| w.cut.is_some())
                .collect::<Vec<_>>(),
            CUT_COUNTERS,
        ),
        instructions_per_frame: counts,
        cut_frames: cuts,
        steady_max_over_median,
        memory,
        stability: vec![],
    })
}

/// One side of a frame's work: what was counted, or its formula. Both sides have the same
/// fields, so a counter names its field once and reads it from each ([`work_sides`]).
#[derive(Clone, Copy, Debug)]
struct WorkSide {
    solve: WorkCount,
    detection: DetectionWork,
    line: LineWork,
    /// The cut event (zero in a frame that does not cut)…
    cut: CutWork,
    /// … and the rebuild of the linear system after it.
    rebuild: WorkCount,
}

/// The counted side and the formula's side of a frame's work.
fn work_sides(w: &FrameWork) -> (WorkSide, WorkSide) {
    let (cut, rebuild) = w.cut.unwrap_or_default();
    let counted = WorkSide {
        solve: w.solve,
        detection: w.detection,
        line: w.line,
        cut,
        rebuild,
    };
    let formula = WorkSide {
        solve: w.solve_bound,
        detection: w.detection_bound.0,
        line: w.detection_bound.1,
        cut: w.cut_bound.0,
        rebuild: w.cut_bound.1,
    };
    (counted, formula)
}

/// A work counter of a frame: stage, name, and the field it reads from each [`WorkSide`].
type Counter = (&'static str, &'static str, fn(&WorkSide) -> u64);

/// The counters of every frame.
const STEADY_COUNTERS: &[Counter] = &[
    ("solve", "element tangents", |w| w.solve.element_tangents),
    ("solve", "element evaluations", |w| {
        w.solve.element_evaluations
    }),
    ("solve", "feature evaluations", |w| {
        w.solve.feature_evaluations
    }),
    ("solve", "factorization multiply-adds", |w| {
        w.solve.factor_flops
    }),
    ("solve", "solve multiply-adds", |w| w.solve.solve_flops),
    ("solve", "PCG product multiply-adds", |w| {
        w.solve.matvec_flops
    }),
    ("solve", "state copies", |w| w.solve.state_copies),
    ("detection", "feature visits", |w| {
        w.detection.feature_visits
    }),
    ("detection", "pair visits", |w| w.detection.pair_visits),
    ("detection", "selection steps", |w| {
        w.detection.selection_steps
    }),
    ("cut line", "fit tests", |w| w.line.fit_tests),
    ("cut line", "point visits", |w| w.line.point_visits),
    ("cut line", "anchor visits", |w| w.line.anchor_visits),
];

/// The counters of a cut event (frames that cut only).
const CUT_COUNTERS: &[Counter] = &[
    ("cut", "node tests", |w| w.cut.node_tests),
    ("cut", "element visits", |w| w.cut.element_tests),
    ("cut", "faces sorted", |w| w.cut.faces_sorted),
    ("cut", "star entries", |w| w.cut.star_entries),
    ("cut", "re-embedding tests", |w| w.cut.embed_tests),
    ("cut", "segment tests", |w| w.cut.segment_tests),
    ("cut", "boundary triangle tests", |w| w.cut.triangle_tests),
    ("rebuild", "element tangents", |w| {
        w.rebuild.element_tangents
    }),
    ("rebuild", "factorization multiply-adds", |w| {
        w.rebuild.factor_flops
    }),
];

fn worst_case_rows(works: &[FrameWork], counters: &[Counter]) -> Vec<WorstCaseRow> {
    if works.is_empty() {
        return vec![];
    }
    let sides: Vec<(WorkSide, WorkSide)> = works.iter().map(work_sides).collect();
    counters
        .iter()
        .map(|&(stage, counter, read)| {
            let pairs: Vec<(u64, u64)> = sides.iter().map(|(c, f)| (read(c), read(f))).collect();
            let counted: Vec<f64> = pairs.iter().map(|p| p.0 as f64).collect();
            WorstCaseRow {
                stage,
                counter,
                formula: pairs.iter().map(|p| p.1).max().unwrap_or(0),
                max: pairs.iter().map(|p| p.0).max().unwrap_or(0),
                median: median(&counted).unwrap_or(0.0),
                max_over_formula: pairs
                    .iter()
                    .map(|&(c, f)| match (c, f) {
                        (0, _) => 0.0,
                        (_, 0) => f64::INFINITY,
                        _ => c as f64 / f as f64,
                    })
                    .fold(0.0, f64::max),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::steady_spread;

    #[test]
    fn the_steady_spread_is_taken_within_each_topology() {
        // Frames 1..=9: 100, 100, 100, 100, 101 before a cut at frame 6, then 150, 150, 153.
        let counts = [100, 100, 100, 100, 101, 400, 150, 150, 153];
        let spread = steady_spread(&counts, &[6]).unwrap();
        // 101 / 100 before the cut, 153 / 150 after it: the larger, 1.02; not the dearest
        // topology's frame over the median of all steady frames mixed (153 / 100), nor the
        // cut frame's 400.
        assert!((spread - 1.02).abs() < 1e-12, "{spread}");
        let counts = [100, 100, 100, 100, 102, 400, 150, 150, 150];
        assert!((steady_spread(&counts, &[6]).unwrap() - 1.02).abs() < 1e-12);
        // No cut: one topology; no steady frame: none.
        assert!((steady_spread(&[10, 10, 11], &[]).unwrap() - 1.1).abs() < 1e-12);
        assert_eq!(steady_spread(&[5], &[1]), None);
    }
}
