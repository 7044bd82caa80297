//! The committed scenes: every one runs, the cut scenes leave the uncut model a real gap while
//! the uncut band is followed closely, regenerating a scene gives the same bytes, and broken
//! scene files are reported with their file and line.

use std::path::{Path, PathBuf};

use incise::generate::pipeline::generate;
use incise::run::{RunOptions, Summary, run_scene};
use incise::scene::Scene;

const SCENES: [&str; 6] = [
    "band-side-cut",
    "band-middle-cut",
    "band-no-cut",
    "band-stiff",
    "block-extreme",
    "liver-lobe",
];

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures")
}

fn run(name: &str) -> Summary {
    let scene = Scene::load(&fixtures().join(name)).unwrap_or_else(|e| panic!("{e}"));
    run_scene(&scene, &RunOptions::default())
        .unwrap_or_else(|e| panic!("{name}: {e}"))
        .0
}

#[test]
fn every_committed_scene_runs_and_reports_the_json_fields() {
    for name in SCENES {
        let s = run(name);
        let json = serde_json::to_value(&s).unwrap();
        for key in [
            "scene",
            "frames",
            "features",
            "pairs",
            "cut_detected_frame",
            "dice_final_uncut",
            "dice_final",
            "dice_mean_after_cut",
            "surface_rmse_mm_final",
            "tre_mm_final",
            "tre_mm_final_uncut",
            "ms_per_frame_median",
            "ms_per_frame_max",
            "cut_open_frame",
            "cut_hausdorff_px",
            "pairs_lost",
            "image_width",
            "image_height",
        ] {
            assert!(json.get(key).is_some(), "{name}: no {key} in {json}");
        }
        assert_eq!(s.scene, name);
        assert_eq!(s.frames, 40);
        assert!((0.0..=1.0).contains(&s.dice_final), "{name}: {s:?}");
        assert!(s.surface_rmse_mm_final.is_finite() && s.tre_mm_final.is_finite());
        eprintln!(
            "{name:16} dice uncut {:.3} final {:.3} surface {:.2} mm tre {:.2} mm",
            s.dice_final_uncut, s.dice_final, s.surface_rmse_mm_final, s.tre_mm_final
        );
    }
}

