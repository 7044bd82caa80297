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
//!   gt/cut.csv        frame,u,v — the true cut line in the image per frame (if cut)
//! ```
//!
//! Every error names the file and, where there is one, the line.

use std::fmt;
use std::path::{Path, PathBuf};

use incise_core::nalgebra::{Matrix3, Vector3};
use incise_core::{
    Camera, Intrinsics, Material, MeshInput, ModelConfig, Observation, SolverConfig, Strategy,
};
use serde::{Deserialize, Serialize};

use crate::limits::{self, Refusal};
use crate::msh;
use crate::storage::{ModelStorage, SceneCapacities, StorageError};

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

/// `scene.toml`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Scene name.
    pub name: String,
    /// One line on what the scene shows.
    #[serde(default)]
    pub description: String,
    /// The model.
    pub model: ModelSection,
    /// The camera.
    pub camera: CameraSection,
    /// The per-frame solve.
    pub solver: SolverSection,
    /// Cut detection parameters (written only where they differ from the defaults).
    #[serde(default, skip_serializing_if = "DetectionSection::is_default")]
    pub detection: DetectionSection,
    /// Capacities of the core's fixed storage.
    #[serde(default)]
    pub capacities: SceneCapacities,
    /// Facts of the ground truth.
    #[serde(default)]
    pub ground_truth: GroundTruthSection,
}

/// `[model]`: the coarse uncut mesh and its material.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ModelSection {
    /// The Gmsh mesh, relative to the scene directory.
    pub mesh: String,
    /// Metres per mesh unit (0.01 for a mesh in centimetres).
    #[serde(default = "one")]
    pub scale: f64,
    /// 0-based indices of the nodes held at their rest position.
    pub fixed: Vec<u32>,
    /// Young's modulus of the model, pascals.
    pub young: f64,
    /// Poisson ratio of the model.
    pub poisson: f64,
}

fn one() -> f64 {
    1.0
}

/// `[camera]`: pinhole intrinsics (pixels) and world-to-camera pose (metres).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CameraSection {
    /// Focal length along u, pixels.
    pub fx: f64,
    /// Focal length along v, pixels.
    pub fy: f64,
    /// Principal point, pixels.
    pub cx: f64,
    /// Principal point, pixels.
    pub cy: f64,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// World-to-camera rotation, rows.
    pub rotation: [[f64; 3]; 3],
    /// World-to-camera translation, metres.
    pub translation: [f64; 3],
    /// Near plane, metres.
    #[serde(default = "default_near")]
    pub near: f64,
}

fn default_near() -> f64 {
    1e-4
}

/// `[solver]`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SolverSection {
    /// `"refactor"` or `"frozen"`.
    pub strategy: String,
    /// PCG iterations per Newton step for `"frozen"`.
    #[serde(default = "default_pcg")]
    pub pcg_iterations: u32,
    /// Newton steps per frame.
    pub newton_iterations: u32,
    /// Line-search trials per Newton step.
    pub line_search_steps: u32,
    /// Spring stiffness, J/px².
    pub spring_stiffness: f64,
    /// Damping toward the previous frame, fraction of the rest stiffness.
    pub damping: f64,
    /// Prior on depth (against motion along the camera rays), fraction of the rest stiffness.
    #[serde(default = "default_depth_prior")]
    pub depth_prior: f64,
    /// Observations farther outside the image are rejected, pixels.
    #[serde(default = "default_margin")]
    pub image_margin: f64,
}

/// The core's default prior on depth (see `incise_core::solve`).
pub fn default_depth_prior() -> f64 {
    incise_core::solve::DEFAULT_DEPTH_PRIOR
}

fn default_pcg() -> u32 {
    10
}

fn default_margin() -> f64 {
    50.0
}

