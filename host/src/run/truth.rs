//! The ground truth a run is measured against (the `gt/` directory of a synthetic scene: true
//! silhouettes, internal targets, surface and cut line), and the measures of one frame.

use std::path::PathBuf;

use incise_core::{Camera, Model, Real};

use super::to_f64;
use crate::metrics::{
    DirectedHausdorff, dice, directed_hausdorff_to_parts, paired_rms, surface_rms,
};
use crate::render::{Mask, silhouette};
use crate::scene::{
    CutParts, Scene, SceneError, Surface, TrueOutlier, read_cut_csv, read_obj, read_outliers_csv,
    read_points_csv,
};

/// Ground truth of a scene, read once.
pub(crate) struct Truth {
    /// Internal target positions per frame, metres.
    targets: Vec<Vec<[f64; 3]>>,
    /// The true surface at the last frame, metres.
    surface: Surface,
    /// The true cut in the image per frame: its parts, pixels.
    cut: Vec<CutParts>,
}

impl Truth {
    /// The scene's ground truth, or `None` for a scene without a `gt/` directory (a real
    /// video): the run then reports no metric.
    pub(crate) fn load(scene: &Scene) -> Result<Option<Truth>, SceneError> {
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
        // The core carries as many targets as the capacity says: refused here, naming both
        // files, rather than by the core once the model is built.
        let room = scene.file.capacities.targets;
        if let Some(first) = targets.first()
            && first.len() > room
        {
            return Err(crate::scene::at_key(
                &scene.dir,
                "capacities",
                "targets",
                format!(
                    "[capacities] targets: {room}, but {} holds {} targets at frame 0",
                    p.display(),
                    first.len()
                ),
            ));
        }
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

    /// Reads the scene's `gt/outliers.csv` alone; `None` where it has none (a real video, or a
    /// scene generated before the file was written).
    pub(crate) fn load_outliers(scene: &Scene) -> Result<Option<Vec<TrueOutlier>>, SceneError> {
        let p = scene.dir.join("gt").join("outliers.csv");
        if !p.is_file() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&p)
            .map_err(|e| SceneError::new(&p, 0, format!("cannot read: {e}")))?;
        read_outliers_csv(&text, &p).map(Some)
    }

    /// The internal targets at frame 0, where the model embeds them.
    pub(crate) fn first_targets(&self) -> Option<&[[f64; 3]]> {
        self.targets.first().map(Vec::as_slice)
    }

    /// The true cut in the image at `frame` as polylines (its parts), if it has one.
    pub(crate) fn cut_at(&self, frame: usize) -> Option<Vec<Vec<[f64; 2]>>> {
        let parts = self.cut.get(frame).filter(|p| !p.is_empty())?;
        Some(
            parts
                .iter()
                .map(|part| part.iter().map(|p| p.uv).collect())
                .collect(),
        )
    }

    /// Every point of the true cut at `frame`, whichever part it is in.
    pub(crate) fn cut_points_at(&self, frame: usize) -> Vec<[f64; 2]> {
        self.cut
            .get(frame)
            .map(|parts| parts.iter().flatten().map(|p| p.uv).collect())
            .unwrap_or_default()
    }

    /// Target registration error of `predicted` at `frame`, metres: NaN for a frame without
    /// targets, 0 when the model carries another number of targets than the truth.
    fn target_error(&self, frame: usize, predicted: &[[f64; 3]]) -> f64 {
        self.targets.get(frame).map_or(f64::NAN, |gt| {
            if gt.len() == predicted.len() {
                paired_rms(predicted, gt)
            } else {
                0.0
            }
        })
    }

    /// Target registration error at the last frame of the targets left at rest, metres (NaN
    /// when the counts differ or there is none): the baseline any registration must beat.
    pub(crate) fn rest_target_error(&self, rest: &[[f64; 3]]) -> f64 {
        self.targets
            .last()
            .filter(|gt| gt.len() == rest.len() && !gt.is_empty())
            .map_or(f64::NAN, |gt| paired_rms(rest, gt))
    }

