//! `incise gen` as a user runs it: the live-cut scene regenerates to its committed bytes, and
//! a scene family is written variant by variant, each variant regenerating from its own
//! scenario.toml to the same bytes.

use std::path::{Path, PathBuf};
use std::process::Command;

use incise::generate::pipeline::generate;

fn incise() -> Command {
    Command::new(env!("CARGO_BIN_EXE_incise"))
}

/// Runs `command`, which must succeed (else its stderr is the failure), and returns its
/// standard output.
fn succeeds(command: &mut Command) -> Vec<u8> {
    let output = command.output().unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    output.stdout
}

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures")
}

/// Every file below `dir`, relative, sorted.
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = vec![];
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p.strip_prefix(dir).unwrap().to_path_buf());
            }
        }
    }
    out.sort();
    out
}

/// `a` and `b` hold the same files with the same bytes.
fn assert_same_files(a: &Path, b: &Path) {
    let (fa, fb) = (files(a), files(b));
    assert_eq!(fa, fb, "different file lists");
    for f in &fa {
        assert!(
            std::fs::read(a.join(f)).unwrap() == std::fs::read(b.join(f)).unwrap(),
            "{} differs",
            f.display()
        );
    }
}

#[test]
fn the_live_cut_scene_regenerates_to_its_committed_bytes() {
    let committed = fixtures().join("band-live-cut");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("band-live-cut");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::copy(committed.join("scenario.toml"), out.join("scenario.toml")).unwrap();
    let g = generate(&out.join("scenario.toml"), &out, false).unwrap();
    assert_same_files(&committed, &out);
    // The cut starts growing at frame 5 and opens behind the scissors.
    assert!(g.cut_open_frame.is_some_and(|f| f > 5), "{g:?}");
    // Pulled 3 cm along the 9 cm between its held and its grasped end, the band stretches by
    // a third on average there, so by more somewhere (most at the slit's tip), and most once
    // the pull is complete (frame 28).
    let s = g.stretch;
    assert!(s.largest > 1.3 && s.frame >= 28, "{g:?}");
    assert!((1.0..=s.largest).contains(&s.one_percent), "{g:?}");
}

#[test]
fn a_family_is_written_variant_by_variant_and_each_regenerates() {
    let tmp = tempfile::tempdir().unwrap();
    let family = tmp.path().join("family.toml");
    std::fs::write(
        &family,
        format!(
            "name = \"small\"\nbase = {:?}\nvariants = 2\nseed = 5\nintact_fraction = 0.5\n\
             live_fraction = 1.0\nnoise_px = [0.5, 1.0]\npull_frames = [10, 20]\n\
             oblique_degrees = [0.0, 30.0]\ncut_shift = [-0.1, 0.1]\ncut_length = [0.6, 0.9]\n",
            fixtures()
                .join("band-side-cut/scenario.toml")
                .display()
                .to_string()
        ),
    )
    .unwrap();
    let out = tmp.path().join("variants");
    succeeds(
        incise()
            .args(["gen", "--family"])
            .arg(&family)
            .arg("--out")
            .arg(&out),
    );
    let mut live = 0;
    for name in ["small-00", "small-01"] {
        let dir = out.join(name);
        for f in [
            "scenario.toml",
            "scene.toml",
            "tracks.csv",
            "gt/cut.csv",
            "gt/outliers.csv",
        ] {
            assert!(dir.join(f).exists(), "{name}: no {f}");
        }
        let scenario = std::fs::read_to_string(dir.join("scenario.toml")).unwrap();
        live += usize::from(scenario.contains("grow = ["));
        // The variant's own scenario.toml regenerates the scene byte for byte.
        let again = tmp.path().join("again").join(name);
        std::fs::create_dir_all(&again).unwrap();
        std::fs::copy(dir.join("scenario.toml"), again.join("scenario.toml")).unwrap();
        succeeds(incise().arg("gen").arg(again.join("scenario.toml")));
        assert_same_files(&dir, &again);
    }
    // One intact and one cut variant, and every cut variant of this family is live.
    assert_eq!(live, 1);

    // --family needs --out and takes no scenarios.
    let output = incise()
        .args(["gen", "--family"])
        .arg(&family)
        .output()
        .unwrap();
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("--out"));
}

