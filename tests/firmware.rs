//! The firmware build of a generated scene (issue 15): `incise codegen` writes the scene as a
//! module, `firmware/` (`#![no_std]`, `#![no_main]`, linking only incise-core) is built with it
//! for each feature set the README lists, linked with a C `main` and run. The test checks
//! - that no allocator symbol and no formatting machinery (`core::fmt`) is linked;
//! - that without the `cut` feature neither the minimum-degree ordering nor the symbolic
//!   analysis is linked, and that with it both are (so the check can see them); that the
//!   detector is linked exactly with `detect` (or `cut`);
//! - that the firmware's node positions after the scene's frames are the host's, bit for bit,
//!   with the same settings (the host's model built with `Model::new`, detection off for a
//!   build that does not cut: detection alone moves no node), in mixed precision too (the
//!   host's model an `f64` one with an `f32` factor); in `f32`, within a micrometre;
//! - that its static RAM is the storage the capacities give, that leaving cutting out, then
//!   detection, shrinks code and RAM, that `f32` saves 4 bytes of RAM per scalar, and mixed
//!   precision 4 bytes per scalar of the factor's part.

use std::path::{Path, PathBuf};
use std::process::Command;

use incise::codegen::footprint::{self, FeatureSet, Firmware, feature_sets};
use incise::codegen::{self, CodegenOptions};
use incise::scene::Scene;
use incise::storage::ModelStorage;
use incise_validation::symbols::allocator_symbols;

const SCENES: [&str; 2] = ["band-side-cut", "liver-lobe"];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The node positions the host computes for the scene's first `frames` frames with the
/// firmware's capacities and the settings of feature set `set`, as bits.
fn host_positions(scene: &Scene, frames: usize, set: &FeatureSet) -> Vec<[u64; 3]> {
    let input = scene.mesh_input();
    let mut config = scene.model_config().unwrap();
    // Detection moves nodes only through the cuts it makes: off, unless the build cuts.
    config.detection.enabled &= set.features.contains(&"cut");
    if !set.features.contains(&"temporal-filter") {
        config.detection.temporal_sigmas = f64::INFINITY;
    }
    let caps = codegen::firmware_capacities(scene).unwrap();
    if set.features.contains(&"mixed") {
        let mut storage = ModelStorage::<f64, f32>::with_factor_in(&input, &caps).unwrap();
        let model = storage.model(&input, &config).unwrap();
        run_frames(model, scene, frames)
    } else {
        let mut storage = ModelStorage::<f64>::new(&input, &caps).unwrap();
        let model = storage.model(&input, &config).unwrap();
        run_frames(model, scene, frames)
    }
}

/// Places the features at frame 0, steps through frames `1..frames` as the firmware does, and
/// returns the node positions as bits.
fn run_frames<F: incise_core::Real>(
    mut model: incise_core::Model<'_, f64, F>,
    scene: &Scene,
    frames: usize,
) -> Vec<[u64; 3]> {
    model.embed_features(&scene.frames[0]).unwrap();
    for frame in &scene.frames[1..frames] {
        let known: Vec<_> = frame
            .iter()
            .copied()
            .filter(|o| model.features().slot_of(o.id).is_some())
            .collect();
        // A refused frame leaves the model as it was, as in the firmware.
        let _ = model.step(&known);
    }
    model
        .positions()
        .iter()
        .map(|p| p.map(f64::to_bits))
        .collect()
}

