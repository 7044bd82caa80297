//! `incise codegen`: one scene as a Rust module for a firmware build.
//!
//! The module holds the scene as `static` and `const` data (rest positions, tetrahedra, fixed
//! nodes, camera, solver and detection settings, capacities and the buffer lengths that follow
//! from them as compile-time constants, the uncut mesh's ordering and symbolic analysis, and a
//! few frames of tracks), so the device builds its model with
//! [`incise_core::Model::from_precomputed`] and does no ordering or analysis at start-up.
//! `firmware/` is the `#![no_std]` program that includes it; [`footprint`] builds that program
//! and measures it.
//!
//! Nothing is written unless the whole scene checks out: the model is built from the scene in
//! the host first (the core refuses a bad mesh or capacities with its own words), and the file
//! is written to a temporary name and renamed.

pub mod footprint;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use incise_core::mesh::MeshCapacity;
use incise_core::sparse::PrecomputedAnalysis;
use incise_core::{
    Capacities, Coupling, ModelConfig, ModelSize, Observation, Projection, StoragePart, Strategy,
    WorkCount,
};

use crate::scene::Scene;
use crate::storage::{ModelStorage, SceneCapacities};

/// What `incise codegen` is asked for.
#[derive(Clone, Debug)]
pub struct CodegenOptions {
    /// Frames of tracks included (frame 0, where the features are placed, and the next ones);
    /// at most the scene's.
    pub frames: usize,
}

impl Default for CodegenOptions {
    fn default() -> Self {
        CodegenOptions { frames: 5 }
    }
}

/// A scene ready to be written as a module.
#[derive(Clone, Debug)]
pub struct Generated {
    /// The scene's name.
    pub name: String,
    /// The capacities the module sizes its buffers for in a build with the `cut` feature:
    /// the scene's, with its cut room.
    pub capacities: Capacities,
    /// The capacities of a build with the `detect` feature and without `cut`: exactly the
    /// uncut mesh and its factor, the features of frame 0, and the scene's room for the
    /// detection's pairs and the cut line.
    pub detect_capacities: Capacities,
    /// The capacities of a build with neither: no room for detection either.
    pub register_capacities: Capacities,
    /// The module's source.
    pub source: String,
    /// Frames of tracks it holds.
    pub frames: usize,
    /// The worst-case work of one steady frame of the uncut model with the features of frame 0
    /// placed ([`incise_core::Model::worst_case_work`]).
    pub worst_case: WorkCount,
    /// Whether the scene's detection is on, so its firmware needs the `cut` feature.
    pub needs_cut: bool,
    /// The scene's linear strategy.
    pub strategy: Strategy,
    /// The scene's camera projection.
    pub projection: Projection,
    /// The model's strain energy law: a firmware build of a scene on the stable Neo-Hookean
    /// law needs the core's `neo-hookean` feature ([`footprint::build`] adds it).
    pub law: incise_core::Law,
}

/// Why `incise codegen` refused a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct CodegenError(pub String);

impl std::fmt::Display for CodegenError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for CodegenError {}

/// The capacities of a firmware build of `scene`: the scene's own (`[capacities]`, the mesh's
/// nodes and tetrahedra plus the cut room it asks for), with room for exactly the features
/// tracked at frame 0, the only ones a model can place.
///
/// # Errors
/// The scene's capacities or mesh refused, in the host's words.
pub fn firmware_capacities(scene: &Scene) -> Result<SceneCapacities, CodegenError> {
    let tracked = scene.frames.first().map_or(0, Vec::len);
    if tracked == 0 {
        return Err(CodegenError(format!(
            "{}: no feature is tracked at frame 0, so the model would carry none",
            scene.dir.join("tracks.csv").display()
        )));
    }
    Ok(SceneCapacities {
        features: tracked.min(scene.file.capacities.features),
        ..scene.file.capacities.clone()
    })
}

