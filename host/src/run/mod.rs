//! `incise run`: drive the core frame by frame over a scene's tracks and measure it against
//! the scene's ground truth.
//!
//! The frame loop ([`run_with`]) is here; each of its ends has a module:
//! - `sources`: where frames come from ([`FrameSource`]: tracks in memory, or with the `opencv`
//!   feature a video tracked on the fly), and the rest silhouette a tracker starts in;
//! - `truth`: the scene's ground truth and the measures of one frame (Dice, target error);
//! - `sinks`: where overlays, meshes and per-frame records go ([`FrameSink`]);
//! - `trace`: what a pass records ([`Trace`]) and the summary `incise run` prints
//!   ([`Summary`]).

mod sinks;
mod sources;
mod trace;
mod truth;

use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

use incise_core::{Error as CoreError, Model, Observation};
use indicatif::{ProgressBar, ProgressStyle};

pub use sinks::FrameSink;
#[cfg(feature = "opencv")]
pub use sources::VideoFrames;
pub use sources::{FrameSource, SourceFrame, TrackSource, rest_silhouette};
pub use trace::{CutTrace, DetectionTrace, FrameRecord, Summary, Trace};

use crate::render::overlay::{self, Overlay};
use crate::render::silhouette;
use crate::scene::{Scene, SceneError};
use crate::storage::{ModelStorage, StorageError};
use sinks::Outputs;
use truth::{FrameMeasure, Truth, target_positions};

/// A failure of a run.
#[derive(Debug)]
pub enum RunError {
    /// A scene file is missing or malformed.
    Scene(SceneError),
    /// The core refused the scene or a frame.
    Core {
        /// What was being done.
        context: String,
        /// The core's error.
        error: CoreError,
    },
    /// The input (a video, its tracking) could not be read.
    Input(String),
    /// An output could not be written.
    Output(String),
}

impl fmt::Display for RunError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RunError::Scene(e) => write!(f, "{e}"),
            RunError::Core { context, error } => write!(f, "{context}: {error}"),
            RunError::Input(m) | RunError::Output(m) => write!(f, "{m}"),
        }
    }
}

impl std::error::Error for RunError {}

impl From<SceneError> for RunError {
    fn from(e: SceneError) -> Self {
        RunError::Scene(e)
    }
}

/// The core's error as a [`RunError`] while doing `context`.
pub(crate) fn core(context: impl Into<String>) -> impl FnOnce(CoreError) -> RunError {
    let context = context.into();
    move |error| RunError::Core { context, error }
}

/// An output's error as a [`RunError`].
pub(crate) fn output(e: impl fmt::Display) -> RunError {
    RunError::Output(e.to_string())
}

/// Options of a run.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Write overlay pictures and VTU meshes here.
    pub out: Option<PathBuf>,
    /// Show a progress bar.
    pub progress: bool,
}

/// The storage of `scene`'s model, its capacities checked.
///
/// # Errors
/// A [`RunError::Scene`] naming `scene.toml` for capacities beyond their bounds or the memory
/// budget; a [`RunError::Core`] for a mesh the core refuses.
pub(crate) fn scene_storage(scene: &Scene) -> Result<ModelStorage<f64>, RunError> {
    let toml = scene.dir.join("scene.toml");
    ModelStorage::new(&scene.mesh_input(), &scene.file.capacities).map_err(|e| match e {
        StorageError::Refused(r) => RunError::Scene(SceneError::new(&toml, 0, r.to_string())),
        StorageError::Core(error) => RunError::Core {
            context: "sizing the model".into(),
            error,
        },
    })
}

/// A progress bar over `len` frames (unknown: 0) headed `prefix`.
pub(crate) fn progress_bar(len: Option<usize>, prefix: &str) -> ProgressBar {
    let bar = ProgressBar::new(len.unwrap_or(0) as u64);
    if let Ok(style) = ProgressStyle::with_template("{prefix:>16} [{bar:30}] {pos}/{len} frames") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_prefix(prefix.to_string());
    bar
}

/// Runs the scene once over its `tracks.csv`, with cutting on or off; writes pictures and
/// meshes into `out`.
///
/// # Errors
/// A [`RunError`] for a scene the core refuses, a frame it rejects, or an output that cannot
/// be written.
pub fn run_once(
    scene: &Scene,
    cutting: bool,
    out: Option<&Path>,
    progress: bool,
) -> Result<Trace, RunError> {
    run_with(
        scene,
        &mut TrackSource::new(&scene.frames),
        cutting,
        out,
        None,
        progress,
    )
}

