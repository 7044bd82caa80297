//! `incise run`: drive the core frame by frame over a scene's tracks and measure it against
//! the scene's ground truth.

use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

use image::RgbImage;
use incise_core::mesh::MeshCapacity;
use incise_core::{
    Capacities, Error as CoreError, MeshAnalysis, MeshInput, Model, ModelBuffers, ModelConfig,
    ModelSize, Observation, Real, analyse_mesh, analyse_mesh_work_len,
};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use crate::limits::{self, Refusal};
use crate::metrics::{dice, paired_rms, surface_rms};
use crate::render::{Mask, silhouette};
use crate::scene::{
    CapacitySection, Scene, SceneError, Surface, read_cut_csv, read_obj, read_points_csv,
};
use crate::vtu;

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

fn core(context: impl Into<String>) -> impl FnOnce(CoreError) -> RunError {
    let context = context.into();
    move |error| RunError::Core { context, error }
}

fn output(e: impl fmt::Display) -> RunError {
    RunError::Output(e.to_string())
}

/// Why a model's storage was not allocated.
#[derive(Debug, Clone, PartialEq)]
pub enum StorageError {
    /// A capacity beyond its bound, or storage beyond the host's memory budget
    /// ([`crate::limits`]).
    Refused(Refusal),
    /// The core refused the mesh.
    Core(CoreError),
}

impl fmt::Display for StorageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StorageError::Refused(r) => write!(f, "{r}"),
            StorageError::Core(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for StorageError {}

impl StorageError {
    /// The error of a run of the scene whose `scene.toml` is `toml`.
    pub fn in_scene(self, toml: &Path) -> RunError {
        match self {
            StorageError::Refused(r) => RunError::Scene(SceneError::new(toml, 0, r.to_string())),
            StorageError::Core(error) => RunError::Core {
                context: "sizing the model".into(),
                error,
            },
        }
    }
}

/// A model's storage as owned vectors of the lengths [`ModelSize`] gives for a set of
/// capacities: what a host does with the core's caller-sized API. Checks nothing beyond what
/// the core checks (the tests that set every capacity, down to one too small, build on it);
/// [`ModelStorage`] checks a scene's capacities and memory first.
pub struct OwnedStorage<T> {
    /// The sizes.
    pub size: ModelSize,
    reals: Vec<T>,
    indices: Vec<u32>,
}

impl<T: Real> OwnedStorage<T> {
    /// Storage for `capacities`.
    ///
    /// # Errors
    /// The core's [`CoreError::TooLarge`] for capacities it cannot hold ([`ModelSize::new`]),
    /// before anything is allocated.
    pub fn new(capacities: &Capacities) -> Result<Self, CoreError> {
        let size = ModelSize::new(capacities)?;
        Ok(OwnedStorage {
            size,
            reals: vec![T::zero(); size.real_len()],
            indices: vec![0; size.index_len()],
        })
    }

    /// Builds a model in this storage.
    ///
    /// # Errors
    /// The core's error.
    pub fn model<'a>(
        &'a mut self,
        mesh: &MeshInput<'_, T>,
        config: &ModelConfig<T>,
    ) -> Result<Model<'a, T>, CoreError> {
        let buffers = ModelBuffers::new(&self.size, &mut self.reals, &mut self.indices)?;
        Model::new(mesh, config, &self.size, buffers)
    }

    /// Bytes of the storage (scalars and indices), what a firmware build would hold.
    pub fn bytes(&self) -> usize {
        self.reals.len() * std::mem::size_of::<T>() + self.indices.len() * 4
    }
}

/// The storage of one scene's model: its capacities checked against the host's bounds and
/// memory budget, then [`OwnedStorage`].
pub struct ModelStorage<T> {
    /// What the uncut mesh needs of the linear algebra.
    pub analysis: MeshAnalysis,
    storage: OwnedStorage<T>,
}

