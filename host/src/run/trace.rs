//! What a run records: the trace of one pass over a scene, frame by frame, and the summary
//! `incise run --json` prints.

use incise_core::{CutWork, DetectionWork, LineWork, Observation, WorkCount};
use serde::Serialize;

use crate::metrics::DirectedHausdorff;
use crate::scene::{ModelLaw, Precision, Scene};

/// What `incise run --json` prints.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Summary {
    /// The scalar type the core computed in.
    pub precision: Precision,
    /// The model's strain energy law.
    pub law: ModelLaw,
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
    /// Which, and when.
    pub filtered_features: Vec<FilteredFeature>,
    /// The filter against the features the generator made jump, for a scene that lists them
    /// (`gt/outliers.csv`).
    pub filter_truth: Option<FilterTruth>,
    /// The features' spacing at frame 0, pixels: the unit of the cut line's lengths.
    pub feature_spacing_px: f64,
    /// The springs' stiffness `k`, J/px²: the scene's, or derived from it (`[solver] coupling`).
    pub spring_stiffness: f64,
    /// Where the springs turn from quadratic to linear (Huber's loss), pixels: `[solver]
    /// spring_threshold` feature spacings (null for quadratic springs).
    pub spring_threshold_px: Option<f64>,
    /// Frame at which a cut was detected, if any.
    pub cut_detected_frame: Option<u32>,
    /// Frame at which the true cut opens (ground truth), if the scene has one.
    pub cut_open_frame: Option<u32>,
    /// The first frame, from the cut's opening on (from frame 1 without a ground truth), in
    /// which the detector held as many separation points as the cut line's start needs
    /// (`[detection] init_points`). From the opening to it the detection waits for evidence,
    /// from it to `cut_detected_frame` for the line's start to accept the evidence.
    pub cut_evidence_frame: Option<u32>,
    /// Hausdorff distance of the final detected polyline to the true cut (the slit where the
    /// camera sees it at the last frame), pixels.
    pub cut_hausdorff_px: Option<f64>,
    /// The same, in percent of the image diagonal.
    pub cut_hausdorff_percent: Option<f64>,
    /// The same to the stretches of the true cut whose lips are a pixel or more apart in the
    /// image, in percent of the image diagonal.
    pub cut_open_hausdorff_percent: Option<f64>,
    /// Of `cut_hausdorff_percent`, the farthest the line strays from the true cut (the larger
    /// of the two directed distances is the Hausdorff distance), percent of the diagonal.
    pub cut_line_to_cut_percent: Option<f64>,
    /// The other half: the farthest a point of the true cut lies from the line, what the line
    /// leaves uncovered, percent of the diagonal.
    pub cut_to_line_percent: Option<f64>,
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
    /// Dice of the last frame with the mesh cut along the true cut instead of the detected one
    /// (`--true-cut`; a scene with a cut): what a perfect detector would reach.
    pub dice_final_true_cut: Option<f64>,
    /// Target registration error of the last frame with the mesh cut along the true cut,
    /// millimetres (`--true-cut`).
    pub tre_mm_final_true_cut: Option<f64>,
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
    /// Median residual difference `μ` over the measured pairs, pixels (NaN without a
    /// detection that frame).
    pub difference_median_px: f64,
    /// Its robust deviation `σ̂` (1.4826 × MAD), pixels (NaN likewise).
    pub difference_deviation_px: f64,
    /// Vertices of the cut line.
    pub cut_vertices: usize,
    /// The work the core counted in this frame, beside its worst-case formulas (`None` for
    /// frame 0 and for a refused frame).
    #[serde(skip)]
    pub work: Option<FrameWork>,
    /// The numerical health of the frame's solve (`None` for frame 0 and a refused frame).
    #[serde(skip)]
    pub health: Option<FrameHealth>,
}

/// The numerical health of one frame's solve.
#[derive(Clone, Copy, Debug)]
pub struct FrameHealth {
    /// Norm of the gradient over the free unknowns at the start of the frame.
    pub gradient_before: f64,
    /// ... and at its end.
    pub gradient_after: f64,
    /// Smallest and largest pivot `dᵢ` of the factor in service after the frame (their ratio
    /// is a lower bound of the condition number of the factored matrix); NaN if none.
    pub pivots: (f64, f64),
    /// Every node position finite after the frame.
    pub finite: bool,
    /// Tetrahedra turned inside out (signed volume not positive) after the frame.
    pub inverted: usize,
}