/// `[detection]`: the cut detection of the paper's §2.2–2.3 (see
/// [`incise_core::DetectionConfig`] for each parameter). Every field has a default that
/// calibrates itself from the data; a scene needs this section only to switch detection off or
/// to study a setting.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct DetectionSection {
    /// Whether cutting is on for this scene.
    pub enabled: bool,
    /// Neighbour radius, pixels (0: `radius_spacings` feature spacings).
    pub radius: f64,
    /// Neighbour radius in feature spacings when `radius` is 0.
    pub radius_spacings: f64,
    /// Features closer in the image are not paired when they are farther apart than this on
    /// the model (relative to their image distance at their depth): pairs across a fold or a
    /// grazing slope (0: pair by image distance alone).
    pub max_surface_ratio: f64,
    /// Outlier margin in robust standard deviations of the frame's residual differences.
    pub outlier_sigmas: f64,
    /// Temporal-filter margin in robust standard deviations of the residual changes.
    pub temporal_sigmas: f64,
    /// Differences below this are never outliers, pixels (the floor for noise-free data).
    pub min_difference: f64,
    /// Frames in a row a pair must be an outlier to count as split.
    pub persistence: u32,
    /// Separation points needed to start the cut line.
    pub init_points: u32,
    /// Angular restriction of a front, degrees.
    pub alpha: f64,
    /// Shortest advance of a front, feature spacings.
    pub min_step: f64,
    /// Longest advance of a front, feature spacings.
    pub max_step: f64,
    /// Separation points ahead needed to advance a front.
    pub min_support: u32,
    /// Distance within which separation points support a candidate line, feature spacings.
    pub line_tolerance: f64,
    /// Largest spread across the fitted line, relative to along it, to start the cut line.
    pub max_line_spread: f64,
    /// Count only pairs whose residuals diverge (an opening cut).
    pub opening_only: bool,
    /// Largest fraction of a feature's pairs that may be outliers before the feature itself
    /// is taken for a tracking failure in that frame.
    pub max_outlier_fraction: f64,
    /// Extrusion direction of the separation surface (world); absent: the camera's axis.
    pub depth: Option<[f64; 3]>,
}

impl Default for DetectionSection {
    fn default() -> Self {
        let p = incise_core::DetectionConfig::<f64>::paper();
        DetectionSection {
            enabled: p.enabled,
            radius: p.radius_px,
            radius_spacings: p.radius_spacings,
            max_surface_ratio: p.max_surface_ratio,
            outlier_sigmas: p.outlier_sigmas,
            temporal_sigmas: p.temporal_sigmas,
            min_difference: p.min_difference_px,
            persistence: p.persistence,
            init_points: p.init_points,
            alpha: p.alpha_degrees,
            min_step: p.min_step,
            max_step: p.max_step,
            min_support: p.min_support,
            line_tolerance: p.line_tolerance,
            max_line_spread: p.max_line_spread,
            opening_only: p.opening_only,
            max_outlier_fraction: p.max_outlier_fraction,
            depth: p.depth,
        }
    }
}

impl DetectionSection {
    /// Whether every field has its default (the scene then needs no `[detection]` section).
    pub fn is_default(&self) -> bool {
        *self == DetectionSection::default()
    }

    /// The core's configuration.
    pub fn config(&self) -> incise_core::DetectionConfig<f64> {
        incise_core::DetectionConfig {
            enabled: self.enabled,
            radius_px: self.radius,
            radius_spacings: self.radius_spacings,
            max_surface_ratio: self.max_surface_ratio,
            outlier_sigmas: self.outlier_sigmas,
            temporal_sigmas: self.temporal_sigmas,
            min_difference_px: self.min_difference,
            persistence: self.persistence,
            init_points: self.init_points,
            alpha_degrees: self.alpha,
            min_step: self.min_step,
            max_step: self.max_step,
            min_support: self.min_support,
            line_tolerance: self.line_tolerance,
            max_line_spread: self.max_line_spread,
            opening_only: self.opening_only,
            max_outlier_fraction: self.max_outlier_fraction,
            depth: self.depth,
        }
    }
}

/// `[ground_truth]`: facts the generator knows.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GroundTruthSection {
    /// First frame at which the true cut has opened (absent: no cut).
    #[serde(default)]
    pub cut_open_frame: Option<u32>,
    /// Number of frames, frame 0 included (0: as many as `tracks.csv` holds). `tracks.csv`
    /// may not hold more; frames after its last row are frames in which every feature was
    /// lost.
    #[serde(default)]
    pub frames: u32,
}

/// A loaded scene.
#[derive(Clone, Debug)]
pub struct Scene {
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

/// Line (1-based) of a byte offset in a text.
fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].matches('\n').count() + 1
}