impl<T: Real> ModelStorage<T> {
    /// Sizes storage for `mesh` with the scene's capacities: the mesh's nodes and tetrahedra
    /// plus the room a cut may take, and the factor entries the section states (absent: three
    /// times the uncut model's). Checks the capacities and the memory first
    /// ([`ModelStorage::plan`]).
    ///
    /// # Errors
    /// As [`ModelStorage::plan`].
    pub fn new(mesh: &MeshInput<'_, T>, c: &CapacitySection) -> Result<Self, StorageError> {
        let (size, analysis) = Self::plan(mesh, c)?;
        Ok(ModelStorage {
            analysis,
            storage: OwnedStorage::new(size.capacities()).map_err(StorageError::Core)?,
        })
    }

    /// The sizes [`ModelStorage::new`] would allocate, and the mesh's analysis, with nothing
    /// allocated but the analysis's workspace (the size of the mesh): every capacity is
    /// checked against its bound ([`CapacitySection::check`]) and the storage against
    /// [`limits::MEMORY_BUDGET`].
    ///
    /// # Errors
    /// [`StorageError::Refused`] naming the capacity at fault, or the whole `[capacities]`
    /// section when only their sum is too much; [`StorageError::Core`] for a mesh or capacities
    /// the core refuses.
    pub fn plan(
        mesh: &MeshInput<'_, T>,
        c: &CapacitySection,
    ) -> Result<(ModelSize, MeshAnalysis), StorageError> {
        c.check(false).map_err(StorageError::Refused)?;
        let (n, t) = (mesh.rest.len(), mesh.tets.len());
        let mut work = vec![0u32; analyse_mesh_work_len(n, t)];
        let analysis = analyse_mesh(mesh, &mut work).map_err(StorageError::Core)?;
        let tets = t.saturating_add(c.cut_tets);
        let caps = Capacities {
            mesh: MeshCapacity {
                nodes: n.saturating_add(c.cut_nodes),
                tets,
                surface_triangles: tets.saturating_mul(4),
            },
            features: c.features,
            targets: c.targets,
            factor_entries: c.factor_entries.unwrap_or(analysis.nnz_l.saturating_mul(3)),
            pairs: c.pairs,
            cut_vertices: c.cut_vertices,
        };
        let size = ModelSize::new(&caps).map_err(StorageError::Core)?;
        let bytes = size.real_len() as u128 * std::mem::size_of::<T>() as u128
            + size.index_len() as u128 * 4;
        limits::budget(
            "capacities",
            "",
            bytes,
            &format!(
                "the model's storage ({n} nodes and {t} tetrahedra, with room for {} features, \
                 {} pairs, {} cut nodes, {} cut tetrahedra and {} factor entries)",
                caps.features, caps.pairs, c.cut_nodes, c.cut_tets, caps.factor_entries
            ),
        )
        .map_err(StorageError::Refused)?;
        Ok((size, analysis))
    }

    /// Storage for `mesh` with room for `features` features and the default capacities
    /// otherwise.
    ///
    /// # Errors
    /// As [`ModelStorage::new`].
    pub fn with_features(mesh: &MeshInput<'_, T>, features: usize) -> Result<Self, StorageError> {
        Self::new(
            mesh,
            &CapacitySection {
                features,
                ..CapacitySection::default()
            },
        )
    }

    /// Builds the model in this storage.
    ///
    /// # Errors
    /// The core's error.
    pub fn model<'a>(
        &'a mut self,
        mesh: &MeshInput<'_, T>,
        config: &ModelConfig<T>,
    ) -> Result<Model<'a, T>, CoreError> {
        self.storage.model(mesh, config)
    }

    /// Bytes of the model's storage (scalars and indices), what a firmware build would hold.
    pub fn bytes(&self) -> usize {
        self.storage.bytes()
    }

    /// The sizes.
    pub fn size(&self) -> &ModelSize {
        &self.storage.size
    }
}

/// Options of a run.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Write overlay pictures and VTU meshes here.
    pub out: Option<PathBuf>,
    /// Show a progress bar.
    pub progress: bool,
}

