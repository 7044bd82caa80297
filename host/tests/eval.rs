//! `incise eval` over the committed scene families (`fixtures/families/`).
//!
//! In CI: the first variant of each kind of each family, end to end through the command line
//! (generate, run, sum up, JSON), checked for consistency and for being reproduced from the
//! scenes it keeps. Issue 11's acceptance over the whole families is
//! `families_meet_the_detection_acceptance`, ignored until it holds (about five minutes):
//! `cargo test -p incise --test eval -- --ignored`.

use std::path::{Path, PathBuf};
use std::process::Command;

use incise::eval::{ACCEPTANCE, EvalOptions, Selection, eval_family, markdown_table};
use incise::generate::pipeline::ModelMesh;

fn families() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/families");
    ["band", "dome", "liver"]
        .iter()
        .map(|f| dir.join(format!("{f}.toml")))
        .collect()
}

/// `incise eval FAMILIES --per-kind 1 --json --work WORK EXTRA…`, parsed.
fn eval_json_of(families: &[PathBuf], work: &Path, extra: &[&str]) -> serde_json::Value {
    let json = [&["--json"], extra].concat();
    serde_json::from_slice(&eval_output(families, work, &json)).unwrap()
}

/// `incise eval FAMILIES --per-kind 1 --work WORK ARGS…`, its output, once it succeeded.
fn eval_output(families: &[PathBuf], work: &Path, args: &[&str]) -> Vec<u8> {
    let out = Command::new(env!("CARGO_BIN_EXE_incise"))
        .arg("eval")
        .args(families)
        .args(["--per-kind", "1", "--work"])
        .arg(work)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

fn eval_json(work: &Path) -> serde_json::Value {
    eval_json_of(&families(), work, &[])
}

#[test]
fn eval_runs_one_variant_of_each_kind_and_sums_them_up_consistently() {
    let tmp = tempfile::tempdir().unwrap();
    let first = eval_json(tmp.path());
    let list = first.as_array().unwrap();
    assert_eq!(list.len(), 3);
    for f in list {
        let name = f["family"].as_str().unwrap();
        let variants = f["variants"].as_array().unwrap();
        let kinds: Vec<&str> = variants
            .iter()
            .map(|v| v["kind"].as_str().unwrap())
            .collect();
        let mut sorted = kinds.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, ["intact", "live", "pre-cut"], "{name}");
        assert_eq!(f["intact"], 1);
        assert_eq!(f["cut"], 2);
        assert_eq!(f["live"], 1);
        let (mut false_cuts, mut missed) = (0, 0);
        for v in variants {
            let s = &v["summary"];
            assert!(
                tmp.path()
                    .join(name)
                    .join(v["name"].as_str().unwrap())
                    .join("scene.toml")
                    .is_file()
            );
            let dice = s["dice_final"].as_f64().unwrap();
            assert!((0.0..=1.0).contains(&dice), "{v}");
            if v["kind"] == "intact" {
                assert!(v["latency"].is_null() && v["hausdorff_percent"].is_null());
                assert!(
                    s["cut_open_frame"].is_null(),
                    "an intact variant opens: {v}"
                );
                false_cuts += usize::from(v["false_cut"].as_bool().unwrap());
            } else {
                let open = s["cut_open_frame"].as_i64().expect("a cut opens");
                match s["cut_detected_frame"].as_i64() {
                    Some(d) => {
                        assert_eq!(v["latency"].as_i64(), Some(d - open));
                        // The Hausdorff distance is the larger of its two directed halves.
                        let halves = [&v["line_to_cut_percent"], &v["cut_to_line_percent"]]
                            .map(|h| h.as_f64().expect("both halves of a detected line"));
                        assert_eq!(
                            v["hausdorff_percent"].as_f64(),
                            Some(halves[0].max(halves[1])),
                            "{v}"
                        );
                        // A line starts on as many separation points as its start needs, so
                        // a cut found after it opens had that evidence by then: the latency
                        // is the wait for it and then for the start.
                        if d >= open {
                            let evidence = s["cut_evidence_frame"].as_i64().expect("evidence");
                            assert!((open..=d).contains(&evidence), "{v}");
                            let waits = [&v["evidence_wait"], &v["start_wait"]]
                                .map(|w| w.as_i64().expect("a wait"));
                            assert_eq!(waits, [evidence - open, d - evidence], "{v}");
                        }
                    }
                    None => {
                        assert!(v["missed"].as_bool().unwrap());
                        missed += 1;
                    }
                }
            }
        }
        assert_eq!(f["false_cuts"], false_cuts, "{name}");
        assert_eq!(f["missed"], missed, "{name}");
    }
    // A second run reuses the scenes it wrote and gives the same numbers (timings aside),
    // drawing its pictures or not.
    let pictures = tmp.path().join("pictures");
    let second = eval_json_of(
        &families(),
        tmp.path(),
        &["--pictures", pictures.to_str().unwrap()],
    );
    for f in second.as_array().unwrap() {
        let name = f["family"].as_str().unwrap();
        let variants = f["variants"].as_array().unwrap();
        // Each variant's last frame at full size, and a sheet of them at half size, five to a
        // row under their captions.
        let mut size = None;
        for v in variants {
            let file = pictures
                .join(name)
                .join(format!("{}.png", v["name"].as_str().unwrap()));
            let picture = image::open(&file).unwrap();
            assert!(picture.width() > 100, "{}", file.display());
            size = Some((picture.width(), picture.height()));
        }
        let (w, h) = size.unwrap();
        let sheet = image::open(pictures.join(format!("{name}.png"))).unwrap();
        assert_eq!(sheet.width(), 5 * (w / 2), "{name}");
        assert!(sheet.height() > h / 2, "{name}");
    }
    assert_eq!(without_timings(first.clone()), without_timings(second));
    // Reading the pairs as the oracle would changes no result, and its tests weaken in order
    // of level, frames and pairs: a weaker one holds no later (a cut variant) and in no fewer
    // frames (an intact one).
    let plot = tmp.path().join("evidence.svg");
    let third = eval_json_of(
        &families(),
        tmp.path(),
        &["--evidence", "--plot", plot.to_str().unwrap()],
    );
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("<circle"), "{svg}");
    let mut read = third.clone();
    for f in read.as_array_mut().unwrap() {
        f.as_object_mut()
            .unwrap()
            .insert("evidence".into(), serde_json::Value::Null);
        for v in f["variants"].as_array_mut().unwrap() {
            v.as_object_mut()
                .unwrap()
                .insert("evidence".into(), serde_json::Value::Null);
        }
    }
    assert_eq!(without_timings(first), without_timings(read));
    // The same per variant, as text: one row per variant after the oracle's heading, a cell per
    // test and per level.
    let out = eval_output(&families()[..1], tmp.path(), &["--evidence", "--variants"]);
    let text = String::from_utf8(out).unwrap();
    let table: Vec<&str> = text
        .split("read by the oracle")
        .nth(1)
        .expect("the per-variant oracle table")
        .lines()
        .filter(|l| l.starts_with("| band-"))
        .collect();
    assert_eq!(table.len(), 3, "{text}");
    for row in table {
        let cells = 2 + incise::eval::evidence::TESTS.len() + incise::eval::evidence::LEVELS.len();
        assert_eq!(row.matches('|').count(), cells + 1, "{row}");
    }
    for f in third.as_array().unwrap() {
        let rows = f["evidence"]["tests"].as_array().expect("evidence rows");
        // The cut left beyond the crossing pairs: a share of the diagonal per variant and
        // level, and the family's rows count the variants without any such pair.
        let coverage = f["evidence"]["coverage"].as_array().unwrap();
        let cut_variants: Vec<&serde_json::Value> = f["variants"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|v| v["kind"] != "intact")
            .collect();
        for (k, row) in coverage.iter().enumerate() {
            let gaps: Vec<Option<f64>> = cut_variants
                .iter()
                .map(|v| v["evidence"]["end_gap_percent"][k].as_f64())
                .collect();
            assert!(
                gaps.iter().flatten().all(|g| (0.0..=100.0).contains(g)),
                "{gaps:?}"
            );
            let none = gaps.iter().filter(|g| g.is_none()).count();
            assert_eq!(row["none"].as_u64(), Some(none as u64), "{row}");
        }
        let tests: Vec<[f64; 3]> = rows
            .iter()
            .map(|r| ["deviations", "frames", "pairs"].map(|k| r["test"][k].as_f64().unwrap()))
            .collect();
        assert_eq!(tests[0], [6.0, 2.0, 6.0], "the detector's own test first");
        for v in f["variants"].as_array().unwrap() {
            let e = &v["evidence"];
            let (key, intact) = if v["kind"] == "intact" {
                ("frames_held", true)
            } else {
                ("oracle_latency", false)
            };
            let per_test = e[key].as_array().unwrap();
            assert_eq!(per_test.len(), tests.len(), "{v}");
            for (a, ta) in tests.iter().enumerate() {
                for (b, tb) in tests.iter().enumerate() {
                    if (0..3).any(|k| tb[k] > ta[k]) {
                        continue;
                    }
                    let (x, y) = (&per_test[a], &per_test[b]);
                    if intact {
                        assert!(y.as_u64() >= x.as_u64(), "{} {a} {b}: {e}", v["name"]);
                    } else if let Some(x) = x.as_i64() {
                        assert!(
                            y.as_i64().is_some_and(|y| y <= x),
                            "{} {a} {b}: {e}",
                            v["name"]
                        );
                    }
                }
            }
        }
    }
}