impl SceneFile {
    /// Parses `scene.toml` text; `file` names it in errors.
    ///
    /// # Errors
    /// A [`SceneError`] with the line of the offending key or value.
    pub fn parse(text: &str, file: &Path) -> Result<Self, SceneError> {
        let scene: SceneFile = toml::from_str(text).map_err(|e| {
            let line = e.span().map_or(0, |s| line_of(text, s.start));
            SceneError::new(file, line, e.message().to_string())
        })?;
        scene
            .check()
            .map_err(|r| SceneError::new(file, r.line(text), r.to_string()))?;
        Ok(scene)
    }

    /// Checks the values that need no mesh: every capacity against its bound (see
    /// [`SceneCapacities::check`]), the image size, the model's scale and material, and the
    /// ground truth's frames. [`SceneFile::parse`] calls it; [`Scene::load_model`] checks what
    /// needs the mesh.
    ///
    /// # Errors
    /// A [`Refusal`] naming the first key at fault.
    pub fn check(&self) -> Result<(), Refusal> {
        self.capacities.check(self.detection.enabled)?;
        let c = &self.camera;
        limits::image_size(c.width, c.height)?;
        let m = &self.model;
        limits::positive("model", "scale", m.scale)?;
        limits::positive("model", "young", m.young)?;
        limits::poisson("model", "poisson", m.poisson)?;
        let g = &self.ground_truth;
        limits::within(
            "ground_truth",
            "frames",
            g.frames.into(),
            0,
            limits::MAX_FRAMES,
        )?;
        if let Some(open) = g.cut_open_frame
            && g.frames > 0
            && open >= g.frames
        {
            return Err(Refusal::new(
                "ground_truth",
                "cut_open_frame",
                format!("{open} is not a frame of the scene's {}", g.frames),
            ));
        }
        Ok(())
    }

    /// The camera.
    ///
    /// # Errors
    /// A [`SceneError`] naming `scene.toml` if the parameters are invalid.
    pub fn camera(&self, file: &Path) -> Result<Camera<f64>, SceneError> {
        let c = &self.camera;
        let r = Matrix3::from_row_slice(&c.rotation.concat());
        Camera::new(
            Intrinsics {
                fx: c.fx,
                fy: c.fy,
                cx: c.cx,
                cy: c.cy,
                width: c.width,
                height: c.height,
            },
            r,
            Vector3::from(c.translation),
            c.near,
        )
        .map_err(|e| SceneError::new(file, 0, format!("[camera]: {e}")))
    }

    /// The solver configuration.
    ///
    /// # Errors
    /// A [`SceneError`] naming `scene.toml` for an unknown strategy or an invalid value.
    pub fn solver(&self, file: &Path) -> Result<SolverConfig<f64>, SceneError> {
        self.solver
            .config()
            .map_err(|r| SceneError::new(file, 0, r.to_string()))
    }
}

impl SolverSection {
    /// The core's solver configuration, validated.
    ///
    /// # Errors
    /// A [`Refusal`] naming `[solver]` for an unknown strategy or an invalid value.
    pub fn config(&self) -> Result<SolverConfig<f64>, Refusal> {
        let s = self;
        let strategy = match s.strategy.as_str() {
            "refactor" => Strategy::Refactor,
            "frozen" => Strategy::Frozen {
                pcg_iterations: s.pcg_iterations,
            },
            other => {
                return Err(Refusal::new(
                    "solver",
                    "strategy",
                    format!("must be \"refactor\" or \"frozen\", not {other:?}"),
                ));
            }
        };
        let config = SolverConfig {
            strategy,
            newton_iterations: s.newton_iterations,
            line_search_steps: s.line_search_steps,
            spring_stiffness: s.spring_stiffness,
            damping: s.damping,
            depth_prior: s.depth_prior,
            image_margin: s.image_margin,
        };
        config
            .validate()
            .map_err(|e| Refusal::new("solver", "", e.to_string()))?;
        Ok(config)
    }
}