/// `incise gen SCENARIO ARGS --out OUT`, which must succeed.
fn gen_into(scenario: &Path, args: &[&str], out: &Path) {
    succeeds(
        incise()
            .arg("gen")
            .arg(scenario)
            .args(args)
            .arg("--out")
            .arg(out),
    );
}

/// `incise gen` with `args` but no `--out`, on a copy of `scenario` in its own directory under
/// `tmp`: refused, naming `--out`, and nothing written beside the copy.
fn refused_without_out(tmp: &Path, scenario: &Path, args: &[&str]) {
    let elsewhere = tmp.join("unwritten");
    std::fs::create_dir_all(&elsewhere).unwrap();
    std::fs::copy(scenario, elsewhere.join("scenario.toml")).unwrap();
    let output = incise()
        .arg("gen")
        .arg(elsewhere.join("scenario.toml"))
        .args(args)
        .output()
        .unwrap();
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("--out"));
    assert_eq!(files(&elsewhere), [PathBuf::from("scenario.toml")]);
}

/// `--intact` writes the scene with its object left whole, with the scenario it came from (no
/// `[slit]`), so that `incise gen` on that file regenerates it: nothing opens, nothing is
/// detected, and the model is never cut. Without `--out` it is refused before anything is
/// written.
#[test]
fn gen_intact_writes_the_scene_with_its_object_left_whole() {
    let tmp = tempfile::tempdir().unwrap();
    let scenario = fixtures().join("band-side-cut/scenario.toml");
    let out = tmp.path().join("intact");
    gen_into(&scenario, &["--intact"], &out);
    let written: toml::Table =
        toml::from_str(&std::fs::read_to_string(out.join("scenario.toml")).unwrap()).unwrap();
    assert!(!written.contains_key("slit"));
    assert_eq!(written["name"].as_str(), Some("band-side-cut"));
    let cut = std::fs::read_to_string(out.join("gt/cut.csv")).unwrap();
    assert_eq!(cut.lines().count(), 1, "the true cut has rows: {cut}");

    let stdout = succeeds(incise().arg("run").arg(&out).arg("--json"));
    let run: serde_json::Value = serde_json::from_slice(&stdout).unwrap();
    assert!(run["cut_open_frame"].is_null());
    assert!(run["cut_detected_frame"].is_null());
    assert_eq!(run["cut_events"], 0);
    assert_eq!(run["dice_final"], run["dice_final_uncut"]);
    // The band pulled whole is followed closely (0.998 when written).
    assert!(run["dice_final"].as_f64().unwrap() > 0.99);

    refused_without_out(tmp.path(), &scenario, &["--intact"]);
}

/// `--model-mesh refined` writes the same scene modelled by the refined mesh: the same tracks
/// and truth, the refined grid's nodes, and a run of it measures against the same rest
/// baseline. Without `--out` it is refused before anything is written.
#[test]
fn gen_models_the_object_by_another_mesh_beside_the_same_truth() {
    let tmp = tempfile::tempdir().unwrap();
    let scenario = fixtures().join("band-side-cut/scenario.toml");
    let out = tmp.path().join("refined");
    gen_into(&scenario, &["--model-mesh", "refined"], &out);
    let own = fixtures().join("band-side-cut");
    for f in ["tracks.csv", "gt/cut.csv", "gt/targets.csv"] {
        assert_eq!(
            std::fs::read(own.join(f)).unwrap(),
            std::fs::read(out.join(f)).unwrap(),
            "{f} differs"
        );
    }
    let run = |dir: &Path| -> serde_json::Value {
        let stdout = succeeds(incise().arg("run").arg(dir).arg("--json"));
        serde_json::from_slice(&stdout).unwrap()
    };
    let (coarse, fine) = (run(&own), run(&out));
    // The scenario's 16 × 5 × 1 cells (17 · 6 · 2 nodes) refine to 32 × 10 × 2 cells.
    assert_eq!(coarse["nodes_initial"], 17 * 6 * 2);
    assert_eq!(fine["nodes_initial"], 33 * 11 * 3);
    // The targets at rest, embedded in either mesh, are where the truth has them (to rounding).
    let rest = |v: &serde_json::Value| v["tre_mm_final_rest"].as_f64().unwrap();
    assert!((rest(&coarse) - rest(&fine)).abs() < 1e-9);

    refused_without_out(tmp.path(), &scenario, &["--model-mesh", "fine"]);
}
