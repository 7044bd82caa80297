//! `scenario.toml`: what `incise gen` simulates — the real object, its cut, its motion, the
//! camera, the tracker's imperfections — and the model settings written into the scene.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::limits::{self, Refusal};
use crate::scene::{DetectionSection, SceneError, SolverSection};
use crate::storage::SceneCapacities;

/// A whole scenario.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Scene name.
    pub name: String,
    /// One line on what the scene shows.
    #[serde(default)]
    pub description: String,
    /// Seed of every random choice (features, noise, drop-outs, outliers).
    pub seed: u64,
    /// Frames, frame 0 (the rest state) included.
    pub frames: u32,
    /// The real object.
    pub object: ObjectSection,
    /// The pre-cut slit, if any.
    #[serde(default)]
    pub slit: Option<SlitSection>,
    /// Scripted motion: held and grasped regions.
    pub motion: MotionSection,
    /// The camera.
    pub camera: CameraSpec,
    /// The tracker's output quality.
    pub tracking: TrackingSection,
    /// The model written into the scene.
    pub model: ModelSpec,
    /// The model's solver.
    pub solver: SolverSection,
    /// Cut detection (written only where it differs from the defaults).
    #[serde(default, skip_serializing_if = "DetectionSection::is_default")]
    pub detection: DetectionSection,
    /// Capacities.
    #[serde(default)]
    pub capacities: SceneCapacities,
}

/// `[object]`: the shape and material of the real object.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ObjectSection {
    /// `"band"` (a box), `"dome"` (a thick spherical shell over a curved square, see
    /// [`super::object::TetMesh::dome`]) or `"mesh"` (a mesh file).
    pub shape: String,
    /// Band: size `[length x, width y, thickness z]`, metres; its corner at the origin.
    /// Dome: `[arc length along x, arc length along y, thickness]` of its mid-surface through
    /// the apex, metres.
    #[serde(default, skip_serializing_if = "is_zero3")]
    pub size: [f64; 3],
    /// Dome: radius of the sphere of its mid-surface, metres; the apex of the mid-surface is
    /// at the origin, the sphere's centre at `(0, 0, −radius)`, so the dome bulges toward +z.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub radius: f64,
    /// Band, dome: cells of the fine (real) mesh along each axis (x, y, through the
    /// thickness).
    #[serde(default, skip_serializing_if = "no_cells")]
    pub fine_cells: [usize; 3],
    /// Band, dome: cells of the coarse model mesh along each axis.
    #[serde(default, skip_serializing_if = "no_cells")]
    pub model_cells: [usize; 3],
    /// Mesh: the Gmsh file, relative to the scenario file; it is the model, and (without
    /// `real_mesh`) its uniform refinement (each tetrahedron into eight) is the real object.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub mesh: String,
    /// Mesh: metres per mesh unit.
    #[serde(default = "one")]
    pub scale: f64,
    /// Mesh: the real object's own mesh (Gmsh `.msh` or VTK XML `.vtu`), relative to the
    /// scenario file, instead of the model refined: an independent, finer mesh of the same
    /// organ in the same frame (SOFA's `liverFine.vtu` for the liver). Empty: the refinement.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub real_mesh: String,
    /// Metres per unit of `real_mesh` (default: `scale`).
    #[serde(default)]
    pub real_scale: Option<f64>,
    /// Young's modulus of the real object (Neo-Hookean), pascals.
    pub young: f64,
    /// Poisson ratio of the real object.
    pub poisson: f64,
    /// Internal targets: how many points inside the object to follow.
    #[serde(default = "default_targets")]
    pub targets: usize,
}

fn one() -> f64 {
    1.0
}