/// Runs the scene once over frames from `source`, with cutting on or off; writes pictures,
/// meshes and `frames.csv` into `out` and overlay pictures to `sink`. The trace records the
/// observations used, so that a second pass (cutting off) can replay them.
///
/// The stages: build the model, place the frame-0 features and the internal targets on it,
/// then per frame step the model (`Pass::step`), read its cut line, measure it against the
/// ground truth (`truth::FrameMeasure`) and hand the frame to the outputs (`sinks::Outputs`).
///
/// # Errors
/// As [`run_once`], and the source's or the sink's errors.
pub fn run_with(
    scene: &Scene,
    source: &mut dyn FrameSource,
    cutting: bool,
    out: Option<&Path>,
    sink: Option<&mut dyn FrameSink>,
    progress: bool,
) -> Result<Trace, RunError> {
    let toml = scene.dir.join("scene.toml");
    let mut config = scene.model_config()?;
    config.detection.enabled &= cutting;
    config
        .detection
        .validate()
        .map_err(|e| SceneError::new(&toml, 0, format!("[detection]: {e}")))?;
    let camera = config.camera;
    let mut storage = scene_storage(scene)?;
    let model_bytes = storage.bytes();
    let mut model = storage
        .model(&scene.mesh_input(), &config)
        .map_err(core("building the model"))?;
    let rest_silhouette = silhouette(&camera, &scene.rest, model.mesh().surface());
    let first = source
        .next_frame(&rest_silhouette)?
        .ok_or_else(|| RunError::Input("the input holds no frame".into()))?;
    let placed = model
        .embed_features(&first.observations)
        .map_err(core("placing the frame-0 features on the model"))?;
    let truth = Truth::load(scene)?;
    // The model carries the internal targets (through cuts, each on its own side).
    if let Some(points) = truth.as_ref().and_then(Truth::first_targets) {
        model
            .embed_targets(points)
            .map_err(core("embedding the internal targets"))?;
    }
    let rest_targets = target_positions(&model);
    let mut outputs = Outputs::new(out, sink)?;
    let bar = if progress {
        progress_bar(source.len_hint(), &scene.file.name)
    } else {
        ProgressBar::hidden()
    };
    let mut pass = Pass::new(scene.file.capacities.cut_vertices);
    let mut pending = Some(first);
    for f in 0.. {
        let frame = match pending.take() {
            Some(frame) => frame,
            None => match source.next_frame(&rest_silhouette)? {
                Some(frame) => frame,
                None => break,
            },
        };
        let mut record = pass.step(&mut model, f, &frame.observations);
        let x = model.positions().to_vec();
        let surface = model.mesh().surface().to_vec();
        pass.read_cut_line(&model, f)?;
        let measure = FrameMeasure::new(scene, truth.as_ref(), f, &camera, &model, (&x, &surface))?;
        if outputs.wants_overlay() {
            let canvas = overlay::draw(&Overlay {
                scene: &scene.file.name,
                frame: f,
                camera: &camera,
                picture: frame.image.as_ref(),
                model: &model,
                positions: &x,
                surface: &surface,
                model_mask: &measure.model_mask,
                truth_mask: measure.truth_mask.as_ref(),
                true_cut: truth.as_ref().and_then(|t| t.cut_at(f)),
                observations: &frame.observations,
                cut_line: &pass.detection.polyline,
                targets: &measure.targets,
                dice: measure.dice,
                target_error_mm: measure.tre * 1e3,
            });
            outputs.overlay(f, &canvas)?;
        }
        outputs.mesh(f, &model)?;
        record.dice = measure.dice;
        record.tre_mm = measure.tre * 1e3;
        pass.frames.push(record);
        pass.last = (measure.dice, measure.tre);
        pass.observations.push(frame.observations);
        bar.inc(1);
    }
    bar.finish_and_clear();
    outputs.finish(&pass.frames)?;
    let mut detection = pass.detection;
    detection.hausdorff_px = truth
        .as_ref()
        .and_then(|t| t.cut_distance(&detection.polyline));
    Ok(Trace {
        observations: pass.observations,
        detection,
        frames: pass.frames,
        dice_final: pass.last.0,
        surface_rms_final: truth
            .as_ref()
            .map_or(f64::NAN, |t| t.surface_distance(&model)),
        tre_final: pass.last.1,
        tre_rest_final: truth
            .as_ref()
            .map_or(f64::NAN, |t| t.rest_target_error(&rest_targets)),
        cuts: pass.cuts,
        rejected: pass.rejected,
        mesh_final: (model.mesh().n_nodes(), model.mesh().n_tets()),
        embedded: placed.embedded,
        missed: placed.missed,
        model_bytes,
    })
}

