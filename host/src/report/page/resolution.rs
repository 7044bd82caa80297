//! The mesh-resolution axis of the error against run time: a scene run with three model meshes
//! of the same object against the same ground truth. The scene's own (coarse) model, that mesh
//! refined (every tetrahedron into eight), and the real object's own fine mesh (before its
//! slit: for the liver, SOFA's fine liver, 4293 nodes). The object is simulated once; each
//! model is written as a scene beside the same truth and tracks, and run with the scene's own
//! setting.

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::generate::pipeline::{ModelMesh, simulate, write_scene};
use crate::run::{RunOptions, run_scene};
use crate::scene::Scene;

use super::instructions;

/// The scenes whose shapes get the axis: the band (cut from one side) and the liver.
pub(super) const BASES: [&str; 2] = ["band-side-cut", "liver-lobe"];

/// Frames counted under callgrind per model: one, since every steady frame of a topology does
/// nearly the same work (the summary's steady max / median per topology is at most 1.013), and
/// the fine liver costs
/// about a minute per frame there (with two, the full report took 9 min 53 s of its 10).
const COUNTED_FRAMES: usize = 1;

/// The models of the axis, coarsest first.
const MODELS: [&str; 3] = ["the scene's", "refined ×8", "the real object's"];

/// One model of the axis.
#[derive(Clone, Debug, Serialize)]
pub struct Model {
    /// Which mesh ([`MODELS`]).
    pub mesh: &'static str,
    /// Its nodes.
    pub nodes: usize,
    /// Its tetrahedra.
    pub tets: usize,
    /// Dice of the last frame (cutting on), and with cutting off.
    pub dice_final: f64,
    /// ... with cutting off.
    pub dice_final_uncut: f64,
    /// Target error of the last frame, millimetres.
    pub tre_mm_final: f64,
    /// Target error of the rest model left in place, millimetres.
    pub tre_mm_rest: f64,
    /// Surface error of the last frame, millimetres.
    pub surface_mm_final: f64,
    /// Wall time of a steady step, milliseconds (median).
    pub ms_steady: f64,
    /// Instructions of a steady frame (mean of the counted frames), if counted.
    pub instructions: Option<f64>,
    /// A cut the core refused, with its reason.
    pub cut_refused: Option<String>,
    /// The model's static storage, bytes.
    pub model_bytes: usize,
}

/// The axis of one scene.
#[derive(Clone, Debug, Serialize)]
pub struct Resolution {
    /// The scene.
    pub scene: String,
    /// Its models, coarsest first.
    pub models: Vec<Model>,
}

/// How many models [`measure`] runs per base (for the progress bar).
pub(super) const fn len() -> usize {
    MODELS.len()
}

/// One model to run: the scene it makes (the base itself, or a variant written to `dir`).
pub(super) struct Job {
    base: usize,
    label: &'static str,
    scene: Scene,
    dir: PathBuf,
}

impl Job {
    /// The model's nodes (the report runs the largest first).
    pub(super) fn nodes(&self) -> usize {
        self.scene.rest.len()
    }
}

/// The models of every base, their variants written into a directory of their own that is
/// removed when this is dropped (the runs read the variants' truth from it).
pub(super) struct Prepared {
    pub jobs: Vec<Job>,
    work: tempfile::TempDir,
}

/// Writes the finer models of each of `bases` (whose `scenario.toml` lies beside them) beside
/// the same truth.
///
/// # Errors
/// A message naming the model that could not be made.
pub(super) fn prepare(bases: &[&Scene]) -> Result<Prepared, String> {
    let mut prepared = Prepared {
        jobs: vec![],
        work: super::scratch_dir("resolution")?,
    };
    // One base per core: each simulates its object anew.
    let numbered: Vec<(usize, &Scene)> = bases.iter().copied().enumerate().collect();
    let made = super::on_every_core(&numbered, |&(base, scene)| {
        variants(base, scene, prepared.work.path())
    });
    for jobs in made {
        prepared.jobs.extend(jobs?);
    }
    Ok(prepared)
}

/// Runs one model (and counts it when `counting`).
///
/// # Errors
/// A message naming the base and the model.
pub(super) fn run(job: &Job, bases: &[&Scene], counting: bool) -> Result<Model, String> {
    run_model(&job.scene, &job.dir, job.label, counting).map_err(|e| {
        let name = bases.get(job.base).map_or("", |b| b.file.name.as_str());
        format!("{name} with {} mesh: {e}", job.label)
    })
}

