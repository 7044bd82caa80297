//! `scene.toml`: its sections as read, the checks that need no mesh, and the core's camera and
//! solver configuration built from them.

use std::path::Path;

use incise_core::nalgebra::{Matrix3, Vector3};
use incise_core::{Camera, Coupling, Intrinsics, Parameter, Projection, SolverConfig, Strategy};
use serde::{Deserialize, Serialize};

use super::SceneError;
use crate::limits::{self, Refusal};
use crate::storage::SceneCapacities;

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
    /// Whether the model's energy has the inversion barrier
    /// ([`incise_core::material::InversionBarrier`]); on unless a scene turns it off.
    #[serde(default = "yes", skip_serializing_if = "is_yes")]
    pub inversion_barrier: bool,
    /// The model's strain energy law (`"saint-venant-kirchhoff"`, the paper's and the default,
    /// or `"stable-neo-hookean"`).
    #[serde(default, skip_serializing_if = "ModelLaw::is_default")]
    pub law: ModelLaw,
}

/// `[model] law`: the strain energy law of the model ([`incise_core::Law`]).
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq, Eq, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum ModelLaw {
    /// Saint Venant–Kirchhoff, the paper's.
    #[default]
    SaintVenantKirchhoff,
    /// Stable Neo-Hookean (Smith, de Goes and Kim 2018, without its log term).
    StableNeoHookean,
}

impl ModelLaw {
    // serde hands the field by reference.
    #[allow(clippy::trivially_copy_pass_by_ref)]
    fn is_default(&self) -> bool {
        *self == ModelLaw::default()
    }

    /// The core's law.
    pub fn core(self) -> incise_core::Law {
        match self {
            ModelLaw::SaintVenantKirchhoff => incise_core::Law::SaintVenantKirchhoff,
            ModelLaw::StableNeoHookean => incise_core::Law::StableNeoHookean,
        }
    }
}

fn yes() -> bool {
    true
}

// serde hands the field by reference.
#[allow(clippy::trivially_copy_pass_by_ref)]
fn is_yes(b: &bool) -> bool {
    *b
}

fn one() -> f64 {
    1.0
}

/// `[camera]`: intrinsics (pixels) and world-to-camera pose (metres).
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
    /// `"perspective"` (a pinhole, the default) or `"orthographic"` (parallel rays; `fx`, `fy`
    /// then in pixels per metre).
    #[serde(default = "default_projection", skip_serializing_if = "is_perspective")]
    pub projection: String,
}

fn default_near() -> f64 {
    1e-4
}

fn default_projection() -> String {
    "perspective".into()
}

fn is_perspective(p: &String) -> bool {
    p == "perspective"
}

/// `[solver]`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SolverSection {
    /// `"refactor"`, `"frozen"`, `"factor-once"` or `"quasi-newton"`.
    pub strategy: String,
    /// PCG iterations per Newton step for `"frozen"` (and per later Newton step for
    /// `"factor-once"`; `"refactor"` and `"quasi-newton"` run none).
    #[serde(default = "default_pcg")]
    pub pcg_iterations: u32,
    /// Newton steps per frame.
    pub newton_iterations: u32,
    /// Line-search trials per Newton step.
    pub line_search_steps: u32,
    /// The springs' stiffness relative to the material and the feature spacing (`β` of
    /// `incise_core::Coupling::Relative`, dimensionless); the core's default when neither this
    /// nor `spring_stiffness` is given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coupling: Option<f64>,
    /// The springs' stiffness `k` as a number, J/px², in place of `coupling`: for a `k`
    /// measured or taken from elsewhere.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spring_stiffness: Option<f64>,
    /// Where the springs turn from quadratic to linear (Huber's loss), in feature spacings;
    /// `inf` for quadratic springs. The core's default when not given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spring_threshold: Option<f64>,
    /// Damping toward the previous frame, fraction of the rest stiffness.
    pub damping: f64,
    /// Prior on depth (against each node's change of depth, its motion along the optical axis),
    /// fraction of the rest stiffness.
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
            opening_only: self.opening_only,
            max_outlier_fraction: self.max_outlier_fraction,
            depth: self.depth,
        }
    }

    /// This section with one field set as a `[detection]` section would write it.
    ///
    /// # Errors
    /// A message naming the field when the section has no such field, the value is not of its
    /// type, or the setting leaves the section out of its ranges
    /// ([`incise_core::DetectionConfig::validate`]).
    pub fn with(&self, setting: &DetectionSetting) -> Result<DetectionSection, String> {
        let mut table = toml::Table::try_from(self).map_err(|e| e.to_string())?;
        // `outlier_sigmas=5` means 5.0: an integer given for a field that holds a float.
        let value = match (table.get(&setting.key), &setting.value) {
            (Some(toml::Value::Float(_)), &toml::Value::Integer(i)) => toml::Value::Float(i as f64),
            (_, v) => v.clone(),
        };
        table.insert(setting.key.clone(), value);
        let set: DetectionSection = table
            .try_into()
            .map_err(|e: toml::de::Error| format!("[detection] {setting}: {}", e.message()))?;
        set.config()
            .validate()
            .map_err(|e| format!("[detection] {setting}: {e}"))?;
        Ok(set)
    }
}