/// What `incise run --json` prints.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Summary {
    /// Scene name.
    pub scene: String,
    /// Frames, frame 0 included.
    pub frames: usize,
    /// Features tracked at frame 0.
    pub features: usize,
    /// Features whose ray missed the model at frame 0 (left out).
    pub features_missed: usize,
    /// Neighbour pairs used for detection.
    pub pairs: usize,
    /// Pairs dropped by the temporal filter.
    pub pairs_lost: usize,
    /// Features taken out of detection by the temporal filter.
    pub features_filtered: usize,
    /// The features' spacing at frame 0, pixels: the unit of the cut line's lengths.
    pub feature_spacing_px: f64,
    /// Frame at which a cut was detected, if any.
    pub cut_detected_frame: Option<u32>,
    /// Frame at which the true cut opens (ground truth), if the scene has one.
    pub cut_open_frame: Option<u32>,
    /// Hausdorff distance of the final detected polyline to the true cut, pixels.
    pub cut_hausdorff_px: Option<f64>,
    /// The same, in percent of the image diagonal.
    pub cut_hausdorff_percent: Option<f64>,
    /// Dice of the last frame with cutting switched off.
    pub dice_final_uncut: f64,
    /// Dice of the last frame.
    pub dice_final: f64,
    /// Mean Dice over the frames from the opening of the cut (all frames without a cut).
    pub dice_mean_after_cut: f64,
    /// Surface RMS distance at the last frame, millimetres.
    pub surface_rmse_mm_final: f64,
    /// Target registration error at the last frame, millimetres.
    pub tre_mm_final: f64,
    /// The same with cutting switched off.
    pub tre_mm_final_uncut: f64,
    /// The same for the rest model left in place: the baseline any registration must beat.
    pub tre_mm_final_rest: f64,
    /// Cut events (a new topology put in service).
    pub cut_events: usize,
    /// Frame of the first cut event.
    pub cut_first_frame: Option<usize>,
    /// Nodes of the model at the start.
    pub nodes_initial: usize,
    /// Nodes and tetrahedra of the model at the end (more than at the start once cut).
    pub nodes_final: usize,
    /// Tetrahedra of the model at the end.
    pub tets_final: usize,
    /// The first cut the core refused, if any: frame and reason.
    pub cut_refused: Option<String>,
    /// Median time of `Model::step`, milliseconds.
    pub ms_per_frame_median: f64,
    /// Largest time of `Model::step`, milliseconds.
    pub ms_per_frame_max: f64,
    /// Median time of the steps that did not cut the mesh (the steady frame), milliseconds.
    pub ms_steady_median: f64,
    /// Largest time of a step that cut the mesh (the steady work plus the cut event: the
    /// geometry, the new ordering, symbolic analysis and factorization), milliseconds.
    pub ms_cut_frame_max: Option<f64>,
    /// Image width, pixels.
    pub image_width: u32,
    /// Image height, pixels.
    pub image_height: u32,
    /// Bytes of the model's fixed storage.
    pub model_bytes: usize,
    /// Frames the core refused (the model stayed as it was and the run went on).
    pub frames_rejected: usize,
    /// The first refused frame and the core's reason.
    pub first_rejected: Option<String>,
}

/// Per-frame record of one run.
#[derive(Clone, Debug, Serialize)]
pub struct FrameRecord {
    /// Frame number.
    pub frame: usize,
    /// Dice against the true silhouette.
    pub dice: f64,
    /// Target registration error, millimetres.
    pub tre_mm: f64,
    /// Time of the step, milliseconds.
    pub ms: f64,
    /// Features observed.
    pub observed: usize,
    /// Outlier pairs of the cut detection.
    pub outlier_pairs: usize,
    /// Separation points.
    pub separation_points: usize,
    /// Vertices of the cut line.
    pub cut_vertices: usize,
}

/// What the cut detection did over a run.
#[derive(Clone, Debug, Default)]
pub struct DetectionTrace {
    /// Frame at which the cut line started.
    pub detected_frame: Option<u32>,
    /// Neighbour pairs.
    pub pairs: usize,
    /// Pairs dropped by the temporal filter, by the end.
    pub pairs_lost: usize,
    /// Features taken out by the temporal filter, by the end.
    pub features_filtered: usize,
    /// The features' spacing at frame 0 (the unit of the cut line's lengths), pixels.
    pub spacing_px: f64,
    /// The cut line at the last frame, pixels.
    pub polyline: Vec<[f64; 2]>,
    /// Its Hausdorff distance to the true cut at the last frame, pixels.
    pub hausdorff_px: Option<f64>,
}

