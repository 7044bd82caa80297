//! Fuzzing of the core's public entry points with generated hostile input (issue 13):
//!
//! - `sequences`: a model built on a small box, fed a long sequence of calls that alternate
//!   good and bad input: frames with NaN, ±∞ or huge coordinates, duplicate and unknown ids,
//!   empty frames, every feature lost, features jumping 50 px, pixels far outside the image;
//!   hostile positions (`set_positions`), strategies at and beyond their bounds, internal
//!   targets, cut polylines, new frame-0 features, cuts of the detected line. Half the
//!   models run the stable Neo-Hookean law, half SVK (in `meshes` too).
//! - `meshes`: meshes with degenerate, inverted, duplicated or disconnected elements, bad node
//!   indices, non-finite coordinates, no fixed node; capacities at and one below what the mesh
//!   needs; configurations at and beyond every bound. Each mesh the core accepts then takes a
//!   short run of frames.
//!
//! Properties: no panic; no NaN or infinity in the positions, ever; after every error the
//! model's fingerprint, positions, observations and target count are unchanged bit for bit.
//!
//! **What counts as an input:** one call of a public entry point with generated arguments —
//! one frame given to `Model::step`, one `Model::new`, one `set_positions`, one `cut_along`,
//! and so on. Each property prints its count. The case count per property comes from
//! `INCISE_FUZZ_CASES` (default 210: a little over 20,000 inputs in all, what CI runs);
//! `INCISE_FUZZ_CASES=9300 cargo test --test fuzz_core -- --nocapture` runs a little over a
//! million (1,009,544 inputs in 8 min 46 s on two cores; the README's "Reliability" section).

use std::sync::atomic::{AtomicU64, Ordering};

use incise::storage::OwnedStorage;
use incise_core::solve::{MAX_LINE_SEARCH_STEPS, MAX_NEWTON_ITERATIONS, MAX_PCG_ITERATIONS};
use incise_core::{Capacities, Coupling, Error, Law, Model, Observation, Strategy as Linear};
use incise_validation::bench_model::{Bench, SIZE, Snapshot};
use incise_validation::rng::Rng;
use proptest::prelude::*;