/// Builds `scene`'s model in the host (which checks the mesh, the settings and the
/// capacities), takes its symbolic analysis, and writes the module's source.
///
/// # Errors
/// A message naming what is wrong: the capacities, the mesh or settings the core refuses, or
/// frames asked beyond the scene's.
pub fn generate(scene: &Scene, options: &CodegenOptions) -> Result<Generated, CodegenError> {
    let name = scene.file.name.clone();
    let fail = |what: &str, e: &dyn std::fmt::Display| {
        CodegenError(format!("{}: {what}: {e}", scene.dir.display()))
    };
    if options.frames == 0 || options.frames > scene.frames.len() {
        return Err(CodegenError(format!(
            "--frames {}: the scene has {} frames (at least frame 0 is needed)",
            options.frames,
            scene.frames.len()
        )));
    }
    let config = scene
        .model_config()
        .map_err(|e| CodegenError(e.to_string()))?;
    let input = scene.mesh_input();
    let caps = firmware_capacities(scene)?;
    let mut storage =
        ModelStorage::<f64>::new(&input, &caps).map_err(|e| fail("capacities", &e))?;
    let capacities = *storage.size().capacities();
    let mut model = storage
        .model(&input, &config)
        .map_err(|e| fail("the model cannot be built", &e))?;
    model
        .embed_features(&scene.frames[0])
        .map_err(|e| fail("the features of frame 0 cannot be placed", &e))?;
    let worst_case = model.worst_case_work();
    let analysis = model.symbolic().precomputed();
    let mesh = model.mesh();
    let detect_capacities = Capacities {
        mesh: MeshCapacity {
            nodes: mesh.n_nodes(),
            tets: mesh.n_tets(),
            surface_triangles: mesh.surface().len(),
        },
        factor_entries: analysis.size.nnz_l,
        ..capacities
    };
    let register_capacities = Capacities {
        pairs: 0,
        cut_vertices: 0,
        ..detect_capacities
    };
    let mut s = String::new();
    emit(
        &mut s,
        &Emit {
            scene,
            config: &config,
            capacities: &capacities,
            detect_capacities: &detect_capacities,
            register_capacities: &register_capacities,
            analysis: &analysis,
            frames: &scene.frames[..options.frames],
        },
    );
    Ok(Generated {
        name,
        capacities,
        detect_capacities,
        register_capacities,
        source: s,
        frames: options.frames,
        worst_case,
        needs_cut: config.detection.enabled,
        strategy: config.solver.strategy,
        projection: config.camera.projection(),
        law: config.material.law,
    })
}

/// Writes `generated` to `out`: to a temporary file beside it, then renamed, so a failure
/// leaves no partial module.
///
/// # Errors
/// The file system's error, naming the path.
pub fn write(generated: &Generated, out: &Path) -> Result<(), CodegenError> {
    // A module that is already there as it would be written is left alone, its time stamp
    // too: a firmware build that includes it (`footprint::build`) is then still fresh.
    if std::fs::read(out).is_ok_and(|old| old == generated.source.as_bytes()) {
        return Ok(());
    }
    let tmp: PathBuf = out.with_extension("rs.tmp");
    let fail = |p: &Path, e: std::io::Error| CodegenError(format!("{}: {e}", p.display()));
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| fail(parent, e))?;
    }
    std::fs::write(&tmp, &generated.source).map_err(|e| fail(&tmp, e))?;
    std::fs::rename(&tmp, out).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        fail(out, e)
    })
}

struct Emit<'e> {
    scene: &'e Scene,
    config: &'e ModelConfig<f64>,
    capacities: &'e Capacities,
    detect_capacities: &'e Capacities,
    register_capacities: &'e Capacities,
    analysis: &'e PrecomputedAnalysis<'e>,
    frames: &'e [Vec<Observation<f64>>],
}

/// `{:?}` of an `f64` is the shortest decimal that reads back to the same bits, and a valid
/// Rust literal for every finite value (the scene was checked finite).
fn real(x: f64) -> String {
    format!("{x:?}")
}

fn u32_array(s: &mut String, name: &str, doc: &str, values: &[u32]) {
    let _ = writeln!(s, "/// {doc}");
    let _ = write!(s, "pub static {name}: [u32; {}] = [", values.len());
    for (k, v) in values.iter().enumerate() {
        if k % 16 == 0 {
            s.push_str("\n    ");
        } else {
            s.push(' ');
        }
        let _ = write!(s, "{v},");
    }
    s.push_str("\n];\n\n");
}

