//! Bad input, tried as a new user would, each on a copy of `band-side-cut`: every value is
//! refused before anything is allocated or simulated, with exit status 1 and a message naming
//! the file, the line and the key; nothing panics.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use incise::scene::Scene;

mod common;
use common::copy_dir;

fn incise() -> Command {
    Command::new(env!("CARGO_BIN_EXE_incise"))
}

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/band-side-cut")
}

/// `text` with `from` (which must be there) replaced by `to`.
fn edit(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "{from:?} is not in the file");
    text.replacen(from, to, 1)
}

/// A copy of the scene in a temporary directory, `scene.toml` edited.
fn scene_with(from: &str, to: &str) -> tempfile::TempDir {
    let tmp = tempfile::tempdir().unwrap();
    let src = fixture();
    for f in ["scene.toml", "model.msh", "tracks.csv"] {
        std::fs::copy(src.join(f), tmp.path().join(f)).unwrap();
    }
    let toml = std::fs::read_to_string(src.join("scene.toml")).unwrap();
    std::fs::write(tmp.path().join("scene.toml"), edit(&toml, from, to)).unwrap();
    tmp
}

/// Exit status 1, no panic, and a message that holds every one of `words`; the message.
fn refused(output: &Output, words: &[&str]) -> String {
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    for w in words {
        assert!(stderr.contains(w), "{w:?} missing from: {stderr}");
    }
    stderr
}

/// `incise run` on the scene with `from` replaced by `to` is refused, naming `words`.
fn run_refuses(from: &str, to: &str, words: &[&str]) -> String {
    let tmp = scene_with(from, to);
    let output = incise().arg("run").arg(tmp.path()).output().unwrap();
    refused(&output, words)
}

#[test]
fn scene_sizes_beyond_their_bounds_are_refused_naming_the_key_and_line() {
    run_refuses(
        "features = 1024",
        "features = 10000000000",
        &["scene.toml:33:", "[capacities] features", "65536"],
    );
    run_refuses(
        "cut_tets = 1024",
        "cut_tets = 4000000",
        &["scene.toml:", "[capacities]", "budget"],
    );
    run_refuses(
        "cut_vertices = 64",
        "cut_vertices = 64\nfactor_entries = 200000000",
        &["[capacities]", "200000000 factor entries", "GiB"],
    );
    run_refuses(
        "pairs = 32768",
        "pairs = 100000000",
        &["scene.toml:37:", "[capacities] pairs"],
    );
    run_refuses(
        "width = 640",
        "width = 100000",
        &["scene.toml:17:", "[camera] width"],
    );
    run_refuses(
        "frames = 40",
        "frames = 1000000",
        &["scene.toml:42:", "[ground_truth] frames"],
    );
}

#[test]
fn unknown_keys_are_refused() {
    // The issue's `factor_headroom_percent` is not a key of this scene format.
    run_refuses(
        "cut_vertices = 64",
        "cut_vertices = 64\nfactor_headroom_percent = 4000000000",
        &["scene.toml:39:", "unknown field `factor_headroom_percent`"],
    );
    run_refuses(
        "frames = 40",
        "frames = 40\nframe_rate = 25",
        &["scene.toml:43:", "unknown field `frame_rate`"],
    );
}

#[test]
fn a_scene_that_cannot_work_is_refused_saying_why() {
    let e = run_refuses(
        "cut_vertices = 64",
        "cut_vertices = 0",
        &["scene.toml:38:", "[capacities] cut_vertices", "detection"],
    );
    assert!(e.contains("enabled = false"), "{e}");
    run_refuses(
        "pairs = 32768",
        "pairs = 0",
        &["scene.toml:37:", "[capacities] pairs", "detection"],
    );
    run_refuses(
        "features = 1024",
        "features = 0",
        &["[capacities] features"],
    );
    // Fewer than the 300 features tracks.csv follows.
    run_refuses(
        "features = 1024",
        "features = 100",
        &["scene.toml:33:", "[capacities] features", "tracks.csv"],
    );
    // Every one of the 204 nodes fixed.
    let all: Vec<String> = (0..204).map(|v| v.to_string()).collect();
    let toml = std::fs::read_to_string(fixture().join("scene.toml")).unwrap();
    let fixed = toml.lines().find(|l| l.starts_with("fixed = ")).unwrap();
    run_refuses(
        fixed,
        &format!("fixed = [{}]", all.join(", ")),
        &["scene.toml:8:", "[model] fixed", "every one"],
    );
    run_refuses(
        "young = 30000.0",
        "young = -1.0",
        &["scene.toml:9:", "[model] young"],
    );
}