/// What the frame loop gathers over one pass.
struct Pass {
    /// Per-frame records.
    frames: Vec<FrameRecord>,
    /// The observations of every frame, as used.
    observations: Vec<Vec<Observation<f64>>>,
    detection: DetectionTrace,
    cuts: CutTrace,
    /// Frames the core refused, with its reason.
    rejected: Vec<(usize, String)>,
    /// Room for the whole cut line: `cut_vertices` entries.
    polyline: Vec<[f64; 2]>,
    /// Dice and target error (metres) of the last frame.
    last: (f64, f64),
}

impl Pass {
    fn new(cut_vertices: usize) -> Self {
        Pass {
            frames: vec![],
            observations: vec![],
            detection: DetectionTrace::default(),
            cuts: CutTrace::default(),
            rejected: vec![],
            polyline: vec![[0.0; 2]; cut_vertices.max(1)],
            last: (0.0, 0.0),
        }
    }

    /// Steps the model over frame `f`'s observations (frame 0 only placed the features) and
    /// returns the frame's record, its measures still to fill.
    fn step(
        &mut self,
        model: &mut Model<'_, f64>,
        f: usize,
        obs: &[Observation<f64>],
    ) -> FrameRecord {
        let mut record = FrameRecord {
            frame: f,
            dice: f64::NAN,
            tre_mm: f64::NAN,
            ms: 0.0,
            observed: obs.len(),
            outlier_pairs: 0,
            separation_points: 0,
            cut_vertices: 0,
        };
        if f == 0 {
            return record;
        }
        // Features that missed the model at frame 0 are unknown to it.
        let known: Vec<Observation<f64>> = obs
            .iter()
            .copied()
            .filter(|o| model.features().slot_of(o.id).is_some())
            .collect();
        record.observed = known.len();
        let t0 = Instant::now();
        // A frame the core refuses (nothing seen, a non-finite or out-of-image point, a solve
        // that breaks down) leaves the model as it was: the run notes it and goes on with the
        // next frame, as the device would.
        let step = model.step(&known);
        record.ms = t0.elapsed().as_secs_f64() * 1e3;
        match step {
            Err(e) => self.rejected.push((f, e.to_string())),
            Ok(report) => {
                record.outlier_pairs = report.detection.outliers;
                record.separation_points = report.detection.separation_points;
                record.cut_vertices = report.cut_line.vertices;
                self.cuts.record(f, &report.cut);
                let d = &mut self.detection;
                d.pairs = report.detection.pairs;
                d.pairs_lost = report.detection.pairs_lost;
                d.features_filtered = report.detection.features_filtered;
                d.spacing_px = model.detector().spacing();
                if d.detected_frame.is_none() {
                    d.detected_frame = report.cut_line.detected_frame.map(|_| f as u32);
                }
            }
        }
        record
    }

    /// Copies the model's cut line after frame `f` into the detection trace.
    fn read_cut_line(&mut self, model: &Model<'_, f64>, f: usize) -> Result<(), RunError> {
        // `polyline` holds `cut_vertices` entries: the whole line always fits.
        let n = model
            .cut_polyline(&mut self.polyline)
            .map_err(core(format!("frame {f}: cut line")))?;
        self.detection.polyline = self.polyline[..n].to_vec();
        Ok(())
    }
}

/// Runs a scene and summarises it (with cutting on, and, for the `_uncut` figures, off).
///
/// # Errors
/// As [`run_once`].
pub fn run_scene(scene: &Scene, options: &RunOptions) -> Result<(Summary, Trace), RunError> {
    run_scene_with(scene, &mut TrackSource::new(&scene.frames), None, options)
}

/// Runs a scene over frames from `source` (a video, say), writing overlays to `sink`, and
/// summarises it; the `_uncut` figures replay the same observations with cutting off.
///
/// # Errors
/// As [`run_with`].
pub fn run_scene_with(
    scene: &Scene,
    source: &mut dyn FrameSource,
    sink: Option<&mut dyn FrameSink>,
    options: &RunOptions,
) -> Result<(Summary, Trace), RunError> {
    let trace = run_with(
        scene,
        source,
        true,
        options.out.as_deref(),
        sink,
        options.progress,
    )?;
    // The same observations with cutting switched off, for the `_uncut` figures.
    let uncut = run_with(
        scene,
        &mut TrackSource::new(&trace.observations),
        false,
        None,
        None,
        false,
    )?;
    Ok((Summary::new(scene, &trace, &uncut), trace))
}