/// `CAPACITIES` for the builds `cfg` selects (the firmware program's features).
fn emit_capacities(s: &mut String, doc: &str, cfg: &str, c: &Capacities) {
    let _ = writeln!(
        s,
        "/// What the model holds at most. {doc}\n\
         #[cfg({cfg})]\n\
         pub const CAPACITIES: Capacities = Capacities {{\n    \
         mesh: MeshCapacity {{\n        nodes: {},\n        tets: {},\n        \
         surface_triangles: {},\n    }},\n    features: {},\n    targets: {},\n    \
         factor_entries: {},\n    pairs: {},\n    cut_vertices: {},\n}};\n",
        c.mesh.nodes,
        c.mesh.tets,
        c.mesh.surface_triangles,
        c.features,
        c.targets,
        c.factor_entries,
        c.pairs,
        c.cut_vertices
    );
}

fn emit(s: &mut String, e: &Emit<'_>) {
    let scene = e.scene;
    let c = e.capacities;
    let _ = writeln!(
        s,
        "// Generated by `incise codegen` from the scene \"{}\" ({}).\n\
         // Do not edit: generate it again from the scene.\n",
        scene.file.name,
        scene.dir.display()
    );
    s.push_str(
        "#[allow(unused_imports)]\n\
         use incise_core::nalgebra::{Matrix3, Vector3};\n\
         #[allow(unused_imports)]\n\
         use incise_core::sparse::{PrecomputedAnalysis, SymbolicSize};\n\
         #[allow(unused_imports)]\n\
         use incise_core::{\n    \
             Camera, Capacities, Coupling, DetectionConfig, Error, Intrinsics, Law, Material, \
             MeshCapacity, MeshInput,\n    ModelConfig, ModelSize, Observation, Projection, SolverConfig, Strategy,\n};\n\n",
    );
    let _ = writeln!(
        s,
        "/// The scene's name.\npub const NAME: &str = {:?};\n",
        scene.file.name
    );
    s.push_str(
        "/// The scalar the model computes in: `f64`, or `f32` in a build with the `f32` feature.\n\
         /// The values below are written as decimals that read back to the scene's `f64` bits,\n\
         /// so an `f32` build rounds each once.\n\
         #[cfg(not(feature = \"f32\"))]\npub type Scalar = f64;\n\
         /// The scalar the model computes in.\n\
         #[cfg(feature = \"f32\")]\npub type Scalar = f32;\n\
         /// The scalar of the factor and its triangular solves: `f32` in a build with the\n\
         /// `mixed` feature (mixed precision, refined on `Scalar` residuals), else `Scalar`.\n\
         #[cfg(feature = \"mixed\")]\npub type FactorScalar = f32;\n\
         /// The scalar of the factor and its triangular solves.\n\
         #[cfg(not(feature = \"mixed\"))]\npub type FactorScalar = Scalar;\n\n",
    );
    emit_capacities(
        s,
        "With the `cut` feature: the mesh plus the cut room the scene asks for, and the\n\
         /// features tracked at frame 0.",
        "feature = \"cut\"",
        c,
    );
    emit_capacities(
        s,
        "With the `detect` feature but not `cut`: the uncut mesh, its factor, the features\n\
         /// tracked at frame 0 and the detection's room; none for cuts.",
        "all(feature = \"detect\", not(feature = \"cut\"))",
        e.detect_capacities,
    );
    emit_capacities(
        s,
        "Without the `detect` feature: the uncut mesh, its factor and the features tracked at\n\
         /// frame 0; no room for cuts or detection.",
        "not(feature = \"detect\")",
        e.register_capacities,
    );
    s.push_str(
        "/// The storage sizes, computed at compile time by the core this module is built with (its\n\
         /// features decide what the storage holds); capacities the core cannot hold stop the build.\n\
         pub const SIZE: ModelSize = match ModelSize::new(&CAPACITIES) {\n    \
         Ok(size) => size,\n    Err(_) => panic!(\"the scene's capacities are too large for the core\"),\n};\n\
         /// Scalars of the model's storage.\n\
         pub const REAL_LEN: usize = SIZE.real_len();\n\
         /// The part of `REAL_LEN` in `Scalar` (all but the factor's).\n\
         pub const MODEL_REAL_LEN: usize = SIZE.model_real_len();\n\
         /// The part of `REAL_LEN` in `FactorScalar`: the factor's values and workspace.\n\
         pub const FACTOR_REAL_LEN: usize = SIZE.factor_real_len();\n\
         /// Indices of the model's storage.\n\
         pub const INDEX_LEN: usize = SIZE.index_len();\n\n",
    );

    // The mesh.
    let _ = writeln!(s, "/// Rest positions of the nodes, metres.");
    let _ = writeln!(
        s,
        "pub static REST: [[Scalar; 3]; {}] = [",
        scene.rest.len()
    );
    for p in &scene.rest {
        let _ = writeln!(s, "    [{}, {}, {}],", real(p[0]), real(p[1]), real(p[2]));
    }
    s.push_str("];\n\n");
    let _ = writeln!(s, "/// Tetrahedra, positively oriented.");
    let _ = writeln!(s, "pub static TETS: [[u32; 4]; {}] = [", scene.tets.len());
    for t in &scene.tets {
        let _ = writeln!(s, "    [{}, {}, {}, {}],", t[0], t[1], t[2], t[3]);
    }
    s.push_str("];\n\n");
    u32_array(s, "FIXED", "Fixed nodes.", &scene.file.model.fixed);
    s.push_str(
        "/// The model mesh as the core takes it.\n\
         pub static MESH: MeshInput<'static, Scalar> = MeshInput {\n    \
         rest: &REST,\n    tets: &TETS,\n    fixed: &FIXED,\n};\n\n",
    );

    // Settings.
    let cfg = e.config;
    let cam = &cfg.camera;
    let i = cam.intrinsics();
    let r = cam.rotation();
    let t = cam.translation();
    let sv = &cfg.solver;
    let projection = cam.projection();
    let strategy = match sv.strategy {
        Strategy::Refactor => "Strategy::Refactor".to_string(),
        Strategy::Frozen { pcg_iterations } => {
            format!("Strategy::Frozen {{ pcg_iterations: {pcg_iterations} }}")
        }
        Strategy::FactorOnce { pcg_iterations } => {
            format!("Strategy::FactorOnce {{ pcg_iterations: {pcg_iterations} }}")
        }
        Strategy::QuasiNewton => "Strategy::QuasiNewton".to_string(),
    };
    let _ = writeln!(
        s,
        "/// Material, camera, solver and detection settings.\n\
         ///\n/// # Errors\n/// None for the generated values, which the host checked; the camera's\n\
         /// constructor checks them again.\n\
         pub fn config() -> Result<ModelConfig<Scalar>, Error> {{\n    \
         let camera = Camera::with_projection(\n        Projection::{projection:?},\n        Intrinsics {{\n            fx: {},\n            fy: {},\n            \
         cx: {},\n            cy: {},\n            width: {},\n            height: {},\n        }},\n        \
         Matrix3::new({}, {}, {}, {}, {}, {}, {}, {}, {}),\n        Vector3::new({}, {}, {}),\n        {},\n    )?;\n    \
         Ok(ModelConfig {{\n        material: Material {{\n            young: {},\n            poisson: {},\n            inversion_barrier: {},\n            law: Law::{:?},\n        }},\n        \
         camera,\n        solver: SolverConfig {{\n            strategy: {strategy},\n            \
         newton_iterations: {},\n            line_search_steps: {},\n            coupling: {},\n            \
         spring_threshold: {},\n            damping: {},\n            depth_prior: {},\n            image_margin: {},\n        }},\n        \
         detection: {:?},\n    }})\n}}\n",
        real(i.fx),
        real(i.fy),
        real(i.cx),
        real(i.cy),
        i.width,
        i.height,
        real(r[(0, 0)]),
        real(r[(0, 1)]),
        real(r[(0, 2)]),
        real(r[(1, 0)]),
        real(r[(1, 1)]),
        real(r[(1, 2)]),
        real(r[(2, 0)]),
        real(r[(2, 1)]),
        real(r[(2, 2)]),
        real(t.x),
        real(t.y),
        real(t.z),
        real(cam.near()),
        real(cfg.material.young),
        real(cfg.material.poisson),
        cfg.material.inversion_barrier,
        cfg.material.law,
        sv.newton_iterations,
        sv.line_search_steps,
        match sv.coupling {
            Coupling::Relative(beta) => format!("Coupling::Relative({})", real(beta)),
            Coupling::Stiffness(k) => format!("Coupling::Stiffness({})", real(k)),
        },
        // `inf` is not a Rust literal.
        if sv.spring_threshold.is_finite() {
            real(sv.spring_threshold)
        } else {
            "Scalar::INFINITY".to_string()
        },
        real(sv.damping),
        real(sv.depth_prior),
        real(sv.image_margin),
        cfg.detection,
    );

    // The analysis.
    let a = e.analysis;
    let arrays: [(&str, &str, &[u32]); 12] = [
        ("PERM", "Fill-reducing ordering of the unknowns.", a.perm),
        ("ETREE", "Elimination tree.", a.etree),
        ("C_PTR", "Permuted pattern: column pointers.", a.c_ptr),
        ("C_ROW", "Permuted pattern: rows.", a.c_row),
        (
            "C_SRC",
            "Permuted pattern: where each value comes from.",
            a.c_src,
        ),
        (
            "C_DST",
            "Permuted pattern: where each value lands in L.",
            a.c_dst,
        ),
        ("L_PTR", "Column pointers of L.", a.l_ptr),
        ("L_ROW", "Rows of L.", a.l_row),
        ("LT_PTR", "Row pointers of L.", a.lt_ptr),
        ("LT_COL", "Columns of L.", a.lt_col),
        ("SN_PTR", "First column of each supernode.", a.sn_ptr),
        ("COL_SN", "Supernode of each column.", a.col_sn),
    ];
    for (name, doc, values) in arrays {
        u32_array(s, name, doc, values);
    }
    let _ = writeln!(
        s,
        "/// The uncut mesh's symbolic analysis ({} unknowns, {} matrix entries, {} factor entries).\n\
         pub const ANALYSIS: PrecomputedAnalysis<'static> = PrecomputedAnalysis {{\n    \
         size: SymbolicSize {{\n        n: {},\n        nnz_a: {},\n        nnz_l: {},\n    }},\n    \
         perm: &PERM,\n    etree: &ETREE,\n    c_ptr: &C_PTR,\n    c_row: &C_ROW,\n    c_src: &C_SRC,\n    \
         c_dst: &C_DST,\n    l_ptr: &L_PTR,\n    l_row: &L_ROW,\n    lt_ptr: &LT_PTR,\n    lt_col: &LT_COL,\n    \
         sn_ptr: &SN_PTR,\n    col_sn: &COL_SN,\n    checksum: {:#018x},\n}};\n",
        a.size.n, a.size.nnz_a, a.size.nnz_l, a.size.n, a.size.nnz_a, a.size.nnz_l, a.checksum
    );

    // Tracks.
    let most = e.frames.iter().map(Vec::len).max().unwrap_or(0);
    let _ = writeln!(
        s,
        "/// Most observations in one frame.\npub const MAX_OBSERVATIONS: usize = {most};\n"
    );
    let _ = writeln!(
        s,
        "/// The first {} frames of tracks (frame 0 places the features).",
        e.frames.len()
    );
    let _ = writeln!(
        s,
        "pub static FRAMES: [&[Observation<Scalar>]; {}] = [",
        e.frames.len()
    );
    for frame in e.frames {
        s.push_str("    &[\n");
        for o in frame {
            let _ = writeln!(
                s,
                "        Observation {{ id: {}, uv: [{}, {}] }},",
                o.id,
                real(o.uv[0]),
                real(o.uv[1])
            );
        }
        s.push_str("    ],\n");
    }
    s.push_str("];\n");
}

