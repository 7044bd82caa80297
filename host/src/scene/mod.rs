//! The scene directory: what `incise run` reads and `incise gen` writes.
//!
//! ```text
//! <scene>/
//!   scene.toml        model mesh, material, fixed nodes, camera, solver, detection, capacities,
//!                     ground-truth facts
//!   model.msh         the coarse uncut model mesh (Gmsh); any path, relative to the scene
//!   tracks.csv        frame,id,u,v — tracked features per frame; a missing row = lost
//!   gt/silhouettes/NNNN.png   true silhouette per frame at camera resolution
//!   gt/targets.csv    frame,id,x,y,z — true positions of internal targets (metres)
//!   gt/surface.obj    true surface at the last frame (metres)
//!   gt/cut.csv        frame,part,u,v,open — the true cut in the image per frame (if cut)
//!   gt/outliers.csv   id,start,frames,du,dv — the features made to jump (absent in older scenes)
//! ```
//!
//! Every error names the file and, where there is one, the line.
//!
//! Here: [`Scene`] (loading a scene directory and what the core is built from) and
//! [`SceneError`]; `file`: `scene.toml` and its sections; `formats`: the CSV and OBJ files.

use std::fmt;
use std::path::{Path, PathBuf};

use incise_core::{Material, MeshInput, ModelConfig, Observation};

use crate::generate::object::TetMesh;
use crate::limits;
use crate::msh;
use crate::storage::{ModelStorage, StorageError};

mod file;
mod formats;

pub(crate) use file::refusal_of;

pub use file::{
    CameraSection, DetectionSection, DetectionSetting, GroundTruthSection, ModelLaw, ModelSection,
    SceneFile, SolverSection, default_depth_prior,
};
pub use formats::{
    CutParts, CutPoint, Surface, TrueOutlier, read_cut_csv, read_obj, read_outliers_csv,
    read_points_csv, read_tracks, write_obj, write_outliers_csv, write_tracks,
};

/// An error while reading a scene: the file, the line (0 when the whole file is at fault) and
/// what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneError {
    /// The file.
    pub file: PathBuf,
    /// 1-based line, 0 if not tied to a line.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

impl SceneError {
    /// An error about `file` at `line`.
    pub fn new(file: impl Into<PathBuf>, line: usize, message: impl Into<String>) -> Self {
        SceneError {
            file: file.into(),
            line,
            message: message.into(),
        }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line > 0 {
            write!(f, "{}:{}: {}", self.file.display(), self.line, self.message)
        } else {
            write!(f, "{}: {}", self.file.display(), self.message)
        }
    }
}

impl std::error::Error for SceneError {}

/// A loaded scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The scalar type the core runs this scene in (`incise run --real`); `f64` as loaded.
    pub precision: Precision,
    /// Whether a run's overlays also draw the detector's evidence: the neighbour pairs that
    /// are outliers in the frame and those counted as split (`incise run --pairs`); off as
    /// loaded.
    pub overlay_pairs: bool,
    /// Whether a run records, frame by frame, the pairs that stand out and whether they cross
    /// the true cut (`Trace::excess`, for `incise eval --evidence`); off as loaded.
    pub record_excess: bool,
    /// The scene directory.
    pub dir: PathBuf,
    /// `scene.toml` as read.
    pub file: SceneFile,
    /// Model node rest positions, metres.
    pub rest: Vec<[f64; 3]>,
    /// Model tetrahedra, positively oriented.
    pub tets: Vec<[u32; 4]>,
    /// Tracked features per frame (index 0 is frame 0).
    pub frames: Vec<Vec<Observation<f64>>>,
}

/// The scalar type the core computes in. The host reads, measures and reports in `f64`
/// whatever the core runs in: only the model and its inputs are rounded.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// Single precision: what a vision co-processor with a single-precision unit runs.
    F32,
    /// Double precision.
    #[default]
    F64,
    /// Mixed precision: the model in `f64`, its factor (the factorization and the triangular
    /// solves) in `f32`, each solve refined on the `f64` residual.
    Mixed,
}

impl Precision {
    /// `"f32"`, `"f64"` or `"mixed"`.
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
            Precision::Mixed => "mixed",
        }
    }
}

fn read_text(path: &Path) -> Result<String, SceneError> {
    std::fs::read_to_string(path).map_err(|e| SceneError::new(path, 0, format!("cannot read: {e}")))
}

impl Scene {
    /// The core's configuration of this scene: material, camera, solver and detection.
    ///
    /// # Errors
    /// A [`SceneError`] naming `scene.toml` for a bad camera or solver section.
    pub fn model_config(&self) -> Result<ModelConfig<f64>, SceneError> {
        let toml = self.dir.join("scene.toml");
        Ok(ModelConfig {
            material: Material {
                young: self.file.model.young,
                poisson: self.file.model.poisson,
                inversion_barrier: self.file.model.inversion_barrier,
                law: self.file.model.law.core(),
            },
            camera: self.file.camera(&toml)?,
            solver: self.file.solver(&toml)?,
            detection: self.file.detection.config(),
        })
    }

