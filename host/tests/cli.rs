//! The `incise` binary as a user runs it.

use std::process::Command;

fn incise() -> Command {
    Command::new(env!("CARGO_BIN_EXE_incise"))
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
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(stdout.contains("Dice last frame"), "{stdout}");
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
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(v["scene"], "band-no-cut");
    assert!(v["cut_detected_frame"].is_null());
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