/// The model's static storage in a firmware build with the features `set`, part by part
/// ([`incise_core::ModelSize::parts`]), and its total, in bytes. The host's core has every
/// feature, so the sizes of a smaller set are the parts it brings, of its capacities: a slight
/// over-estimate (the workspace of a cut and the record of cut nodes stay counted), which
/// `--footprint` replaces with the measured figure.
fn storage_parts(
    generated: &Generated,
    features: &[&str],
) -> Result<(Vec<StoragePart>, u64), CodegenError> {
    // A feature the set names, or one it brings: `cut` brings `detect`, `strategies` every
    // strategy (`quasi-newton` the storage of its secant pairs and kept gradient share).
    let has = |f: &str| {
        features.contains(&f)
            || (f == "detect" && features.contains(&"cut"))
            || (f == "quasi-newton" && features.contains(&"strategies"))
    };
    let capacities = if has("cut") {
        &generated.capacities
    } else if has("detect") {
        &generated.detect_capacities
    } else {
        &generated.register_capacities
    };
    let size = ModelSize::new(capacities).map_err(|e| CodegenError(e.to_string()))?;
    let parts: Vec<StoragePart> = size
        .parts()
        .into_iter()
        .filter(|p| p.feature.is_none_or(has))
        .collect();
    let total = parts.iter().map(|p| p.bytes::<f64>() as u64).sum();
    Ok((parts, total))
}