#[test]
fn the_uncut_model_leaves_a_gap_on_the_side_cut_and_follows_the_uncut_band() {
    let side = run("band-side-cut");
    assert!(side.dice_final_uncut <= 0.92, "{side:?}");
    assert!(side.cut_open_frame.is_some());
    let none = run("band-no-cut");
    assert!(none.dice_final_uncut >= 0.97, "{none:?}");
    assert_eq!(none.cut_open_frame, None);
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

#[test]
fn regenerating_a_scene_gives_the_committed_bytes() {
    let committed = fixtures().join("band-no-cut");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("band-no-cut");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::copy(committed.join("scenario.toml"), out.join("scenario.toml")).unwrap();
    generate(&out.join("scenario.toml"), &out, false).unwrap();
    let (a, b) = (files(&committed), files(&out));
    assert_eq!(a, b, "different file lists");
    for f in &a {
        let (x, y) = (
            std::fs::read(committed.join(f)).unwrap(),
            std::fs::read(out.join(f)).unwrap(),
        );
        assert!(x == y, "{} differs from the committed file", f.display());
    }
}

/// A copy of a committed scene in a temporary directory, to break.
fn scratch_scene(name: &str) -> tempfile::TempDir {
    let tmp = tempfile::tempdir().unwrap();
    let from = fixtures().join(name);
    for f in files(&from) {
        let to = tmp.path().join(&f);
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(from.join(&f), &to).unwrap();
    }
    tmp
}

fn replace_in(path: &Path, from: &str, to: &str) {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(text.contains(from), "{} has no {from:?}", path.display());
    std::fs::write(path, text.replacen(from, to, 1)).unwrap();
}

fn line_of(path: &Path, needle: &str) -> usize {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .position(|l| l.contains(needle))
        .unwrap()
        + 1
}

#[test]
fn malformed_scene_files_name_the_file_and_line() {
    // A non-numeric value.
    let dir = scratch_scene("band-no-cut");
    let toml = dir.path().join("scene.toml");
    replace_in(&toml, "young = 30000.0", "young = \"soft\"");
    let err = Scene::load(dir.path()).unwrap_err();
    assert_eq!(err.file, toml);
    assert_eq!(err.line, line_of(&toml, "young = \"soft\""), "{err}");

    // A missing key.
    let dir = scratch_scene("band-no-cut");
    let toml = dir.path().join("scene.toml");
    replace_in(&toml, "poisson = 0.45\n", "");
    let err = Scene::load(dir.path()).unwrap_err();
    assert_eq!(err.file, toml);
    assert!(err.line > 0 && err.message.contains("poisson"), "{err}");

    // An id never seen at frame 0.
    let dir = scratch_scene("band-no-cut");
    let tracks = dir.path().join("tracks.csv");
    let text = std::fs::read_to_string(&tracks).unwrap();
    let first_row_of_frame_5 = text.lines().position(|l| l.starts_with("5,")).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let fields: Vec<&str> = lines[first_row_of_frame_5].split(',').collect();
    lines[first_row_of_frame_5] = format!("5,99999,{},{}", fields[2], fields[3]);
    std::fs::write(&tracks, lines.join("\n") + "\n").unwrap();
    let err = Scene::load(dir.path()).unwrap_err();
    assert_eq!(err.file, tracks);
    assert_eq!(err.line, first_row_of_frame_5 + 1, "{err}");
    assert!(err.message.contains("99999"), "{err}");

    // A non-numeric coordinate in the tracks.
    let dir = scratch_scene("band-no-cut");
    let tracks = dir.path().join("tracks.csv");
    let text = std::fs::read_to_string(&tracks).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    lines[7] = "0,3,abc,1.0".into();
    std::fs::write(&tracks, lines.join("\n") + "\n").unwrap();
    let err = Scene::load(dir.path()).unwrap_err();
    assert_eq!((err.file.clone(), err.line), (tracks, 8), "{err}");

    // A truncated mesh.
    let dir = scratch_scene("band-no-cut");
    let mesh = dir.path().join("model.msh");
    let text = std::fs::read_to_string(&mesh).unwrap();
    let keep: Vec<&str> = text.lines().take(60).collect();
    std::fs::write(&mesh, keep.join("\n") + "\n").unwrap();
    let err = Scene::load(dir.path()).unwrap_err();
    assert_eq!(err.file, mesh, "{err}");
    assert!(err.line >= 59, "{err}");

    // A fixed node that does not exist.
    let dir = scratch_scene("band-no-cut");
    let toml = dir.path().join("scene.toml");
    replace_in(&toml, "fixed = [", "fixed = [100000, ");
    let err = Scene::load(dir.path()).unwrap_err();
    assert!(err.message.contains("100000"), "{err}");
}

/// However stiff the springs, the targets end nearer the truth than the rest model's (the
/// stability envelope's standard, `incise report`). The springs act across the
/// camera rays only (`core-nostd/src/solve.rs`, `W_S`), so they cannot fit the tracker's noise
/// with depth, and the depth prior keeps its ratio to them (`W_R`), so what the model cannot
/// match is not shed along the rays; and no spring pulls harder than the default coupling's
/// (`DEFAULT_SPRING_THRESHOLD`), so features the model cannot follow do not tear it out of
/// shape. Before the first, `band-stiff` at 10⁶ times its coupling
/// put its targets 176 mm from the truth (the rest model: 3.7 mm) and `block-extreme` 75 mm
/// (7.0 mm); before the second, `band-side-cut` 36 mm (21.2 mm); before the third,
/// `liver-lobe` 6.8 mm (3.3 mm).
#[test]
fn stiff_springs_do_not_move_the_model_in_depth() {
    let scenes = [
        "band-no-cut",
        "band-stiff",
        "block-extreme",
        "band-side-cut",
        "band-live-cut",
        "band-middle-cut",
        "liver-lobe",
    ];
    for name in scenes {
        let mut scene = Scene::load(&fixtures().join(name)).unwrap_or_else(|e| panic!("{e}"));
        let own = incise_core::solve::DEFAULT_COUPLING;
        assert_eq!(
            scene.file.solver.coupling, None,
            "{name} keeps the default coupling"
        );
        scene.file.solver.coupling = Some(own * 1e6);
        let s = run_scene(&scene, &RunOptions::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"))
            .0;
        let at_default = run(name);
        let rest = s.tre_mm_final_rest;
        eprintln!(
            "{name}: springs × 10⁶: TRE {:.2} mm, at the default {:.2} mm, rest {rest:.2} mm",
            s.tre_mm_final, at_default.tre_mm_final
        );
        assert_eq!(s.frames_rejected, 0, "{name}: {s:?}");
        assert!(s.tre_mm_final < rest, "{name}: {s:?}");
    }
}

/// Issue 10's acceptance, as far as the committed cut scenes reach it, kept from slipping back:
/// on `band-side-cut` all of it (Dice at least 0.97, at least 75 % of the uncut model's Dice
/// deficit closed, the targets at least 40 % nearer the truth than the uncut model's and nearer
/// than the rest model's); on `band-middle-cut` the Dice and the targets; on `liver-lobe` the
/// targets nearer than the rest model's, and at least 40 % of its deficit closed (42 % since a
/// cut event cuts along the whole line as it is seen then, 32 % when it cut only the segments
/// added since the last event: the line's first vertices, fitted tilted across the cut, are
/// straightened later, and the material between is cut then). What is missing (the middle cut
/// closes 69 % of the deficit, the liver 42 % with a Dice of 0.953) is in the README under
/// "Scenes".
#[test]
fn the_cut_scenes_keep_what_they_reach_of_issue_10() {
    let closed = |s: &Summary| (s.dice_final - s.dice_final_uncut) / (1.0 - s.dice_final_uncut);
    let side = run("band-side-cut");
    assert!(side.dice_final >= 0.97, "{side:?}");
    assert!(closed(&side) >= 0.75, "{side:?}");
    let middle = run("band-middle-cut");
    assert!(middle.dice_final >= 0.97, "{middle:?}");
    for s in [&side, &middle] {
        assert!(s.tre_mm_final <= 0.6 * s.tre_mm_final_uncut, "{s:?}");
    }
    let liver = run("liver-lobe");
    assert!(closed(&liver) >= 0.40, "{liver:?}");
    for s in [&side, &middle, &liver] {
        eprintln!(
            "{}: Dice {:.3} (uncut {:.3}, {:.0} % closed), targets {:.2} mm (uncut {:.2}, rest {:.2})",
            s.scene,
            s.dice_final,
            s.dice_final_uncut,
            100.0 * closed(s),
            s.tre_mm_final,
            s.tre_mm_final_uncut,
            s.tre_mm_final_rest
        );
        assert!(s.dice_final > s.dice_final_uncut, "{s:?}");
        assert!(s.tre_mm_final < s.tre_mm_final_rest, "{s:?}");
    }
}
