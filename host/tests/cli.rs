//! The `incise` binary as a user runs it.

use std::process::Command;

mod common;

fn incise() -> Command {
    Command::new(env!("CARGO_BIN_EXE_incise"))
}

/// Fails the test with the command's standard error unless it succeeded.
fn assert_succeeded(output: &std::process::Output) {
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

#[test]
fn demo_writes_pictures_and_a_summary() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("demo");
    let output = incise()
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["demo", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert_succeeded(&output);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(stdout.contains("Dice last frame"), "{stdout}");
    // The demo's cut is detected: how far its line ends from the true cut.
    assert!(
        stdout.contains("cut line at the last frame:") && stdout.contains("% from the line"),
        "{stdout}"
    );
    for f in [
        "overview.png",
        "dice.svg",
        "frames/frame_0000.png",
        "frames/frame_0039.png",
        "frames/mesh.pvd",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
}

#[test]
fn run_json_is_one_object() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/band-no-cut");
    let output = incise().args(["run", scene, "--json"]).output().unwrap();
    assert_succeeded(&output);
    let v: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(v["scene"], "band-no-cut");
    assert!(v["cut_detected_frame"].is_null());
    // The features the filter took out, each once, and its measure against the scene's list
    // of jumping features: every one taken out is a jump or a genuine feature.
    let filtered = v["filtered_features"].as_array().unwrap();
    assert_eq!(
        filtered.len() as u64,
        v["features_filtered"].as_u64().unwrap()
    );
    let truth = &v["filter_truth"];
    let count = |k: &str| truth[k].as_u64().unwrap();
    assert_eq!(
        count("outliers_filtered") + count("genuine_filtered"),
        filtered.len() as u64
    );
    assert!(count("outliers_filtered") <= count("outliers"));
}

#[test]
fn table_prints_the_filter_against_the_true_jumps_when_asked() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/band-no-cut");
    let output = incise()
        .args(["table", "--filter", scene])
        .output()
        .unwrap();
    assert_succeeded(&output);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        stdout.contains("| jumps made | jumps taken out |"),
        "{stdout}"
    );
    // The scene table's row and the filter table's.
    assert_eq!(
        stdout.matches("| band-no-cut | 300 |").count(),
        2,
        "{stdout}"
    );
}

/// `table --set` runs the scenes under a detection setting: switched off, the side cut is
/// neither found nor cut; a field that `[detection]` does not have is refused by name.
#[test]
fn table_runs_the_scenes_under_a_detection_setting() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/band-side-cut");
    let row = |extra: &[&str]| {
        let output = incise()
            .arg("table")
            .args(extra)
            .arg(scene)
            .output()
            .unwrap();
        assert_succeeded(&output);
        let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
        let line = stdout.lines().find(|l| l.starts_with("| band-side-cut |"));
        // The cells up to the Dice, the timings left out.
        line.unwrap()
            .split('|')
            .take(9)
            .collect::<Vec<_>>()
            .join("|")
    };
    let plain = row(&[]);
    assert_eq!(row(&["--set", "persistence=2"]), plain);
    let off = row(&["--set", "enabled=false"]);
    assert_ne!(off, plain);
    assert!(off.contains("| – | – |"), "{off}");
    let output = incise()
        .args(["table", "--set", "persistance=2", scene])
        .output()
        .unwrap();
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("persistance"));
}

/// `--pairs` draws the detector's split pairs (orange) on the overlays: none at frame 0,
/// many once the side cut is found (frame 7).
#[test]
fn run_draws_the_detector_pairs_when_asked() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/band-side-cut");
    let tmp = tempfile::tempdir().unwrap();
    let (plain, pairs) = (tmp.path().join("plain"), tmp.path().join("pairs"));
    for (out, extra) in [(&plain, None), (&pairs, Some("--pairs"))] {
        let output = incise()
            .args(["run", scene, "--json", "--out"])
            .arg(out)
            .args(extra)
            .output()
            .unwrap();
        assert_succeeded(&output);
    }
    let split = image::Rgb([255u8, 160, 0]);
    let count = |dir: &std::path::Path, f: &str| {
        let img = image::open(dir.join(f)).unwrap().to_rgb8();
        img.pixels().filter(|p| **p == split).count()
    };
    // At frame 0 no pair is split: the legend's swatch is the only orange added.
    let legend = count(&pairs, "frame_0000.png") - count(&plain, "frame_0000.png");
    assert!((50..200).contains(&legend), "{legend}");
    let with = count(&pairs, "frame_0009.png") - legend;
    let without = count(&plain, "frame_0009.png");
    assert!(
        with > without + 200,
        "{with} orange pixels with --pairs, {without} without"
    );
    // And `pairs.csv`: every measured pair of every frame after the first, what its test read
    // and whether it crosses the true cut; an outlier lies above its level, and the pairs
    // that cross the true cut carry the evidence the detector found.
    assert!(!plain.join("pairs.csv").exists());
    let text = std::fs::read_to_string(pairs.join("pairs.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (frame, difference, level, outlier, split, crosses) = (
        column("frame"),
        column("difference_px"),
        column("level_px"),
        column("outlier"),
        column("split"),
        column("crosses_true_cut"),
    );
    let (mut rows, mut outliers, mut crossing_outliers) = (0, 0, 0);
    for line in lines {
        let cells: Vec<&str> = line.split(',').collect();
        assert_eq!(cells.len(), header.len(), "{line}");
        assert!(cells[frame].parse::<usize>().unwrap() >= 1, "{line}");
        let number = |k: usize| cells[k].parse::<f64>().unwrap();
        if cells[outlier] == "1" {
            assert!(number(difference) > number(level), "{line}");
            outliers += 1;
            crossing_outliers += usize::from(cells[crosses] == "1");
        }
        assert!(cells[split] == "0" || cells[split] == "1", "{line}");
        assert!(cells[crosses] == "0" || cells[crosses] == "1", "{line}");
        rows += 1;
    }
    assert!(rows > 10_000, "{rows} rows");
    assert!(
        outliers > 0 && 2 * crossing_outliers > outliers,
        "{crossing_outliers} of {outliers} outliers cross the true cut"
    );
    let frames = std::fs::read_to_string(pairs.join("frames.csv")).unwrap();
    assert!(frames.starts_with("frame,dice,tre_mm,step_ms,observed,outlier_pairs,separation_points,difference_median_px,difference_deviation_px,"));
}