/// A Markdown table of the model's static storage by part, for each feature set
/// ([`footprint::FEATURE_SETS`]).
///
/// # Errors
/// Capacities the core cannot hold.
pub fn storage_table(generated: &Generated) -> Result<String, CodegenError> {
    let sets = footprint::FEATURE_SETS;
    let mut columns = Vec::new();
    for set in &sets {
        columns.push(storage_parts(generated, set.features)?);
    }
    let mut s = format!(
        "Static storage of the model of {} (f64), KiB, by feature set (estimates; the \
         footprint below is measured):\n\n| part |",
        generated.name
    );
    for set in &sets {
        let _ = write!(s, " {} |", set.name);
    }
    s.push_str(" grows with |\n|---|");
    for _ in &sets {
        s.push_str("---:|");
    }
    s.push_str("---|\n");
    let (all, _) = &columns[0];
    for p in all {
        let _ = write!(s, "| {} |", p.name);
        for (parts, _) in &columns {
            let cell = parts
                .iter()
                .find(|q| q.name == p.name)
                .map_or("–".to_string(), |q| {
                    footprint::kib(q.bytes::<f64>() as u64)
                });
            let _ = write!(s, " {cell} |");
        }
        let _ = writeln!(s, " {} |", p.grows_with);
    }
    s.push_str("| total |");
    for (_, total) in &columns {
        let _ = write!(s, " {} |", footprint::kib(*total));
    }
    s.push_str(" |\n");
    Ok(s)
}