/// Refuses `section.key` = `value` beyond `[capacities] capacity` = `room` (a scene that
/// `incise run` would refuse), then checks it against `lo..=max`.
fn within_capacity(
    (section, key): (&'static str, &'static str),
    value: usize,
    (capacity, room): (&str, usize),
    lo: u64,
    max: u64,
) -> Result<(), Refusal> {
    if value > room {
        return Err(Refusal::new(
            section,
            key,
            format!(
                "{value} is more than the scene's [capacities] {capacity} = {room} holds; \
                 raise that or ask for fewer"
            ),
        ));
    }
    limits::within(section, key, value as u64, lo, max)
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

fn is_zero3(x: &[f64; 3]) -> bool {
    x.iter().all(|&c| c == 0.0)
}

fn no_cells(x: &[usize; 3]) -> bool {
    x.iter().all(|&c| c == 0)
}

fn default_targets() -> usize {
    20
}

/// `[slit]`: a cut through the object, given one of two ways:
///
/// - `point`, `normal` and `region`: the part of a plane inside an axis-aligned box;
/// - `image`: the surface swept by the camera rays through a segment of the image at rest,
///   through the whole object (optionally only inside `region`). It is the surface that the
///   model's cut (the image line extruded along the camera rays) should find: a cut made
///   straight down into the object as the camera sees it.
///
/// Without `grow` the slit is there from frame 0 (a pre-cut). With `grow = [start, end]` it
/// is a live cut: it grows from the object's boundary while the object is filmed, like
/// scissors advancing, and reaches its full length at `end` (see `grow`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SlitSection {
    /// A point of the plane, metres (after scaling).
    #[serde(default)]
    pub point: Option<[f64; 3]>,
    /// Its normal.
    #[serde(default)]
    pub normal: Option<[f64; 3]>,
    /// The slit is the part of the plane inside this axis-aligned box `[min, max]`, metres.
    #[serde(default)]
    pub region: Option<[[f64; 3]; 2]>,
    /// The slit seen in the image at rest: from pixel `[u, v]` to pixel `[u, v]`, extruded
    /// along the camera rays.
    #[serde(default)]
    pub image: Option<[[f64; 2]; 2]>,
    /// The camera `image` is given in (default: the scene's `[camera]`). Scene families set it
    /// to the base scenario's camera when they turn the camera, so that the cut stays at the
    /// same place on the object.
    #[serde(default)]
    pub camera: Option<CameraSpec>,
    /// A live cut: `[start, end]` frames. The slit is cut over that range, its front moving
    /// at constant speed from where the slit meets the object's boundary (an image slit: from
    /// its first end `image[0]`; a plane slit: from the side of `region` that reaches past the
    /// object, which must be exactly one side along one axis in the plane) to its full length
    /// at `end`. Nothing is open up to `start`; the lips of a node pair come apart from the
    /// frame the front has passed it (the first pairs at `start + 1`, the last at `end`).
    /// `0 ≤ start < end < frames`. Absent: the slit is cut before frame 0.
    #[serde(default)]
    pub grow: Option<[u32; 2]>,
}

/// `[motion]`: boxes of nodes held still and boxes grasped and moved.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MotionSection {
    /// Boxes `[min, max]` (metres) whose nodes are held at rest.
    pub held: Vec<[[f64; 3]; 2]>,
    /// Grasped regions.
    pub grasp: Vec<GraspSpec>,
}

/// One grasped region and its displacement.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GraspSpec {
    /// Box `[min, max]` (metres) of the grasped nodes.
    pub region: [[f64; 3]; 2],
    /// Final displacement, metres.
    pub displacement: [f64; 3],
    /// Rotation about the box centre at the end, degrees about `axis`.
    #[serde(default)]
    pub rotation_degrees: f64,
    /// Axis of that rotation.
    #[serde(default = "z_axis")]
    pub axis: [f64; 3],
    /// Frame where the motion starts.
    pub start: u32,
    /// Frame where it ends (held afterwards). The motion is smooth (cosine ramp).
    pub end: u32,
}

fn z_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// `[camera]`: a camera looking at a point.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    /// Camera centre, metres.
    pub eye: [f64; 3],
    /// Point looked at, metres.
    pub target: [f64; 3],
    /// Up in the image.
    pub up: [f64; 3],
    /// Focal length, pixels.
    pub focal: f64,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}

/// The camera's `eye`, `target` and `up` make a pose: finite, the eye apart from the target,
/// and up not along the view.
fn check_pose(c: &CameraSpec) -> Result<(), Refusal> {
    let finite = [c.eye, c.target, c.up]
        .iter()
        .flatten()
        .all(|x| x.is_finite());
    let view: [f64; 3] = std::array::from_fn(|k| c.target[k] - c.eye[k]);
    let norm = |v: [f64; 3]| v.iter().map(|a| a * a).sum::<f64>().sqrt();
    let cross = [
        view[1] * c.up[2] - view[2] * c.up[1],
        view[2] * c.up[0] - view[0] * c.up[2],
        view[0] * c.up[1] - view[1] * c.up[0],
    ];
    if !finite {
        return Err(Refusal::new(
            "camera",
            "eye",
            "eye, target and up must be finite",
        ));
    }
    if norm(view) <= 0.0 {
        return Err(Refusal::new(
            "camera",
            "target",
            "the target must lie apart from the eye",
        ));
    }
    // Up within about half a degree of the view leaves the image's orientation undefined.
    if norm(cross) <= 1e-2 * norm(view) * norm(c.up) {
        return Err(Refusal::new(
            "camera",
            "up",
            format!("{:?} must not point along the view (eye to target)", c.up),
        ));
    }
    Ok(())
}

