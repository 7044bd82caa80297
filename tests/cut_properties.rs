//! Property test of cutting (issue 10): random meshes cut along random planes and polylines —
//! through the whole object, partial cuts that stop inside an element, internal slits, cuts
//! through nodes, along edges and faces, nearly tangent to the boundary, bent polylines, a
//! second cut that continues a first, and a line cut again whole after its first vertices moved
//! (as each cut event cuts the detected line) — with capacities that sometimes cannot hold the
//! cut.
//!
//! After every cut: each element positive and above the quality floor, the boundary closed and
//! manifold and outward, every feature and target in its tetrahedron and on its own side, the
//! target's material point where it was (up to snapping), the factor in service equal to
//! faer's solution of the new matrix, the material joined beyond the end of a partial cut.
//! A refused cut leaves the model's fingerprint unchanged.

use incise::render::silhouette;
use incise::storage::{ModelStorage, SceneCapacities};
use incise_core::cut::SNAP_TOLERANCE;
use incise_core::nalgebra::{Matrix3, Rotation3, Vector3};
use incise_core::{
    Camera, Coupling, DetectionConfig, Intrinsics, Law, Material, MeshInput, Model, ModelConfig,
    Observation, SolverConfig, Strategy as Linear,
};
use incise_validation::cutcheck::{
    check_embeddings, check_factor, check_feature_sides, check_mesh, check_targets_stay,
    components, longest_edge, quality_floor,
};
use incise_validation::rng::Rng;
use incise_validation::testmesh::{box_mesh, signed_volume};
use proptest::prelude::*;

/// How the polyline is drawn.
#[derive(Clone, Copy, Debug)]
enum Kind {
    /// A straight line across the whole object.
    Through,
    /// From outside to a point inside.
    Partial,
    /// Both ends inside: a slit that does not reach the boundary.
    Internal,
    /// Through the images of two nodes.
    ThroughNodes,
    /// Through a node along the image of one of its edges.
    AlongEdge,
    /// Nearly along a boundary edge of the silhouette, just inside it.
    NearlyTangent,
    /// Three vertices with a bend of at most 80°.
    Bent,
    /// A partial cut, then its continuation through the rest.
    Progressive,
    /// A partial cut, then the whole line again, as a cut event cuts it once the line has grown:
    /// its first vertices moved across it by up to 15 px (a quarter of the time not at all, so
    /// that part of the surface runs along the faces the first cut separated), then on through
    /// the rest.
    Recut,
}

#[derive(Clone, Debug)]
struct Case {
    cells: [usize; 3],
    size: [f64; 3],
    seed: u64,
    tilt: [f64; 2],
    kind: Kind,
    extension_px: f64,
    /// Room for new nodes and tetrahedra (small values make some cuts overflow).
    room: (usize, usize),
    /// How far interior coordinates move off the box's grid, in cells.
    jitter: f64,
}

fn case() -> impl proptest::strategy::Strategy<Value = Case> {
    (
        (1usize..=4, 1usize..=3, 1usize..=2),
        (0.02f64..0.06, 0.015f64..0.04, 0.004f64..0.015),
        any::<u64>(),
        (-0.25f64..0.25, -0.25f64..0.25),
        prop_oneof![
            Just(Kind::Through),
            Just(Kind::Partial),
            Just(Kind::Internal),
            Just(Kind::ThroughNodes),
            Just(Kind::AlongEdge),
            Just(Kind::NearlyTangent),
            Just(Kind::Bent),
            Just(Kind::Progressive),
            Just(Kind::Recut),
        ],
        0.0f64..30.0,
        prop_oneof![
            3 => Just((2000usize, 8000usize)),
            1 => (0usize..12, 0usize..24),
        ],
    )
        .prop_map(|(c, s, seed, tilt, kind, ext, room)| Case {
            cells: [c.0 + 1, c.1 + 1, c.2],
            size: [s.0, s.1, s.2],
            seed,
            tilt: [tilt.0, tilt.1],
            kind,
            extension_px: ext,
            room,
            jitter: 0.2,
        })
}

struct Setup {
    rest: Vec<[f64; 3]>,
    tets: Vec<[u32; 4]>,
    fixed: Vec<u32>,
    camera: Camera<f64>,
}