impl DetectionSection {
    /// This section with `settings` set one after the other ([`DetectionSection::with`]).
    ///
    /// # Errors
    /// As [`DetectionSection::with`], for the first setting that fails.
    pub fn with_all(&self, settings: &[DetectionSetting]) -> Result<DetectionSection, String> {
        settings.iter().try_fold(self.clone(), |set, s| set.with(s))
    }
}

/// One field of `[detection]` set by hand (`KEY=VALUE`, the value as the scene file would write
/// it): what `incise eval --set` and `--sweep` apply to every variant.
#[derive(Clone, Debug, PartialEq)]
pub struct DetectionSetting {
    /// The field's name in `[detection]`, e.g. `persistence`.
    pub key: String,
    /// Its value.
    pub value: toml::Value,
}

impl std::fmt::Display for DetectionSetting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} = {}", self.key, self.value)
    }
}

impl DetectionSetting {
    /// Parses `KEY=VALUE`, the value in TOML (`2`, `6.5`, `true`).
    ///
    /// # Errors
    /// A message saying what is malformed.
    pub fn parse(text: &str) -> Result<DetectionSetting, String> {
        let (key, value) = text
            .split_once('=')
            .ok_or_else(|| format!("`{text}`: expected KEY=VALUE, e.g. persistence=1"))?;
        Ok(DetectionSetting {
            key: key.trim().to_string(),
            value: parse_value(value.trim()).map_err(|e| format!("`{text}`: {e}"))?,
        })
    }

    /// Parses `KEY=V1,V2,…`: one setting per value, in order.
    ///
    /// # Errors
    /// A message saying what is malformed.
    pub fn parse_list(text: &str) -> Result<Vec<DetectionSetting>, String> {
        let (key, values) = text
            .split_once('=')
            .ok_or_else(|| format!("`{text}`: expected KEY=V1,V2,…, e.g. persistence=1,2"))?;
        values
            .split(',')
            .map(|v| DetectionSetting::parse(&format!("{key}={v}")))
            .collect()
    }
}

/// One TOML value on its own.
fn parse_value(text: &str) -> Result<toml::Value, String> {
    let table: toml::Table = format!("v = {text}")
        .parse()
        .map_err(|e: toml::de::Error| e.message().to_string())?;
    table
        .get("v")
        .cloned()
        .ok_or_else(|| "no value".to_string())
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
    /// ground truth's frames. [`SceneFile::parse`] calls it; [`super::Scene::load_model`] checks what
    /// needs the mesh.
    ///
    /// # Errors
    /// A [`Refusal`] naming the first key at fault.
    pub fn check(&self) -> Result<(), Refusal> {
        self.capacities.check(self.detection.enabled)?;
        // Checked here, where the text is at hand, so that the error names the key's line.
        self.solver.config()?;
        self.detection
            .config()
            .validate()
            .map_err(|e| refusal_of("detection", &e))?;
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
        let projection = match c.projection.as_str() {
            "perspective" => Projection::Perspective,
            "orthographic" => Projection::Orthographic,
            other => {
                return Err(SceneError::new(
                    file,
                    0,
                    format!(
                        "[camera] projection: {other:?} is not one of \"perspective\", \
                         \"orthographic\""
                    ),
                ));
            }
        };
        Camera::with_projection(
            projection,
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
            "factor-once" => Strategy::FactorOnce {
                pcg_iterations: s.pcg_iterations,
            },
            "quasi-newton" => Strategy::QuasiNewton,
            other => {
                return Err(Refusal::new(
                    "solver",
                    "strategy",
                    format!(
                        "must be \"refactor\", \"frozen\", \"factor-once\" or \"quasi-newton\", not {other:?}"
                    ),
                ));
            }
        };
        let coupling = match (s.coupling, s.spring_stiffness) {
            (Some(_), Some(_)) => {
                return Err(Refusal::new(
                    "solver",
                    "spring_stiffness",
                    "give either `coupling` (relative to the scene) or `spring_stiffness` (J/px²), \
                     not both",
                ));
            }
            (Some(beta), None) => Coupling::Relative(beta),
            (None, Some(k)) => Coupling::Stiffness(k),
            (None, None) => Coupling::default(),
        };
        let config = SolverConfig {
            strategy,
            newton_iterations: s.newton_iterations,
            line_search_steps: s.line_search_steps,
            coupling,
            spring_threshold: s
                .spring_threshold
                .unwrap_or(incise_core::solve::DEFAULT_SPRING_THRESHOLD),
            damping: s.damping,
            depth_prior: s.depth_prior,
            image_margin: s.image_margin,
        };
        config.validate().map_err(|e| refusal_of("solver", &e))?;
        Ok(config)
    }
}