/// Reads `tracks.csv` (`frame,id,u,v` with a header line): observations grouped by frame, frame
/// 0 first. Frames with no row are empty.
///
/// # Errors
/// A [`SceneError`] with the line for a malformed row, a non-numeric or non-finite value, a
/// frame number that goes backwards, or an id repeated within a frame.
pub fn read_tracks(text: &str, file: &Path) -> Result<Vec<Vec<Observation<f64>>>, SceneError> {
    let mut frames: Vec<Vec<Observation<f64>>> = vec![];
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, header)) if header.trim() == "frame,id,u,v" => {}
        Some((_, other)) => {
            return Err(SceneError::new(
                file,
                1,
                format!("expected the header \"frame,id,u,v\", found {other:?}"),
            ));
        }
        None => return Err(SceneError::new(file, 1, "empty file: no header")),
    }
    for (i, line) in lines {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != 4 {
            return Err(SceneError::new(
                file,
                n,
                format!("expected 4 fields (frame,id,u,v), found {}", fields.len()),
            ));
        }
        let frame: usize = fields[0].parse().map_err(|_| {
            SceneError::new(
                file,
                n,
                format!("frame {:?} is not a whole number", fields[0]),
            )
        })?;
        let id: u32 = fields[1].parse().map_err(|_| {
            SceneError::new(file, n, format!("id {:?} is not a whole number", fields[1]))
        })?;
        let mut uv = [0.0; 2];
        for (k, name) in ["u", "v"].iter().enumerate() {
            let v: f64 = fields[2 + k].parse().map_err(|_| {
                SceneError::new(
                    file,
                    n,
                    format!("{name} {:?} is not a number", fields[2 + k]),
                )
            })?;
            if !v.is_finite() {
                return Err(SceneError::new(file, n, format!("{name} is not finite")));
            }
            uv[k] = v;
        }
        if frame + 1 < frames.len() {
            return Err(SceneError::new(
                file,
                n,
                format!(
                    "frame {frame} comes after frame {}: rows must be in frame order",
                    frames.len() - 1
                ),
            ));
        }
        if frame as u64 >= limits::MAX_FRAMES {
            return Err(SceneError::new(
                file,
                n,
                format!(
                    "frame {frame} is beyond the bound of {} frames",
                    limits::MAX_FRAMES
                ),
            ));
        }
        frames.resize_with(frames.len().max(frame + 1), Vec::new);
        let current = &mut frames[frame];
        if current.iter().any(|o| o.id == id) {
            return Err(SceneError::new(
                file,
                n,
                format!("feature {id} appears twice in frame {frame}"),
            ));
        }
        current.push(Observation { id, uv });
    }
    if frames.is_empty() {
        return Err(SceneError::new(file, 0, "no observations"));
    }
    Ok(frames)
}

/// Writes observations as `tracks.csv` (pixel positions to 1/1000 px).
pub fn write_tracks(frames: &[Vec<Observation<f64>>]) -> String {
    let mut out = String::from("frame,id,u,v\n");
    for (f, obs) in frames.iter().enumerate() {
        for o in obs {
            out.push_str(&format!("{f},{},{:.3},{:.3}\n", o.id, o.uv[0], o.uv[1]));
        }
    }
    out
}

/// Reads a CSV of `frame,id,x,y,z` rows (`gt/targets.csv`) into per-frame point lists.
///
/// # Errors
/// A [`SceneError`] with the line for a malformed row, a value that is not a finite number, or
/// a frame or id that is not a whole number below its bound ([`limits::MAX_FRAMES`],
/// [`limits::MAX_TARGETS`]).
pub fn read_points_csv(text: &str, file: &Path) -> Result<Vec<Vec<[f64; 3]>>, SceneError> {
    let mut frames: Vec<Vec<[f64; 3]>> = vec![];
    for (i, line) in text.lines().enumerate().skip(1) {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != 5 {
            return Err(SceneError::new(
                file,
                n,
                format!("expected 5 fields (frame,id,x,y,z), found {}", f.len()),
            ));
        }
        let num = |k: usize| -> Result<f64, SceneError> {
            f[k].parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    SceneError::new(file, n, format!("{:?} is not a finite number", f[k]))
                })
        };
        let frame = whole(f[0], "frame", limits::MAX_FRAMES, file, n)?;
        let id = whole(f[1], "target id", limits::MAX_TARGETS, file, n)?;
        frames.resize_with(frames.len().max(frame + 1), Vec::new);
        if id != frames[frame].len() {
            return Err(SceneError::new(
                file,
                n,
                format!("target ids must run 0, 1, … within a frame; found {id}"),
            ));
        }
        frames[frame].push([num(2)?, num(3)?, num(4)?]);
    }
    Ok(frames)
}

