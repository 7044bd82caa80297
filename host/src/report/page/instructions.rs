//! Instructions per frame, counted by callgrind: the deterministic cost axis of the report.
//!
//! `incise report` runs its own binary again under `valgrind --tool=callgrind` with the hidden
//! subcommand `count-frames` ([`count_frames`]), which builds the scene's model with one solver
//! setting and steps it over the scene's frames. Callgrind writes a dump before each
//! `Model::step`, so each dump after the first (the set-up) holds one frame's instructions, the
//! cut events included, plus the few thousand instructions of the loop between two steps. Wall time swings with the machine; these counts do
//! not.

use std::path::Path;
use std::process::Command;

use incise_core::{MeshInput, Real};

use crate::run::{cast_observation, embed_scene_targets, known_observations, scene_storage_for};
use crate::scene::{Precision, Scene};

use super::super::SweepSetting;

/// Instructions of each stepped frame (frame 1 first), or why they could not be counted.
///
/// # Errors
/// A message if valgrind is missing or the counted run fails.
pub fn per_frame(
    scene_dir: &Path,
    setting: &SweepSetting,
    frames: usize,
) -> Result<Vec<u64>, String> {
    let exe = std::env::current_exe().map_err(|e| format!("the incise binary: {e}"))?;
    let dir = super::scratch_dir("callgrind")?;
    let out = dir.path().join("cg");
    let mut valgrind = Command::new("valgrind");
    valgrind
        .arg("--tool=callgrind")
        .arg("--dump-before=*incise_core*Model*step*")
        .arg(format!("--callgrind-out-file={}", out.display()));
    match counting_program(&exe) {
        Some(counter) => valgrind.arg(counter),
        None => valgrind.arg(&exe).arg("count-frames"),
    };
    let output = valgrind
        .arg(scene_dir)
        .args(["--strategy", setting.strategy])
        .args(["--newton", &setting.newton.to_string()])
        .args(["--pcg", &setting.pcg.to_string()])
        .args(["--line-search", &setting.line_search.to_string()])
        .args(["--frames", &frames.to_string()])
        .args(["--real", setting.precision.name()])
        .output();
    // `dir` and its dumps go when it is dropped, after they are read.
    match output {
        Err(e) => Err(format!("valgrind could not be started ({e})")),
        // The program's own error is its last line; valgrind's summary (`==pid== …`) follows it.
        Ok(o) if !o.status.success() => Err(format!(
            "the counted run failed: {}",
            String::from_utf8_lossy(&o.stderr)
                .lines()
                .rev()
                .find(|l| !l.starts_with("==") && !l.trim().is_empty())
                .unwrap_or("no message")
        )),
        Ok(_) => read_dumps(dir.path()),
    }
}

/// The mean instructions of the first `frames` stepped frames of the scene in `scene_dir` with
/// its own solver setting, or `None` when not `counting`.
///
/// # Errors
/// As [`per_frame`].
pub(super) fn mean_of_own_setting(
    scene: &Scene,
    scene_dir: &Path,
    frames: usize,
    counting: bool,
) -> Result<Option<f64>, String> {
    if !counting {
        return Ok(None);
    }
    let counts = per_frame(scene_dir, &SweepSetting::of(&scene.file.solver), frames)?;
    Ok(Some(
        counts.iter().map(|&c| c as f64).sum::<f64>() / counts.len().max(1) as f64,
    ))
}

/// The `incise-count-frames` program beside the binary `exe`, if it was built there (`cargo
/// build` builds it with `incise`; `cargo run` builds only the program it runs): it steps the
/// model as `incise count-frames` does, but without the video driver's shared libraries, which
/// valgrind would load and run the start-up code of on every counted run. The counts are the
/// same step by step, up to the few thousand instructions between two steps that differ with
/// the binary.
fn counting_program(exe: &Path) -> Option<std::path::PathBuf> {
    let name = format!("incise-count-frames{}", std::env::consts::EXE_SUFFIX);
    let counter = exe.with_file_name(name);
    counter.is_file().then_some(counter)
}