/// The scene key a core parameter is read from, for an error that points at its line.
fn key_of(parameter: Parameter) -> &'static str {
    match parameter {
        Parameter::NewtonIterations => "newton_iterations",
        Parameter::LineSearchSteps => "line_search_steps",
        Parameter::PcgIterations => "pcg_iterations",
        Parameter::Strategy => "strategy",
        Parameter::Damping => "damping",
        Parameter::DepthPrior => "depth_prior",
        Parameter::SpringThreshold => "spring_threshold",
        Parameter::SpringStiffness => "coupling",
        Parameter::ImageMargin => "image_margin",
        Parameter::RadiusPx => "radius",
        Parameter::RadiusSpacings => "radius_spacings",
        Parameter::MaxSurfaceRatio => "max_surface_ratio",
        Parameter::OutlierSigmas => "outlier_sigmas",
        Parameter::TemporalSigmas => "temporal_sigmas",
        Parameter::MinDifferencePx => "min_difference",
        Parameter::Persistence => "persistence",
        Parameter::InitPoints => "init_points",
        Parameter::AlphaDegrees => "alpha",
        Parameter::MinStep => "min_step",
        Parameter::MaxStep => "max_step",
        Parameter::MinSupport => "min_support",
        Parameter::LineTolerance => "line_tolerance",
        Parameter::MaxOutlierFraction => "max_outlier_fraction",
        Parameter::Depth => "depth",
        _ => "",
    }
}

/// A core error about `[section]` as a refusal naming the key it came from, where the core
/// names one.
pub(crate) fn refusal_of(section: &'static str, e: &incise_core::Error) -> Refusal {
    let key = match e {
        incise_core::Error::InvalidParameter { parameter } => key_of(*parameter),
        _ => "",
    };
    Refusal::new(section, key, e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn the_law_is_svk_unless_the_scene_names_another() {
        let base = include_str!("../../../fixtures/band-side-cut/scene.toml");
        let with_law =
            |law: &str| base.replacen("[model]\n", &format!("[model]\nlaw = {law}\n"), 1);
        let file = SceneFile::parse(base, Path::new("scene.toml")).unwrap();
        assert_eq!(file.model.law, ModelLaw::SaintVenantKirchhoff);
        assert_eq!(
            file.model.law.core(),
            incise_core::Law::SaintVenantKirchhoff
        );
        // Written back, the default stays unwritten (the committed scenes do not change).
        assert!(!toml::to_string(&file).unwrap().contains("law"));
        let nh =
            SceneFile::parse(&with_law("\"stable-neo-hookean\""), Path::new("scene.toml")).unwrap();
        assert_eq!(nh.model.law.core(), incise_core::Law::StableNeoHookean);
        assert!(
            toml::to_string(&nh)
                .unwrap()
                .contains("law = \"stable-neo-hookean\"")
        );
        let err =
            SceneFile::parse(&with_law("\"mooney-rivlin\""), Path::new("scene.toml")).unwrap_err();
        let line = base.lines().position(|l| l == "[model]").unwrap() + 2;
        assert_eq!(err.line, line, "{err}");
        assert!(err.message.contains("stable-neo-hookean"), "{err}");
    }
}
