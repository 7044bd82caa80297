//! `incise run`: drive the core frame by frame over a scene's tracks and measure it against
//! the scene's ground truth.
//!
//! The frame loop ([`run_pass`]) is here; each of its ends has a module:
//! - `sources`: where frames come from ([`FrameSource`]: tracks in memory, or with the `opencv`
//!   feature a video tracked on the fly), and the rest silhouette a tracker starts in;
//! - `truth`: the scene's ground truth and the measures of one frame (Dice, target error);
//! - `pass`: one pass of the frame loop: the step, the cut along the truth, the records;
//! - `sinks`: where overlays, meshes and per-frame records go ([`FrameSink`]);
//! - `trace`: what a pass records ([`Trace`]) and the summary `incise run` prints
//!   ([`Summary`]).

mod pass;
mod sinks;
mod sources;
mod trace;
mod truth;

use std::fmt;
use std::path::{Path, PathBuf};

use incise_core::{Error as CoreError, MeshInput, Model, Observation, Real};
use indicatif::{ProgressBar, ProgressStyle};

pub use sinks::FrameSink;
#[cfg(feature = "opencv")]
pub use sources::VideoFrames;
pub use sources::{FrameSource, SourceFrame, TrackSource, rest_silhouette};
pub use trace::{
    CutTrace, DetectionTrace, EXCESS_FLOOR, FilterTruth, FilteredFeature, FrameHealth, FrameRecord,
    FrameWork, PairExcess, Summary, Trace,
};

use crate::render::overlay::{self, DetectorPairs, Overlay};
use crate::render::silhouette;
use crate::scene::{Precision, Scene, SceneError};
use crate::storage::{ModelStorage, StorageError};
use pass::Pass;
use sinks::Outputs;
pub(crate) use truth::Truth;
use truth::{FrameMeasure, target_positions};

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
    /// Detected but held ([`incise_core::Model::hold_cuts`]): the line grows where the core
    /// finds the cut, and the mesh stays whole, so that every frame's residuals are the
    /// never-cut model's (what `incise eval --evidence` reads the pairs on).
    Held,
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
pub(crate) fn scene_storage_for<T: Real, F: Real>(
    scene: &Scene,
    mesh: &MeshInput<'_, T>,
) -> Result<ModelStorage<T, F>, RunError> {
    let toml = scene.dir.join("scene.toml");
    ModelStorage::with_factor_in(mesh, &scene.file.capacities).map_err(|e| match e {
        StorageError::Refused(r) => RunError::Scene(SceneError::new(&toml, 0, r.to_string())),
        StorageError::Core(error) => RunError::Core {
            context: "sizing the model".into(),
            error,
        },
    })
}

