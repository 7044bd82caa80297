//! Cut detection on the committed scenes (paper §2.2–2.3): the cut scenes are detected soon
//! after their slit opens and the detected line lies on the true one; the scenes without a cut
//! are never cut; the separation surface is the line extruded along the camera rays.

use std::path::{Path, PathBuf};

use incise::run::{RunOptions, run_scene};
use incise::scene::Scene;
use incise::storage::ModelStorage;
use incise_core::nalgebra::Vector3;
use incise_core::{MeshInput, Observation};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures")
}

fn load(name: &str) -> Scene {
    Scene::load(&fixtures().join(name)).unwrap_or_else(|e| panic!("{e}"))
}

/// Prints what detection did on a cut scene and checks that the cut was detected within five
/// frames of its opening (and not before).
fn assert_detected_in_time(name: &str, s: &incise::run::Summary) -> f64 {
    let open = s.cut_open_frame.expect("the scene has a cut");
    let detected = s
        .cut_detected_frame
        .unwrap_or_else(|| panic!("{name}: no cut detected"));
    let diagonal = f64::from(s.image_width).hypot(f64::from(s.image_height));
    let hausdorff = s.cut_hausdorff_px.expect("a final polyline");
    eprintln!(
        "{name}: opens {open}, detected {detected}, Hausdorff {hausdorff:.1} px ({:.1}% of the diagonal), {} pairs, {} lost, {} cut events",
        100.0 * hausdorff / diagonal,
        s.pairs,
        s.pairs_lost,
        s.cut_events
    );
    assert!(
        detected >= open.saturating_sub(1),
        "{name}: detected before the cut opened"
    );
    assert!(
        detected <= open + 5,
        "{name}: detected at {detected}, cut opens at {open}"
    );
    hausdorff / diagonal
}

#[test]
fn cuts_are_detected_within_five_frames_and_on_the_true_line() {
    // The side cut: the final line lies within 3% of the image diagonal of the true one, with
    // the mesh cut as the line grows and with the detector on its own (no room reserved for a
    // cut: every cut is refused, the mesh stays whole and detection goes on).
    let side = load("band-side-cut");
    let (s, _) = run_scene(&side, &RunOptions::default()).unwrap();
    assert!(s.cut_events >= 1, "{s:?}");
    let off = assert_detected_in_time("band-side-cut", &s);
    assert!(
        off <= 0.03,
        "band-side-cut: line {:.1}% of the diagonal off",
        100.0 * off
    );
    let mut whole = side.clone();
    whole.file.capacities.cut_nodes = 0;
    whole.file.capacities.cut_tets = 0;
    let (s, _) = run_scene(&whole, &RunOptions::default()).unwrap();
    assert_eq!(s.cut_events, 0, "no room, no cut");
    assert!(s.cut_refused.is_some(), "the cut is refused");
    let off = assert_detected_in_time("band-side-cut (mesh left whole)", &s);
    assert!(
        off <= 0.03,
        "band-side-cut: line {:.1}% of the diagonal off",
        100.0 * off
    );
    // The middle cut opens into a wide eye: detected in time, but with the detector's
    // defaults the line's lower part bends beside the true slit (about 5% of the diagonal; see
    // the README's detection section), so only its timing is checked here.
    let (s, _) = run_scene(&load("band-middle-cut"), &RunOptions::default()).unwrap();
    assert!(s.cut_events >= 1, "{s:?}");
    assert_detected_in_time("band-middle-cut", &s);
}

#[test]
fn scenes_without_a_cut_are_never_cut() {
    // band-no-cut: the same motion as the side cut; band-stiff: a model that lags everywhere;
    // block-extreme: large compression, noise doubled (0.6 px) and 5% jumping features.
    for name in ["band-no-cut", "band-stiff", "block-extreme"] {
        let scene = load(name);
        let (s, trace) = run_scene(&scene, &RunOptions::default()).unwrap();
        assert_eq!(s.cut_detected_frame, None, "{name}");
        assert!(trace.frames.iter().all(|r| r.cut_vertices == 0), "{name}");
        eprintln!(
            "{name}: no cut; {} pairs, {} lost, {} features filtered",
            s.pairs, s.pairs_lost, s.features_filtered
        );
    }
    // The jumping features of block-extreme (the generator's list, `gt/outliers.csv`) are
    // caught by the temporal filter.
    let (s, _) = run_scene(&load("block-extreme"), &RunOptions::default()).unwrap();
    let truth = s
        .filter_truth
        .expect("block-extreme lists its jumping features");
    assert!(truth.outliers_filtered >= 5, "{truth:?}");
}