    /// Hausdorff distance of a detected cut line to the true cut at `frame` (every part of the
    /// slit the camera sees), both directed halves, pixels; `None` when either is empty.
    pub(crate) fn cut_distance(
        &self,
        frame: usize,
        polyline: &[[f64; 2]],
    ) -> Option<DirectedHausdorff> {
        directed_hausdorff_to_parts(polyline, &self.cut_at(frame)?)
    }

    /// The frames the true cut is given for (the last is `cut_frames() - 1`).
    pub(crate) fn cut_frames(&self) -> usize {
        self.cut.len()
    }

    /// The same to the stretches of the true cut whose lips are a pixel or more apart in the
    /// image at the last frame (the rule of `cut_open_frame`); `None` when either is empty.
    pub(crate) fn open_cut_distance(&self, polyline: &[[f64; 2]]) -> Option<f64> {
        let last = self.cut.last()?;
        let mut open: Vec<Vec<[f64; 2]>> = vec![];
        for part in last {
            let mut run: Vec<[f64; 2]> = vec![];
            for p in part {
                if p.open {
                    run.push(p.uv);
                } else if !run.is_empty() {
                    open.push(std::mem::take(&mut run));
                }
            }
            if !run.is_empty() {
                open.push(run);
            }
        }
        directed_hausdorff_to_parts(polyline, &open).map(|h| h.distance())
    }

    /// RMS distance between the true surface and the model's, both ways (true surface points
    /// to the model's boundary, the model's boundary nodes to the true surface), metres.
    pub(crate) fn surface_distance<T: Real, F: Real>(&self, model: &Model<'_, T, F>) -> f64 {
        let x: Vec<[f64; 3]> = model.positions().iter().map(to_f64).collect();
        let surface = model.mesh().surface();
        let (gt_pos, gt_tri) = (&self.surface.positions, &self.surface.triangles);
        let mut surface_nodes: Vec<u32> = surface.iter().flatten().copied().collect();
        surface_nodes.sort_unstable();
        surface_nodes.dedup();
        let model_points: Vec<[f64; 3]> = surface_nodes.iter().map(|&v| x[v as usize]).collect();
        let a = surface_rms(gt_pos, &x, surface);
        let b = surface_rms(&model_points, gt_pos, gt_tri);
        let (na, nb) = (gt_pos.len() as f64, model_points.len() as f64);
        ((a * a * na + b * b * nb) / (na + nb).max(1.0)).sqrt()
    }
}

/// The internal targets where the model carries them, metres.
pub(crate) fn target_positions<T: Real, F: Real>(model: &Model<'_, T, F>) -> Vec<[f64; 3]> {
    (0..model.n_targets())
        .filter_map(|k| model.target_position(k))
        .map(|p| to_f64(&p))
        .collect()
}

/// What one frame measures against the ground truth.
pub(crate) struct FrameMeasure {
    /// The model's silhouette.
    pub(crate) model_mask: Mask,
    /// The true silhouette, with a ground truth.
    pub(crate) truth_mask: Option<Mask>,
    /// Dice of the two (NaN without a ground truth).
    pub(crate) dice: f64,
    /// The internal targets where the model carries them, metres.
    pub(crate) targets: Vec<[f64; 3]>,
    /// Their registration error, metres (NaN without a ground truth).
    pub(crate) tre: f64,
}

impl FrameMeasure {
    /// Measures the model (node positions `x`, boundary triangles `surface`) at `frame`.
    pub(crate) fn new<T: Real, F: Real>(
        scene: &Scene,
        truth: Option<&Truth>,
        frame: usize,
        camera: &Camera<f64>,
        model: &Model<'_, T, F>,
        (x, surface): (&[[f64; 3]], &[[u32; 3]]),
    ) -> Result<Self, SceneError> {
        let model_mask = silhouette(camera, x, surface);
        let truth_mask = match truth {
            Some(_) => Some(load_silhouette(scene, frame, &model_mask)?),
            None => None,
        };
        let dice = truth_mask
            .as_ref()
            .map_or(f64::NAN, |t| dice(&model_mask, t));
        let targets = target_positions(model);
        let tre = truth.map_or(f64::NAN, |t| t.target_error(frame, &targets));
        Ok(FrameMeasure {
            model_mask,
            truth_mask,
            dice,
            targets,
            tre,
        })
    }
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