/// The observations of `frame` whose features the model knows (those that missed the model at
/// frame 0 were never embedded), in the model's scalar type.
pub(crate) fn known_observations<T: Real, F: Real>(
    model: &Model<'_, T, F>,
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
fn embed_targets<T: Real, F: Real>(
    truth: Option<&Truth>,
    model: &mut Model<'_, T, F>,
) -> Result<(), RunError> {
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
pub(crate) fn embed_scene_targets<T: Real, F: Real>(
    scene: &Scene,
    model: &mut Model<'_, T, F>,
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
    let cutting = if cutting {
        Cutting::Detected
    } else {
        Cutting::Off
    };
    run_pass(
        scene,
        &mut TrackSource::new(&scene.frames),
        cutting,
        out,
        None,
        progress,
    )
}

/// Runs the scene once over frames from `source`, cutting the mesh as `cutting` says, in the
/// scene's [`Precision`]; writes pictures, meshes and `frames.csv` into `out` and overlay
/// pictures to `sink`. The trace records the observations used, so that a second pass
/// (cutting off) can replay them.
///
/// The stages: build the model, place the frame-0 features and the internal targets on it,
/// then per frame step the model (`Pass::step`), read its cut line, measure it against the
/// ground truth (`truth::FrameMeasure`) and hand the frame to the outputs (`sinks::Outputs`).
///
/// # Errors
/// As [`run_once`], and the source's or the sink's errors.
pub fn run_pass(
    scene: &Scene,
    source: &mut dyn FrameSource,
    cutting: Cutting,
    out: Option<&Path>,
    sink: Option<&mut dyn FrameSink>,
    progress: bool,
) -> Result<Trace, RunError> {
    match scene.precision {
        Precision::F64 => run_pass_in::<f64, f64>(scene, source, cutting, out, sink, progress),
        Precision::F32 => run_pass_in::<f32, f32>(scene, source, cutting, out, sink, progress),
        Precision::Mixed => run_pass_in::<f64, f32>(scene, source, cutting, out, sink, progress),
    }
}

/// [`run_pass`] with the core in `T` and its factor in `F`: the scene, the observations and the true targets are
/// rounded to `T` on their way in, the model's positions widened to `f64` on their way out,
/// and everything the host measures and draws is `f64`.
fn run_pass_in<T: Real, F: Real>(
    scene: &Scene,
    source: &mut dyn FrameSource,
    cutting: Cutting,
    out: Option<&Path>,
    sink: Option<&mut dyn FrameSink>,
    progress: bool,
) -> Result<Trace, RunError> {
    let toml = scene.dir.join("scene.toml");
    let mut config = scene.model_config()?;
    config.detection.enabled &= matches!(cutting, Cutting::Detected | Cutting::Held);
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
    let mut storage = scene_storage_for::<T, F>(scene, &mesh)?;
    let model_bytes = storage.bytes();
    let mut model = storage
        .model(&mesh, &config)
        .map_err(core("building the model"))?;
    model.hold_cuts(cutting == Cutting::Held);
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
    let mut outputs = Outputs::new(out, sink, scene.overlay_pairs)?;
    let bar = if progress {
        progress_bar(source.len_hint(), &scene.file.name)
    } else {
        ProgressBar::hidden()
    };
    let mut pass = Pass::new(scene.file.capacities.cut_vertices);
    let mut pending = Some(first);
    // Where the overlays' legend is: kept from frame to frame while it hides little.
    let mut legend_at = None;
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
        if outputs.wants_pairs() || scene.record_excess {
            let true_cut = truth.as_ref().and_then(|t| t.cut_at(f));
            if outputs.wants_pairs() {
                let rows = pair_rows(&model, &record, &scene.file.detection, true_cut.as_deref());
                outputs.pairs(&rows);
            }
            if scene.record_excess {
                pass.excess
                    .push(pair_excess(&model, &record, true_cut.as_deref()));
            }
        }
        if outputs.wants_overlay() {
            let virtual_features: Vec<[f64; 2]> = (0..model.features().len())
                .filter_map(|slot| model.projected_feature(slot).ok())
                .map(|uv| to_f64(&uv))
                .collect();
            let separation_points: Vec<[f64; 2]> =
                model.detector().points().iter().map(to_f64).collect();
            let filtered: Vec<[f64; 2]> = frame
                .observations
                .iter()
                .filter(|o| pass.detection.filtered.iter().any(|f| f.id == o.id))
                .map(|o| o.uv)
                .collect();
            let pairs = scene.overlay_pairs.then(|| detector_pairs(&model));
            let true_cut = truth.as_ref().and_then(|t| t.cut_at(f));
            let farthest = truth
                .as_ref()
                .and_then(|t| t.cut_distance(f, &pass.detection.polyline));
            let canvas = overlay::draw(
                &Overlay {
                    scene: &scene.file.name,
                    frame: f,
                    camera: &camera,
                    picture: frame.image.as_ref(),
                    virtual_features: &virtual_features,
                    separation_points: &separation_points,
                    pairs: pairs.as_ref(),
                    positions: &x,
                    surface: &surface,
                    model_mask: &measure.model_mask,
                    truth_mask: measure.truth_mask.as_ref(),
                    true_cut: true_cut.as_deref(),
                    observations: &frame.observations,
                    filtered: &filtered,
                    cut_line: &pass.detection.polyline,
                    farthest,
                    targets: &measure.targets,
                    dice: measure.dice,
                    target_error_mm: measure.tre * 1e3,
                },
                &mut legend_at,
            );
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
    detection.distance_px = truth
        .as_ref()
        .and_then(|t| t.cut_distance(t.cut_frames().checked_sub(1)?, &detection.polyline));
    detection.open_hausdorff_px = truth
        .as_ref()
        .and_then(|t| t.open_cut_distance(&detection.polyline));
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
        spring_threshold_px: model.spring_threshold_px().to_f64(),
        model_bytes,
        excess: pass.excess,
    })
}

/// The detector's outlier and split pairs as segments between their features' latest
/// positions (the overlay's `--pairs`).
fn detector_pairs<T: Real, F: Real>(model: &Model<'_, T, F>) -> DetectorPairs {
    let detector = model.detector();
    let seen = model.features().targets();
    let mut pairs = DetectorPairs::default();
    for (k, &[i, j]) in detector.pairs().iter().enumerate() {
        let (Some(a), Some(b)) = (seen.get(i as usize), seen.get(j as usize)) else {
            continue;
        };
        let segment = [to_f64(a), to_f64(b)];
        if detector.is_split(k) {
            pairs.split.push(segment);
        } else if detector.is_outlier(k) {
            pairs.outliers.push(segment);
        }
    }
    pairs
}

/// One pair the detector measured in a frame, between its features' tracked positions, as
/// its outlier test read it.
struct MeasuredPair {
    /// Its index in the detector.
    k: usize,
    /// Its features' ids.
    ids: [u32; 2],
    /// Its features' tracked positions, pixels.
    ends: [[f64; 2]; 2],
    /// `μ`, pixels.
    difference: f64,
    /// The smooth field's share `min(sᵢ, sⱼ)·ℓ`, pixels.
    smooth: f64,
    /// Whether it was an outlier this frame.
    outlier: bool,
    /// Whether it is split.
    split: bool,
}

/// Every pair the detector measured in the frame it last stepped.
fn measured_pairs<'m, T: Real, F: Real>(
    model: &'m Model<'_, T, F>,
) -> impl Iterator<Item = MeasuredPair> + 'm {
    let detector = model.detector();
    let features = model.features();
    let seen = features.targets();
    detector
        .pairs()
        .iter()
        .enumerate()
        .filter_map(move |(k, &[i, j])| {
            let m = detector.pair_measure(k)?;
            Some(MeasuredPair {
                k,
                ids: [features.id_of(i as usize)?, features.id_of(j as usize)?],
                ends: [
                    seen.get(i as usize).map(to_f64)?,
                    seen.get(j as usize).map(to_f64)?,
                ],
                difference: m.difference.to_f64(),
                smooth: m.smooth.to_f64(),
                outlier: detector.is_outlier(k),
                split: detector.is_split(k),
            })
        })
}