/// A frame number or id of a ground-truth CSV: a whole number below `bound` (written as an
/// integer or, as some tools do, `12.0`).
fn whole(
    text: &str,
    what: &str,
    bound: u64,
    file: &Path,
    line: usize,
) -> Result<usize, SceneError> {
    let value = text.parse::<f64>().ok().filter(|v| v.fract() == 0.0);
    match value {
        Some(v) if v >= 0.0 && v < bound as f64 => Ok(v as usize),
        _ => Err(SceneError::new(
            file,
            line,
            format!("{what} {text:?} is not a whole number below {bound}"),
        )),
    }
}

/// Reads `gt/cut.csv` (`frame,u,v`): the true cut line per frame.
///
/// # Errors
/// A [`SceneError`] with the line for a malformed row, or a frame that is not a whole number
/// below [`limits::MAX_FRAMES`].
pub fn read_cut_csv(text: &str, file: &Path) -> Result<Vec<Vec<[f64; 2]>>, SceneError> {
    let mut frames: Vec<Vec<[f64; 2]>> = vec![];
    for (i, line) in text.lines().enumerate().skip(1) {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let parsed: Option<Vec<f64>> = f
            .iter()
            .map(|s| s.parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect();
        match parsed.as_deref() {
            Some([_, u, v]) => {
                let frame = whole(f[0], "frame", limits::MAX_FRAMES, file, n)?;
                frames.resize_with(frames.len().max(frame + 1), Vec::new);
                frames[frame].push([*u, *v]);
            }
            _ => return Err(SceneError::new(file, n, "expected frame,u,v as numbers")),
        }
    }
    Ok(frames)
}

/// A triangulated surface.
#[derive(Clone, Debug, PartialEq)]
pub struct Surface {
    /// Vertex positions.
    pub positions: Vec<[f64; 3]>,
    /// Triangles (0-based vertex indices).
    pub triangles: Vec<[u32; 3]>,
}

/// Reads a triangle surface from a minimal OBJ (`v x y z`, `f a b c`, 1-based).
///
/// # Errors
/// A [`SceneError`] with the line for a malformed record or an index out of range.
pub fn read_obj(text: &str, file: &Path) -> Result<Surface, SceneError> {
    let (mut v, mut f) = (vec![], vec![]);
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let c: Option<Vec<f64>> = it
                    .map(|s| s.parse().ok().filter(|x: &f64| x.is_finite()))
                    .collect();
                match c.as_deref() {
                    Some([x, y, z]) => v.push([*x, *y, *z]),
                    _ => {
                        return Err(SceneError::new(
                            file,
                            n,
                            "a vertex needs three finite numbers",
                        ));
                    }
                }
            }
            Some("f") => {
                let c: Option<Vec<u32>> = it
                    .map(|s| s.split('/').next().and_then(|k| k.parse::<u32>().ok()))
                    .collect();
                match c.as_deref() {
                    Some([a, b, c]) if [*a, *b, *c].iter().all(|&k| k >= 1) => {
                        f.push([a - 1, b - 1, c - 1])
                    }
                    _ => {
                        return Err(SceneError::new(
                            file,
                            n,
                            "a face needs three 1-based vertex indices",
                        ));
                    }
                }
            }
            _ => {}
        }
    }
    if let Some((k, _)) = f
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&i| i as usize >= v.len()))
    {
        return Err(SceneError::new(
            file,
            0,
            format!(
                "face {} refers to a vertex beyond the {} given",
                k + 1,
                v.len()
            ),
        ));
    }
    Ok(Surface {
        positions: v,
        triangles: f,
    })
}

