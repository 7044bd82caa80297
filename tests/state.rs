//! Every error path of every public entry point of the core leaves the state as it was
//! (issue 13): each test provokes an error and compares the model before and after, bit for
//! bit ([`Model::fingerprint`] hashes every state buffer; the positions, targets and observed
//! flags are compared as bits besides), and checks that the error names the exact parameter,
//! resource or index at fault.

use incise::storage::OwnedStorage;
use incise_core::sparse::{LdlFactor, Symbolic, UpperCsc, analyse_work_len};
use incise_core::{
    Capacities, Coupling, DetectionConfig, Error, Model, Observation, Parameter, Resource, Strategy,
};
use incise_validation::bench_model::{Bench, Snapshot};

/// A bench of 4 × 3 × 1 cells with 6 × 6 features.
fn bench() -> Bench {
    Bench::new([4, 3, 1], 6)
}

/// Runs `f` on a model embedded with the bench's features and stepped through a few frames
/// (so that observations, damping reference, factor and detector all hold something).
fn with_model(
    strategy: Strategy,
    capacities: impl FnOnce(&Bench) -> Capacities,
    f: impl FnOnce(&Bench, &mut Model<'_, f64>),
) {
    let b = bench();
    let mut storage = OwnedStorage::<f64>::new(&capacities(&b)).unwrap();
    let mut model = storage.model(&b.input(), &b.config(strategy)).unwrap();
    model.embed_features(&b.frame0()).unwrap();
    model
        .embed_targets(&[[0.02, 0.015, 0.005], [0.03, 0.01, 0.002]])
        .unwrap();
    for t in 1..4 {
        model.step(&b.frame(t, 3.0)).unwrap();
    }
    f(&b, &mut model);
}

fn default_caps(b: &Bench) -> Capacities {
    b.capacities(64, 4000)
}

/// Calls `call`, which must fail with an error `expect` accepts, and checks that the model is
/// unchanged bit for bit.
#[track_caller]
fn refused<R: std::fmt::Debug>(
    model: &mut Model<'_, f64>,
    what: &str,
    call: impl FnOnce(&mut Model<'_, f64>) -> Result<R, Error>,
    expect: impl FnOnce(&Error) -> bool,
) -> Error {
    let before = Snapshot::of(model);
    let result = call(model);
    let e = match result {
        Err(e) => e,
        Ok(r) => panic!("{what}: accepted ({r:?})"),
    };
    assert!(expect(&e), "{what}: unexpected error {e:?}");
    assert_eq!(Snapshot::of(model), before, "{what}: {e} changed the model");
    e
}

/// Moves every node 1e200 times farther from the origin: finite, but the energy overflows.
fn blow_up(model: &mut Model<'_, f64>) {
    let huge: Vec<[f64; 3]> = model
        .positions()
        .iter()
        .map(|p| p.map(|c| c * 1e200))
        .collect();
    model.set_positions(&huge).unwrap();
}

/// A named input and the error it must get.
type Case = (&'static str, Vec<Observation<f64>>, fn(&Error) -> bool);

fn obs(id: u32, u: f64, v: f64) -> Observation<f64> {
    Observation { id, uv: [u, v] }
}

#[test]
fn model_new_names_the_parameter_resource_and_index_at_fault() {
    let b = bench();
    let caps = default_caps(&b);
    let good = b.config(Strategy::Refactor);
    let build = |config: &incise_core::ModelConfig<f64>,
                 rest: &[[f64; 3]],
                 tets: &[[u32; 4]],
                 fixed: &[u32],
                 caps: &Capacities| {
        let mut storage = OwnedStorage::<f64>::new(caps).unwrap();
        let input = incise_core::MeshInput { rest, tets, fixed };
        storage.model(&input, config).map(|_| ())
    };
    let with = |f: &dyn Fn(&mut incise_core::ModelConfig<f64>)| {
        let mut c = good;
        f(&mut c);
        build(&c, &b.rest, &b.tets, &b.fixed, &caps)
    };
    let invalid = |parameter| Err(Error::InvalidParameter { parameter });
    assert_eq!(
        with(&|c| c.material.young = f64::NAN),
        invalid(Parameter::YoungModulus)
    );
    assert_eq!(
        with(&|c| c.material.poisson = 0.5),
        invalid(Parameter::PoissonRatio)
    );
    assert_eq!(
        with(&|c| c.solver.newton_iterations = 0),
        invalid(Parameter::NewtonIterations)
    );
    assert_eq!(
        with(&|c| c.solver.line_search_steps = 17),
        invalid(Parameter::LineSearchSteps)
    );
    assert_eq!(
        with(&|c| c.solver.strategy = Strategy::Frozen { pcg_iterations: 0 }),
        invalid(Parameter::PcgIterations)
    );
    assert_eq!(
        with(&|c| c.solver.coupling = Coupling::Stiffness(0.0)),
        invalid(Parameter::SpringStiffness)
    );
    assert_eq!(
        with(&|c| c.solver.image_margin = -1.0),
        invalid(Parameter::ImageMargin)
    );
    // Each detection field has its own name.
    type Mutation = fn(&mut DetectionConfig<f64>);
    let detection: [(Mutation, Parameter); 16] = [
        (|d| d.radius_px = -1.0, Parameter::RadiusPx),
        (|d| d.radius_spacings = 0.0, Parameter::RadiusSpacings),
        (|d| d.max_surface_ratio = 0.5, Parameter::MaxSurfaceRatio),
        (|d| d.outlier_sigmas = f64::NAN, Parameter::OutlierSigmas),
        (|d| d.temporal_sigmas = -2.0, Parameter::TemporalSigmas),
        (
            |d| d.min_difference_px = f64::INFINITY,
            Parameter::MinDifferencePx,
        ),
        (|d| d.persistence = 0, Parameter::Persistence),
        (|d| d.persistence = 255, Parameter::Persistence),
        (|d| d.init_points = 1, Parameter::InitPoints),
        (|d| d.alpha_degrees = 90.5, Parameter::AlphaDegrees),
        (|d| d.min_step = 2.0, Parameter::MinStep),
        (|d| d.max_step = 0.0, Parameter::MaxStep),
        (|d| d.min_support = 0, Parameter::MinSupport),
        (|d| d.line_tolerance = 0.0, Parameter::LineTolerance),
        (
            |d| d.max_outlier_fraction = 0.0,
            Parameter::MaxOutlierFraction,
        ),
        (|d| d.depth = Some([0.0; 3]), Parameter::Depth),
    ];
    for (mutate, parameter) in detection {
        let mut c = good;
        mutate(&mut c.detection);
        assert_eq!(c.detection.validate(), invalid(parameter));
        assert_eq!(
            build(&c, &b.rest, &b.tets, &b.fixed, &caps),
            invalid(parameter)
        );
    }
    // Too many tetrahedra is named as such, with tetrahedron counts.
    let mut small = caps;
    small.mesh.tets = b.tets.len() - 1;
    assert_eq!(
        build(&good, &b.rest, &b.tets, &b.fixed, &small),
        Err(Error::Capacity {
            resource: Resource::Tetrahedra,
            needed: b.tets.len(),
            available: b.tets.len() - 1,
        })
    );
    let mut small = caps;
    small.mesh.nodes = b.rest.len() - 1;
    assert_eq!(
        build(&good, &b.rest, &b.tets, &b.fixed, &small),
        Err(Error::Capacity {
            resource: Resource::Nodes,
            needed: b.rest.len(),
            available: b.rest.len() - 1,
        })
    );
    // Mesh faults name the element, node or position.
    let mut rest = b.rest.clone();
    rest[5][1] = f64::NAN;
    assert_eq!(
        build(&good, &rest, &b.tets, &b.fixed, &caps),
        Err(Error::NonFiniteInput {
            resource: Resource::Nodes,
            position: 5,
        })
    );
    let mut tets = b.tets.clone();
    tets[3].swap(0, 1);
    assert_eq!(
        build(&good, &b.rest, &tets, &b.fixed, &caps),
        Err(Error::InvertedElement { tet: 3 })
    );
    let mut tets = b.tets.clone();
    tets[4][1] = tets[4][0];
    assert_eq!(
        build(&good, &b.rest, &tets, &b.fixed, &caps),
        Err(Error::DegenerateElement { tet: 4 })
    );
    let mut tets = b.tets.clone();
    tets[2][3] = b.rest.len() as u32;
    assert_eq!(
        build(&good, &b.rest, &tets, &b.fixed, &caps),
        Err(Error::IndexOutOfRange {
            resource: Resource::Tetrahedra,
            position: 11,
            index: b.rest.len(),
            bound: b.rest.len(),
        })
    );
    assert_eq!(
        build(&good, &b.rest, &b.tets, &[], &caps),
        Err(Error::NoFixedNodes)
    );
    // Storage one short.
    let size = incise_core::ModelSize::new(&caps).unwrap();
    let mut reals = vec![0.0f64; size.real_len() - 1];
    let mut indices = vec![0u32; size.index_len()];
    assert_eq!(
        incise_core::ModelBuffers::new(&size, &mut reals, &mut indices).map(|_| ()),
        Err(Error::Capacity {
            resource: Resource::RealStorage,
            needed: size.real_len(),
            available: size.real_len() - 1,
        })
    );
}

#[test]
fn a_bad_frame_leaves_the_model_as_it_was() {
    for strategy in [
        Strategy::Refactor,
        Strategy::Frozen { pcg_iterations: 8 },
        Strategy::FactorOnce { pcg_iterations: 3 },
    ] {
        with_model(strategy, default_caps, |b, model| {
            let good = b.frame(5, 3.0);
            let [u, v] = good[0].uv;
            let cases: Vec<Case> = vec![
                ("empty frame", vec![], |e| *e == Error::EmptyFrame),
                ("unknown id", vec![obs(1000, u, v)], |e| {
                    *e == Error::UnknownFeature { id: 1000 }
                }),
                ("duplicate id", vec![good[0], good[0]], |e| {
                    *e == Error::DuplicateFeature { id: 0 }
                }),
                ("NaN", vec![good[1], obs(0, f64::NAN, v)], |e| {
                    *e == Error::NonFiniteInput {
                        resource: Resource::Observations,
                        position: 1,
                    }
                }),
                ("infinity", vec![obs(0, u, f64::NEG_INFINITY)], |e| {
                    matches!(e, Error::NonFiniteInput { .. })
                }),
                ("far outside", vec![obs(0, 1e300, v)], |e| {
                    *e == Error::OutsideImage { id: 0 }
                }),
                (
                    "bad last of many",
                    {
                        let mut f = good.clone();
                        f.push(obs(99_999, u, v));
                        f
                    },
                    |e| *e == Error::UnknownFeature { id: 99_999 },
                ),
            ];
            for (what, frame, expect) in cases {
                refused(model, what, |m| m.step(&frame), expect);
                refused(model, what, |m| m.observe(&frame), expect);
            }
            // The model goes on from where it was: the next good frame succeeds.
            model.step(&good).unwrap();
        });
    }
}

/// After `model.observe(frame)`: exactly the slots whose ids the frame holds are observed,
/// each with its target from the frame.
#[track_caller]
fn observed_as(model: &Model<'_, f64>, frame: &[Observation<f64>]) {
    let features = model.features();
    for &[id, slot] in features.ids() {
        let seen = frame.iter().find(|o| o.id == id);
        let slot = slot as usize;
        assert_eq!(
            features.active()[slot],
            u32::from(seen.is_some()),
            "id {id}"
        );
        if let Some(o) = seen {
            assert_eq!(features.targets()[slot], o.uv, "id {id}");
        }
    }
}

#[test]
fn a_frame_observes_exactly_its_ids_in_any_order_and_after_any_refused_frame() {
    with_model(Strategy::Refactor, default_caps, |b, model| {
        let good = b.frame(5, 3.0);
        let n = good.len();
        assert!(n >= 6, "{n}");
        model.observe(&good).unwrap();
        observed_as(model, &good);
        // Reversed: every id where another stood in the frame before.
        let reversed: Vec<_> = good.iter().rev().copied().collect();
        model.observe(&reversed).unwrap();
        observed_as(model, &reversed);
        // Every other id, shifted: the ids left out must not count as seen, though where
        // they stood before now holds another observation.
        let some: Vec<_> = good.iter().skip(1).step_by(2).copied().collect();
        model.observe(&some).unwrap();
        observed_as(model, &some);
        // A repeated id, whichever of its two places the previous frame left it at.
        for (first, second) in [(0, n - 1), (1, 2), (n - 2, n - 1)] {
            let mut repeated = good.clone();
            repeated[second] = repeated[first];
            let id = repeated[first].id;
            assert_eq!(
                model.observe(&repeated),
                Err(Error::DuplicateFeature { id })
            );
            observed_as(model, &some);
        }
        // An unknown id after half the frame: nothing taken, and the next frame as it is.
        let mut unknown = reversed.clone();
        unknown[n / 2] = obs(99_999, good[0].uv[0], good[0].uv[1]);
        assert_eq!(
            model.observe(&unknown),
            Err(Error::UnknownFeature { id: 99_999 })
        );
        observed_as(model, &some);
        model.observe(&good[..1]).unwrap();
        observed_as(model, &good[..1]);
        model.observe(&good).unwrap();
        observed_as(model, &good);
    });
}

#[test]
fn a_solve_that_fails_leaves_observations_damping_reference_and_factor_as_they_were() {
    for strategy in [
        Strategy::Refactor,
        Strategy::Frozen { pcg_iterations: 8 },
        Strategy::FactorOnce { pcg_iterations: 3 },
        Strategy::QuasiNewton,
    ] {
        with_model(strategy, default_caps, |b, model| {
            let good = b.frame(5, 3.0);
            // Two good frames first, so that the quasi-Newton strategy holds secant pairs (the
            // fingerprint covers them) when a frame fails.
            model.step(&good).unwrap();
            model.step(&good).unwrap();
            let lifted: Vec<[f64; 3]> = model
                .positions()
                .iter()
                .map(|p| [p[0], p[1], p[2] + 1.0])
                .collect();
            // Every free node behind the camera: the springs cannot be evaluated.
            model.set_positions(&lifted).unwrap();
            let e = refused(
                model,
                "behind the camera",
                |m| m.step(&good),
                |e| matches!(e, Error::FeatureBehindCamera { .. }),
            );
            // The error names the slot and the id it holds.
            if let Error::FeatureBehindCamera { slot, id } = e {
                assert_eq!(model.features().slot_of(id), Some(slot));
            }
            // Finite but enormous positions: the energy overflows.
            blow_up(model);
            refused(
                model,
                "huge positions",
                |m| m.step(&good),
                |e| {
                    matches!(
                        e,
                        Error::NotFinite { .. }
                            | Error::Diverged
                            | Error::NotPositiveDefinite { .. }
                            | Error::FeatureBehindCamera { .. }
                    )
                },
            );
        });
    }
}

/// The quasi-Newton strategy with one line-search trial keeps the elements' share of the
/// gradient from frame to frame (the fingerprint covers it, and whether it is valid): frames
/// that fail after the nodes were moved (which forgets the share; the failing frame's first
/// assembly keeps one before it fails) leave the model as it was, and a twin stepped through
/// the same good frames agrees with it bit for bit before.
#[test]
fn a_failed_quasi_newton_frame_puts_back_the_elements_share_it_started_from() {
    let b = bench();
    let mut cfg = b.config(Strategy::QuasiNewton);
    cfg.solver.line_search_steps = 1;
    let mut storage = OwnedStorage::<f64>::new(&default_caps(&b)).unwrap();
    let mut model = storage.model(&b.input(), &cfg).unwrap();
    let mut twin_storage = OwnedStorage::<f64>::new(&default_caps(&b)).unwrap();
    let mut twin = twin_storage.model(&b.input(), &cfg).unwrap();
    for m in [&mut model, &mut twin] {
        m.embed_features(&b.frame0()).unwrap();
        for t in 1..4 {
            m.step(&b.frame(t, 3.0)).unwrap();
        }
    }
    assert_eq!(model.fingerprint(), twin.fingerprint());
    let good = b.frame(4, 3.0);
    let shifted: Vec<[f64; 3]> = model
        .positions()
        .iter()
        .map(|p| [p[0] + 1e-4, p[1], p[2]])
        .collect();
    model.set_positions(&shifted).unwrap();
    let moved = model.fingerprint();
    // Enormous but finite positions: the energy overflows.
    blow_up(&mut model);
    refused(
        &mut model,
        "huge positions",
        |m| m.step(&good),
        |e| {
            matches!(
                e,
                Error::NotFinite { .. } | Error::Diverged | Error::FeatureBehindCamera { .. }
            )
        },
    );
    model.set_positions(&shifted).unwrap();
    assert_eq!(model.fingerprint(), moved);
    // Stepping on from the shifted nodes is stepping the twin from them.
    twin.set_positions(&shifted).unwrap();
    let r = model.step(&good).unwrap();
    let t = twin.step(&good).unwrap();
    assert_eq!(r.energy_after, t.energy_after);
    assert_eq!(model.fingerprint(), twin.fingerprint());
}

#[test]
fn a_strategy_switch_whose_first_frame_fails_keeps_the_old_strategy_state() {
    with_model(Strategy::Refactor, default_caps, |b, model| {
        model
            .set_strategy(Strategy::Frozen { pcg_iterations: 4 })
            .unwrap();
        blow_up(model);
        // The first frame would prepare the frozen factor: it fails, and what the factor holds
        // (the fingerprint covers it) is what it was.
        refused(
            model,
            "frozen set-up",
            |m| m.step(&b.frame(5, 3.0)),
            |_| true,
        );
    });
}

#[test]
fn set_strategy_set_positions_and_embed_targets_refuse_without_a_trace() {
    with_model(Strategy::Refactor, default_caps, |_, model| {
        for pcg_iterations in [0, incise_core::solve::MAX_PCG_ITERATIONS + 1] {
            refused(
                model,
                "pcg iterations",
                |m| m.set_strategy(Strategy::Frozen { pcg_iterations }),
                |e| {
                    *e == Error::InvalidParameter {
                        parameter: Parameter::PcgIterations,
                    }
                },
            );
        }
        let n = model.positions().len();
        let x: Vec<[f64; 3]> = model.positions().to_vec();
        refused(
            model,
            "one short",
            |m| m.set_positions(&x[..n - 1]),
            |e| {
                *e == Error::Length {
                    resource: Resource::Nodes,
                    expected: n,
                    found: n - 1,
                }
            },
        );
        let mut bad = x.clone();
        bad[n - 1][2] = f64::INFINITY;
        refused(
            model,
            "infinite position",
            |m| m.set_positions(&bad),
            |e| {
                *e == Error::NonFiniteInput {
                    resource: Resource::Nodes,
                    position: n - 1,
                }
            },
        );
        let many = vec![[0.01, 0.01, 0.005]; 17];
        refused(
            model,
            "too many targets",
            |m| m.embed_targets(&many),
            |e| {
                *e == Error::Capacity {
                    resource: Resource::Targets,
                    needed: 17,
                    available: 16,
                }
            },
        );
        refused(
            model,
            "NaN target",
            |m| m.embed_targets(&[[0.01, 0.01, 0.005], [f64::NAN, 0.0, 0.0]]),
            |e| {
                *e == Error::NonFiniteInput {
                    resource: Resource::Targets,
                    position: 1,
                }
            },
        );
        refused(
            model,
            "slot out of range",
            |m| m.projected_feature(1000),
            |e| {
                matches!(
                    e,
                    Error::IndexOutOfRange {
                        resource: Resource::FeatureSlots,
                        index: 1000,
                        ..
                    }
                )
            },
        );
    });
}

#[test]
fn embed_features_refuses_without_a_trace() {
    with_model(
        Strategy::Frozen { pcg_iterations: 8 },
        default_caps,
        |b, model| {
            let frame0 = b.frame0();
            let [u, v] = frame0[0].uv;
            let too_many: Vec<Observation<f64>> = (0..65).map(|id| obs(id, u, v)).collect();
            let cases: Vec<Case> = vec![
                ("more than the capacity", too_many, |e| {
                    *e == Error::Capacity {
                        resource: Resource::Features,
                        needed: 65,
                        available: 64,
                    }
                }),
                ("empty", vec![], |e| *e == Error::NoFeatures),
                // The image corner sees no model: every ray misses.
                (
                    "all miss",
                    vec![obs(0, 1.0, 1.0), obs(1, 639.0, 479.0)],
                    |e| *e == Error::NoFeatures,
                ),
                ("NaN", vec![obs(0, u, f64::NAN)], |e| {
                    matches!(e, Error::NonFiniteInput { .. })
                }),
                ("duplicate", vec![frame0[0], frame0[1], frame0[0]], |e| {
                    *e == Error::DuplicateFeature { id: 0 }
                }),
                ("outside", vec![obs(3, -1e6, v)], |e| {
                    *e == Error::OutsideImage { id: 3 }
                }),
            ];
            for (what, frame, expect) in cases {
                refused(model, what, |m| m.embed_features(&frame), expect);
            }
            model.step(&b.frame(5, 3.0)).unwrap();
        },
    );
}

/// A failed re-embedding keeps what the frozen factor's preparation touched: the quasi-Newton
/// strategy's secant pairs (and their step scale) included, which that preparation clears
/// before the detector's pairs, the last step, are counted.
#[test]
fn embed_features_with_more_pairs_than_the_capacity_keeps_the_features_and_detector() {
    for strategy in [
        Strategy::Frozen { pcg_iterations: 8 },
        Strategy::QuasiNewton,
    ] {
        // Room for the pairs of 4 features (at most 6) but not for those of 36.
        let b = bench();
        let mut storage = OwnedStorage::<f64>::new(&b.capacities(64, 6)).unwrap();
        let mut model = storage.model(&b.input(), &b.config(strategy)).unwrap();
        let all = b.frame0();
        let few: Vec<Observation<f64>> = [0, 5, 30, 35].iter().map(|&k| all[k]).collect();
        model.embed_features(&few).unwrap();
        // Frames that move, so that the quasi-Newton strategy holds secant pairs.
        let frame = |t: f64| -> Vec<Observation<f64>> {
            few.iter()
                .map(|o| obs(o.id, o.uv[0] + 0.5 * t, o.uv[1]))
                .collect()
        };
        for t in 1..=3 {
            model.step(&frame(t as f64)).unwrap();
        }
        let e = refused(
            &mut model,
            &format!("{strategy:?}: too many pairs"),
            |m| m.embed_features(&all),
            |e| {
                matches!(
                    e,
                    Error::Capacity {
                        resource: Resource::Pairs,
                        available: 6,
                        ..
                    }
                )
            },
        );
        // The count of pairs needed is the whole count, not the first that did not fit.
        if let Error::Capacity { needed, .. } = e {
            assert!(needed > 7, "needed {needed}");
        }
        model.step(&frame(4.0)).unwrap();
    }
}

#[test]
fn step_before_any_feature_is_refused_without_a_trace() {
    let b = bench();
    let mut storage = OwnedStorage::<f64>::new(&default_caps(&b)).unwrap();
    let mut model = storage
        .model(&b.input(), &b.config(Strategy::Refactor))
        .unwrap();
    refused(
        &mut model,
        "no features",
        |m| m.step(&b.frame0()),
        |e| *e == Error::NoFeatures,
    );
}

#[test]
fn a_cut_that_cannot_be_made_leaves_the_model_as_it_was() {
    with_model(Strategy::Refactor, default_caps, |b, model| {
        let a = b.frame0()[2].uv;
        let z = b.frame0()[33].uv;
        let line = [[a[0], a[1] - 400.0], [z[0], z[1] + 400.0]];
        refused(
            model,
            "NaN vertex",
            |m| m.cut_along(&[line[0], [f64::NAN, 0.0]], 5.0),
            |e| {
                *e == Error::NonFiniteInput {
                    resource: Resource::CutVertices,
                    position: 1,
                }
            },
        );
        for extension in [f64::NAN, -1.0, f64::INFINITY] {
            refused(
                model,
                "bad extension",
                |m| m.cut_along(&line, extension),
                |e| {
                    *e == Error::InvalidParameter {
                        parameter: incise_core::Parameter::CutExtension,
                    }
                },
            );
        }
        // Longer than the cut line's capacity (32 vertices; the projections hold 64).
        let long = vec![line[0]; 33];
        refused(
            model,
            "too long",
            |m| m.cut_along(&long, 5.0),
            |e| {
                matches!(
                    e,
                    Error::Capacity {
                        resource: Resource::CutVertices,
                        needed: 33,
                        available: 32,
                    }
                )
            },
        );
        // No line detected: nothing to apply, nothing changes.
        let before = Snapshot::of(model);
        assert!(!model.apply_cut().unwrap().applied);
        assert_eq!(Snapshot::of(model), before);
    });
    // Capacities with no room for a new node: the cut is refused whole.
    with_model(
        Strategy::Refactor,
        |b| {
            let mut c = default_caps(b);
            c.mesh.nodes = b.rest.len();
            c
        },
        |b, model| {
            let a = b.frame0()[2].uv;
            let z = b.frame0()[33].uv;
            let line = [[a[0], a[1] - 400.0], [z[0], z[1] + 400.0]];
            refused(
                model,
                "no room",
                |m| m.cut_along(&line, 5.0),
                |e| {
                    matches!(
                        e,
                        Error::Capacity {
                            resource: Resource::Nodes,
                            ..
                        }
                    )
                },
            );
            model.step(&b.frame(5, 3.0)).unwrap();
        },
    );
}

/// The 2 × 2 dense pattern.
fn dense2() -> (Vec<u32>, Vec<u32>) {
    (vec![0, 1, 3], vec![0, 0, 1])
}

#[test]
fn sparse_phases_keep_what_they_held_on_error() {
    let (cp, ri) = dense2();
    let a = UpperCsc::new(2, &cp, &ri).unwrap();
    let perm = [0u32, 1];
    let mut awork = vec![0u32; analyse_work_len(2, a.nnz())];
    let size = Symbolic::size(&a, &perm, &mut awork).unwrap();
    let mut sstore = vec![0u32; size.index_len()];
    let mut sym = Symbolic::new(&a, &perm, &mut sstore, &mut awork).unwrap();
    let held = |s: &Symbolic<'_>| {
        (
            s.size_info(),
            s.perm().to_vec(),
            s.l_ptr().to_vec(),
            s.l_row().to_vec(),
            s.c_ptr().to_vec(),
            s.c_row().to_vec(),
        )
    };

    // Symbolic: a bad permutation, and a pattern beyond the capacity.
    let before = held(&sym);
    assert_eq!(
        sym.analyse(&a, &[1, 1], &mut awork),
        Err(Error::NotAPermutation { position: 1 })
    );
    assert_eq!(held(&sym), before);
    let (cp3, ri3) = (vec![0u32, 1, 3, 6], vec![0u32, 0, 1, 0, 1, 2]);
    let a3 = UpperCsc::new(3, &cp3, &ri3).unwrap();
    let mut awork3 = vec![0u32; analyse_work_len(3, a3.nnz())];
    assert_eq!(
        sym.analyse(&a3, &[0, 1, 2], &mut awork3),
        Err(Error::Capacity {
            resource: Resource::Unknowns,
            needed: 3,
            available: 2,
        })
    );
    assert_eq!(held(&sym), before);

    // Numeric: a failed factorization keeps the factor in service; inside a checkpoint, the
    // checkpoint's factor comes back after any number of factorizations.
    let mut fstore = vec![0.0f64; LdlFactor::<f64>::storage_len(&size)];
    let mut factor = LdlFactor::new(&size, &mut fstore).unwrap();
    let (mut y, mut cursor) = ([0.0; 2], [0u32; 2]);
    let values = |f: &LdlFactor<'_, f64>| {
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        (bits(f.l_values().unwrap()), bits(f.d_values().unwrap()))
    };
    factor
        .factorize(&sym, &[2.0, 1.0, 2.0], &mut y, &mut cursor)
        .unwrap();
    let first = values(&factor);
    for bad in [[1.0, 2.0, 1.0], [f64::NAN, 0.0, 1.0]] {
        assert!(factor.factorize(&sym, &bad, &mut y, &mut cursor).is_err());
        assert_eq!(values(&factor), first);
    }
    factor.checkpoint();
    factor
        .factorize(&sym, &[4.0, 1.0, 3.0], &mut y, &mut cursor)
        .unwrap();
    factor
        .factorize(&sym, &[5.0, 2.0, 3.0], &mut y, &mut cursor)
        .unwrap();
    assert_ne!(values(&factor), first);
    factor
        .factorize(&sym, &[6.0, 1.0, 4.0], &mut y, &mut cursor)
        .unwrap();
    factor.rollback();
    assert_eq!(values(&factor), first);
    // A failure inside a checkpoint also brings the checkpoint's factor back.
    factor.checkpoint();
    factor
        .factorize(&sym, &[4.0, 1.0, 3.0], &mut y, &mut cursor)
        .unwrap();
    assert!(
        factor
            .factorize(&sym, &[1.0, 2.0, 1.0], &mut y, &mut cursor)
            .is_err()
    );
    assert_eq!(values(&factor), first);
    factor.commit();
    assert_eq!(values(&factor), first);
    // Committed: the new factor stays.
    factor.checkpoint();
    factor
        .factorize(&sym, &[4.0, 1.0, 3.0], &mut y, &mut cursor)
        .unwrap();
    factor.commit();
    assert_ne!(values(&factor), first);
}

#[test]
fn duplicated_and_disconnected_elements_get_the_answer_the_readme_gives() {
    let b = bench();
    let caps = default_caps(&b);
    let config = b.config(Strategy::Refactor);
    // A tetrahedron listed twice: its faces are shared by too many tetrahedra.
    let mut tets = b.tets.clone();
    tets.push(tets[0]);
    let mut storage = OwnedStorage::<f64>::new(&caps).unwrap();
    let input = incise_core::MeshInput {
        rest: &b.rest,
        tets: &tets,
        fixed: &b.fixed,
    };
    assert!(matches!(
        storage.model(&input, &config).map(|_| ()),
        Err(Error::NonManifold { .. })
    ));
    // A floating tetrahedron with no fixed node is accepted, and frames keep it finite.
    let mut rest = b.rest.clone();
    let base = rest.len() as u32;
    rest.extend([
        [0.1, 0.1, 0.0],
        [0.11, 0.1, 0.0],
        [0.1, 0.11, 0.0],
        [0.1, 0.1, 0.01],
    ]);
    let mut tets = b.tets.clone();
    tets.push([base, base + 1, base + 2, base + 3]);
    let mut storage = OwnedStorage::<f64>::new(&caps).unwrap();
    let input = incise_core::MeshInput {
        rest: &rest,
        tets: &tets,
        fixed: &b.fixed,
    };
    let mut model = storage.model(&input, &config).unwrap();
    model.embed_features(&b.frame0()).unwrap();
    for t in 1..6 {
        model.step(&b.frame(t, 3.0)).unwrap();
    }
    assert!(model.positions().iter().flatten().all(|c| c.is_finite()));
}
