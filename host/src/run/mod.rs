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

use incise_core::{CutWork, Error as CoreError, MeshInput, Model, Observation, Real};
use indicatif::{ProgressBar, ProgressStyle};

pub use sinks::FrameSink;
#[cfg(feature = "opencv")]
pub use sources::VideoFrames;
pub use sources::{FrameSource, SourceFrame, TrackSource, rest_silhouette};
pub use trace::{CutTrace, DetectionTrace, FrameHealth, FrameRecord, FrameWork, Summary, Trace};

use crate::render::overlay::{self, Overlay};
use crate::render::silhouette;
use crate::scene::{Precision, Scene, SceneError};
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
    /// Also run the scene with its mesh cut along the true cut instead of the detected one
    /// ([`Cutting::AlongTruth`]), for [`Summary::dice_final_true_cut`] and
    /// [`Summary::tre_mm_final_true_cut`].
    pub true_cut: bool,
}

/// How a pass cuts the mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cutting {
    /// Never: detection off, the model stays whole.
    Off,
    /// Where the core detects the cut (the product).
    Detected,
    /// Along the true cut of the ground truth, detection off: the straight line through the
    /// true cut's points in the image (total least squares, from end to end, extended by a
    /// feature spacing as a detected line is), cut into the mesh in the first frame after the
    /// cut opens and again whenever the true line has grown by 5 % (a cut that grows while
    /// filmed). What the model reaches with a perfect detector:
    /// the difference to [`Cutting::Detected`] is the detector's share of the error, the rest
    /// the model's.
    AlongTruth,
}

/// The storage of `scene`'s model, its capacities checked.
///
/// # Errors
/// A [`RunError::Scene`] naming `scene.toml` for capacities beyond their bounds or the memory
/// budget; a [`RunError::Core`] for a mesh the core refuses.
pub(crate) fn scene_storage(scene: &Scene) -> Result<ModelStorage<f64>, RunError> {
    scene_storage_for(scene, &scene.mesh_input())
}

/// [`scene_storage`] for the scene's mesh given in the core's scalar type.
pub(crate) fn scene_storage_for<T: Real>(
    scene: &Scene,
    mesh: &MeshInput<'_, T>,
) -> Result<ModelStorage<T>, RunError> {
    let toml = scene.dir.join("scene.toml");
    ModelStorage::new(mesh, &scene.file.capacities).map_err(|e| match e {
        StorageError::Refused(r) => RunError::Scene(SceneError::new(&toml, 0, r.to_string())),
        StorageError::Core(error) => RunError::Core {
            context: "sizing the model".into(),
            error,
        },
    })
}

/// The observations of `frame` whose features the model knows (those that missed the model at
/// frame 0 were never embedded), in the model's scalar type.
pub(crate) fn known_observations<T: Real>(
    model: &Model<'_, T>,
    frame: &[Observation<f64>],
) -> Vec<Observation<T>> {
    frame
        .iter()
        .filter(|o| model.features().slot_of(o.id).is_some())
        .map(cast_observation)
        .collect()
}

/// An observation in the core's scalar type.
pub(crate) fn cast_observation<T: Real>(o: &Observation<f64>) -> Observation<T> {
    Observation {
        id: o.id,
        uv: o.uv.map(T::of),
    }
}

/// A point in the core's scalar type.
fn cast_point<T: Real, const N: usize>(p: &[f64; N]) -> [T; N] {
    p.map(T::of)
}

/// A point of the core in `f64`.
pub(crate) fn to_f64<T: Real, const N: usize>(p: &[T; N]) -> [f64; N] {
    p.map(Real::to_f64)
}

/// Embeds the internal targets of the ground truth (their frame-0 positions) in `model`,
/// which carries them from then on (through cuts, each on its own side).
fn embed_targets<T: Real>(truth: Option<&Truth>, model: &mut Model<'_, T>) -> Result<(), RunError> {
    if let Some(points) = truth.and_then(Truth::first_targets) {
        let points: Vec<[T; 3]> = points.iter().map(cast_point).collect();
        model
            .embed_targets(&points)
            .map_err(core("embedding the internal targets"))?;
    }
    Ok(())
}