/// The rows of `pairs.csv` for one frame: every pair the detector measured in it, between its
/// features' tracked positions, with what its outlier test read (the difference `μ`, the
/// smooth field's share `min(sᵢ, sⱼ)·ℓ`, the level `max(median, smooth) + margin` that `μ`
/// must pass, the margin `max(κ σ̂, min_difference)`), whether it was an outlier and is split,
/// and, with a ground truth, whether it crosses the true cut of that frame (1 or 0): the
/// evidence the detector had, pair by pair, to study a rule against.
fn pair_rows<T: Real, F: Real>(
    model: &Model<'_, T, F>,
    record: &FrameRecord,
    detection: &crate::scene::DetectionSection,
    true_cut: Option<&[Vec<[f64; 2]>]>,
) -> String {
    use std::fmt::Write;
    if record.difference_median_px.is_nan() {
        // No pair measured this frame (frame 0, a refused frame).
        return String::new();
    }
    let margin =
        (detection.outlier_sigmas * record.difference_deviation_px).max(detection.min_difference);
    let mut rows = String::new();
    for p in measured_pairs(model) {
        let [a, b] = p.ends;
        let level = record.difference_median_px.max(p.smooth) + margin;
        let crosses = true_cut.map_or("", |parts| {
            if crosses_polyline(a, b, parts) {
                "1"
            } else {
                "0"
            }
        });
        let _ = writeln!(
            rows,
            "{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.4},{:.4},{level:.4},{margin:.4},{},{},{crosses}",
            record.frame,
            p.k,
            p.ids[0],
            p.ids[1],
            a[0],
            a[1],
            b[0],
            b[1],
            p.difference,
            p.smooth,
            u8::from(p.outlier),
            u8::from(p.split),
        );
    }
    rows
}

/// The pairs of one frame that stand [`EXCESS_FLOOR`] robust deviations or more above what
/// the frame explains (`max(median, smooth)`), and whether each crosses the true cut: what an
/// outlier test at any level from the floor up would have read ([`Trace::excess`]).
fn pair_excess<T: Real, F: Real>(
    model: &Model<'_, T, F>,
    record: &FrameRecord,
    true_cut: Option<&[Vec<[f64; 2]>]>,
) -> Vec<PairExcess> {
    let deviation = record.difference_deviation_px;
    if record.difference_median_px.is_nan() || deviation.is_nan() || deviation <= 0.0 {
        return Vec::new();
    }
    measured_pairs(model)
        .filter_map(|p| {
            let excess = (p.difference - record.difference_median_px.max(p.smooth)) / deviation;
            let [a, b] = p.ends;
            (excess >= EXCESS_FLOOR).then(|| PairExcess {
                pair: p.k as u32,
                ids: p.ids,
                deviations: excess as f32,
                crosses: true_cut.is_some_and(|parts| crosses_polyline(a, b, parts)),
                midpoint: [(0.5 * (a[0] + b[0])) as f32, (0.5 * (a[1] + b[1])) as f32],
            })
        })
        .collect()
}