/// Whether callgrind can be run here.
pub(super) fn available() -> bool {
    Command::new("valgrind")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// The instructions of each step from the dumps in `dir`: `cg.1` holds the set-up, `cg.n`
/// (n ≥ 2) the step n − 1, and `cg`, written at exit, the last step.
fn read_dumps(dir: &Path) -> Result<Vec<u64>, String> {
    let mut counts = vec![];
    let mut last = None;
    for entry in std::fs::read_dir(dir).map_err(|e| e.to_string())? {
        let path = entry.map_err(|e| e.to_string())?.path();
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default();
        let n = match name.strip_prefix("cg") {
            Some("") => None,
            Some(n) => match n.strip_prefix('.').and_then(|n| n.parse::<usize>().ok()) {
                Some(n) => Some(n),
                None => continue,
            },
            None => continue,
        };
        let text = std::fs::read_to_string(&path).map_err(|e| e.to_string())?;
        let total = text
            .lines()
            .find_map(|l| l.strip_prefix("totals: ").or(l.strip_prefix("summary: ")))
            .and_then(|t| t.split_whitespace().next())
            .and_then(|t| t.parse::<u64>().ok())
            .ok_or_else(|| format!("{}: no instruction total", path.display()))?;
        match n {
            None => last = Some(total),
            Some(1) => {}
            Some(n) => counts.push((n, total)),
        }
    }
    counts.sort_unstable();
    let Some(last) = last else {
        return Err("callgrind wrote no dump at exit".into());
    };
    if counts.is_empty() && !dir.join("cg.1").exists() {
        return Err("callgrind wrote no dump before a step".into());
    }
    Ok(counts.into_iter().map(|c| c.1).chain([last]).collect())
}

/// The hidden `count-frames` subcommand: builds the model of the scene in `dir` with
/// `setting`, embeds the frame-0 features and steps frames 1 to `frames` (all if fewer),
/// printing nothing. What callgrind counts in [`per_frame`].
///
/// # Errors
/// A message naming the scene or the frame the core refuses.
pub fn count_frames(dir: &Path, setting: &SweepSetting, frames: usize) -> Result<(), String> {
    let mut scene = Scene::load(dir).map_err(|e| e.to_string())?;
    setting.apply(&mut scene);
    match setting.precision {
        Precision::F64 => count_frames_in::<f64, f64>(&scene, frames),
        Precision::F32 => count_frames_in::<f32, f32>(&scene, frames),
        Precision::Mixed => count_frames_in::<f64, f32>(&scene, frames),
    }
}

/// [`count_frames`] with the core in `T` and its factor in `F`.
fn count_frames_in<T: Real, F: Real>(scene: &Scene, frames: usize) -> Result<(), String> {
    let config = scene
        .model_config()
        .map_err(|e| e.to_string())?
        .cast::<T>()
        .map_err(|e| e.to_string())?;
    let rest: Vec<[T; 3]> = scene.rest.iter().map(|p| p.map(T::of)).collect();
    let mesh = MeshInput {
        rest: &rest,
        tets: &scene.tets,
        fixed: &scene.file.model.fixed,
    };
    let mut storage = scene_storage_for::<T, F>(scene, &mesh).map_err(|e| e.to_string())?;
    let mut model = storage
        .model(&mesh, &config)
        .map_err(|e| format!("building the model: {e}"))?;
    let first = scene.frames.first().ok_or("the scene holds no frame")?;
    model
        .embed_features(&first.iter().map(cast_observation).collect::<Vec<_>>())
        .map_err(|e| format!("placing the frame-0 features: {e}"))?;
    embed_scene_targets(scene, &mut model).map_err(|e| e.to_string())?;
    for frame in scene.frames.iter().skip(1).take(frames) {
        // A refused frame leaves the model as it was; the run goes on, as `incise run` does.
        let _ = model.step(&known_observations(&model, frame));
    }
    Ok(())
}