/// Loads `scene`'s ground truth and embeds its internal targets in `model`, as a run does.
///
/// # Errors
/// A [`RunError`] for a ground truth that cannot be read or targets the core refuses.
pub(crate) fn embed_scene_targets<T: Real>(
    scene: &Scene,
    model: &mut Model<'_, T>,
) -> Result<(), RunError> {
    embed_targets(Truth::load(scene)?.as_ref(), model)
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
    let mode = if cutting {
        Cutting::Detected
    } else {
        Cutting::Off
    };
    run_pass(scene, source, mode, out, sink, progress)
}

/// [`run_with`] with the way the mesh is cut spelled out, in the scene's
/// [`Precision`].
///
/// # Errors
/// As [`run_with`].
pub fn run_pass(
    scene: &Scene,
    source: &mut dyn FrameSource,
    cutting: Cutting,
    out: Option<&Path>,
    sink: Option<&mut dyn FrameSink>,
    progress: bool,
) -> Result<Trace, RunError> {
    match scene.precision {
        Precision::F64 => run_pass_in::<f64>(scene, source, cutting, out, sink, progress),
        Precision::F32 => run_pass_in::<f32>(scene, source, cutting, out, sink, progress),
    }
}

/// [`run_pass`] with the core in `T`: the scene, the observations and the true targets are
/// rounded to `T` on their way in, the model's positions widened to `f64` on their way out,
/// and everything the host measures and draws is `f64`.
fn run_pass_in<T: Real>(
    scene: &Scene,
    source: &mut dyn FrameSource,
    cutting: Cutting,
    out: Option<&Path>,
    sink: Option<&mut dyn FrameSink>,
    progress: bool,
) -> Result<Trace, RunError> {
    let toml = scene.dir.join("scene.toml");
    let mut config = scene.model_config()?;
    config.detection.enabled &= cutting == Cutting::Detected;
    config
        .detection
        .validate()
        .map_err(|e| SceneError::new(&toml, 0, format!("[detection]: {e}")))?;
    let camera = config.camera;
    let config = config.cast::<T>().map_err(core(format!(
        "the scene's camera in {}",
        scene.precision.name()
    )))?;
    let rest: Vec<[T; 3]> = scene.rest.iter().map(cast_point).collect();
    let mesh = MeshInput {
        rest: &rest,
        tets: &scene.tets,
        fixed: &scene.file.model.fixed,
    };
    let mut storage = scene_storage_for(scene, &mesh)?;
    let model_bytes = storage.bytes();
    let mut model = storage
        .model(&mesh, &config)
        .map_err(core("building the model"))?;
    let rest_silhouette = silhouette(&camera, &scene.rest, model.mesh().surface());
    let first = source
        .next_frame(&rest_silhouette)?
        .ok_or_else(|| RunError::Input("the input holds no frame".into()))?;
    let frame0: Vec<Observation<T>> = first.observations.iter().map(cast_observation).collect();
    let placed = model
        .embed_features(&frame0)
        .map_err(core("placing the frame-0 features on the model"))?;
    let truth = Truth::load(scene)?;
    embed_targets(truth.as_ref(), &mut model)?;
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
        if cutting == Cutting::AlongTruth
            && let Some(t) = truth.as_ref()
        {
            pass.cut_along_truth(&mut model, f, t, scene.file.ground_truth.cut_open_frame);
        }
        let x: Vec<[f64; 3]> = model.positions().iter().map(to_f64).collect();
        let surface = model.mesh().surface().to_vec();
        pass.read_cut_line(&model, f)?;
        let measure = FrameMeasure::new(scene, truth.as_ref(), f, &camera, &model, (&x, &surface))?;
        if outputs.wants_overlay() {
            let virtual_features: Vec<[f64; 2]> = (0..model.features().len())
                .filter_map(|slot| model.projected_feature(slot).ok())
                .map(|uv| to_f64(&uv))
                .collect();
            let separation_points: Vec<[f64; 2]> =
                model.detector().points().iter().map(to_f64).collect();
            let canvas = overlay::draw(&Overlay {
                scene: &scene.file.name,
                frame: f,
                camera: &camera,
                picture: frame.image.as_ref(),
                virtual_features: &virtual_features,
                separation_points: &separation_points,
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
        spring_stiffness: model.spring_stiffness().to_f64(),
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
    /// Room the whole cut line needs: `cut_vertices` entries.
    cut_vertices: usize,
    /// Dice and target error (metres) of the last frame.
    last: (f64, f64),
    /// Length of the true cut line last cut into the mesh ([`Cutting::AlongTruth`]), pixels.
    true_cut_px: f64,
}

impl Pass {
    fn new(cut_vertices: usize) -> Self {
        Pass {
            frames: vec![],
            observations: vec![],
            detection: DetectionTrace::default(),
            cuts: CutTrace::default(),
            rejected: vec![],
            cut_vertices: cut_vertices.max(1),
            last: (0.0, 0.0),
            true_cut_px: 0.0,
        }
    }

    /// Steps the model over frame `f`'s observations (frame 0 only placed the features) and
    /// returns the frame's record, its measures still to fill.
    fn step<T: Real>(
        &mut self,
        model: &mut Model<'_, T>,
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
            work: None,
            health: None,
        };
        if f == 0 {
            return record;
        }
        let known = known_observations(model, obs);
        record.observed = known.len();
        // The formulas of the model this frame starts with (a cut at its end changes them).
        let bounds = (
            model.worst_case_work(),
            model.worst_case_detection_work(),
            model.worst_case_cut_work(),
        );
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
                record.work = Some(FrameWork {
                    solve: report.work,
                    solve_bound: bounds.0,
                    detection: report.detection.work,
                    line: report.cut_line.work,
                    detection_bound: bounds.1,
                    // A cut event that found nothing new to cut still did its work.
                    cut: (report.cut.applied || report.cut.event.work != CutWork::default())
                        .then_some((report.cut.event.work, report.cut.work)),
                    cut_bound: bounds.2,
                });
                let pivots = model.factor().d_values().map_or((f64::NAN, f64::NAN), |d| {
                    d.iter()
                        .map(|v| v.to_f64())
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                            (lo.min(v), hi.max(v))
                        })
                });
                record.health = Some(FrameHealth {
                    gradient_before: report.gradient_norm_before.to_f64(),
                    gradient_after: report.gradient_norm_after.to_f64(),
                    pivots,
                    finite: model.positions().iter().flatten().all(|v| v.finite()),
                });
                self.cuts.record(f, &report.cut);
                let d = &mut self.detection;
                d.pairs = report.detection.pairs;
                d.pairs_lost = report.detection.pairs_lost;
                d.features_filtered = report.detection.features_filtered;
                d.spacing_px = model.detector().spacing().to_f64();
                if d.detected_frame.is_none() {
                    d.detected_frame = report.cut_line.detected_frame.map(|_| f as u32);
                }
            }
        }
        record
    }

    /// [`Cutting::AlongTruth`]: after frame `f`'s step, cuts the mesh along the true cut's
    /// straight line if the cut has opened (`open`) and its line is new or has grown by 5 %.
    fn cut_along_truth<T: Real>(
        &mut self,
        model: &mut Model<'_, T>,
        f: usize,
        truth: &Truth,
        open: Option<u32>,
    ) {
        if open.is_none_or(|o| f <= o as usize) {
            return;
        }
        let Some(line) = truth.cut_at(f).and_then(straight_line) else {
            return;
        };
        let length = (line[1][0] - line[0][0]).hypot(line[1][1] - line[0][1]);
        if length <= 1.05 * self.true_cut_px {
            return;
        }
        // Extended by a feature spacing, as the core extends a detected line's open ends.
        let extension = model.detector().spacing();
        let report = model
            .cut_along(&line.map(|p| cast_point(&p)), extension)
            .unwrap_or_else(incise_core::CutReport::refused);
        self.cuts.record(f, &report);
        if report.applied {
            self.true_cut_px = length;
        }
    }

    /// Copies the model's cut line after frame `f` into the detection trace.
    fn read_cut_line<T: Real>(&mut self, model: &Model<'_, T>, f: usize) -> Result<(), RunError> {
        // `cut_vertices` entries: the whole line always fits.
        let mut polyline = vec![[T::zero(); 2]; self.cut_vertices];
        let n = model
            .cut_polyline(&mut polyline)
            .map_err(core(format!("frame {f}: cut line")))?;
        self.detection.polyline = polyline[..n].iter().map(to_f64).collect();
        Ok(())
    }
}