/// What cutting the mesh did over a run.
#[derive(Clone, Debug, Default)]
pub struct CutTrace {
    /// Frames at which a cut went into service.
    pub frames: Vec<usize>,
    /// Tetrahedra split, nodes and tetrahedra added, over all events.
    pub tets_split: usize,
    /// Nodes added (on cut edges and as copies).
    pub nodes_added: usize,
    /// Tetrahedra added.
    pub tets_added: usize,
    /// Lowest shape quality of a tetrahedron a cut created or moved.
    pub min_quality: f64,
    /// The first cut the core refused, and why.
    pub refused: Option<(usize, String)>,
}

impl CutTrace {
    fn record(&mut self, frame: usize, r: &incise_core::CutReport) {
        if r.applied {
            let e = &r.event;
            if self.frames.is_empty() {
                self.min_quality = 1.0;
            }
            self.frames.push(frame);
            self.tets_split += e.tets_split;
            self.nodes_added += e.edge_nodes + e.nodes_duplicated;
            self.tets_added += e.tets_added;
            self.min_quality = self.min_quality.min(f64::from(e.min_quality_milli) / 1e3);
        }
        if let (None, Some(err)) = (&self.refused, r.refused) {
            self.refused = Some((frame, err.to_string()));
        }
    }
}

/// One pass over a scene.
#[derive(Clone, Debug)]
pub struct Trace {
    /// The observations of every frame, as used (to replay the run).
    pub observations: Vec<Vec<Observation<f64>>>,
    /// The cut detection.
    pub detection: DetectionTrace,
    /// Per frame (frame 0 included, with no step time).
    pub frames: Vec<FrameRecord>,
    /// Dice of the last frame.
    pub dice_final: f64,
    /// Surface RMS distance at the last frame, metres.
    pub surface_rms_final: f64,
    /// TRE at the last frame, metres.
    pub tre_final: f64,
    /// TRE at the last frame of the rest model left in place, metres: the baseline any
    /// registration must beat.
    pub tre_rest_final: f64,
    /// Cutting the mesh.
    pub cuts: CutTrace,
    /// Frames the core refused, with its reason; the model stayed as it was and the run went
    /// on.
    pub rejected: Vec<(usize, String)>,
    /// Nodes and tetrahedra of the model at the end.
    pub mesh_final: (usize, usize),
    /// Features embedded / missed.
    pub embedded: usize,
    /// Features missed.
    pub missed: usize,
    /// Storage bytes.
    pub model_bytes: usize,
}

/// Ground truth of a scene, read once.
struct Truth {
    targets: Vec<Vec<[f64; 3]>>,
    surface: Surface,
    cut: Vec<Vec<[f64; 2]>>,
}

/// The scene's ground truth, or `None` for a scene without a `gt/` directory (a real video):
/// the run then reports no metric.
fn load_truth(scene: &Scene) -> Result<Option<Truth>, SceneError> {
    let gt = scene.dir.join("gt");
    if !gt.is_dir() {
        return Ok(None);
    }
    let read = |name: &str| -> Result<(PathBuf, String), SceneError> {
        let p = gt.join(name);
        let text = std::fs::read_to_string(&p)
            .map_err(|e| SceneError::new(&p, 0, format!("cannot read: {e}")))?;
        Ok((p, text))
    };
    let (p, t) = read("targets.csv")?;
    let targets = read_points_csv(&t, &p)?;
    let (p, t) = read("surface.obj")?;
    let surface = read_obj(&t, &p)?;
    let (p, t) = read("cut.csv")?;
    let cut = read_cut_csv(&t, &p)?;
    Ok(Some(Truth {
        targets,
        surface,
        cut,
    }))
}