#[test]
fn the_ground_truth_frames_are_read() {
    // Fewer frames than tracks.csv holds: refused.
    run_refuses(
        "frames = 40",
        "frames = 30",
        &["scene.toml:42:", "[ground_truth] frames", "40 frames"],
    );
    // More: the frames after the last row lost every feature.
    let tmp = scene_with("frames = 40", "frames = 42");
    let scene = Scene::load(tmp.path()).unwrap();
    assert_eq!(scene.frames.len(), 42);
    assert!(scene.frames[40].is_empty() && scene.frames[41].is_empty());
    assert!(!scene.frames[39].is_empty());
    // Absent: tracks.csv decides.
    let tmp = scene_with("frames = 40", "");
    assert_eq!(Scene::load(tmp.path()).unwrap().frames.len(), 40);
}

#[test]
fn capacities_without_detection_need_no_cut_line() {
    let tmp = scene_with(
        "cut_vertices = 64",
        "cut_vertices = 0\n\n[detection]\nenabled = false",
    );
    Scene::load(tmp.path()).unwrap();
}

/// A copy of the scenario in a temporary directory with `from` replaced by `to`; its path.
fn scenario_with(tmp: &Path, from: &str, to: &str) -> PathBuf {
    let text = std::fs::read_to_string(fixture().join("scenario.toml")).unwrap();
    let path = tmp.join("scenario.toml");
    std::fs::write(&path, edit(&text, from, to)).unwrap();
    path
}

/// `incise gen` on the scenario with `from` replaced by `to` is refused, naming `words`, and
/// writes nothing.
fn gen_refuses(from: &str, to: &str, words: &[&str]) -> String {
    let tmp = tempfile::tempdir().unwrap();
    let path = scenario_with(tmp.path(), from, to);
    let out = tmp.path().join("out");
    let output = incise()
        .arg("gen")
        .arg(&path)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let e = refused(&output, words);
    assert!(!out.exists(), "gen wrote {} before refusing", out.display());
    // The path once, not twice.
    let name = path.display().to_string();
    assert_eq!(e.matches(&name).count(), 1, "{e}");
    e
}

#[test]
fn scenario_sizes_beyond_their_bounds_are_refused_before_any_work() {
    gen_refuses(
        "fine_cells = [40, 12, 2]",
        "fine_cells = [10000, 10000, 10000]",
        &["scenario.toml:13:", "[object] fine_cells"],
    );
    gen_refuses(
        "fine_cells = [40, 12, 2]",
        "fine_cells = [1000, 1000, 2]",
        &["scenario.toml:13:", "[object] fine_cells", "nodes"],
    );
    gen_refuses(
        "targets = 20",
        "targets = 100000000",
        &["scenario.toml:17:", "[object] targets"],
    );
    gen_refuses(
        "features = 300",
        "features = 10000000",
        &["scenario.toml:42:", "[tracking] features"],
    );
    // Within the bound, but more than the scene's capacity: `run` would refuse the scene.
    gen_refuses(
        "features = 300",
        "features = 2000",
        &["[tracking] features", "[capacities] features = 1024"],
    );
    gen_refuses(
        "frames = 40",
        "frames = 10000000",
        &["scenario.toml:8:", "frames", "100000"],
    );
    // Within the bound, but the positions of every frame are beyond the memory budget.
    gen_refuses(
        "frames = 40",
        "frames = 60000",
        &["scenario.toml:8:", "frames", "budget"],
    );
    gen_refuses("width = 640", "width = 100000", &["[camera] width"]);
}

#[test]
fn scenarios_that_would_write_an_unusable_scene_are_refused() {
    gen_refuses(
        "noise_px = 0.3",
        "noise_px = nan",
        &["scenario.toml:43:", "[tracking] noise_px"],
    );
    gen_refuses(
        "dropout = 0.02",
        "dropout = 2.0",
        &["scenario.toml:44:", "[tracking] dropout"],
    );
    gen_refuses("dropout = 0.02", "dropout = 1.0", &["[tracking] dropout"]);
    gen_refuses(
        "features = 300",
        "features = 0",
        &["scenario.toml:42:", "[tracking] features"],
    );
    gen_refuses("frames = 40", "frames = 0", &["scenario.toml:8:", "frames"]);
    gen_refuses("frames = 40", "frames = 1", &["scenario.toml:8:", "frames"]);
    gen_refuses(
        "fine_cells = [40, 12, 2]",
        "fine_cells = [40, 0, 2]",
        &["[object] fine_cells"],
    );
    gen_refuses(
        "outlier_fraction = 0.01",
        "outlier_fraction = -0.5",
        &["[tracking] outlier_fraction"],
    );
    gen_refuses(
        "strategy = \"factor-once\"",
        "strategy = \"fast\"",
        &["[solver] strategy"],
    );
    gen_refuses(
        "features = 300",
        "features = 300\nspeed = 2",
        &["scenario.toml:43:", "unknown field `speed`"],
    );
}