/// The summaries with their timings taken out (the rest is reproduced run to run).
fn without_timings(mut families: serde_json::Value) -> serde_json::Value {
    for f in families.as_array_mut().unwrap() {
        for variant in f["variants"].as_array_mut().unwrap() {
            let s = variant["summary"].as_object_mut().unwrap();
            s.retain(|k, _| !k.starts_with("ms_"));
        }
    }
    families
}

#[test]
fn a_sweep_runs_every_setting_and_its_defaults_are_the_plain_run() {
    let tmp = tempfile::tempdir().unwrap();
    let band = &families()[..1];
    let plain = eval_json_of(band, tmp.path(), &[]);
    let plot = tmp.path().join("sweep.svg");
    let rows = eval_json_of(
        band,
        tmp.path(),
        &[
            "--sweep",
            "persistence=1,2",
            "--plot",
            plot.to_str().unwrap(),
        ],
    );
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!(rows[0]["settings"], serde_json::json!(["persistence = 1"]));
    assert_eq!(rows[0]["defaults"], false);
    assert_eq!(rows[1]["defaults"], true);
    // The defaults' row is the plain run, and every family pooled sums its families up.
    assert_eq!(
        without_timings(rows[1]["families"].clone()),
        without_timings(plain)
    );
    for r in rows {
        assert_eq!(r["all"]["family"], "all");
        let families = r["families"].as_array().unwrap();
        for key in ["false_cuts", "missed", "intact", "cut"] {
            let sum: u64 = families.iter().map(|f| f[key].as_u64().unwrap()).sum();
            assert_eq!(r["all"][key].as_u64(), Some(sum), "{key}");
        }
    }
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("<circle"), "{svg}");
}