/// The true silhouette of `frame`, checked against the camera's size.
fn load_silhouette(scene: &Scene, frame: usize, model_mask: &Mask) -> Result<Mask, SceneError> {
    let path = scene.silhouette_path(frame);
    let mask = Mask::load_png(&path)
        .map_err(|e| SceneError::new(&path, 0, format!("cannot read: {e}")))?;
    if (mask.width, mask.height) != (model_mask.width, model_mask.height) {
        return Err(SceneError::new(
            &path,
            0,
            format!(
                "silhouette is {}×{}, the camera {}×{}",
                mask.width, mask.height, model_mask.width, model_mask.height
            ),
        ));
    }
    Ok(mask)
}

fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    s[s.len() / 2]
}

/// One frame of input: the tracked features and, when the input is a video, its picture.
#[derive(Clone, Debug, Default)]
pub struct SourceFrame {
    /// Tracked features (undistorted pixels).
    pub observations: Vec<Observation<f64>>,
    /// The camera's picture, if any (drawn under the overlay).
    pub image: Option<RgbImage>,
}

/// Where the frames of a run come from: a scene's `tracks.csv`, or a video tracked on the fly
/// (the `opencv` feature). Frames are pulled one at a time, so a video is never held whole.
pub trait FrameSource {
    /// Number of frames, if known in advance (for the progress bar).
    fn len_hint(&self) -> Option<usize>;
    /// The next frame, `None` at the end. `model_silhouette` is the model's silhouette at rest
    /// (where a tracker should look for features at frame 0).
    ///
    /// # Errors
    /// A [`RunError`] if the input cannot be read.
    fn next_frame(&mut self, model_silhouette: &Mask) -> Result<Option<SourceFrame>, RunError>;
}

/// Frames from observations held in memory (a scene's `tracks.csv`, or a recorded run).
pub struct TrackSource<'s> {
    frames: &'s [Vec<Observation<f64>>],
    next: usize,
}

impl<'s> TrackSource<'s> {
    /// Frames from `frames`, frame 0 first.
    pub fn new(frames: &'s [Vec<Observation<f64>>]) -> Self {
        TrackSource { frames, next: 0 }
    }
}

impl FrameSource for TrackSource<'_> {
    fn len_hint(&self) -> Option<usize> {
        Some(self.frames.len())
    }

    fn next_frame(&mut self, _: &Mask) -> Result<Option<SourceFrame>, RunError> {
        let frame = self.frames.get(self.next).map(|obs| SourceFrame {
            observations: obs.clone(),
            image: None,
        });
        self.next += 1;
        Ok(frame)
    }
}

/// Where overlay pictures go besides PNG stills: an overlay video (the `opencv` feature).
pub trait FrameSink {
    /// Appends one overlay picture.
    ///
    /// # Errors
    /// A [`RunError`] if it cannot be written.
    fn write(&mut self, picture: &RgbImage) -> Result<(), RunError>;
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
/// # Errors
/// As [`run_once`], and the source's or the sink's errors.
pub fn run_with(
    scene: &Scene,
    source: &mut dyn FrameSource,
    cutting: bool,
    out: Option<&Path>,
    mut sink: Option<&mut dyn FrameSink>,
    progress: bool,
) -> Result<Trace, RunError> {
    let toml = scene.dir.join("scene.toml");
    let base = scene.model_config()?;
    let camera = base.camera;
    let config = ModelConfig {
        detection: incise_core::DetectionConfig {
            enabled: cutting && base.detection.enabled,
            ..base.detection
        },
        ..base
    };
    config
        .detection
        .validate()
        .map_err(|e| SceneError::new(&toml, 0, format!("[detection]: {e}")))?;
    let input = MeshInput {
        rest: &scene.rest,
        tets: &scene.tets,
        fixed: &scene.file.model.fixed,
    };
    let caps = &scene.file.capacities;
    let mut storage = ModelStorage::new(&input, caps).map_err(|e| e.in_scene(&toml))?;
    let model_bytes = storage.bytes();
    let mut model = storage
        .model(&input, &config)
        .map_err(core("building the model"))?;
    let rest_silhouette = silhouette(&camera, &scene.rest, model.mesh().surface());
    let first = source
        .next_frame(&rest_silhouette)?
        .ok_or_else(|| RunError::Input("the input holds no frame".into()))?;
    let report = model
        .embed_features(&first.observations)
        .map_err(core("placing the frame-0 features on the model"))?;
    let mut pending = Some(first);
    let truth = load_truth(scene)?;
    // The model carries the internal targets (through cuts, each on its own side).
    if let Some(points) = truth.as_ref().and_then(|t| t.targets.first()) {
        model
            .embed_targets(points)
            .map_err(core("embedding the internal targets"))?;
    }
    let predict = |model: &Model<'_, f64>| -> Vec<[f64; 3]> {
        (0..model.n_targets())
            .filter_map(|k| model.target_position(k))
            .collect()
    };
    let rest_targets = predict(&model);