/// Writes a triangle surface as OBJ (coordinates to 1 µm when in metres).
pub fn write_obj(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> String {
    let mut out = String::new();
    for p in positions {
        out.push_str(&format!("v {:.7} {:.7} {:.7}\n", p[0], p[1], p[2]));
    }
    for t in triangles {
        out.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    out
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
        let mut mesh = msh::read_msh(&mesh_path)
            .map_err(|e| SceneError::new(&e.file, e.line, e.message.clone()))?;
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
fn at_key(dir: &Path, section: &str, key: &str, message: String) -> SceneError {
    let toml = dir.join("scene.toml");
    let line = read_text(&toml).map_or(0, |text| limits::key_line(&text, section, key));
    SceneError::new(&toml, line, message)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tracks_round_trip_and_errors_name_the_line() {
        let frames = vec![
            vec![
                Observation {
                    id: 0,
                    uv: [1.0, 2.0],
                },
                Observation {
                    id: 3,
                    uv: [4.5, 6.25],
                },
            ],
            vec![Observation {
                id: 3,
                uv: [4.0, 6.0],
            }],
        ];
        let text = write_tracks(&frames);
        let back = read_tracks(&text, Path::new("t.csv")).unwrap();
        assert_eq!(back, frames);
        let err = read_tracks(
            "frame,id,u,v\n0,1,2.0,3.0\n0,2,abc,3.0\n",
            Path::new("t.csv"),
        )
        .unwrap_err();
        assert_eq!(err.line, 3);
        assert!(err.message.contains("abc"), "{err}");
        let err = read_tracks("frame,id,u,v\n0,1,2.0\n", Path::new("t.csv")).unwrap_err();
        assert_eq!(err.line, 2);
        let err = read_tracks("frame,id,u,v\n1,1,2,2\n0,1,2,2\n", Path::new("t.csv")).unwrap_err();
        assert_eq!(err.line, 3);
        let err = read_tracks("frame,id,u,v\n0,1,2,2\n0,1,3,3\n", Path::new("t.csv")).unwrap_err();
        assert!(err.message.contains("twice"));
        assert_eq!(
            err.to_string(),
            "t.csv:3: feature 1 appears twice in frame 0"
        );
    }

    #[test]
    fn toml_errors_carry_the_line() {
        let text = "name = \"x\"\n[model]\nmesh = \"m.msh\"\nfixed = [0]\nyoung = \"soft\"\npoisson = 0.3\n";
        let err = SceneFile::parse(text, Path::new("scene.toml")).unwrap_err();
        assert_eq!(err.line, 5, "{err}");
        let missing = "name = \"x\"\n";
        let err = SceneFile::parse(missing, Path::new("scene.toml")).unwrap_err();
        assert!(err.message.contains("model"), "{err}");
    }

    #[test]
    fn ground_truth_frames_and_ids_are_bounded() {
        // Once cast to an index, 1e19 overflowed `frame + 1`; 1e12 asked for a terabyte.
        for row in [
            "1e19,0,0,0,0",
            "1000000000000,0,0,0,0",
            "-1,0,0,0,0",
            "0.5,0,0,0,0",
        ] {
            let text = format!("frame,id,x,y,z\n0,0,0,0,0\n{row}\n");
            let err = read_points_csv(&text, Path::new("t.csv")).unwrap_err();
            assert_eq!(err.line, 3, "{err}");
            assert!(err.message.contains("frame"), "{err}");
        }
        let err =
            read_points_csv("frame,id,x,y,z\n0,1e19,0,0,0\n", Path::new("t.csv")).unwrap_err();
        assert!(err.message.contains("target id"), "{err}");
        let err = read_cut_csv("frame,u,v\n1e12,1,2\n", Path::new("c.csv")).unwrap_err();
        assert_eq!(
            (err.line, err.file.as_path()),
            (2, Path::new("c.csv")),
            "{err}"
        );
        let ok = read_points_csv("frame,id,x,y,z\n1.0,0.0,1,2,3\n", Path::new("t.csv")).unwrap();
        assert_eq!(ok, vec![vec![], vec![[1.0, 2.0, 3.0]]]);
    }

    #[test]
    fn obj_round_trip() {
        let pos = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.5]];
        let tri = vec![[0, 1, 2]];
        let s = read_obj(&write_obj(&pos, &tri), Path::new("s.obj")).unwrap();
        assert_eq!((s.positions, s.triangles), (pos, tri));
        assert!(read_obj("v 0 0 0\nf 1 2 3\n", Path::new("s.obj")).is_err());
    }
}