#[test]
fn the_listed_outliers_jump_in_the_tracks_and_the_filter_is_measured_against_them() {
    for name in ["band-middle-cut", "block-extreme", "liver-lobe"] {
        let scene = load(name);
        let text = std::fs::read_to_string(scene.dir.join("gt").join("outliers.csv")).unwrap();
        let outliers = incise::scene::read_outliers_csv(&text, Path::new("outliers.csv")).unwrap();
        assert!(!outliers.is_empty(), "{name}");
        // Each listed feature, seen the frame before its jump and the frame of it, moves by
        // its jump beside its neighbours (within 40 px at the frame before): its displacement
        // minus their median displacement is the jump, give or take the noise and the
        // motion's variation over that neighbourhood.
        let mut checked = 0;
        for o in &outliers {
            let (Some(before), Some(at)) = (
                scene.frames.get(o.start as usize - 1),
                scene.frames.get(o.start as usize),
            ) else {
                continue;
            };
            let find =
                |obs: &[Observation<f64>], id: u32| obs.iter().find(|x| x.id == id).map(|x| x.uv);
            let (Some(a), Some(b)) = (find(before, o.id), find(at, o.id)) else {
                continue;
            };
            let mut du = vec![];
            let mut dv = vec![];
            for x in before {
                let near = (x.uv[0] - a[0]).hypot(x.uv[1] - a[1]) < 40.0;
                if x.id != o.id
                    && near
                    && !outliers.iter().any(|p| p.id == x.id)
                    && let Some(y) = find(at, x.id)
                {
                    du.push(y[0] - x.uv[0]);
                    dv.push(y[1] - x.uv[1]);
                }
            }
            let median = |v: &mut Vec<f64>| {
                v.sort_by(f64::total_cmp);
                v[v.len() / 2]
            };
            assert!(du.len() >= 3, "{name}: feature {} has no neighbours", o.id);
            let moved = [b[0] - a[0] - median(&mut du), b[1] - a[1] - median(&mut dv)];
            let off = (moved[0] - o.jump[0]).hypot(moved[1] - o.jump[1]);
            let jump = o.jump[0].hypot(o.jump[1]);
            assert!(
                off < 0.25 * jump,
                "{name}: feature {} moved {moved:?} beside its neighbours, listed {:?}",
                o.id,
                o.jump
            );
            checked += 1;
        }
        assert!(checked >= 1, "{name}: no listed jump was seen");
        // Every feature the filter took out is either a listed jump or a genuine feature.
        let (s, _) = run_scene(&scene, &RunOptions::default()).unwrap();
        let truth = s
            .filter_truth
            .expect("the scene lists its jumping features");
        assert_eq!(s.filtered_features.len(), s.features_filtered, "{name}");
        assert_eq!(
            truth.outliers_filtered + truth.genuine_filtered,
            s.features_filtered,
            "{name}: {truth:?}"
        );
        assert!(
            truth.outliers_filtered <= truth.outliers,
            "{name}: {truth:?}"
        );
        eprintln!("{name}: {truth:?}");
    }
}