    if let Some(dir) = out {
        std::fs::create_dir_all(dir).map_err(output)?;
    }
    let bar = if progress {
        let b = ProgressBar::new(source.len_hint().unwrap_or(0) as u64);
        if let Ok(style) =
            ProgressStyle::with_template("{prefix:>16} [{bar:30}] {pos}/{len} frames")
        {
            b.set_style(style.progress_chars("=> "));
        }
        b.set_prefix(scene.file.name.clone());
        b
    } else {
        ProgressBar::hidden()
    };
    let mut frames = vec![];
    let mut pvd = vec![];
    let mut detection = DetectionTrace::default();
    let mut polyline = vec![[0.0; 2]; caps.cut_vertices.max(1)];
    let (mut last_dice, mut last_tre) = (0.0, 0.0);
    let mut recorded = vec![];
    let mut cuts = CutTrace::default();
    let mut rejected = vec![];
    for f in 0.. {
        let frame = match pending.take() {
            Some(frame) => frame,
            None => match source.next_frame(&rest_silhouette)? {
                Some(frame) => frame,
                None => break,
            },
        };
        let obs = &frame.observations;
        let mut ms = 0.0;
        let mut observed = obs.len();
        let mut frame_detection = (0, 0, 0);
        if f > 0 {
            // Features that missed the model at frame 0 are unknown to it.
            let known: Vec<Observation<f64>> = obs
                .iter()
                .copied()
                .filter(|o| model.features().slot_of(o.id).is_some())
                .collect();
            observed = known.len();
            let t0 = Instant::now();
            // A frame the core refuses (nothing seen, a non-finite or out-of-image point, a
            // solve that breaks down) leaves the model as it was: the run notes it and goes on
            // with the next frame, as the device would.
            let step = model.step(&known);
            ms = t0.elapsed().as_secs_f64() * 1e3;
            if let Err(e) = &step {
                rejected.push((f, e.to_string()));
            }
            if let Ok(report) = step {
                frame_detection = (
                    report.detection.outliers,
                    report.detection.separation_points,
                    report.cut_line.vertices,
                );
                cuts.record(f, &report.cut);
                detection.pairs = report.detection.pairs;
                detection.pairs_lost = report.detection.pairs_lost;
                detection.features_filtered = report.detection.features_filtered;
                detection.spacing_px = model.detector().spacing();
                if detection.detected_frame.is_none() {
                    detection.detected_frame = report.cut_line.detected_frame.map(|_| f as u32);
                }
            }
        }
        let x = model.positions().to_vec();
        let surface = model.mesh().surface().to_vec();
        // `polyline` holds `cut_vertices` entries: the whole line always fits.
        let n_line = model
            .cut_polyline(&mut polyline)
            .map_err(core(format!("frame {f}: cut line")))?;
        detection.polyline = polyline[..n_line].to_vec();
        let model_mask = silhouette(&camera, &x, &surface);
        let truth_mask = match &truth {
            Some(_) => Some(load_silhouette(scene, f, &model_mask)?),
            None => None,
        };
        let d = truth_mask
            .as_ref()
            .map_or(f64::NAN, |t| dice(&model_mask, t));
        let predicted = predict(&model);
        let tre = truth
            .as_ref()
            .and_then(|t| t.targets.get(f))
            .map_or(f64::NAN, |gt| {
                if gt.len() == predicted.len() {
                    paired_rms(&predicted, gt)
                } else {
                    0.0
                }
            });
        if out.is_some() || sink.is_some() {
            let canvas = crate::overlay::draw(&crate::overlay::Overlay {
                scene: &scene.file.name,
                frame: f,
                camera: &camera,
                picture: frame.image.as_ref(),
                model: &model,
                positions: &x,
                surface: &surface,
                model_mask: &model_mask,
                truth_mask: truth_mask.as_ref(),
                true_cut: truth
                    .as_ref()
                    .and_then(|t| t.cut.get(f))
                    .map(Vec::as_slice)
                    .filter(|l| !l.is_empty()),
                observations: obs,
                cut_line: &detection.polyline,
                targets: &predicted,
                dice: d,
                target_error_mm: tre * 1e3,
            });
            if let Some(sink) = sink.as_deref_mut() {
                sink.write(&canvas.image)?;
            }
            if let Some(dir) = out {
                canvas
                    .save(&dir.join(format!("frame_{f:04}.png")))
                    .map_err(output)?;
            }
        }
        if let Some(dir) = out {
            pvd.push((f as f64, write_mesh(dir, f, &model)?));
        }
        frames.push(FrameRecord {
            frame: f,
            dice: d,
            tre_mm: tre * 1e3,
            ms,
            observed,
            outlier_pairs: frame_detection.0,
            separation_points: frame_detection.1,
            cut_vertices: frame_detection.2,
        });
        last_dice = d;
        last_tre = tre;
        recorded.push(frame.observations);
        bar.inc(1);
    }
    bar.finish_and_clear();
    if let Some(dir) = out {
        vtu::write_pvd(&dir.join("mesh.pvd"), &pvd).map_err(output)?;
        write_frames_csv(&dir.join("frames.csv"), &frames)?;
    }
    let surface_rms_final = truth
        .as_ref()
        .map_or(f64::NAN, |t| surface_distance(&t.surface, &model));
    detection.hausdorff_px = match (
        detection.polyline.is_empty(),
        truth.as_ref().and_then(|t| t.cut.last()),
    ) {
        (false, Some(line)) if !line.is_empty() => Some(crate::metrics::hausdorff_polyline(
            &detection.polyline,
            line,
        )),
        _ => None,
    };
    Ok(Trace {
        observations: recorded,
        detection,
        frames,
        dice_final: last_dice,
        surface_rms_final,
        tre_final: last_tre,
        tre_rest_final: truth
            .as_ref()
            .and_then(|t| t.targets.last())
            .filter(|gt| gt.len() == rest_targets.len() && !gt.is_empty())
            .map_or(f64::NAN, |gt| paired_rms(&rest_targets, gt)),
        cuts,
        rejected,
        mesh_final: (model.mesh().n_nodes(), model.mesh().n_tets()),
        embedded: report.embedded,
        missed: report.missed,
        model_bytes,
    })
}