#[test]
fn values_the_core_refuses_are_named_by_their_key_and_line() {
    // A solver value: the line of the key, the bound as a number (not a constant's name).
    run_refuses(
        "newton_iterations = 3",
        "newton_iterations = 0",
        &["scene.toml:26:", "[solver] newton_iterations", "1..=64"],
    );
    run_refuses(
        "strategy = \"factor-once\"",
        "strategy = \"fast\"",
        &["scene.toml:24:", "[solver] strategy"],
    );
    // A detection value, in the section a scene adds to study a setting.
    run_refuses(
        "[capacities]",
        "[detection]\nalpha = -5.0\n\n[capacities]",
        &["scene.toml:33:", "[detection] alpha"],
    );
    // More internal targets than the capacity: both files named, before the model is built.
    let tmp = scene_with("targets = 64", "targets = 2");
    copy_dir(&fixture().join("gt"), &tmp.path().join("gt"));
    let output = incise().arg("run").arg(tmp.path()).output().unwrap();
    refused(
        &output,
        &["scene.toml:", "[capacities] targets", "targets.csv"],
    );
}

#[test]
fn a_camera_or_a_grasp_that_cannot_be_simulated_is_refused_naming_its_key() {
    gen_refuses(
        "up = [0.0, 1.0, 0.0]",
        "up = [0.0, 0.0, 1.0]",
        &["scenario.toml:36:", "[camera] up"],
    );
    gen_refuses(
        "target = [0.055, 0.015, 0.0]",
        "target = [0.055, 0.015, 0.5]",
        &["scenario.toml:35:", "[camera] target"],
    );
    gen_refuses(
        "end = 28",
        "end = 40",
        &["[motion.grasp] end", "frames (40)"],
    );
    gen_refuses(
        "end = 28",
        "end = 28\nrotation_degrees = 10.0\naxis = [0.0, 0.0, 0.0]",
        &["[motion.grasp] axis"],
    );
}

#[test]
fn a_damaged_mesh_is_an_error_naming_it_with_no_panic_printed() {
    // A VTU file the VTK reader panics on (a zlib header of zeros).
    let zeros = "AAAAAAAAAAAAAAAAAAAAAA==";
    let array = |kind: &str, name: &str| {
        format!("<DataArray type=\"{kind}\" {name} format=\"binary\">\n{zeros}\n</DataArray>")
    };
    let vtu = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" \
         byte_order=\"LittleEndian\" compressor=\"vtkZLibDataCompressor\">\n\
         <UnstructuredGrid><Piece NumberOfPoints=\"5\" NumberOfCells=\"2\">\n\
         <Points>{}</Points><Cells>{}{}{}</Cells></Piece></UnstructuredGrid></VTKFile>\n",
        array("Float64", "NumberOfComponents=\"3\""),
        array("Int64", "Name=\"connectivity\""),
        array("Int64", "Name=\"offsets\""),
        array("UInt8", "Name=\"types\""),
    );
    let tmp = scene_with("mesh = \"model.msh\"", "mesh = \"damaged.vtu\"");
    std::fs::write(tmp.path().join("damaged.vtu"), vtu).unwrap();
    let output = incise().arg("run").arg(tmp.path()).output().unwrap();
    let e = refused(&output, &["damaged.vtu", "cannot read"]);
    assert!(!e.contains("backtrace") && e.lines().count() == 1, "{e}");
}

#[test]
fn an_output_that_cannot_be_written_is_named_and_another_scene_never_replaces_the_scenario() {
    // An output directory that is a file.
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("a-file");
    std::fs::write(&file, "").unwrap();
    let output = incise()
        .arg("run")
        .arg(fixture())
        .arg("--out")
        .arg(&file)
        .output()
        .unwrap();
    refused(&output, &[&file.display().to_string()]);
    // The object left whole, or another model mesh, written into the scenario's own
    // directory: refused before anything is simulated, the scenario as it was.
    let scenario = scenario_with(tmp.path(), "frames = 40", "frames = 40");
    let before = std::fs::read(&scenario).unwrap();
    for option in [&["--intact"][..], &["--model-mesh", "refined"][..]] {
        let output = incise()
            .arg("gen")
            .arg(&scenario)
            .args(option)
            .arg("--out")
            .arg(tmp.path().join("."))
            .output()
            .unwrap();
        refused(&output, &["own directory", option[0]]);
    }
    assert_eq!(std::fs::read(&scenario).unwrap(), before);
    assert!(!tmp.path().join("scene.toml").exists());
}