    /// The model mesh as the core takes it: rest positions, tetrahedra, fixed nodes.
    pub fn mesh_input(&self) -> MeshInput<'_, f64> {
        MeshInput {
            rest: &self.rest,
            tets: &self.tets,
            fixed: &self.file.model.fixed,
        }
    }

    /// Loads the scene in `dir`: `scene.toml`, its model mesh and `tracks.csv`.
    ///
    /// # Errors
    /// A [`SceneError`] naming the file (and line) at fault: a missing or malformed file, an
    /// invalid parameter, a fixed node out of range, a truncated mesh, a track id absent from
    /// frame 0.
    pub fn load(dir: &Path) -> Result<Scene, SceneError> {
        let mut scene = Self::load_model(dir)?;
        let tracks_path = dir.join("tracks.csv");
        let text = read_text(&tracks_path)?;
        let frames = read_tracks(&text, &tracks_path)?;
        // Every id must have been seen at frame 0, where features are placed on the model.
        let known: std::collections::HashSet<u32> = frames[0].iter().map(|o| o.id).collect();
        for (i, line) in text.lines().enumerate().skip(1) {
            let id = line
                .split(',')
                .nth(1)
                .and_then(|s| s.trim().parse::<u32>().ok());
            if let Some(id) = id
                && !known.contains(&id)
            {
                return Err(SceneError::new(
                    &tracks_path,
                    i + 1,
                    format!("feature id {id} was not tracked at frame 0"),
                ));
            }
        }
        // The core holds as many features as the capacity says: refuse more now rather than
        // after the model is built.
        let room = scene.file.capacities.features;
        if frames[0].len() > room {
            return Err(at_key(
                dir,
                "capacities",
                "features",
                format!(
                    "[capacities] features: {room}, but {} tracks {} features at frame 0",
                    tracks_path.display(),
                    frames[0].len()
                ),
            ));
        }
        scene.frames = frames;
        // The scene's length, if stated: frames after the last row of tracks.csv lost every
        // feature.
        let stated = scene.file.ground_truth.frames as usize;
        if stated > 0 {
            if scene.frames.len() > stated {
                return Err(at_key(
                    dir,
                    "ground_truth",
                    "frames",
                    format!(
                        "[ground_truth] frames: {stated}, but {} holds {} frames",
                        tracks_path.display(),
                        scene.frames.len()
                    ),
                ));
            }
            scene.frames.resize_with(stated, Vec::new);
        }
        Ok(scene)
    }

    /// Loads `scene.toml` and the model mesh only, with no tracks (`frames` is empty): what
    /// a video run needs, whose features come from the video.
    ///
    /// # Errors
    /// As [`Scene::load`], for `scene.toml` and the mesh.
    pub fn load_model(dir: &Path) -> Result<Scene, SceneError> {
        let toml_path = dir.join("scene.toml");
        let text = read_text(&toml_path)?;
        let file = SceneFile::parse(&text, &toml_path)?;
        file.camera(&toml_path)?;
        file.solver(&toml_path)?;
        let mesh_path = dir.join(&file.model.mesh);
        // Gmsh (`.msh`) or VTK XML (`.vtu`, SOFA's fine liver), as the generator reads them.
        let is_vtu = mesh_path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("vtu"));
        let mut mesh = if is_vtu {
            let m = crate::vtu::read_vtu(&mesh_path)
                .map_err(|e| SceneError::new(&e.file, 0, e.message.clone()))?;
            TetMesh {
                nodes: m.nodes,
                tets: m.tets,
            }
        } else {
            let m = msh::read_msh(&mesh_path)
                .map_err(|e| SceneError::new(&e.file, e.line, e.message.clone()))?;
            TetMesh {
                nodes: m.nodes,
                tets: m.tets,
            }
        };
        mesh.orient_positive();
        let scale = file.model.scale;
        let rest: Vec<[f64; 3]> = mesh.nodes.iter().map(|p| p.map(|c| c * scale)).collect();
        let fixed_line = || limits::key_line(&text, "model", "fixed");
        if let Some(&bad) = file.model.fixed.iter().find(|&&f| f as usize >= rest.len()) {
            return Err(SceneError::new(
                &toml_path,
                fixed_line(),
                format!(
                    "[model] fixed node {bad} does not exist: the mesh has {} nodes",
                    rest.len()
                ),
            ));
        }
        let mut fixed = file.model.fixed.clone();
        fixed.sort_unstable();
        fixed.dedup();
        if fixed.len() == rest.len() {
            return Err(SceneError::new(
                &toml_path,
                fixed_line(),
                format!(
                    "[model] fixed: every one of the mesh's {} nodes is fixed, so nothing can \
                     move; leave free the nodes the features should pull",
                    rest.len()
                ),
            ));
        }
        // The memory the capacities imply with this mesh, before a run asks for it. A mesh
        // the core refuses is left to the run, which says why in its own words.
        let input = MeshInput {
            rest: &rest,
            tets: &mesh.tets,
            fixed: &file.model.fixed,
        };
        if let Err(StorageError::Refused(r)) = ModelStorage::<f64>::plan(&input, &file.capacities) {
            return Err(SceneError::new(&toml_path, r.line(&text), r.to_string()));
        }
        Ok(Scene {
            precision: Precision::F64,
            overlay_pairs: false,
            record_excess: false,
            dir: dir.to_path_buf(),
            file,
            rest,
            tets: mesh.tets,
            frames: vec![],
        })
    }

    /// Path of the true silhouette of `frame`.
    pub fn silhouette_path(&self, frame: usize) -> PathBuf {
        silhouette_path(&self.dir, frame)
    }
}

/// Path of the true silhouette of `frame` in scene directory `dir`.
pub fn silhouette_path(dir: &Path, frame: usize) -> PathBuf {
    dir.join("gt")
        .join("silhouettes")
        .join(format!("{frame:04}.png"))
}

/// An error at `[section] key` of the scene's `scene.toml` in `dir`, with its line (0 when the
/// file cannot be read again).
pub(crate) fn at_key(dir: &Path, section: &str, key: &str, message: String) -> SceneError {
    let toml = dir.join("scene.toml");
    let line = read_text(&toml).map_or(0, |text| limits::key_line(&text, section, key));
    SceneError::new(&toml, line, message)
}