#[test]
fn a_setting_that_is_no_field_is_refused_before_anything_runs() {
    let tmp = tempfile::tempdir().unwrap();
    for args in [
        ["--set", "persistance=1"],
        ["--sweep", "persistence=0,1"],
        ["--set", "outlier_sigmas"],
        ["--plot", "plot.svg"],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_incise"))
            .arg("eval")
            .args(families())
            .arg("--work")
            .arg(tmp.path().join("work"))
            .args(args)
            .output()
            .unwrap();
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("persistance")
                || err.contains("persistence")
                || err.contains("KEY")
                || err.contains("--plot needs"),
            "{args:?}: {err}"
        );
        assert!(!tmp.path().join("work").exists(), "{args:?}");
    }
}

/// The `seed =` line of a variant's scenario.
fn variant_seed(dir: &Path) -> String {
    let text = std::fs::read_to_string(dir.join("scenario.toml")).unwrap();
    text.lines()
        .find(|l| l.starts_with("seed"))
        .unwrap()
        .to_string()
}

#[test]
fn another_seed_draws_other_variants_kept_apart() {
    let tmp = tempfile::tempdir().unwrap();
    let run = |extra: &[&str]| eval_json_of(&families()[..1], tmp.path(), extra);
    let own = run(&[]);
    let other = run(&["--seed", "7"]);
    let name = |v: &serde_json::Value| v[0]["variants"][0]["name"].as_str().unwrap().to_string();
    let first = name(&own);
    assert_eq!(first, name(&other));
    let (own_dir, other_dir) = (
        tmp.path().join("band").join(&first),
        tmp.path().join("band-seed-7").join(&first),
    );
    // Each run wrote its own variants, and they were drawn differently.
    assert_ne!(variant_seed(&own_dir), variant_seed(&other_dir));
    // The family's own seed given again is the family's own variants, in its own folder.
    run(&["--seed", "1"]);
    assert!(!tmp.path().join("band-seed-1").exists());
    // The same variants modelled by the refined mesh: their own folder, the same truth
    // (the rest model's target error), eight times as many tetrahedra in the model.
    let refined = run(&["--model-mesh", "refined"]);
    let refined_dir = tmp.path().join("band-refined").join(&first);
    let summary =
        |v: &serde_json::Value, key: &str| v[0]["variants"][0]["summary"][key].as_f64().unwrap();
    assert!(
        (summary(&own, "tre_mm_final_rest") - summary(&refined, "tre_mm_final_rest")).abs() < 1e-9
    );
    assert!(summary(&refined, "nodes_initial") > summary(&own, "nodes_initial"));
    let tets = |dir: &Path| incise::scene::Scene::load(dir).unwrap().tets.len();
    assert_eq!(tets(&refined_dir), 8 * tets(&own_dir));
}

#[test]
#[ignore = "issue 11: not met yet (see the README's family table)"]
fn families_meet_the_detection_acceptance() {
    let tmp = tempfile::tempdir().unwrap();
    let options = EvalOptions {
        work: tmp.path().to_path_buf(),
        selection: Selection::default(),
        fresh: false,
        progress: false,
        law: None,
        seed: None,
        model_mesh: ModelMesh::Scenario,
        pictures: None,
        detection: vec![],
        evidence: false,
    };
    let done: Vec<_> = families()
        .iter()
        .map(|f| eval_family(f, &options).unwrap())
        .collect();
    let (intact, cut): (usize, usize) = done
        .iter()
        .fold((0, 0), |(i, c), f| (i + f.intact, c + f.cut));
    assert!(intact >= 20 && cut >= 20, "{intact} intact, {cut} cut");
    assert!(
        done.iter().all(|f| f.passes),
        "{ACCEPTANCE:?}\n{}",
        markdown_table(&done)
    );
}