/// The axis of every base from the models' results (in the order of `prepared.jobs`).
///
/// # Errors
/// The first model that could not be run.
pub(super) fn assemble(
    bases: &[&Scene],
    prepared: &Prepared,
    models: Vec<Result<Model, String>>,
) -> Result<Vec<Resolution>, String> {
    let mut axes: Vec<Resolution> = bases
        .iter()
        .map(|b| Resolution {
            scene: b.file.name.clone(),
            models: vec![],
        })
        .collect();
    for (job, model) in prepared.jobs.iter().zip(models) {
        if let Some(axis) = axes.get_mut(job.base) {
            axis.models.push(model?);
        }
    }
    for axis in &mut axes {
        axis.models.sort_by_key(|m| m.nodes);
    }
    Ok(axes)
}

/// The three models of `scene` (base number `base`): the scene itself, and the finer meshes
/// written under `work` beside the same truth.
fn variants(base: usize, scene: &Scene, work: &Path) -> Result<Vec<Job>, String> {
    let name = &scene.file.name;
    let scenario = scene.dir.join("scenario.toml");
    let sim = simulate(&scenario, false).map_err(|e| format!("{name}: {e}"))?;
    let mut jobs = vec![Job {
        base,
        label: MODELS[0],
        scene: scene.clone(),
        dir: scene.dir.clone(),
    }];
    for (label, mesh) in [
        (MODELS[1], ModelMesh::Refined),
        (MODELS[2], ModelMesh::Fine),
    ] {
        let mut model = sim.clone();
        model.remodel(mesh);
        let dir = work.join(format!("{name}-{}", model.meshes.model.nodes.len()));
        let variant = write_scene(&model, &scenario, &dir, false)
            .map_err(|e| e.to_string())
            .and_then(|_| Scene::load(&dir).map_err(|e| e.to_string()))
            .map_err(|e| format!("{name} with {label} mesh: {e}"))?;
        jobs.push(Job {
            base,
            label,
            scene: variant,
            dir,
        });
    }
    Ok(jobs)
}

fn run_model(
    scene: &Scene,
    dir: &Path,
    mesh: &'static str,
    counting: bool,
) -> Result<Model, String> {
    let (summary, _) = run_scene(scene, &RunOptions::default()).map_err(|e| e.to_string())?;
    let instructions = instructions::mean_of_own_setting(scene, dir, COUNTED_FRAMES, counting)?;
    Ok(Model {
        mesh,
        nodes: summary.nodes_initial,
        tets: scene.tets.len(),
        dice_final: summary.dice_final,
        dice_final_uncut: summary.dice_final_uncut,
        tre_mm_final: summary.tre_mm_final,
        tre_mm_rest: summary.tre_mm_final_rest,
        surface_mm_final: summary.surface_rmse_mm_final,
        ms_steady: summary.ms_steady_median,
        instructions,
        cut_refused: summary.cut_refused,
        model_bytes: summary.model_bytes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The band's three models, run against the same truth: the scene's own is the committed
    /// scene, the finer ones have more nodes and register as well as a model should (nearer
    /// than the rest model, the cut improving Dice).
    #[test]
    fn the_band_is_run_with_three_meshes_against_one_truth() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/band-side-cut");
        let scene = Scene::load(&dir).unwrap();
        let prepared = prepare(&[&scene]).unwrap();
        assert_eq!(prepared.jobs.len(), len());
        let models = prepared
            .jobs
            .iter()
            .map(|job| run(job, &[&scene], false))
            .collect();
        let axis = assemble(&[&scene], &prepared, models).unwrap().remove(0);
        assert_eq!(axis.models.len(), 3);
        let own = run_scene(&scene, &RunOptions::default()).unwrap().0;
        assert_eq!(axis.models[0].dice_final, own.dice_final);
        assert_eq!(axis.models[0].nodes, scene.rest.len());
        for pair in axis.models.windows(2) {
            assert!(pair[1].nodes > pair[0].nodes, "{pair:?}");
        }
        for m in &axis.models {
            // One truth: the rest model's error does not depend on the model's mesh.
            assert!(
                (m.tre_mm_rest - own.tre_mm_final_rest).abs() < 0.05 * own.tre_mm_final_rest,
                "{m:?}"
            );
            assert!(m.tre_mm_final < m.tre_mm_rest, "{m:?}");
            assert!(m.dice_final >= m.dice_final_uncut, "{m:?}");
        }
        // The finer models were written into a scratch directory that goes with them.
        let work = prepared.work.path().to_path_buf();
        assert!(work.is_dir() && std::fs::read_dir(&work).unwrap().count() > 0);
        drop(prepared);
        assert!(!work.exists(), "{} left behind", work.display());
    }
}
