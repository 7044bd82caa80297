//! Cutting the mesh on the committed scenes (issue 10): after every cut event the mesh is
//! valid (every element above the quality floor, the boundary closed and manifold), every
//! feature and target is on its own side, the new factorization matches faer on the new matrix,
//! and the event's work is within its formula in the capacities; a cut that does not fit the
//! capacities leaves the model exactly as it was.

use std::path::{Path, PathBuf};

use incise::scene::{Scene, read_points_csv};
use incise::storage::{ModelStorage, SceneCapacities};
use incise_core::cut::SNAP_TOLERANCE;
use incise_core::nalgebra::Vector3;
use incise_core::{Error, MeshInput, Model, ModelConfig, Observation, Resource};
use incise_validation::cutcheck::{
    check_embeddings, check_factor, check_feature_sides, check_mesh, check_targets_stay,
    longest_edge, quality_floor,
};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures")
}

fn load(name: &str) -> Scene {
    Scene::load(&fixtures().join(name)).unwrap_or_else(|e| panic!("{e}"))
}

fn config(scene: &Scene) -> ModelConfig<f64> {
    scene.model_config().unwrap()
}

fn rest_targets(scene: &Scene) -> Vec<[f64; 3]> {
    let path = scene.dir.join("gt").join("targets.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    read_points_csv(&text, &path).unwrap().remove(0)
}

fn known(model: &Model<'_, f64>, frame: &[Observation<f64>]) -> Vec<Observation<f64>> {
    frame
        .iter()
        .copied()
        .filter(|o| model.features().slot_of(o.id).is_some())
        .collect()
}

/// The largest image length of a mesh edge near the cut, times the snapping tolerance: how far
/// a piece may reach across the line.
fn margin_px(scene: &Scene, config: &ModelConfig<f64>) -> f64 {
    let edge = longest_edge(&scene.rest, &scene.tets);
    let c = &config.camera;
    let depth = scene
        .rest
        .iter()
        .map(|p| c.to_camera(&Vector3::from(*p)).z)
        .fold(f64::INFINITY, f64::min);
    SNAP_TOLERANCE * edge * c.intrinsics().fx / depth + 2.0
}

#[test]
fn every_cut_event_keeps_the_mesh_valid_and_everything_on_its_side() {
    for name in ["band-side-cut", "band-middle-cut", "liver-lobe"] {
        let scene = load(name);
        let config = config(&scene);
        let input = MeshInput {
            rest: &scene.rest,
            tets: &scene.tets,
            fixed: &scene.file.model.fixed,
        };
        let floor = quality_floor(&scene.rest, &scene.tets);
        let targets = rest_targets(&scene);
        let tolerance = SNAP_TOLERANCE * longest_edge(&scene.rest, &scene.tets);
        let margin = margin_px(&scene, &config);
        let mut storage = ModelStorage::new(&input, &scene.file.capacities).unwrap();
        let mut model = storage.model(&input, &config).unwrap();
        model.embed_features(&scene.frames[0]).unwrap();
        model.embed_targets(&targets).unwrap();
        check_mesh(model.mesh(), floor).unwrap();
        let (mut events, mut sides) = (0, 0);
        for (f, frame) in scene.frames.iter().enumerate().skip(1) {
            let report = model.step(&known(&model, frame)).unwrap();
            // A refused event leaves the model as it was (the overflow test below checks that
            // bit for bit), but on the committed scenes none may be refused: a cut whose
            // separation would leave a non-manifold boundary keeps those faces joined instead.
            assert_eq!(report.cut.refused, None, "{name} frame {f}");
            if !report.cut.applied {
                continue;
            }
            events += 1;
            let at = |e: String| format!("{name}, cut at frame {f}: {e}");
            check_mesh(model.mesh(), floor).map_err(at).unwrap();
            check_embeddings(&model).map_err(at).unwrap();
            check_targets_stay(&model, &targets, tolerance)
                .map_err(at)
                .unwrap();
            let mut line = vec![[0.0; 2]; 64];
            let n = model.cut_polyline(&mut line).unwrap();
            sides += check_feature_sides(&model, &line[..n], margin)
                .map_err(at)
                .unwrap();
            let rel = check_factor(&mut model, 1e-8).map_err(at).unwrap();
            // The event's work is within its formula in the capacities.
            let (geometry, rebuild) = model.worst_case_cut_work();
            let (g, r) = (report.cut.event.work, report.cut.work);
            assert!(
                g.within(&geometry),
                "{name} frame {f}: {g:?} beyond {geometry:?}"
            );
            assert!(
                r.assemblies <= rebuild.assemblies
                    && r.element_tangents <= rebuild.element_tangents
                    && r.feature_evaluations <= rebuild.feature_evaluations
                    && r.factorizations <= rebuild.factorizations
                    && r.factor_flops <= rebuild.factor_flops,
                "{name} frame {f}: {r:?} beyond {rebuild:?}"
            );
            eprintln!(
                "{name}: cut at frame {f}: {} nodes, {} tetrahedra, {} faces cut, factor vs faer {rel:.1e}, \
                 segment tests {} (bound {}), boundary triangle tests {} (bound {})",
                model.mesh().n_nodes(),
                model.mesh().n_tets(),
                report.cut.event.faces_cut,
                g.segment_tests,
                geometry.segment_tests,
                g.triangle_tests,
                geometry.triangle_tests
            );
        }
        assert!(events >= 1, "{name}: the mesh was never cut");
        assert!(sides > 0, "{name}: no feature near the cut was checked");
    }
}

/// Runs `scene` with `capacities` until a cut is refused; returns the model's fingerprint and
/// the error of trying the same cut again (which must not change the fingerprint).
fn refused_cut(name: &str, capacities: SceneCapacities) -> Error {
    let scene = load(name);
    let config = config(&scene);
    let input = MeshInput {
        rest: &scene.rest,
        tets: &scene.tets,
        fixed: &scene.file.model.fixed,
    };
    let mut storage = ModelStorage::new(&input, &capacities).unwrap();
    let mut model = storage.model(&input, &config).unwrap();
    model.embed_features(&scene.frames[0]).unwrap();
    model.embed_targets(&rest_targets(&scene)).unwrap();
    for frame in &scene.frames[1..] {
        let report = model.step(&known(&model, frame)).unwrap();
        assert!(!report.cut.applied, "{name}: the cut fitted {capacities:?}");
        if report.cut.refused.is_some() {
            let before = model.fingerprint();
            let positions = model.positions().to_vec();
            let tets = model.mesh().tets().to_vec();
            let error = model
                .apply_cut()
                .expect_err("the same cut is refused again");
            assert_eq!(
                model.fingerprint(),
                before,
                "{name}: a refused cut changed the model"
            );
            assert_eq!(model.positions(), &positions[..]);
            assert_eq!(model.mesh().tets(), &tets[..]);
            return error;
        }
    }
    panic!("{name}: no cut was attempted");
}

#[test]
fn a_cut_that_overflows_a_capacity_leaves_the_model_exactly_as_it_was() {
    let scene = load("band-side-cut");
    // No room for the copies of the nodes along the cut.
    let e = refused_cut(
        "band-side-cut",
        SceneCapacities {
            cut_nodes: 1,
            ..scene.file.capacities.clone()
        },
    );
    assert!(
        matches!(
            e,
            Error::Capacity {
                resource: Resource::Nodes,
                ..
            }
        ),
        "{e}"
    );
    // No room for the fill of the first cut mesh that needs more than the uncut one: one entry
    // short of it. (The band's cuts only remove couplings; the liver's add elements.)
    let scene = load("liver-lobe");
    let config = config(&scene);
    let input = MeshInput {
        rest: &scene.rest,
        tets: &scene.tets,
        fixed: &scene.file.model.fixed,
    };
    let mut storage = ModelStorage::new(&input, &scene.file.capacities).unwrap();
    let mut model = storage.model(&input, &config).unwrap();
    model.embed_features(&scene.frames[0]).unwrap();
    let uncut = model.symbolic().nnz_l();
    let mut needed = None;
    for frame in &scene.frames[1..] {
        let report = model.step(&known(&model, frame)).unwrap();
        if report.cut.applied && model.symbolic().nnz_l() > uncut {
            needed = Some(model.symbolic().nnz_l());
            break;
        }
    }
    let exact = needed.expect("a cut adds fill") - 1;
    let e = refused_cut(
        "liver-lobe",
        SceneCapacities {
            factor_entries: Some(exact),
            ..scene.file.capacities.clone()
        },
    );
    assert!(
        matches!(
            e,
            Error::Capacity {
                resource: Resource::FactorEntries,
                ..
            }
        ),
        "{e}"
    );
}