/// The straight segment through `points` (total least squares), between the smallest and the
/// largest projection of the points on it: `None` for fewer than two distinct points.
fn straight_line(points: &[[f64; 2]]) -> Option<[[f64; 2]; 2]> {
    let (c, e) = crate::metrics::principal_axis(points)?;
    let t = |p: &[f64; 2]| (p[0] - c[0]) * e[0] + (p[1] - c[1]) * e[1];
    let lo = points.iter().map(t).fold(f64::INFINITY, f64::min);
    let hi = points.iter().map(t).fold(f64::NEG_INFINITY, f64::max);
    (hi > lo).then(|| {
        [
            [c[0] + e[0] * lo, c[1] + e[1] * lo],
            [c[0] + e[0] * hi, c[1] + e[1] * hi],
        ]
    })
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
    let mut summary = Summary::new(scene, &trace, &uncut);
    if options.true_cut && scene.file.ground_truth.cut_open_frame.is_some() {
        // Its pictures and meshes beside the detected run's, to compare the two.
        let out = options.out.as_ref().map(|o| o.join("true-cut"));
        let along = run_pass(
            scene,
            &mut TrackSource::new(&trace.observations),
            Cutting::AlongTruth,
            out.as_deref(),
            None,
            false,
        )?;
        summary.dice_final_true_cut = Some(along.dice_final);
        summary.tre_mm_final_true_cut = Some(along.tre_final * 1e3);
    }
    Ok((summary, trace))
}