/// A jittered box held at `x = 0`, seen from above (tilted a little).
fn setup(c: &Case, rng: &mut Rng) -> Setup {
    let mesh = box_mesh(c.cells, c.size);
    let h = [0, 1, 2].map(|k| c.size[k] / c.cells[k] as f64);
    let mut rest = mesh.nodes.clone();
    for p in rest.iter_mut() {
        for k in 0..3 {
            // Interior coordinates move by up to `jitter` cells; the box stays a box.
            let on_face = p[k].abs() < 1e-12 || (p[k] - c.size[k]).abs() < 1e-12;
            if !on_face {
                p[k] += (rng.uniform() - 0.5) * 2.0 * c.jitter * h[k];
            }
        }
    }
    // Jitter can only spoil a tetrahedron if it flips it: keep the mesh valid.
    let tets: Vec<[u32; 4]> = mesh.tets.clone();
    assert!(tets.iter().all(|&t| signed_volume(&rest, t) > 0.0));
    let fixed: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize][0].abs() < 1e-12)
        .collect();
    let centre = Vector3::new(c.size[0] / 2.0, c.size[1] / 2.0, c.size[2]);
    let tilt = Rotation3::from_euler_angles(c.tilt[0], c.tilt[1], 0.0);
    let eye = centre + tilt * Vector3::new(0.0, 0.0, 0.3);
    let forward = (centre - eye).normalize();
    let right = forward.cross(&Vector3::y()).normalize();
    let down = forward.cross(&right);
    let r = Matrix3::from_rows(&[right.transpose(), down.transpose(), forward.transpose()]);
    let span = c.size[0].max(c.size[1]);
    let camera = Camera::new(
        Intrinsics {
            fx: 400.0 * 0.3 / span,
            fy: 400.0 * 0.3 / span,
            cx: 320.0,
            cy: 240.0,
            width: 640,
            height: 480,
        },
        r,
        -(r * eye),
        1e-4,
    )
    .unwrap();
    Setup {
        rest,
        tets,
        fixed,
        camera,
    }
}

fn project(camera: &Camera<f64>, p: [f64; 3]) -> [f64; 2] {
    let uv = camera.project(&Vector3::from(p), 0).unwrap();
    [uv.x, uv.y]
}

fn lerp2(a: [f64; 2], b: [f64; 2], t: f64) -> [f64; 2] {
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]
}

/// A line through `p` along `d`, reaching `reach` pixels each way.
fn through(p: [f64; 2], d: [f64; 2], reach: f64) -> Vec<[f64; 2]> {
    let n = (d[0] * d[0] + d[1] * d[1]).sqrt().max(1e-12);
    let d = [d[0] / n, d[1] / n];
    vec![
        [p[0] - d[0] * reach, p[1] - d[1] * reach],
        [p[0] + d[0] * reach, p[1] + d[1] * reach],
    ]
}