/// Runs the firmware executable and parses its `node x y z` lines (coordinates as bits).
fn firmware_positions(exe: &Path) -> Vec<[u64; 3]> {
    let out = Command::new(exe).output().expect("the firmware runs");
    assert!(
        out.status.success(),
        "the firmware failed: {:?} {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .enumerate()
        .map(|(k, line)| {
            let w: Vec<&str> = line.split_whitespace().collect();
            assert_eq!(w.len(), 4, "line {k}: {line}");
            assert_eq!(w[0].parse::<usize>().unwrap(), k);
            [1, 2, 3].map(|i| u64::from_str_radix(w[i], 16).unwrap())
        })
        .collect()
}

/// Generates `name`'s module with all its frames, builds the firmware with `set` and checks it.
fn check(name: &str, set: &FeatureSet) -> Firmware {
    check_scene(&root().join("fixtures").join(name), name, set)
}

/// As [`check`], for the scene in `dir`. Every feature set of a scene builds in one target
/// directory of its own (`target/firmware/NAME`): the dependencies are built once per scene,
/// the scenes' tests build side by side (each build ends in a single-threaded link-time
/// optimisation), and a second run of the tests (CI's with `--features opencv`) finds every
/// build fresh, since the module is left as it was when nothing in it changed.
fn check_scene(dir: &Path, name: &str, set: &FeatureSet) -> Firmware {
    let scene = Scene::load(dir).unwrap();
    let frames = scene.frames.len();
    let dir = root().join("target").join("firmware").join(name);
    let module = dir.join(format!("{name}.rs"));
    let generated = codegen::generate(&scene, &CodegenOptions { frames }).unwrap();
    codegen::write(&generated, &module).unwrap();
    let firmware = footprint::build(&module, set, generated.law, &dir).unwrap();
    let lib = dir.join("release").join("libincise_firmware.a");
    for file in [&lib, &firmware.exe] {
        let heap = allocator_symbols(file);
        assert!(
            heap.is_empty(),
            "{name}, {}: allocator symbols {heap:?}",
            set.name
        );
    }
    let symbols = footprint::symbols(&firmware.exe).unwrap();
    let fmt: Vec<&String> = symbols.iter().filter(|s| s.contains("core::fmt")).collect();
    assert!(
        fmt.is_empty(),
        "{name}, {}: formatting linked: {fmt:?}",
        set.name
    );
    let cut = set.features.contains(&"cut");
    let detect = cut || set.features.contains(&"detect");
    for (needle, expected) in [
        ("sparse::order::minimum_degree", cut),
        ("sparse::dissect::nested_dissection", cut),
        ("Symbolic::analyse", cut),
        ("incise_core::detect::detector", detect),
    ] {
        let linked = symbols.iter().any(|s| s.contains(needle));
        assert_eq!(
            linked, expected,
            "{name}, {}: {needle} linked: {linked}",
            set.name
        );
    }
    let host = host_positions(&scene, frames, set);
    let device = firmware_positions(&firmware.exe);
    assert_eq!(device.len(), host.len(), "{name}, {}: node count", set.name);
    let f32 = set.features.contains(&"f32");
    for (v, (d, h)) in device.iter().zip(&host).enumerate() {
        if f32 {
            // Within a micrometre of the f64 run (the scenes are centimetres across).
            let (d, h) = (d.map(f64::from_bits), h.map(f64::from_bits));
            let distance = (0..3).map(|k| (d[k] - h[k]).powi(2)).sum::<f64>().sqrt();
            assert!(
                distance < 1e-6,
                "{name}, {}: node {v} {distance} m away",
                set.name
            );
        } else {
            assert_eq!(d, h, "{name}, {}: node {v}", set.name);
        }
    }
    if cut && !f32 {
        // The host's core has the `cut` feature: its storage is the firmware's.
        let size = incise_core::ModelSize::new(&generated.capacities).unwrap();
        let storage = if set.features.contains(&"mixed") {
            size.bytes_mixed::<f64, f32>()
        } else {
            size.bytes::<f64>()
        } as u64;
        let ram = firmware.footprint.ram();
        assert!(
            ram >= storage && ram <= storage + 64 * 1024,
            "{name}: static RAM {ram} B, model storage {storage} B"
        );
    }
    firmware
}

#[test]
fn each_feature_set_runs_band_side_cut_as_the_host_does_and_leaving_stages_out_shrinks_it() {
    feature_sets_run_as_the_host_does(SCENES[0]);
}

#[test]
fn each_feature_set_runs_liver_lobe_as_the_host_does_and_leaving_stages_out_shrinks_it() {
    feature_sets_run_as_the_host_does(SCENES[1]);
}

/// Builds scene `name` with every feature set ([`check`]), and holds the builds to what leaving
/// stages out and the scalar types must save.
fn feature_sets_run_as_the_host_does(name: &str) {
    {
        let scene = Scene::load(&root().join("fixtures").join(name)).unwrap();
        let config = scene.model_config().unwrap();
        let builds: Vec<(FeatureSet, Firmware)> =
            feature_sets(config.solver.strategy, config.camera.projection())
                .into_iter()
                .map(|set| (set, check(name, &set)))
                .collect();
        let footprint = |set: &str| {
            builds
                .iter()
                .find(|(s, _)| s.name == set)
                .map(|(_, f)| f.footprint)
                .unwrap()
        };
        // Each stage left out (cutting, then detection) takes a fifth of the code at least,
        // and RAM. Keeping one strategy of three saves next to nothing (they share assembly,
        // factorization and solves; the README's table shows it), so only the stages are held
        // to a saving.
        for (more, less) in [("cut", "detect"), ("detect", "register")] {
            let (m, l) = (footprint(more), footprint(less));
            assert!(
                l.text * 10 < m.text * 8 && l.ram() < m.ram(),
                "{name}: leaving out {more} should shrink the build: {m} against {l}"
            );
        }
        // In f32 each scalar of the storage takes 4 bytes fewer; the indices stay.
        let scalars = incise_core::ModelSize::new(
            &codegen::generate(&scene, &CodegenOptions::default())
                .unwrap()
                .capacities,
        )
        .unwrap()
        .real_len() as u64;
        let (f64, f32) = (footprint("cut"), footprint("cut, f32"));
        let saved = f64.ram() - f32.ram();
        assert!(
            saved.abs_diff(4 * scalars) < 64 * 1024,
            "{name}: f32 {f32} against f64 {f64}: {saved} B saved for {scalars} scalars"
        );
        // Mixed precision saves 4 bytes per scalar of the factor's part only.
        let size = incise_core::ModelSize::new(
            &codegen::generate(&scene, &CodegenOptions::default())
                .unwrap()
                .capacities,
        )
        .unwrap();
        let factor_scalars = size.factor_real_len() as u64;
        let mixed = footprint("cut, mixed");
        let saved = f64.ram() - mixed.ram();
        assert!(
            saved.abs_diff(4 * factor_scalars) < 64 * 1024,
            "{name}: mixed {mixed} against f64 {f64}: {saved} B saved for {factor_scalars} factor scalars"
        );
    }
}

/// `band-side-cut` seen by an orthographic camera (the scene's camera, its focal lengths taken
/// to pixels per metre at the band's depth): the firmware with both projections and the one
/// with the orthographic projection only run as the host does.
#[test]
fn an_orthographic_scene_runs_as_the_host_does() {
    // In a directory of the build, not a temporary one: the module names the scene's
    // directory, and an unchanged module keeps a second run's builds fresh.
    let dir = root()
        .join("target")
        .join("firmware-scenes")
        .join("band-side-cut-orthographic");
    std::fs::create_dir_all(&dir).unwrap();
    let src = root().join("fixtures").join("band-side-cut");
    for f in ["model.msh", "tracks.csv"] {
        std::fs::copy(src.join(f), dir.join(f)).unwrap();
    }
    let toml = std::fs::read_to_string(src.join("scene.toml")).unwrap();
    assert!(
        toml.contains("fx = 4500.0\nfy = 4500.0\n")
            && toml.contains("translation = [-0.055, 0.015, 0.5]")
    );
    let toml = toml.replace(
        "fx = 4500.0\nfy = 4500.0\n",
        "projection = \"orthographic\"\nfx = 9000.0\nfy = 9000.0\n",
    );
    std::fs::write(dir.join("scene.toml"), toml).unwrap();
    let scene = Scene::load(&dir).unwrap();
    let config = scene.model_config().unwrap();
    assert_eq!(
        config.camera.projection(),
        incise_core::Projection::Orthographic
    );
    let sets = feature_sets(config.solver.strategy, config.camera.projection());
    for set in [&sets[0], &sets[sets.len() - 1]] {
        check_scene(&dir, "band-side-cut-orthographic", set);
    }
}