#[cfg(test)]
mod tests {
    use super::straight_line;

    #[test]
    fn straight_line_spans_the_points_along_their_direction() {
        // Pairs of points 1 px either side of the line v = 2u + 10 (along its normal
        // (−2, 1)/√5), u from 3 to 40: total least squares gives the line itself.
        let n = [-2.0 / 5f64.sqrt(), 1.0 / 5f64.sqrt()];
        let points: Vec<[f64; 2]> = (0..24)
            .map(|k| {
                let u = 3.0 + 37.0 * f64::from(k / 2) / 11.0;
                let off = if k % 2 == 0 { 1.0 } else { -1.0 };
                [u + off * n[0], 2.0 * u + 10.0 + off * n[1]]
            })
            .collect();
        let [a, b] = straight_line(&points).expect("a line");
        let slope = (b[1] - a[1]) / (b[0] - a[0]);
        assert!((slope - 2.0).abs() < 1e-9, "slope {slope}");
        // The ends are the extreme points' projections: u = 3 and u = 40 on the line.
        let (lo, hi) = if a[0] < b[0] { (a, b) } else { (b, a) };
        assert!(
            (lo[0] - 3.0).abs() < 1e-9 && (lo[1] - 16.0).abs() < 1e-9,
            "{lo:?}"
        );
        assert!(
            (hi[0] - 40.0).abs() < 1e-9 && (hi[1] - 90.0).abs() < 1e-9,
            "{hi:?}"
        );
    }

    #[test]
    fn straight_line_needs_two_distinct_points() {
        assert!(straight_line(&[]).is_none());
        assert!(straight_line(&[[1.0, 2.0]]).is_none());
        assert!(straight_line(&[[1.0, 2.0], [1.0, 2.0]]).is_none());
    }
}