fn cases() -> u32 {
    std::env::var("INCISE_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(210)
}

/// Calls per case of `sequences`.
const SEQUENCE: usize = 100;

static SEQUENCE_INPUTS: AtomicU64 = AtomicU64::new(0);
static SEQUENCE_ERRORS: AtomicU64 = AtomicU64::new(0);
static MESH_INPUTS: AtomicU64 = AtomicU64::new(0);
static MESH_ERRORS: AtomicU64 = AtomicU64::new(0);

/// A value from the classes a hostile input draws from.
fn nasty(rng: &mut Rng, ordinary: f64) -> f64 {
    match rng.next_u64() % 12 {
        0 => f64::NAN,
        1 => f64::INFINITY,
        2 => f64::NEG_INFINITY,
        3 => 1e300,
        4 => -1e300,
        5 => f64::MAX,
        6 => f64::MIN_POSITIVE,
        7 => 0.0,
        8 => -0.0,
        9 => ordinary * 1e6,
        10 => -ordinary,
        _ => ordinary + rng.range(-1.0, 1.0) * ordinary.abs().max(1.0),
    }
}

/// What a frame is made of.
#[derive(Clone, Copy, Debug)]
enum FrameKind {
    /// The stretch at frame `t` with noise and drop-outs.
    Good,
    /// One coordinate replaced by a hostile value.
    Nasty,
    /// One id repeated.
    Duplicate,
    /// One id never embedded.
    Unknown,
    /// No observation at all.
    Empty,
    /// Every feature lost but one.
    AllButOne,
    /// Every feature jumps 50 px in its own direction.
    Jump,
    /// Observations shuffled, some with ids near `u32::MAX`.
    Shuffled,
}

fn frame_kind() -> impl proptest::strategy::Strategy<Value = FrameKind> {
    prop_oneof![
        8 => Just(FrameKind::Good),
        2 => Just(FrameKind::Nasty),
        1 => Just(FrameKind::Duplicate),
        1 => Just(FrameKind::Unknown),
        1 => Just(FrameKind::Empty),
        1 => Just(FrameKind::AllButOne),
        1 => Just(FrameKind::Jump),
        1 => Just(FrameKind::Shuffled),
    ]
}

fn make_frame(b: &Bench, kind: FrameKind, t: usize, rng: &mut Rng) -> Vec<Observation<f64>> {
    let mut frame = b.frame(t, 4.0);
    let drop = rng.uniform() * 0.3;
    frame.retain(|_| rng.uniform() >= drop);
    for o in frame.iter_mut() {
        o.uv[0] += 0.3 * rng.normal();
        o.uv[1] += 0.3 * rng.normal();
    }
    if frame.is_empty() {
        frame = b.frame(t, 4.0);
    }
    let pick = |rng: &mut Rng, n: usize| (rng.next_u64() % n as u64) as usize;
    match kind {
        FrameKind::Good => {}
        FrameKind::Nasty => {
            let k = pick(rng, frame.len());
            let c = pick(rng, 2);
            frame[k].uv[c] = nasty(rng, frame[k].uv[c]);
        }
        FrameKind::Duplicate => {
            let k = pick(rng, frame.len());
            let o = frame[k];
            let at = pick(rng, frame.len() + 1);
            frame.insert(at, o);
        }
        FrameKind::Unknown => {
            let k = pick(rng, frame.len());
            frame[k].id = 1000 + (rng.next_u64() % 1000) as u32;
        }
        FrameKind::Empty => frame.clear(),
        FrameKind::AllButOne => frame.truncate(1),
        FrameKind::Jump => {
            for o in frame.iter_mut() {
                let a = rng.uniform() * std::f64::consts::TAU;
                o.uv[0] += 50.0 * a.cos();
                o.uv[1] += 50.0 * a.sin();
            }
        }
        FrameKind::Shuffled => {
            for k in (1..frame.len()).rev() {
                frame.swap(k, pick(rng, k + 1));
            }
            if rng.uniform() < 0.5 {
                frame[0].id = u32::MAX - (rng.next_u64() % 3) as u32;
            }
        }
    }
    frame
}

/// One call of the sequence.
#[derive(Clone, Copy, Debug)]
enum Call {
    Step(FrameKind),
    Observe(FrameKind),
    Positions,
    Rest,
    SetStrategy,
    Targets,
    CutAlong,
    ApplyCut,
    Embed(FrameKind),
}

fn call() -> impl proptest::strategy::Strategy<Value = Call> {
    prop_oneof![
        24 => frame_kind().prop_map(Call::Step),
        1 => frame_kind().prop_map(Call::Observe),
        1 => Just(Call::Positions),
        2 => Just(Call::Rest),
        1 => Just(Call::SetStrategy),
        1 => Just(Call::Targets),
        1 => Just(Call::CutAlong),
        1 => Just(Call::ApplyCut),
        1 => frame_kind().prop_map(Call::Embed),
    ]
}

/// Either law, each in half the cases.
fn law_from(rng: &mut Rng) -> Law {
    if rng.next_u64().is_multiple_of(2) {
        Law::SaintVenantKirchhoff
    } else {
        Law::StableNeoHookean
    }
}

fn strategy_from(rng: &mut Rng) -> Linear {
    match rng.next_u64() % 5 {
        0 => Linear::Refactor,
        4 => Linear::QuasiNewton,
        1 => Linear::Frozen {
            pcg_iterations: 1 + (rng.next_u64() % 12) as u32,
        },
        2 => Linear::FactorOnce {
            pcg_iterations: 1 + (rng.next_u64() % 12) as u32,
        },
        _ => Linear::Frozen {
            pcg_iterations: [0, 1, MAX_PCG_ITERATIONS, MAX_PCG_ITERATIONS + 1, u32::MAX]
                [(rng.next_u64() % 5) as usize],
        },
    }
}

/// Runs `f` on `model` and checks the properties: an error leaves the state unchanged, the
/// positions stay finite. Returns whether it failed.
fn checked<R>(
    model: &mut Model<'_, f64>,
    what: &dyn std::fmt::Debug,
    f: impl FnOnce(&mut Model<'_, f64>) -> Result<R, Error>,
) -> Result<bool, TestCaseError> {
    let before = Snapshot::of(model);
    let failed = match f(model) {
        Ok(_) => false,
        Err(e) => {
            prop_assert_eq!(
                &Snapshot::of(model),
                &before,
                "{:?} failed with {:?} and changed the model",
                what,
                e
            );
            true
        }
    };
    prop_assert!(
        model.positions().iter().flatten().all(|c| c.is_finite()),
        "{:?}: non-finite position",
        what
    );
    Ok(failed)
}

fn run_sequence(
    bench_cells: [usize; 3],
    strategy_seed: u64,
    calls: &[(Call, u64)],
) -> Result<(), TestCaseError> {
    let b = Bench::new(bench_cells, 5);
    let mut rng = Rng::new(strategy_seed);
    let strategy = match strategy_from(&mut rng) {
        Linear::Frozen { pcg_iterations } if pcg_iterations == 0 || pcg_iterations > 50 => {
            Linear::Frozen { pcg_iterations: 6 }
        }
        s => s,
    };
    // Half the cases run the stable Neo-Hookean law instead of SVK.
    let mut config = b.config(strategy);
    config.material.law = law_from(&mut rng);
    let mut storage = OwnedStorage::<f64>::new(&b.capacities(32, 2000)).unwrap();
    let mut model = storage
        .model(&b.input(), &config)
        .map_err(|e| TestCaseError::fail(format!("bench refused: {e}")))?;
    let (mut inputs, mut errors) = (0u64, 0u64);
    model
        .embed_features(&b.frame0())
        .map_err(|e| TestCaseError::fail(format!("frame 0 refused: {e}")))?;
    let mut t = 0usize;
    for &(c, seed) in calls {
        let mut rng = Rng::new(seed);
        t += 1;
        inputs += 1;
        let failed = match c {
            Call::Step(kind) => {
                let frame = make_frame(&b, kind, t, &mut rng);
                checked(&mut model, &c, |m| m.step(&frame))?
            }
            Call::Observe(kind) => {
                let frame = make_frame(&b, kind, t, &mut rng);
                checked(&mut model, &c, |m| m.observe(&frame))?
            }
            Call::Positions => {
                let n = model.positions().len();
                let len = match rng.next_u64() % 8 {
                    0 => n - 1,
                    1 => n + 1,
                    _ => n,
                };
                let mut x: Vec<[f64; 3]> = (0..len)
                    .map(|k| {
                        let p = model.positions()[k.min(n - 1)];
                        p.map(|c| c + 0.002 * rng.normal())
                    })
                    .collect();
                match rng.next_u64() % 4 {
                    0 => {
                        let k = (rng.next_u64() % len as u64) as usize;
                        let c = (rng.next_u64() % 3) as usize;
                        x[k][c] = nasty(&mut rng, x[k][c]);
                    }
                    1 => {
                        // Mirror the mesh: every element inverted.
                        for p in x.iter_mut() {
                            p[2] = -p[2];
                        }
                    }
                    _ => {}
                }
                checked(&mut model, &c, |m| m.set_positions(&x))?
            }
            Call::Rest => {
                let rest = b.rest.clone();
                checked(&mut model, &c, |m| m.set_positions(&rest))?
            }
            Call::SetStrategy => {
                let s = strategy_from(&mut rng);
                checked(&mut model, &c, |m| m.set_strategy(s))?
            }
            Call::Targets => {
                let n = (rng.next_u64() % 18) as usize;
                let mut pts: Vec<[f64; 3]> = (0..n)
                    .map(|_| [0, 1, 2].map(|k| SIZE[k] * rng.range(-0.5, 1.5)))
                    .collect();
                if n > 0 && rng.uniform() < 0.3 {
                    let k = (rng.next_u64() % n as u64) as usize;
                    pts[k][0] = nasty(&mut rng, pts[k][0]);
                }
                checked(&mut model, &c, |m| m.embed_targets(&pts))?
            }
            Call::CutAlong => {
                let n = (rng.next_u64() % 5) as usize;
                let mut line: Vec<[f64; 2]> = (0..n)
                    .map(|_| [rng.range(-200.0, 840.0), rng.range(-200.0, 680.0)])
                    .collect();
                if n > 0 && rng.uniform() < 0.3 {
                    let k = (rng.next_u64() % n as u64) as usize;
                    line[k][1] = nasty(&mut rng, line[k][1]);
                }
                if rng.uniform() < 0.05 {
                    line = vec![[320.0, 240.0]; 100];
                }
                let ext = nasty(&mut rng, 5.0);
                checked(&mut model, &c, |m| m.cut_along(&line, ext))?
            }
            Call::ApplyCut => checked(&mut model, &c, |m| m.apply_cut())?,
            Call::Embed(kind) => {
                let mut frame = make_frame(&b, kind, 0, &mut rng);
                if rng.uniform() < 0.2 {
                    // More than the capacity.
                    frame = (0..33)
                        .map(|id| Observation {
                            id,
                            uv: [320.0, 240.0],
                        })
                        .collect();
                }
                checked(&mut model, &c, |m| m.embed_features(&frame))?
            }
        };
        errors += u64::from(failed);
    }
    SEQUENCE_INPUTS.fetch_add(inputs, Ordering::Relaxed);
    SEQUENCE_ERRORS.fetch_add(errors, Ordering::Relaxed);
    Ok(())
}

/// A fault of the mesh or of the capacities.
#[derive(Clone, Copy, Debug)]
enum MeshFault {
    None,
    Degenerate,
    Inverted,
    DuplicateTet,
    Disconnected,
    BadIndex,
    NonFinite,
    NoFixed,
    AllFixed,
    BadFixedIndex,
    NodesOneShort,
    TetsOneShort,
    SurfaceOneShort,
    FactorOneShort,
    FeaturesOneShort,
    PairsTiny,
    Config,
}

fn mesh_fault() -> impl proptest::strategy::Strategy<Value = MeshFault> {
    prop_oneof![
        3 => Just(MeshFault::None),
        1 => Just(MeshFault::Degenerate),
        1 => Just(MeshFault::Inverted),
        1 => Just(MeshFault::DuplicateTet),
        1 => Just(MeshFault::Disconnected),
        1 => Just(MeshFault::BadIndex),
        1 => Just(MeshFault::NonFinite),
        1 => Just(MeshFault::NoFixed),
        1 => Just(MeshFault::AllFixed),
        1 => Just(MeshFault::BadFixedIndex),
        1 => Just(MeshFault::NodesOneShort),
        1 => Just(MeshFault::TetsOneShort),
        1 => Just(MeshFault::SurfaceOneShort),
        1 => Just(MeshFault::FactorOneShort),
        1 => Just(MeshFault::FeaturesOneShort),
        1 => Just(MeshFault::PairsTiny),
        3 => Just(MeshFault::Config),
    ]
}

/// Frames run on each mesh the core accepts.
const MESH_FRAMES: usize = 16;

fn run_mesh(cells: [usize; 3], fault: MeshFault, seed: u64) -> Result<(), TestCaseError> {
    let mut rng = Rng::new(seed);
    let mut b = Bench::new(cells, 4);
    let (n, t) = (b.rest.len(), b.tets.len());
    let pick = |rng: &mut Rng, n: usize| (rng.next_u64() % n as u64) as usize;
    let mut caps: Capacities = b.capacities(16, 500);
    let mut config = b.config(Linear::Refactor);
    config.material.law = law_from(&mut rng);
    let features = b.frame0();
    match fault {
        MeshFault::None => {}
        MeshFault::Degenerate => {
            let k = pick(&mut rng, t);
            b.tets[k][1] = b.tets[k][0];
        }
        MeshFault::Inverted => {
            let k = pick(&mut rng, t);
            b.tets[k].swap(2, 3);
        }
        MeshFault::DuplicateTet => {
            let k = pick(&mut rng, t);
            let tet = b.tets[k];
            b.tets.push(tet);
        }
        MeshFault::Disconnected => {
            // A floating tetrahedron away from the box, with its own nodes.
            let base = b.rest.len() as u32;
            for p in [
                [0.1, 0.1, 0.0],
                [0.11, 0.1, 0.0],
                [0.1, 0.11, 0.0],
                [0.1, 0.1, 0.01],
            ] {
                b.rest.push(p);
            }
            b.tets.push([base, base + 1, base + 2, base + 3]);
        }
        MeshFault::BadIndex => {
            let k = pick(&mut rng, t);
            b.tets[k][pick(&mut rng, 4)] = [n as u32, u32::MAX, n as u32 + 7][pick(&mut rng, 3)];
        }
        MeshFault::NonFinite => {
            let k = pick(&mut rng, n);
            let c = pick(&mut rng, 3);
            b.rest[k][c] = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][pick(&mut rng, 3)];
        }
        MeshFault::NoFixed => b.fixed.clear(),
        MeshFault::AllFixed => b.fixed = (0..n as u32).collect(),
        MeshFault::BadFixedIndex => b.fixed.push(n as u32 + pick(&mut rng, 3) as u32),
        MeshFault::NodesOneShort => caps.mesh.nodes = n - 1,
        MeshFault::TetsOneShort => caps.mesh.tets = t - 1,
        MeshFault::SurfaceOneShort => caps.mesh.surface_triangles = pick(&mut rng, 4 * t),
        MeshFault::FactorOneShort => caps.factor_entries = pick(&mut rng, caps.factor_entries / 4),
        MeshFault::FeaturesOneShort => caps.features = features.len() - 1,
        MeshFault::PairsTiny => caps.pairs = pick(&mut rng, 8),
        MeshFault::Config => {
            let s = &mut config.solver;
            match pick(&mut rng, 10) {
                0 => {
                    s.newton_iterations =
                        [0, 1, MAX_NEWTON_ITERATIONS, MAX_NEWTON_ITERATIONS + 1][pick(&mut rng, 4)]
                }
                1 => {
                    s.line_search_steps =
                        [0, 1, MAX_LINE_SEARCH_STEPS, MAX_LINE_SEARCH_STEPS + 1][pick(&mut rng, 4)]
                }
                2 => {
                    s.coupling = if pick(&mut rng, 2) == 0 {
                        Coupling::Stiffness(nasty(&mut rng, 1e-6))
                    } else {
                        Coupling::Relative(nasty(&mut rng, 100.0))
                    }
                }
                3 => s.damping = nasty(&mut rng, 0.01),
                4 => s.depth_prior = nasty(&mut rng, 0.1),
                5 => s.image_margin = nasty(&mut rng, 50.0),
                6 => config.material.young = nasty(&mut rng, 3e4),
                7 => {
                    config.material.poisson =
                        [0.5, -1.0, 0.499_999, -0.999, f64::NAN][pick(&mut rng, 5)]
                }
                8 => {
                    let d = &mut config.detection;
                    match pick(&mut rng, 8) {
                        0 => d.radius_px = nasty(&mut rng, 0.0),
                        1 => d.alpha_degrees = [0.0, 90.0, 90.000_1, 1e-9][pick(&mut rng, 4)],
                        2 => d.persistence = [0, 1, 254, 255, u32::MAX][pick(&mut rng, 5)],
                        3 => d.init_points = [0, 1, 2, u32::MAX][pick(&mut rng, 4)],
                        4 => d.min_step = nasty(&mut rng, 0.1),
                        5 => {
                            d.max_surface_ratio =
                                [0.0, 0.999, 1.0, f64::INFINITY][pick(&mut rng, 4)]
                        }
                        6 => d.depth = Some([nasty(&mut rng, 0.0), 0.0, nasty(&mut rng, 1.0)]),
                        _ => d.min_support = [0, 1, u32::MAX][pick(&mut rng, 3)],
                    }
                }
                _ => {
                    s.newton_iterations = MAX_NEWTON_ITERATIONS;
                    s.line_search_steps = MAX_LINE_SEARCH_STEPS;
                    s.strategy = Linear::Frozen {
                        pcg_iterations: MAX_PCG_ITERATIONS,
                    };
                }
            }
        }
    }
    let mut storage = OwnedStorage::<f64>::new(&caps).unwrap();
    let (mut inputs, mut errors) = (1u64, 0u64);
    let built = storage.model(&b.input(), &config);
    let mut model = match built {
        Ok(m) => m,
        Err(_) => {
            MESH_INPUTS.fetch_add(inputs, Ordering::Relaxed);
            MESH_ERRORS.fetch_add(1, Ordering::Relaxed);
            return Ok(());
        }
    };
    prop_assert!(model.positions().iter().flatten().all(|c| c.is_finite()));
    inputs += 1;
    let embedded = checked(&mut model, &"embed_features", |m| {
        m.embed_features(&features)
    })?;
    errors += u64::from(embedded);
    for f in 1..=MESH_FRAMES {
        let kind = if f % 3 == 0 {
            FrameKind::Nasty
        } else {
            FrameKind::Good
        };
        let frame = make_frame(&b, kind, f, &mut rng);
        inputs += 1;
        errors += u64::from(checked(&mut model, &kind, |m| m.step(&frame))?);
    }
    MESH_INPUTS.fetch_add(inputs, Ordering::Relaxed);
    MESH_ERRORS.fetch_add(errors, Ordering::Relaxed);
    Ok(())
}

fn report(name: &str, inputs: &AtomicU64, errors: &AtomicU64) {
    println!(
        "fuzz_core {name}: {} inputs, {} refused with an error (state unchanged), {} cases",
        inputs.load(Ordering::Relaxed),
        errors.load(Ordering::Relaxed),
        cases()
    );
}

#[test]
fn sequences() {
    let config = ProptestConfig {
        cases: cases(),
        failure_persistence: None,
        ..ProptestConfig::default()
    };
    proptest!(config, |(
        cells in prop_oneof![Just([3usize, 2, 1]), Just([4usize, 3, 1]), Just([2usize, 2, 2])],
        strategy_seed in any::<u64>(),
        calls in proptest::collection::vec((call(), any::<u64>()), SEQUENCE),
    )| {
        run_sequence(cells, strategy_seed, &calls)?;
    });
    report("sequences", &SEQUENCE_INPUTS, &SEQUENCE_ERRORS);
}

#[test]
fn meshes() {
    let config = ProptestConfig {
        cases: cases(),
        failure_persistence: None,
        ..ProptestConfig::default()
    };
    proptest!(config, |(
        cells in prop_oneof![Just([2usize, 2, 1]), Just([3usize, 2, 1]), Just([1usize, 1, 1])],
        fault in mesh_fault(),
        seed in any::<u64>(),
    )| {
        run_mesh(cells, fault, seed)?;
    });
    report("meshes", &MESH_INPUTS, &MESH_ERRORS);
}