/// RMS distance between the true surface and the model's, both ways (true surface points to
/// the model's boundary, the model's boundary nodes to the true surface), metres.
fn surface_distance(truth: &Surface, model: &Model<'_, f64>) -> f64 {
    let x = model.positions();
    let surface = model.mesh().surface();
    let (gt_pos, gt_tri) = (&truth.positions, &truth.triangles);
    let mut surface_nodes: Vec<u32> = surface.iter().flatten().copied().collect();
    surface_nodes.sort_unstable();
    surface_nodes.dedup();
    let model_points: Vec<[f64; 3]> = surface_nodes.iter().map(|&v| x[v as usize]).collect();
    let a = surface_rms(gt_pos, x, surface);
    let b = surface_rms(&model_points, gt_pos, gt_tri);
    let (na, nb) = (gt_pos.len() as f64, model_points.len() as f64);
    ((a * a * na + b * b * nb) / (na + nb).max(1.0)).sqrt()
}

/// Writes the model as it is after frame `f` (cut, with its lips apart) as `mesh_<f>.vtu` in
/// `dir`, with the displacement from rest; returns the file's name for the `.pvd` series.
fn write_mesh(dir: &Path, f: usize, model: &Model<'_, f64>) -> Result<String, RunError> {
    let name = format!("mesh_{f:04}.vtu");
    let x = model.positions();
    let disp: Vec<[f64; 3]> = x
        .iter()
        .zip(model.mesh().rest())
        .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
        .collect();
    vtu::write_vtu(
        &dir.join(&name),
        x,
        model.mesh().tets(),
        &[("displacement", &disp)],
        &[],
    )
    .map_err(output)?;
    Ok(name)
}