/// `[tracking]`: features and their imperfections.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TrackingSection {
    /// Features sampled on the visible surface at frame 0.
    pub features: usize,
    /// Standard deviation of the Gaussian position noise, pixels.
    pub noise_px: f64,
    /// Probability that a feature is lost in a frame.
    pub dropout: f64,
    /// Fraction of features that jump once, to a wrong place, for a few frames.
    pub outlier_fraction: f64,
    /// Size of a jump, pixels.
    pub outlier_jump_px: f64,
}

/// `[model]`: the model's material.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ModelSpec {
    /// Young's modulus of the model, pascals.
    pub young: f64,
    /// Poisson ratio of the model.
    pub poisson: f64,
    /// The model's strain energy law (`scene.toml`'s `[model] law`; SVK by default).
    #[serde(default, skip_serializing_if = "is_svk")]
    pub law: crate::scene::ModelLaw,
}

// serde hands the field by reference.
#[allow(clippy::trivially_copy_pass_by_ref)]
fn is_svk(law: &crate::scene::ModelLaw) -> bool {
    *law == crate::scene::ModelLaw::default()
}

impl Scenario {
    /// Reads a scenario file.
    ///
    /// # Errors
    /// A [`SceneError`] naming the file and line.
    pub fn load(path: &Path) -> Result<Scenario, SceneError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| SceneError::new(path, 0, format!("cannot read: {e}")))?;
        Scenario::parse(&text, path)
    }

    /// Parses the text of a scenario file; `path` only names it in errors.
    ///
    /// # Errors
    /// A [`SceneError`] naming `path` and the line.
    pub fn parse(text: &str, path: &Path) -> Result<Scenario, SceneError> {
        let s: Scenario = toml::from_str(text).map_err(|e| {
            let line = e.span().map_or(0, |s| {
                text[..s.start.min(text.len())].matches('\n').count() + 1
            });
            SceneError::new(path, line, e.message().to_string())
        })?;
        s.check()
            .map_err(|r| SceneError::new(path, r.line(text), r.to_string()))?;
        Ok(s)
    }

    /// Checks, before anything is built or simulated, that the scenario writes a scene that
    /// `incise run` can use, and that its sizes hold to the bounds of [`crate::limits`]:
    /// at least two frames (the rest state and one moving frame); at least one feature and no
    /// more than the scene's `[capacities]` hold, and so for targets; tracking noise, drop-out
    /// and outliers that are finite and probabilities where they should be (a drop-out of 1
    /// would lose every feature after frame 0); a band or dome with cells along every axis
    /// and no more nodes than [`limits::MAX_FINE_NODES`] (real object) and
    /// [`limits::MAX_MODEL_NODES`] (model); positive moduli and Poisson ratios in
    /// `(-1, 0.5)`; a valid solver and detection; and the positions of every frame of the
    /// real object within [`limits::MEMORY_BUDGET`]. A mesh read from a file is checked once
    /// read ([`Scenario::check_meshes`]).
    ///
    /// # Errors
    /// A [`Refusal`] naming the first key at fault.
    pub fn check(&self) -> Result<(), Refusal> {
        limits::within("", "frames", self.frames.into(), 2, limits::MAX_FRAMES)?;
        let o = &self.object;
        limits::positive("object", "young", o.young)?;
        limits::poisson("object", "poisson", o.poisson)?;
        limits::positive("object", "scale", o.scale)?;
        if let Some(scale) = o.real_scale {
            limits::positive("object", "real_scale", scale)?;
        }
        if matches!(o.shape.as_str(), "band" | "dome") {
            for (k, &v) in o.size.iter().enumerate() {
                if !(v.is_finite() && v > 0.0) {
                    return Err(Refusal::new(
                        "object",
                        "size",
                        format!("{v} (axis {k}) must be positive and finite"),
                    ));
                }
            }
            for (key, cells, max) in [
                ("fine_cells", o.fine_cells, limits::MAX_FINE_NODES),
                ("model_cells", o.model_cells, limits::MAX_MODEL_NODES),
            ] {
                for c in cells {
                    limits::within("object", key, c as u64, 1, limits::MAX_CELLS)?;
                }
                let nodes: u64 = cells.iter().map(|&c| c as u64 + 1).product();
                if nodes > max {
                    return Err(Refusal::new(
                        "object",
                        key,
                        format!(
                            "{cells:?} make a mesh of {nodes} nodes, beyond the bound of {max}"
                        ),
                    ));
                }
            }
            let nodes: u64 = o.fine_cells.iter().map(|&c| c as u64 + 1).product();
            self.check_frames_memory(nodes)?;
        }
        let caps = &self.capacities;
        caps.check(self.detection.enabled)?;
        within_capacity(
            ("object", "targets"),
            o.targets,
            ("targets", caps.targets),
            0,
            limits::MAX_TARGETS,
        )?;
        let t = &self.tracking;
        within_capacity(
            ("tracking", "features"),
            t.features,
            ("features", caps.features),
            1,
            limits::MAX_FEATURES,
        )?;
        limits::within_f64(
            "tracking",
            "noise_px",
            t.noise_px,
            0.0,
            limits::MAX_NOISE_PX,
        )?;
        if !(t.dropout >= 0.0 && t.dropout < 1.0) {
            return Err(Refusal::new(
                "tracking",
                "dropout",
                format!(
                    "{} must be a probability below 1 (at 1 every feature is lost after frame 0)",
                    t.dropout
                ),
            ));
        }
        limits::within_f64("tracking", "outlier_fraction", t.outlier_fraction, 0.0, 1.0)?;
        limits::within_f64(
            "tracking",
            "outlier_jump_px",
            t.outlier_jump_px,
            0.0,
            limits::MAX_JUMP_PX,
        )?;
        let c = &self.camera;
        limits::image_size(c.width, c.height)?;
        limits::positive("camera", "focal", c.focal)?;
        check_pose(c)?;
        self.check_grasps()?;
        limits::positive("model", "young", self.model.young)?;
        limits::poisson("model", "poisson", self.model.poisson)?;
        self.solver.config()?;
        self.detection
            .config()
            .validate()
            .map_err(|e| crate::scene::refusal_of("detection", &e))?;
        Ok(())
    }

    /// Each grasp's axis (a direction, unless it does not turn) and frames (`start ≤ end`,
    /// within the scenario), so that a mistake is named here rather than found as a
    /// non-finite position in the simulation.
    fn check_grasps(&self) -> Result<(), Refusal> {
        for (k, g) in self.motion.grasp.iter().enumerate() {
            let norm = g.axis.iter().map(|a| a * a).sum::<f64>().sqrt();
            if g.rotation_degrees != 0.0 && !(norm.is_finite() && norm > 0.0) {
                return Err(Refusal::new(
                    "motion.grasp",
                    "axis",
                    format!("grasp {k}: {:?} is not a direction to turn about", g.axis),
                ));
            }
            if g.start > g.end || g.end >= self.frames {
                return Err(Refusal::new(
                    "motion.grasp",
                    "end",
                    format!(
                        "grasp {k}: start {} and end {} must satisfy start <= end < frames ({})",
                        g.start, g.end, self.frames
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Checks the real object's node count once its mesh is built or read, and the memory
    /// its positions over every frame take.
    ///
    /// # Errors
    /// A [`Refusal`] naming `[object]` or `frames`.
    pub fn check_meshes(&self, model_nodes: usize, real_nodes: usize) -> Result<(), Refusal> {
        for (what, nodes, max) in [
            ("model", model_nodes, limits::MAX_MODEL_NODES),
            ("real object", real_nodes, limits::MAX_FINE_NODES),
        ] {
            if nodes as u64 > max {
                return Err(Refusal::new(
                    "object",
                    "",
                    format!("the {what}'s mesh has {nodes} nodes, beyond the bound of {max}"),
                ));
            }
        }
        self.check_frames_memory(real_nodes as u64)
    }

    /// The real object's positions, one copy per frame, within the memory budget.
    fn check_frames_memory(&self, real_nodes: u64) -> Result<(), Refusal> {
        let bytes = u128::from(self.frames) * u128::from(real_nodes) * 24;
        limits::budget(
            "",
            "frames",
            bytes,
            &format!(
                "the real object's positions over {} frames ({real_nodes} nodes each)",
                self.frames
            ),
        )
    }

    /// The scenario as the text of a `scenario.toml` that [`Scenario::load`] reads back equal.
    ///
    /// # Errors
    /// A message if TOML cannot represent it (a non-finite number).
    pub fn to_toml(&self) -> Result<String, String> {
        toml::to_string(self).map_err(|e| e.to_string())
    }
}