/// The work the core counted in one frame ([`incise_core::StepReport`]'s counters), beside the
/// worst-case formulas of the model the frame started with.
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameWork {
    /// The steady part of the frame (the solve).
    pub solve: WorkCount,
    /// Its formula ([`incise_core::Model::worst_case_work`]).
    pub solve_bound: WorkCount,
    /// The cut detection.
    pub detection: DetectionWork,
    /// The cut line.
    pub line: LineWork,
    /// Their formula ([`incise_core::Model::worst_case_detection_work`]).
    pub detection_bound: (DetectionWork, LineWork),
    /// A cut event of this frame (one that went into service, or one that found nothing new
    /// to cut): its geometry and the rebuild of the linear system.
    pub cut: Option<(CutWork, WorkCount)>,
    /// Its formula ([`incise_core::Model::worst_case_cut_work`]).
    pub cut_bound: (CutWork, WorkCount),
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
    /// Which: each feature's id and the frame the filter took it out, in that order.
    pub filtered: Vec<FilteredFeature>,
    /// The features' spacing at frame 0 (the unit of the cut line's lengths), pixels.
    pub spacing_px: f64,
    /// The cut line at the last frame, pixels.
    pub polyline: Vec<[f64; 2]>,
    /// Its distance to the true cut at the last frame (the slit where the camera sees it),
    /// pixels, in its two directed halves; the Hausdorff distance is the larger.
    pub distance_px: Option<DirectedHausdorff>,
    /// The same to the stretches of the true cut whose lips are a pixel or more apart.
    pub open_hausdorff_px: Option<f64>,
}

/// A feature the temporal filter took out (as a tracking failure).
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
pub struct FilteredFeature {
    /// Its id, as the tracks name it.
    pub id: u32,
    /// The frame it was taken out.
    pub frame: u32,
}

/// The temporal filter against the features the generator made jump (`gt/outliers.csv`).
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
pub struct FilterTruth {
    /// Features made to jump while they were tracked (reported off their place at least once
    /// after frame 0).
    pub outliers: usize,
    /// Of them, those the filter took out.
    pub outliers_filtered: usize,
    /// Features the filter took out that were never reported off their place: tracked where
    /// they were, whatever their residual did (for instance the lips of a cut opening under
    /// the camera).
    pub genuine_filtered: usize,
    /// Of them, those taken out before the frame the cut was detected (all of them when none
    /// was): evidence the detection never saw.
    pub genuine_before_detection: usize,
}

impl FilterTruth {
    /// `filtered` (what the filter took out) against the `outliers` the generator wrote, over
    /// the `observations` of every frame (a jump the tracker never reported does not count),
    /// the cut detected at frame `detected` if it was.
    pub fn new(
        filtered: &[FilteredFeature],
        outliers: &[crate::scene::TrueOutlier],
        observations: &[Vec<Observation<f64>>],
        detected: Option<u32>,
    ) -> FilterTruth {
        let reported = |o: &crate::scene::TrueOutlier| {
            observations
                .iter()
                .enumerate()
                .skip(1)
                .any(|(f, obs)| o.is_off_at(f as u32) && obs.iter().any(|ob| ob.id == o.id))
        };
        let jumped: Vec<u32> = outliers
            .iter()
            .filter(|o| reported(o))
            .map(|o| o.id)
            .collect();
        let caught = filtered.iter().filter(|f| jumped.contains(&f.id)).count();
        FilterTruth {
            outliers: jumped.len(),
            outliers_filtered: caught,
            genuine_filtered: filtered.len() - caught,
            genuine_before_detection: filtered
                .iter()
                .filter(|f| !jumped.contains(&f.id) && detected.is_none_or(|d| f.frame < d))
                .count(),
        }
    }
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
    pub(crate) fn record(&mut self, frame: usize, r: &incise_core::CutReport) {
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

/// A pair that stood out in a frame (recorded with [`Scene::record_excess`], for `incise
/// eval --evidence`): how far its `μ` stood above what the frame explains, the larger of the
/// frame's median and the smooth field over the pair, in the frame's robust deviations, and
/// whether it crosses the true cut of that frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairExcess {
    /// The pair's index in the detector.
    pub pair: u32,
    /// Its features' ids.
    pub ids: [u32; 2],
    /// `(μ − max(median, smooth)) / σ̂`.
    pub deviations: f32,
    /// Whether the pair crosses the true cut of the frame.
    pub crosses: bool,
    /// The midpoint of its features' tracked positions, pixels.
    pub midpoint: [f32; 2],
}

/// Pairs standing less than this many robust deviations above what the frame explains are
/// not recorded as [`PairExcess`]: the lowest level `incise eval --evidence` tries.
pub const EXCESS_FLOOR: f64 = 2.0;

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
    /// The springs' stiffness in service, J/px² (given, or derived from the scene).
    pub spring_stiffness: f64,
    /// The springs' robust threshold in service, pixels.
    pub spring_threshold_px: f64,
    /// Storage bytes.
    pub model_bytes: usize,
    /// Per frame, the pairs that stood [`EXCESS_FLOOR`] deviations or more above what the
    /// frame explains; empty unless the scene asks for it ([`Scene::record_excess`]).
    pub excess: Vec<Vec<PairExcess>>,
}

