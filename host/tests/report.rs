//! `incise report --quick` on every committed scene: the page, its figures and its data are
//! written and well formed, no work counter of any frame exceeds its worst-case formula, and
//! the stability grid holds no failure.

mod common;

use std::path::Path;
use std::process::Command;

use common::committed_scenes;
use serde_json::Value;

/// The fields of one CSV line (double quotes around a field that holds commas).
fn fields(line: &str) -> Vec<String> {
    let mut out = vec![String::new()];
    let mut quoted = false;
    for c in line.chars() {
        match c {
            '"' => quoted = !quoted,
            ',' if !quoted => out.push(String::new()),
            c => out.last_mut().unwrap().push(c),
        }
    }
    assert!(!quoted, "unbalanced quotes: {line}");
    out
}

/// Every line of the CSV file has as many fields as its header; the rows.
fn csv_rows(path: &Path) -> Vec<Vec<String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = fields(lines.next().expect("a header"));
    let rows: Vec<Vec<String>> = lines.map(fields).collect();
    for row in &rows {
        assert_eq!(row.len(), header.len(), "{}: {row:?}", path.display());
    }
    rows
}

#[test]
fn quick_report_on_every_committed_scene_is_written_and_well_formed() {
    let scenes = committed_scenes();
    assert!(scenes.len() >= 7, "{scenes:?}");
    let out = tempfile::tempdir().unwrap();
    let status = Command::new(env!("CARGO_BIN_EXE_incise"))
        .arg("report")
        .args(&scenes)
        .arg("--out")
        .arg(out.path())
        .arg("--quick")
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );

    let json: Value =
        serde_json::from_str(&std::fs::read_to_string(out.path().join("report.json")).unwrap())
            .unwrap();
    // The cost-growth variants are generated only without --quick.
    assert!(json["scaling"].is_null());
    let reported = json["scenes"].as_array().unwrap();
    assert_eq!(reported.len(), scenes.len());
    let counting = Command::new("valgrind").arg("--version").output().is_ok();
    // Tetrahedra left inside out after the mirrored frames, over the scenes: with the
    // inversion barrier, with SVK alone.
    let mut inverted_left = [0u64; 2];
    for scene in reported {
        let name = scene["name"].as_str().unwrap();
        let settings = scene["settings"].as_array().unwrap();
        assert!(settings.len() >= 4, "{name}");
        assert_eq!(settings[0]["own"], true, "{name}: its own setting first");
        // Then the same in single and in mixed precision, within the stated tolerance of it
        // where both end with the same mesh (`tests/precision.rs`: where a cut event rounded to
        // other nodes, the runs are compared with their uncut models there).
        assert_eq!(settings[0]["precision"], "f64", "{name}");
        for (other, precision) in [(&settings[1], "f32"), (&settings[2], "mixed")] {
            assert_eq!(other["precision"], precision, "{name}");
            if other["mesh_final"] != settings[0]["mesh_final"] {
                continue;
            }
            let delta = |key: &str| {
                (other[key].as_f64().unwrap() - settings[0][key].as_f64().unwrap()).abs()
            };
            assert!(delta("dice_final") <= 0.005, "{name}: {other}");
            assert!(delta("tre_mm_final") <= 0.5, "{name}: {other}");
        }
        // The precisions differ in mesh on the middle cut only (see `tests/precision.rs`).
        let same_mesh = settings[1..3]
            .iter()
            .all(|other| other["mesh_final"] == settings[0]["mesh_final"]);
        assert!(
            same_mesh || name == "band-middle-cut",
            "{name}: {settings:?}"
        );
        for s in settings {
            for key in ["dice_final", "tre_mm_final", "ms_median"] {
                let v = s[key].as_f64().unwrap();
                assert!(v.is_finite() && v >= 0.0, "{name}: {key} = {v}");
            }
        }
        // The front is not empty and the recommendation is on it.
        let front: Vec<u64> = scene["front"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap())
            .collect();
        assert!(!front.is_empty(), "{name}");
        let recommended = scene["recommended"].as_u64().unwrap();
        assert!(front.contains(&recommended), "{name}");
        // No counter exceeds its formula, in a frame or in a cut event.
        let rows = scene["worst_case"].as_array().unwrap();
        assert!(rows.len() >= 10, "{name}");
        for row in rows.iter().chain(scene["cut_events"].as_array().unwrap()) {
            let ratio = row["max_over_formula"].as_f64().unwrap();
            assert!(ratio <= 1.0, "{name}: {row}");
        }
        // The stability grid (`--quick`): the scene's own material with springs at 10⁻³, 1
        // and 10³ times its own coupling; at 10³ in f64, f32 and mixed precision (8 Newton
        // steps of `Refactor`); its tracks with 3 px of noise and 20 % outliers; its tracks with
        // the first frames after frame 0 mirrored (the model pulled inside out), with the
        // inversion barrier and with SVK alone, and on block-extreme the block generated
        // squeezed to 60 % of its length, in f32.
        // Nothing non-finite and no panic anywhere; at the scene's own k and its own tracks
        // the targets end nearer the truth than the rest model's; no cell places them more
        // than 1.2 times farther than the rest model's; mixed precision
        // settles within 10× of f64's residual.
        let cells = scene["stability"].as_array().unwrap();
        let compression = name == "block-extreme";
        assert_eq!(cells.len(), 9 + usize::from(compression), "{name}");
        let mirrored = |barrier: bool| {
            cells
                .iter()
                .find(|c| c["mirrored_frames"].as_u64() == Some(3) && c["barrier"] == barrier)
                .unwrap_or_else(|| panic!("{name}: no mirrored cell with barrier {barrier}"))
        };
        // The barrier turns elements back out: never more are left inside out with it than
        // with SVK alone.
        let (with, without) = (mirrored(true), mirrored(false));
        assert!(
            with["inverted_final"].as_u64() <= without["inverted_final"].as_u64(),
            "{name}: {with} against {without}"
        );
        inverted_left[0] += with["inverted_final"].as_u64().unwrap();
        inverted_left[1] += without["inverted_final"].as_u64().unwrap();
        if compression {
            // Squeezed to 60 %: registered nearer than the rest model, nothing left inside out.
            let cell = cells
                .iter()
                .find(|c| c["compression"].as_f64() == Some(0.6))
                .unwrap();
            assert!(
                cell["tre_mm_final"].as_f64().unwrap() < cell["tre_mm_rest"].as_f64().unwrap(),
                "{cell}"
            );
            assert_eq!(cell["inverted_final"], 0, "{cell}");
        }
        for cell in cells {
            assert_ne!(cell["status"], "failure", "{name}: {cell}");
            let tre = cell["tre_mm_final"].as_f64().unwrap();
            let rest = cell["tre_mm_rest"].as_f64().unwrap();
            if cell["k_scale"].as_f64().unwrap() == 1.0 && cell["block"] == "material" {
                assert!(tre < rest, "{name}: {cell}");
            }
            assert!(tre <= 1.2 * rest, "{name}: {cell}");
        }
        let gradient = |precision: &str| {
            let cell = cells
                .iter()
                .find(|c| c["block"] == "precision" && c["precision"] == precision)
                .unwrap();
            cell["relative_gradient"].as_f64().unwrap()
        };
        assert!(
            gradient("mixed") <= 10.0 * gradient("f64").max(1e-14),
            "{name}: mixed {} against f64 {}",
            gradient("mixed"),
            gradient("f64")
        );
        let memory = scene["memory"].as_array().unwrap();
        assert_eq!(memory.len(), 10, "{name}");
        if counting {
            let frames = scene["instructions_per_frame"].as_array().unwrap();
            assert_eq!(frames.len(), 5, "{name}");
            assert!(
                frames.iter().all(|c| c.as_u64().unwrap() > 1_000_000),
                "{name}"
            );
        }
    }

    assert!(
        inverted_left[0] < inverted_left[1],
        "the barrier left {} inside out, SVK alone {}",
        inverted_left[0],
        inverted_left[1]
    );

    let rows = csv_rows(&out.path().join("error_vs_cost.csv"));
    assert_eq!(rows.len(), 4 * scenes.len());
    assert!(csv_rows(&out.path().join("worst_case.csv")).len() >= 13 * scenes.len());
    assert_eq!(
        csv_rows(&out.path().join("memory.csv")).len(),
        10 * scenes.len()
    );
    let instructions = csv_rows(&out.path().join("instructions.csv"));
    assert_eq!(
        instructions.len(),
        if counting { 5 * scenes.len() } else { 0 }
    );

    let summary = std::fs::read_to_string(out.path().join("summary.md")).unwrap();
    assert_eq!(summary.lines().count(), 2 + scenes.len(), "{summary}");

    let html = std::fs::read_to_string(out.path().join("index.html")).unwrap();
    assert_eq!(
        csv_rows(&out.path().join("stability.csv")).len(),
        9 * scenes.len() + 1
    );
    for section in [
        "id=\"error\"",
        "id=\"worst\"",
        "id=\"stability\"",
        "id=\"memory\"",
    ] {
        assert!(html.contains(section), "{section}");
    }
    assert!(html.trim_end().ends_with("</html>"));
    // Every figure is inline, and also a file of its own.
    let figures = if counting { 2 } else { 1 } * scenes.len();
    assert_eq!(html.matches("<svg").count(), figures);
    let svgs = std::fs::read_dir(out.path())
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "svg")
        })
        .count();
    assert_eq!(svgs, figures);
}