/// Whether segment `a b` crosses one of the polylines `parts` (touching counts).
fn crosses_polyline(a: [f64; 2], b: [f64; 2], parts: &[Vec<[f64; 2]>]) -> bool {
    // The side of `r` from the line `p q`: 1, -1, or 0 on it (`f64::signum` has no zero).
    let side = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
        let c = (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]);
        i32::from(c > 0.0) - i32::from(c < 0.0)
    };
    let overlap = |p: f64, q: f64, r: f64, s: f64| p.min(q) <= r.max(s) && r.min(s) <= p.max(q);
    parts.iter().any(|part| {
        part.windows(2).any(|w| {
            let (c, d) = (w[0], w[1]);
            let (abc, abd) = (side(a, b, c), side(a, b, d));
            if abc == 0 && abd == 0 {
                // On one line: crossing where the two overlap.
                return overlap(a[0], b[0], c[0], d[0]) && overlap(a[1], b[1], c[1], d[1]);
            }
            abc * abd <= 0 && side(c, d, a) * side(c, d, b) <= 0
        })
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
/// As [`run_pass`].
pub fn run_scene_with(
    scene: &Scene,
    source: &mut dyn FrameSource,
    sink: Option<&mut dyn FrameSink>,
    options: &RunOptions,
) -> Result<(Summary, Trace), RunError> {
    // Read before the runs, so that a damaged file costs no run.
    let true_outliers = Truth::load_outliers(scene)?;
    let trace = run_pass(
        scene,
        source,
        Cutting::Detected,
        options.out.as_deref(),
        sink,
        options.progress,
    )?;
    // The same observations with cutting switched off, for the `_uncut` figures.
    let uncut = run_pass(
        scene,
        &mut TrackSource::new(&trace.observations),
        Cutting::Off,
        None,
        None,
        false,
    )?;
    let mut summary = Summary::new(scene, &trace, &uncut);
    summary.filter_truth = true_outliers.map(|outliers| {
        FilterTruth::new(
            &trace.detection.filtered,
            &outliers,
            &trace.observations,
            trace.detection.detected_frame,
        )
    });
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
    use super::crosses_polyline;

    #[test]
    fn a_pair_crosses_the_polyline_it_spans() {
        let cut = vec![vec![[0.0, 0.0], [0.0, 10.0], [5.0, 20.0]]];
        // Across the first segment, across the second, beside both, touching an end.
        assert!(crosses_polyline([-1.0, 5.0], [1.0, 5.0], &cut));
        assert!(crosses_polyline([0.0, 15.0], [5.0, 15.0], &cut));
        assert!(!crosses_polyline([1.0, 5.0], [3.0, 5.0], &cut));
        assert!(crosses_polyline([0.0, -1.0], [0.0, 0.0], &cut));
        // Along the line of a segment: only where the two overlap.
        assert!(crosses_polyline([0.0, 2.0], [0.0, 4.0], &cut));
        assert!(!crosses_polyline([0.0, -3.0], [0.0, -1.0], &cut));
        // No cut, or a part of one point.
        assert!(!crosses_polyline([-1.0, 5.0], [1.0, 5.0], &[]));
        assert!(!crosses_polyline(
            [-1.0, 5.0],
            [1.0, 5.0],
            &[vec![[0.0, 5.0]]]
        ));
    }

    #[test]
    fn a_held_pass_finds_the_cut_and_leaves_the_mesh_whole() {
        use super::{Cutting, TrackSource, run_pass};
        let dir =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/band-side-cut");
        let mut scene = crate::scene::Scene::load(&dir).unwrap();
        scene.record_excess = true;
        let pass = |cutting| {
            run_pass(
                &scene,
                &mut TrackSource::new(&scene.frames),
                cutting,
                None,
                None,
                false,
            )
            .unwrap()
        };
        let (cut, held) = (pass(Cutting::Detected), pass(Cutting::Held));
        // The same detection, the same line; the mesh cut in one pass only.
        assert!(cut.detection.detected_frame.is_some());
        assert_eq!(held.detection.detected_frame, cut.detection.detected_frame);
        assert!(!cut.cuts.frames.is_empty());
        assert!(held.cuts.frames.is_empty());
        assert_eq!(held.mesh_final, (scene.rest.len(), scene.tets.len()));
        // Up to the detection both passes read the same pairs; after it, the cut model follows
        // the lips, and fewer pairs across the cut stand out than on the whole one.
        let d = cut.detection.detected_frame.unwrap() as usize;
        assert_eq!(held.excess[..=d], cut.excess[..=d]);
        let crossing = |t: &super::Trace| {
            t.excess[d + 1..]
                .iter()
                .flatten()
                .filter(|p| p.crosses)
                .count()
        };
        assert!(
            crossing(&held) > crossing(&cut),
            "{} {}",
            crossing(&held),
            crossing(&cut)
        );
    }
}