/// Checks the model's static storage against a RAM budget of `budget` bytes, for the build the
/// scene needs: its own linear strategy and camera projection only (the last of
/// [`footprint::feature_sets`]), with the `cut` feature and the temporal filter when its
/// detection is on. Storage that only another strategy uses (the quasi-Newton strategy's) does
/// not count against a scene that does not use it.
///
/// # Errors
/// When it does not fit: by how much, and which buffer is the largest and what it grows with,
/// so the scene's `[capacities]` can be lowered where it matters.
pub fn check_budget(generated: &Generated, budget: u64) -> Result<(), CodegenError> {
    let cut = generated.needs_cut;
    let [.., own] = footprint::feature_sets(generated.strategy, generated.projection);
    let mut features = own.features.to_vec();
    if cut {
        features.extend(["cut", "temporal-filter"]);
    }
    let (mut parts, total) = storage_parts(generated, &features)?;
    if total <= budget {
        return Ok(());
    }
    parts.sort_by_key(|p| std::cmp::Reverse(p.bytes::<f64>()));
    let over = total - budget;
    let mut s = format!(
        "{}: the model's static storage ({}) takes {} KiB of RAM, {} KiB over the budget of \
         {} KiB. By part, largest first:",
        generated.name,
        if cut {
            "with the cut feature, as the scene's detection is on, and its own strategy and \
             projection only"
        } else {
            "without the cut feature, as the scene's detection is off, and its own strategy \
             and projection only"
        },
        footprint::kib(total),
        footprint::kib(over),
        footprint::kib(budget)
    );
    for p in parts.iter().filter(|p| p.bytes::<f64>() > 0) {
        let _ = write!(
            s,
            "\n  {:>9} KiB  {} (grows with {})",
            footprint::kib(p.bytes::<f64>() as u64),
            p.name,
            p.grows_with
        );
    }
    if let Some(largest) = parts.first() {
        let bytes = largest.bytes::<f64>() as u64;
        if bytes > over {
            let _ = write!(
                s,
                "\nThe largest, {}, would fit if it were {} KiB smaller ({} KiB instead of {}).",
                largest.name,
                footprint::kib(over),
                footprint::kib(bytes - over),
                footprint::kib(bytes)
            );
        } else {
            let _ = write!(
                s,
                "\nEven without its largest part ({}) it would not fit: lower several \
                 capacities{}.",
                largest.name,
                if cut {
                    ", or build without the cut feature (or without detection), which leaves \
                     out the parts marked so"
                } else {
                    ""
                }
            );
        }
    }
    Err(CodegenError(s))
}