#[test]
fn the_separation_surface_is_the_line_extruded_along_the_camera_rays() {
    let scene = load("band-side-cut");
    let config = scene.model_config().unwrap();
    let camera = config.camera;
    let input = MeshInput {
        rest: &scene.rest,
        tets: &scene.tets,
        fixed: &scene.file.model.fixed,
    };
    let mut storage = ModelStorage::new(&input, &scene.file.capacities).unwrap();
    let mut model = storage.model(&input, &config).unwrap();
    model.embed_features(&scene.frames[0]).unwrap();
    for frame in &scene.frames[1..] {
        let known: Vec<Observation<f64>> = frame
            .iter()
            .copied()
            .filter(|o| model.features().slot_of(o.id).is_some())
            .collect();
        model.step(&known).unwrap();
    }
    let mut line = [[0.0; 2]; 64];
    let n = model.cut_polyline(&mut line).unwrap();
    assert!(n >= 2);
    let mut quads = [[[0.0; 3]; 4]; 64];
    let m = model.separation_surface(&mut quads).unwrap();
    // No silent truncation: a buffer one short is refused whole.
    assert!(matches!(
        model.cut_polyline(&mut line[..n - 1]),
        Err(incise_core::Error::Capacity {
            resource: incise_core::Resource::CutVertices,
            ..
        })
    ));
    assert!(matches!(
        model.separation_surface(&mut quads[..m - 1]),
        Err(incise_core::Error::Capacity {
            resource: incise_core::Resource::CutSegments,
            ..
        })
    ));
    assert_eq!(m, n - 1, "one quad per segment");
    let view = camera.view_direction();
    let centre = *camera.centre();
    let depths: Vec<f64> = model
        .positions()
        .iter()
        .map(|p| (Vector3::from(*p) - centre).dot(&view))
        .collect();
    let near = depths.iter().copied().fold(f64::INFINITY, f64::min);
    let far = depths.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    for (k, q) in quads[..m].iter().enumerate() {
        // Corners 0 and 3 lie on the ray through vertex k, corners 1 and 2 on the ray through
        // vertex k + 1, at the model's nearest and farthest depth along the view.
        for (corner, vertex, depth) in
            [(0, k, near), (1, k + 1, near), (2, k + 1, far), (3, k, far)]
        {
            let p = Vector3::from(q[corner]);
            let uv = camera.project(&p, 0).unwrap();
            let v = line[vertex];
            assert!(
                (uv.x - v[0]).hypot(uv.y - v[1]) < 1e-6,
                "quad {k} corner {corner} projects to {uv}, not to vertex {v:?}"
            );
            assert!(((p - centre).dot(&view) - depth).abs() < 1e-9);
        }
    }
}

#[test]
fn detection_work_stays_within_its_formula_on_every_frame() {
    // The detector's and the cut line's work per frame, counted as they run, against the
    // formula in the capacities: on the scenes that start and grow a line (the robust fit is
    // the largest single cost) and on one with many tracking failures.
    for name in ["band-side-cut", "band-middle-cut", "block-extreme"] {
        let scene = load(name);
        let config = scene.model_config().unwrap();
        let input = MeshInput {
            rest: &scene.rest,
            tets: &scene.tets,
            fixed: &scene.file.model.fixed,
        };
        let mut storage = ModelStorage::new(&input, &scene.file.capacities).unwrap();
        let mut model = storage.model(&input, &config).unwrap();
        model.embed_features(&scene.frames[0]).unwrap();
        let (detect_bound, line_bound) = model.worst_case_detection_work();
        let (mut started, mut most) = (false, 0u64);
        for (f, frame) in scene.frames.iter().enumerate().skip(1) {
            let known: Vec<Observation<f64>> = frame
                .iter()
                .copied()
                .filter(|o| model.features().slot_of(o.id).is_some())
                .collect();
            let report = model.step(&known).unwrap();
            let (d, l) = (report.detection.work, report.cut_line.work);
            assert!(
                d.within(&detect_bound),
                "{name} frame {f}: {d:?} > {detect_bound:?}"
            );
            assert!(
                l.within(&line_bound),
                "{name} frame {f}: {l:?} > {line_bound:?}"
            );
            assert!(
                d.pair_visits > 0 && d.selection_steps > 0,
                "{name}: work is counted"
            );
            started |= l.fit_tests > 0;
            most = most.max(d.selection_steps);
        }
        eprintln!(
            "{name}: most selection steps {most} of {} allowed; line started: {started}",
            detect_bound.selection_steps
        );
        if name != "block-extreme" {
            assert!(started, "{name}: the line's start was counted");
        }
    }
}