#[test]
fn unreadable_files_are_named_once() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("missing.toml");
    let output = incise().arg("gen").arg(&missing).output().unwrap();
    let e = refused(&output, &["cannot read"]);
    assert_eq!(e.matches(&missing.display().to_string()).count(), 1, "{e}");
    // A missing silhouette (a scene that claims more frames than its ground truth has).
    let tmp = scene_with("frames = 40", "frames = 42");
    let src = fixture();
    copy_dir(&src.join("gt"), &tmp.path().join("gt"));
    let output = incise().arg("run").arg(tmp.path()).output().unwrap();
    let e = refused(&output, &["0040.png", "cannot read"]);
    assert_eq!(e.matches("0040.png").count(), 1, "{e}");
}

#[test]
fn every_shipped_scene_and_scenario_passes_the_checks() {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures");
    let mut scenes = 0;
    for e in std::fs::read_dir(&fixtures).unwrap() {
        let dir = e.unwrap().path();
        if dir.join("scene.toml").exists() {
            Scene::load(&dir).unwrap();
            scenes += 1;
        }
        if dir.join("scenario.toml").exists() {
            incise::generate::scenario::Scenario::load(&dir.join("scenario.toml")).unwrap();
        }
    }
    assert!(scenes >= 7, "{scenes} scenes");
    // Every family's base scenario (read and checked as a scenario).
    let mut families = 0;
    for e in std::fs::read_dir(fixtures.join("families")).unwrap() {
        let path = e.unwrap().path();
        if let Ok(family) = incise::generate::family::Family::load(&path) {
            family.base_scenario(&path).unwrap();
            families += 1;
        }
    }
    assert!(families >= 3, "{families} families");
}

/// `incise codegen` on the scene with `from` replaced by `to` (and `args`) is refused, naming
/// `words`, and writes nothing.
fn codegen_refuses(from: &str, to: &str, args: &[&str], words: &[&str]) -> String {
    let tmp = scene_with(from, to);
    let out = tmp.path().join("generated").join("scene.rs");
    let output = incise()
        .arg("codegen")
        .arg(tmp.path())
        .arg("-o")
        .arg(&out)
        .args(args)
        .output()
        .unwrap();
    let e = refused(&output, words);
    assert!(!out.exists(), "{} written: {e}", out.display());
    assert!(!out.with_extension("rs.tmp").exists());
    e
}

#[test]
fn codegen_refuses_a_scene_that_does_not_check_out_and_writes_nothing() {
    codegen_refuses(
        "young = 30000.0",
        "young = -1.0",
        &[],
        &["scene.toml:9:", "[model] young"],
    );
    codegen_refuses(
        "cut_vertices = 64",
        "cut_vertices = 64\nfactor_entries = 10",
        &[],
        &["factor entries"],
    );
    codegen_refuses("name = ", "name = ", &["--frames", "0"], &["--frames 0"]);
    codegen_refuses(
        "name = ",
        "name = ",
        &["--frames", "41"],
        &["--frames 41", "40 frames"],
    );
    // The default capacities need megabytes: a 256 KiB budget says by how much it is over
    // and which part is the largest.
    let e = codegen_refuses(
        "name = ",
        "name = ",
        &["--ram-budget-kib", "256"],
        &["over the budget of 256.0 KiB", "largest", "grows with"],
    );
    assert!(e.contains("band-side-cut"), "{e}");
    // Only the storage of the scene's own strategy counts: the quasi-Newton strategy's secant
    // pairs are listed for a scene that uses it, not for this one (`factor-once`).
    assert!(!e.contains("quasi-Newton"), "{e}");
    let e = codegen_refuses(
        "strategy = \"factor-once\"",
        "strategy = \"quasi-newton\"",
        &["--ram-budget-kib", "256"],
        &["over the budget of 256.0 KiB", "quasi-Newton"],
    );
    assert!(e.contains("its own strategy"), "{e}");
}

#[test]
fn codegen_writes_a_module_within_its_budget() {
    let tmp = scene_with("name = ", "name = ");
    let out = tmp.path().join("scene.rs");
    let output = incise()
        .arg("codegen")
        .arg(tmp.path())
        .arg("-o")
        .arg(&out)
        .args(["--ram-budget-kib", "65536"])
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let text = std::fs::read_to_string(&out).unwrap();
    for item in [
        "pub const CAPACITIES",
        "pub const SIZE",
        "pub const ANALYSIS",
        "pub static FRAMES: [&[Observation<Scalar>]; 5]",
        "pub fn config()",
    ] {
        assert!(text.contains(item), "{item} missing");
    }
}