impl Summary {
    /// The summary of a run: `trace` with cutting on, `uncut` the same observations replayed
    /// with cutting off (for the `_uncut` figures).
    pub fn new(scene: &Scene, trace: &Trace, uncut: &Trace) -> Summary {
        let times: Vec<f64> = trace.frames.iter().skip(1).map(|r| r.ms).collect();
        let open = scene.file.ground_truth.cut_open_frame;
        let after: Vec<f64> = trace
            .frames
            .iter()
            .filter(|r| open.is_none_or(|o| r.frame >= o as usize))
            .map(|r| r.dice)
            .collect();
        let camera = &scene.file.camera;
        let diagonal = f64::from(camera.width).hypot(f64::from(camera.height));
        let percent = |h: f64| 100.0 * h / diagonal;
        let distance = trace.detection.distance_px;
        let hausdorff_px = distance.map(|h| h.distance());
        Summary {
            scene: scene.file.name.clone(),
            frames: trace.frames.len(),
            features: trace.observations.first().map_or(0, Vec::len),
            features_missed: trace.missed,
            pairs: trace.detection.pairs,
            pairs_lost: trace.detection.pairs_lost,
            features_filtered: trace.detection.features_filtered,
            filtered_features: trace.detection.filtered.clone(),
            filter_truth: None,
            precision: scene.precision,
            law: scene.file.model.law,
            feature_spacing_px: trace.detection.spacing_px,
            spring_stiffness: trace.spring_stiffness,
            spring_threshold_px: Some(trace.spring_threshold_px).filter(|d| d.is_finite()),
            cut_detected_frame: trace.detection.detected_frame,
            cut_open_frame: open,
            cut_evidence_frame: evidence_frame(
                trace,
                open.unwrap_or(1),
                scene.file.detection.init_points,
            ),
            cut_hausdorff_px: hausdorff_px,
            cut_hausdorff_percent: hausdorff_px.map(percent),
            cut_open_hausdorff_percent: trace.detection.open_hausdorff_px.map(percent),
            cut_line_to_cut_percent: distance.map(|h| percent(h.line_to_cut)),
            cut_to_line_percent: distance.map(|h| percent(h.cut_to_line)),
            dice_final_uncut: uncut.dice_final,
            dice_final: trace.dice_final,
            dice_mean_after_cut: after.iter().sum::<f64>() / after.len().max(1) as f64,
            surface_rmse_mm_final: trace.surface_rms_final * 1e3,
            tre_mm_final: trace.tre_final * 1e3,
            tre_mm_final_uncut: uncut.tre_final * 1e3,
            tre_mm_final_rest: trace.tre_rest_final * 1e3,
            dice_final_true_cut: None,
            tre_mm_final_true_cut: None,
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
        }
    }
}

/// The first frame from `from` on whose record counts at least `needed` separation points.
fn evidence_frame(trace: &Trace, from: u32, needed: u32) -> Option<u32> {
    trace
        .frames
        .iter()
        .find(|r| r.frame >= from as usize && r.separation_points >= needed as usize)
        .map(|r| r.frame as u32)
}

/// The median of `v` (the upper one of an even count), 0 for none.
fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    s[s.len() / 2]
}