/// Writes the per-frame records as CSV.
fn write_frames_csv(path: &Path, frames: &[FrameRecord]) -> Result<(), RunError> {
    let mut csv = String::from(
        "frame,dice,tre_mm,step_ms,observed,outlier_pairs,separation_points,cut_vertices\n",
    );
    for r in frames {
        csv.push_str(&format!(
            "{},{:.5},{:.4},{:.3},{},{},{},{}\n",
            r.frame,
            r.dice,
            r.tre_mm,
            r.ms,
            r.observed,
            r.outlier_pairs,
            r.separation_points,
            r.cut_vertices
        ));
    }
    std::fs::write(path, csv).map_err(output)
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
    let times: Vec<f64> = trace.frames.iter().skip(1).map(|r| r.ms).collect();
    let open = scene.file.ground_truth.cut_open_frame;
    let after: Vec<f64> = trace
        .frames
        .iter()
        .filter(|r| open.is_none_or(|o| r.frame >= o as usize))
        .map(|r| r.dice)
        .collect();
    let camera = &scene.file.camera;
    let summary = Summary {
        scene: scene.file.name.clone(),
        frames: trace.frames.len(),
        features: trace.observations.first().map_or(0, Vec::len),
        features_missed: trace.missed,
        pairs: trace.detection.pairs,
        pairs_lost: trace.detection.pairs_lost,
        features_filtered: trace.detection.features_filtered,
        feature_spacing_px: trace.detection.spacing_px,
        cut_detected_frame: trace.detection.detected_frame,
        cut_open_frame: open,
        cut_hausdorff_px: trace.detection.hausdorff_px,
        cut_hausdorff_percent: trace
            .detection
            .hausdorff_px
            .map(|h| 100.0 * h / f64::from(camera.width).hypot(f64::from(camera.height))),
        dice_final_uncut: uncut.dice_final,
        dice_final: trace.dice_final,
        dice_mean_after_cut: after.iter().sum::<f64>() / after.len().max(1) as f64,
        surface_rmse_mm_final: trace.surface_rms_final * 1e3,
        tre_mm_final: trace.tre_final * 1e3,
        tre_mm_final_uncut: uncut.tre_final * 1e3,
        tre_mm_final_rest: trace.tre_rest_final * 1e3,
        cut_events: trace.cuts.frames.len(),
        cut_first_frame: trace.cuts.frames.first().copied(),
        nodes_initial: scene.rest.len(),
        nodes_final: trace.mesh_final.0,
        tets_final: trace.mesh_final.1,
        cut_refused: trace
            .cuts
            .refused
            .as_ref()
            .map(|(f, e)| format!("frame {f}: {e}")),
        ms_per_frame_median: median(&times),
        ms_per_frame_max: times.iter().copied().fold(0.0, f64::max),
        ms_steady_median: median(
            &trace
                .frames
                .iter()
                .skip(1)
                .filter(|r| !trace.cuts.frames.contains(&r.frame))
                .map(|r| r.ms)
                .collect::<Vec<_>>(),
        ),
        ms_cut_frame_max: trace
            .cuts
            .frames
            .iter()
            .map(|&f| trace.frames[f].ms)
            .reduce(f64::max),
        image_width: camera.width,
        image_height: camera.height,
        model_bytes: trace.model_bytes,
        frames_rejected: trace.rejected.len(),
        first_rejected: trace
            .rejected
            .first()
            .map(|(f, e)| format!("frame {f}: {e}")),
    };
    Ok((summary, trace))
}