#[test]
fn a_missing_scene_is_a_clear_error() {
    let output = incise()
        .args(["run", "/nonexistent/scene"])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("scene.toml") && stderr.contains("cannot read"),
        "{stderr}"
    );
}

#[test]
fn a_closed_output_pipe_ends_quietly() {
    // The reader goes away before anything is printed, as `incise run … | head -c 0` would.
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/band-no-cut");
    let mut child = incise()
        .args(["run", scene])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(
        output.status.code(),
        Some(incise::cli::BROKEN_PIPE_STATUS),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!stderr.contains("Broken pipe"), "{stderr}");
}

/// `incise instructions`: one CSV line per frame with callgrind's count, or, without
/// valgrind, a clear refusal.
#[test]
fn instructions_counts_every_frame_or_says_why_not() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/band-side-cut");
    let output = incise()
        .args(["instructions", scene, "--frames", "8", "--real", "f32"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    if Command::new("valgrind").arg("--version").output().is_err() {
        assert_eq!(output.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains("valgrind"), "{stderr}");
        return;
    }
    assert!(output.status.success(), "{stderr}");
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines[0], "frame,instructions,cut_event,cut_work");
    assert_eq!(lines.len(), 9, "{stdout}");
    for (k, line) in lines[1..].iter().enumerate() {
        let fields: Vec<&str> = line.split(',').collect();
        assert_eq!(fields[0], (k + 1).to_string());
        let count: u64 = fields[1].parse().unwrap();
        assert!(count > 1_000_000, "{line}");
        assert!(["true", "false"].contains(&fields[2]), "{line}");
        assert!(["true", "false"].contains(&fields[3]), "{line}");
        // A frame that cut the mesh ran a cut event.
        assert!(fields[2] == "false" || fields[3] == "true", "{line}");
    }
    // band-side-cut's line is detected and the mesh cut at frame 7.
    assert_eq!(
        lines[7],
        format!("7,{},true,true", lines[7].split(',').nth(1).unwrap())
    );
    // A counted run that fails says why, not what valgrind sums up after it.
    let tmp = tempfile::tempdir().unwrap();
    let copy = tmp.path().join("scene");
    common::copy_dir(std::path::Path::new(scene), &copy);
    std::fs::write(copy.join("gt/targets.csv"), "frame,id,x,y,z\n0,0,abc,1,2\n").unwrap();
    let output = incise()
        .arg("instructions")
        .arg(&copy)
        .args(["--frames", "1"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("targets.csv") && !stderr.contains("=="),
        "{stderr}"
    );
}

/// The counting program `incise report` runs under callgrind steps a scene as `incise
/// count-frames` does and refuses what it refuses; built with the video driver, it still loads
/// a small part of the shared libraries `incise` loads (valgrind starts every counted run with
/// them: about 6 s more each with all of OpenCV's).
#[test]
fn the_counting_program_steps_a_scene_and_links_little() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/band-no-cut");
    let setting = [
        "--strategy",
        "refactor",
        "--newton",
        "1",
        "--pcg",
        "10",
        "--line-search",
        "1",
        "--frames",
        "2",
    ];
    let counter = || Command::new(env!("CARGO_BIN_EXE_incise-count-frames"));
    for mut command in [counter(), {
        let mut c = incise();
        c.arg("count-frames");
        c
    }] {
        let ok = command.arg(scene).args(setting).output().unwrap();
        assert!(
            ok.status.success(),
            "{}",
            String::from_utf8_lossy(&ok.stderr)
        );
        assert!(ok.stdout.is_empty());
    }
    let mut sideways = setting;
    sideways[1] = "sideways";
    let bad = counter().arg(scene).args(sideways).output().unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown strategy \"sideways\""));
    // The shared libraries each loads, where `ldd` can tell.
    let libraries = |exe: &str| {
        Command::new("ldd")
            .arg(exe)
            .output()
            .ok()
            .map(|o| String::from_utf8_lossy(&o.stdout).lines().count())
    };
    if let (Some(counting), Some(all)) = (
        libraries(env!("CARGO_BIN_EXE_incise-count-frames")),
        libraries(env!("CARGO_BIN_EXE_incise")),
    ) && cfg!(feature = "opencv")
    {
        assert!(
            4 * counting < all,
            "{counting} libraries against incise's {all}"
        );
    }
}