/// The polylines to cut along, in order.
fn polylines(c: &Case, s: &Setup, rng: &mut Rng) -> Vec<Vec<[f64; 2]>> {
    let img: Vec<[f64; 2]> = s.rest.iter().map(|&p| project(&s.camera, p)).collect();
    let inside_point = |rng: &mut Rng| -> [f64; 2] {
        // A point of the top face's image, well inside.
        let p = [
            c.size[0] * (0.2 + 0.6 * rng.uniform()),
            c.size[1] * (0.2 + 0.6 * rng.uniform()),
            c.size[2],
        ];
        project(&s.camera, p)
    };
    let angle = |rng: &mut Rng| {
        let a = rng.uniform() * std::f64::consts::PI;
        [a.cos(), a.sin()]
    };
    let far = 2000.0;
    match c.kind {
        Kind::Through => vec![through(inside_point(rng), angle(rng), far)],
        Kind::Partial => {
            let p = inside_point(rng);
            let d = angle(rng);
            vec![vec![[p[0] - d[0] * far, p[1] - d[1] * far], p]]
        }
        Kind::Internal => {
            let (a, b) = (inside_point(rng), inside_point(rng));
            vec![vec![a, lerp2(a, b, 0.5)]]
        }
        Kind::ThroughNodes => {
            let a = (rng.uniform() * img.len() as f64) as usize % img.len();
            let mut b = (rng.uniform() * img.len() as f64) as usize % img.len();
            if (img[a][0] - img[b][0]).hypot(img[a][1] - img[b][1]) < 1e-6 {
                b = (a + 1) % img.len();
            }
            let d = [img[b][0] - img[a][0], img[b][1] - img[a][1]];
            vec![through(img[a], d, far)]
        }
        Kind::AlongEdge => {
            let t = s.tets[(rng.uniform() * s.tets.len() as f64) as usize % s.tets.len()];
            let (a, b) = (img[t[0] as usize], img[t[1] as usize]);
            vec![through(a, [b[0] - a[0], b[1] - a[1]], far)]
        }
        Kind::NearlyTangent => {
            // Along the image of the top face's edge y = 0, a hair inside.
            let (a, b) = (
                project(&s.camera, [0.0, 0.0, c.size[2]]),
                project(&s.camera, [c.size[0], 0.0, c.size[2]]),
            );
            let inward = project(&s.camera, [0.0, c.size[1], c.size[2]]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let n = [inward[0] - a[0], inward[1] - a[1]];
            let nl = n[0].hypot(n[1]);
            let off = 1e-3 + 2.0 * rng.uniform();
            let tilt = 1e-3 * (rng.uniform() - 0.5);
            let p = [a[0] + n[0] / nl * off, a[1] + n[1] / nl * off];
            vec![through(p, [d[0] - d[1] * tilt, d[1] + d[0] * tilt], far)]
        }
        Kind::Bent => {
            // A turn of at most 80 degrees, as a cut line's fronts make (they turn by at most
            // the angle α per step).
            let p = inside_point(rng);
            let d1 = angle(rng);
            let turn = (rng.uniform() - 0.5) * 160f64.to_radians();
            let d2 = [
                d1[0] * turn.cos() - d1[1] * turn.sin(),
                d1[0] * turn.sin() + d1[1] * turn.cos(),
            ];
            vec![vec![
                [p[0] - d1[0] * far, p[1] - d1[1] * far],
                p,
                [p[0] + d2[0] * far, p[1] + d2[1] * far],
            ]]
        }
        Kind::Progressive => {
            let (a, b) = (inside_point(rng), inside_point(rng));
            let d = [b[0] - a[0], b[1] - a[1]];
            let start = [a[0] - d[0] * 50.0, a[1] - d[1] * 50.0];
            vec![
                vec![start, a],
                vec![a, b],
                vec![b, [b[0] + d[0] * 50.0, b[1] + d[1] * 50.0]],
            ]
        }
        Kind::Recut => {
            let (a, b) = (inside_point(rng), inside_point(rng));
            let d = [b[0] - a[0], b[1] - a[1]];
            let start = [a[0] - d[0] * 50.0, a[1] - d[1] * 50.0];
            let l = d[0].hypot(d[1]).max(1e-12);
            let across = [-d[1] / l, d[0] / l];
            let shift = if rng.uniform() < 0.25 {
                0.0
            } else {
                (rng.uniform() - 0.5) * 30.0
            };
            let moved = |p: [f64; 2]| [p[0] + across[0] * shift, p[1] + across[1] * shift];
            let end = [b[0] + d[0] * 50.0, b[1] + d[1] * 50.0];
            vec![vec![start, a], vec![moved(start), moved(a), end]]
        }
    }
}

/// What the cuts of one case did.
#[derive(Default)]
struct Outcome {
    applied: usize,
    refused: usize,
}

/// The model's settings in every case: a soft solid, springs, no depth prior.
fn model_config(camera: Camera<f64>) -> ModelConfig<f64> {
    ModelConfig {
        material: Material {
            young: 3.0e4,
            poisson: 0.4,
            inversion_barrier: true,
            law: Law::SaintVenantKirchhoff,
        },
        camera,
        solver: SolverConfig {
            strategy: Linear::Refactor,
            newton_iterations: 1,
            line_search_steps: 2,
            coupling: Coupling::Stiffness(1e-6),
            spring_threshold: f64::INFINITY,
            damping: 0.01,
            depth_prior: 0.0,
            image_margin: 50.0,
        },
        detection: DetectionConfig::paper(),
    }
}

fn run(c: &Case) -> Result<Outcome, TestCaseError> {
    let mut rng = Rng::new(c.seed);
    let s = setup(c, &mut rng);
    let input = MeshInput {
        rest: &s.rest,
        tets: &s.tets,
        fixed: &s.fixed,
    };
    let config = model_config(s.camera);
    let mut storage = ModelStorage::new(
        &input,
        &SceneCapacities {
            features: 64,
            targets: 16,
            cut_nodes: c.room.0,
            cut_tets: c.room.1,
            ..SceneCapacities::default()
        },
    )
    .unwrap();
    let mut model: Model<'_, f64> = storage.model(&input, &config).unwrap();
    // Features on the top face, targets inside.
    let mut frame0 = vec![];
    for k in 0..36 {
        let p = [
            c.size[0] * (0.05 + 0.9 * ((k % 6) as f64 + rng.uniform()) / 6.0),
            c.size[1] * (0.05 + 0.9 * ((k / 6) as f64 + rng.uniform()) / 6.0),
            c.size[2],
        ];
        frame0.push(Observation {
            id: k,
            uv: project(&s.camera, p),
        });
    }
    model.embed_features(&frame0).unwrap();
    let targets: Vec<[f64; 3]> = (0..16)
        .map(|_| [0, 1, 2].map(|k| c.size[k] * (0.05 + 0.9 * rng.uniform())))
        .collect();
    model.embed_targets(&targets).unwrap();

    let floor = quality_floor(&s.rest, &s.tets);
    let edge = longest_edge(&s.rest, &s.tets);
    let px_per_m = config.camera.intrinsics().fx / 0.3;
    let margin = SNAP_TOLERANCE * edge * px_per_m * 1.5 + 2.0;
    let mask = silhouette(&s.camera, &s.rest, model.mesh().surface());
    let inside = |p: [f64; 2]| {
        p[0] >= 0.0
            && p[1] >= 0.0
            && p[0] < 640.0
            && p[1] < 480.0
            && mask.get(p[0] as u32, p[1] as u32)
    };
    let lines = polylines(c, &s, &mut rng);
    let mut outcome = Outcome::default();
    for line in &lines {
        let before = model.fingerprint();
        match model.cut_along(line, c.extension_px) {
            Err(e) => {
                prop_assert_eq!(model.fingerprint(), before, "refused ({}) but changed", e);
                // Only the room reserved for the cut may run out: a surface that would leave
                // a non-manifold boundary is kept joined there instead of refused.
                prop_assert!(
                    matches!(e, incise_core::Error::Capacity { .. }),
                    "refused with {}",
                    e
                );
                outcome.refused += 1;
                return Ok(outcome);
            }
            Ok(report) if !report.applied => {
                prop_assert_eq!(model.fingerprint(), before, "nothing cut but changed");
            }
            Ok(report) => {
                outcome.applied += 1;
                let at = |e: String| TestCaseError::fail(format!("{:?}: {e}", report.event));
                check_mesh(model.mesh(), floor).map_err(at)?;
                check_embeddings(&model).map_err(at)?;
                check_targets_stay(&model, &targets, SNAP_TOLERANCE * edge * 1.01).map_err(at)?;
                check_feature_sides(&model, line, margin).map_err(at)?;
                check_factor(&mut model, 1e-7).map_err(at)?;
            }
        }
    }
    if outcome.applied == 0 {
        return Ok(outcome);
    }
    // A straight cut through the object leaves two pieces; a cut that stops inside leaves the
    // material joined beyond its end — at the resolution of the mesh: a cut face is cut when
    // its centre lies beside the line, so the cut may reach an element beyond the end (which
    // is extended by up to the extension). So the material around the extended end, within an
    // element's reach, must be there for the cut to be partial.
    let pieces = components(model.mesh().tets());
    let element_px = edge * px_per_m;
    let ends_inside = |line: &[[f64; 2]]| {
        let m = line.len();
        [(line[0], line[1]), (line[m - 1], line[m - 2])]
            .into_iter()
            .any(|(end, next)| {
                let d = [end[0] - next[0], end[1] - next[1]];
                let l = d[0].hypot(d[1]);
                let tip = [
                    end[0] + d[0] / l * c.extension_px,
                    end[1] + d[1] / l * c.extension_px,
                ];
                (0..16).all(|k| {
                    let a = k as f64 * std::f64::consts::PI / 8.0;
                    inside([tip[0] + element_px * a.cos(), tip[1] + element_px * a.sin()])
                }) && inside(end)
            })
    };
    // (A cut through can leave more than two pieces: a plane that grazes a face cuts off a
    // wedge thinner than an element, which the quality floor may leave in fragments.)
    if matches!(c.kind, Kind::Partial | Kind::Internal) && ends_inside(&lines[0]) {
        prop_assert_eq!(pieces, 1, "a partial cut split the object");
    }
    Ok(outcome)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn random_cuts_keep_every_invariant(c in case()) {
        run(&c)?;
    }
}

/// The property above is not vacuous: most generated cases do cut, some are refused, and some
/// lines cut again whole change the mesh a second time.
#[test]
fn most_random_cases_cut_and_some_overflow() {
    use proptest::strategy::{Strategy as _, ValueTree};
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let (mut applied, mut refused, mut recut, cases) = (0, 0, 0, 200);
    for _ in 0..cases {
        let c = case().new_tree(&mut runner).unwrap().current();
        let outcome = run(&c).unwrap_or_else(|e| panic!("{c:?}: {e}"));
        applied += usize::from(outcome.applied > 0);
        refused += outcome.refused;
        recut += usize::from(matches!(c.kind, Kind::Recut) && outcome.applied == 2);
    }
    eprintln!("{applied} of {cases} cases cut, {refused} refused, {recut} lines cut again");
    assert!(applied >= cases / 2, "{applied} of {cases} cases cut");
    assert!(refused >= 5, "{refused} refused");
    assert!(recut >= 3, "{recut} lines cut again");
}

/// The slab of the tests below: 10 × 4 elements of 1 cm, one element (6 mm) thick, held at
/// `x = 0` and seen from 0.3 m above its centre (`Case::size`).
const SLAB: [f64; 3] = [0.1, 0.04, 0.006];

/// What cutting [`SLAB`] from beyond its side `y = 0` to `(x, tip)` on its top face does: the
/// `(x, y)` of the nodes the cut duplicated on its top face and on its bottom face (each copy
/// once), the pieces left, and the rest volume of the cut mesh.
fn cut_slab(x: f64, tip: f64) -> (Vec<[f64; 2]>, Vec<[f64; 2]>, usize, f64) {
    let case = Case {
        cells: [10, 4, 1],
        size: SLAB,
        seed: 1,
        tilt: [0.0, 0.0],
        kind: Kind::Partial,
        extension_px: 0.0,
        room: (2000, 8000),
        jitter: 0.0,
    };
    let s = setup(&case, &mut Rng::new(1));
    let input = MeshInput {
        rest: &s.rest,
        tets: &s.tets,
        fixed: &s.fixed,
    };
    let mut storage = ModelStorage::new(&input, &SceneCapacities::default()).unwrap();
    let mut model: Model<'_, f64> = storage.model(&input, &model_config(s.camera)).unwrap();
    let line = [
        project(&s.camera, [x, -0.01, SLAB[2]]),
        project(&s.camera, [x, tip, SLAB[2]]),
    ];
    let report = model.cut_along(&line, 0.0).unwrap();
    assert!(report.applied, "x {x}, tip {tip}: nothing cut");
    let rest = model.mesh().rest();
    let duplicated_on = |z: f64| -> Vec<[f64; 2]> {
        let on_face: Vec<&[f64; 3]> = rest.iter().filter(|p| (p[2] - z).abs() < 1e-12).collect();
        on_face
            .iter()
            .enumerate()
            .filter(|(i, p)| {
                on_face
                    .iter()
                    .take(*i)
                    .any(|q| (0..3).all(|k| p[k] == q[k]))
            })
            .map(|(_, p)| [p[0], p[1]])
            .collect()
    };
    let pieces = components(model.mesh().tets());
    let volume = model
        .mesh()
        .tets()
        .iter()
        .map(|t| {
            let [a, b, c, d] = t.map(|v| rest[v as usize]);
            let e = |p: [f64; 3]| [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
            let (u, v, w) = (e(b), e(c), e(d));
            (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
                + u[2] * (v[0] * w[1] - v[1] * w[0]))
                .abs()
                / 6.0
        })
        .sum();
    (duplicated_on(SLAB[2]), duplicated_on(0.0), pieces, volume)
}

/// Whether every point of `a` has one of `b` within 1 mm: the separation surface follows the
/// camera rays, within 0.6 mm of the vertical over the slab's thickness along these lines.
fn above(a: &[[f64; 2]], b: &[[f64; 2]]) -> bool {
    a.iter()
        .all(|p| b.iter().any(|q| (p[0] - q[0]).hypot(p[1] - q[1]) < 1.0e-3))
}

/// A cut that ends inside a slab one element thick ends straight through the thickness: the
/// crack front (the duplicated nodes farthest along the cut) is at the same place on the top
/// and the bottom face, whichever way the line's end meets the mesh (between node rows, on one,
/// just before or past one; beside the nodes or through them), and the material beyond the end
/// stays joined. When the faces reaching past the surface's extent to nodes declared on the
/// end's plane were left joined (before 59e7c5c), the crack front ran slanted through the
/// thickness, its bottom node a row short of its top one, and held the lips together there.
/// Through the nodes every duplicated node has its counterpart on the other face.
#[test]
fn a_partial_cut_through_a_thin_slab_ends_straight_through_its_thickness() {
    let front = |nodes: &[[f64; 2]]| nodes.iter().fold(f64::NEG_INFINITY, |m, p| m.max(p[1]));
    for x in [0.0513, 0.05] {
        for tip in [0.0195, 0.02, 0.0205, 0.025] {
            let (top, bottom, pieces, _) = cut_slab(x, tip);
            let at =
                format!("x {x}, tip {tip}: duplicated on top {top:?}, on the bottom {bottom:?}");
            assert!(!top.is_empty() && !bottom.is_empty(), "{at}");
            assert!((front(&top) - front(&bottom)).abs() < 1.0e-3, "{at}");
            // The front stops at the last node row before the tip, or the row before it where
            // the tip is too close past a row to split there (a node declared on the end's
            // plane keeps the material beyond it joined): never a row and a half short.
            assert!(front(&top) < tip && front(&top) > tip - 0.015, "{at}");
            assert_eq!(pieces, 1, "{at}: a partial cut split the slab");
            if x == 0.05 {
                assert!(above(&top, &bottom) && above(&bottom, &top), "{at}");
            }
        }
    }
}

/// Known defect, left open: a cut that enters the slab beside its nodes should snap the rim
/// nodes where it enters along the rims, so that the slab keeps its shape (its volume, to
/// rounding) and the entry corner comes apart on both faces. Snapping lets a boundary node
/// slide along any boundary edge, so the bottom rim node slides up the diagonal of the side
/// face instead: it is duplicated, but 0.8 mm above the bottom face, and a sliver is taken off
/// the slab. The fix (branch `lead/crease-snapping`: no sliding across a crease of the surface)
/// passes this test but costs `band-middle-cut` its detected-cut Dice (0.974 → 0.963).
#[test]
#[ignore = "known defect: a rim node snapped where a cut enters slides off the rim"]
fn a_cut_beside_the_nodes_keeps_the_rims_where_it_enters() {
    let slab = SLAB[0] * SLAB[1] * SLAB[2];
    for tip in [0.0195, 0.025] {
        let (top, bottom, _, volume) = cut_slab(0.0513, tip);
        let at = format!("tip {tip}: duplicated on top {top:?}, on the bottom {bottom:?}");
        assert!(above(&top, &bottom) && above(&bottom, &top), "{at}");
        assert!(
            (volume - slab).abs() < 1.0e-12 * slab,
            "{at}: volume {volume}, slab {slab}"
        );
    }
}
