//! How the cost of a steady frame grows with the model's nodes and with the tracked features:
//! variants of `band-no-cut` generated at several model resolutions and feature counts, each
//! counted by callgrind (and timed), with the exponent of a power law fitted to the counts.

use std::path::Path;

use serde::Serialize;

use crate::generate::pipeline::{simulate, write_scene};
use crate::run::run_once;
use crate::scene::Scene;

use super::instructions;

/// The scenario the variants are made from (the intact band: no cut event in any frame).
pub(super) const BASE: &str = "band-no-cut";

/// Model cells of the node axis: 204, 600, 1089 and 2132 nodes.
const MODEL_CELLS: [[usize; 3]; 4] = [[16, 5, 1], [24, 7, 2], [32, 10, 2], [40, 12, 3]];

/// Features of the feature axis.
const FEATURES: [usize; 4] = [100, 300, 1000, 2000];

/// Frames counted under callgrind per variant: one, as on the mesh-resolution axis (every
/// steady frame of a topology does the same work; the largest model costs about half a
/// minute per frame there).
const COUNTED_FRAMES: usize = 1;

/// One variant.
#[derive(Clone, Debug, Serialize)]
pub struct Point {
    /// Model nodes.
    pub nodes: usize,
    /// Features tracked at frame 0.
    pub features: usize,
    /// Instructions of a steady frame (mean of the counted frames), if counted.
    pub instructions: Option<f64>,
    /// Wall time of a step, milliseconds (median over the run).
    pub ms_median: f64,
}

/// The largest counted model of the mesh-resolution axis, which carries the node axis past
/// the band variants ([`Scaling::include_largest`]).
#[derive(Clone, Debug, Serialize)]
pub struct LargestModel {
    /// The scene it is a model of.
    pub scene: String,
    /// Its mesh, as the mesh-resolution table names it.
    pub mesh: String,
    pub nodes: usize,
    /// Instructions of a steady frame.
    pub instructions: f64,
}

/// Both axes and their fitted exponents.
#[derive(Clone, Debug, Serialize)]
pub struct Scaling {
    /// The node axis (300 features).
    pub nodes: Vec<Point>,
    /// The feature axis (204 nodes).
    pub features: Vec<Point>,
    /// Exponent `b` of `cost ∝ nodesᵇ` (least squares on the logarithms).
    pub nodes_exponent: Option<f64>,
    /// The largest model of the mesh-resolution axis (SOFA's fine liver), when the report has
    /// it and it is larger than every band variant: `(scene, mesh, nodes, instructions)`.
    pub largest: Option<LargestModel>,
    /// The exponent fitted to the node axis and [`Scaling::largest`] together.
    pub nodes_exponent_with_largest: Option<f64>,
    /// Exponent of `cost ∝ featuresᵇ`.
    pub features_exponent: Option<f64>,
    /// The cost the exponents are fitted to.
    pub cost: &'static str,
}

/// The variants (`(model cells, features)`) the two axes need, without repeats.
fn variants() -> Vec<([usize; 3], usize)> {
    let mut v: Vec<([usize; 3], usize)> = MODEL_CELLS.iter().map(|&c| (c, 300)).collect();
    v.extend(
        FEATURES
            .iter()
            .filter(|&&f| f != 300)
            .map(|&f| (MODEL_CELLS[0], f)),
    );
    v
}

/// How many variants [`measure`] makes (for the progress bar).
pub(super) fn len() -> usize {
    variants().len()
}

/// Generates and measures variant `k` of [`variants`] in a directory of its own, removed
/// afterwards (the report runs them in its pool of runs, one per core at a time).
///
/// # Errors
/// A message naming the variant that could not be made or run.
pub(super) fn measure_point(base_scene: &Path, k: usize, counting: bool) -> Result<Point, String> {
    let scenario = base_scene.join("scenario.toml");
    let text =
        std::fs::read_to_string(&scenario).map_err(|e| format!("{}: {e}", scenario.display()))?;
    let &(cells, features) = variants().get(k).ok_or("no such variant")?;
    let dir = super::scratch_dir(&format!(
        "scaling-{}-{}-{}-{features}",
        cells[0], cells[1], cells[2]
    ))?;
    measure_variant(&text, dir.path(), cells, features, counting)
        .map_err(|e| format!("{BASE} with model cells {cells:?} and {features} features: {e}"))
}

/// The two axes and their fitted exponents from the points of every variant, in the order of
/// [`variants`].
///
/// # Errors
/// The first variant that could not be made or run.
pub(super) fn assemble(
    points: Vec<Result<Point, String>>,
    counting: bool,
) -> Result<Scaling, String> {
    let points = points.into_iter().collect::<Result<Vec<Point>, String>>()?;
    let nodes: Vec<Point> = points
        .iter()
        .filter(|p| p.features == 300)
        .cloned()
        .collect();
    let first = nodes.first().map_or(0, |p| p.nodes);
    let mut features: Vec<Point> = points
        .iter()
        .filter(|p| p.nodes == first)
        .cloned()
        .collect();
    features.sort_by_key(|p| p.features);
    let cost = |p: &Point| {
        if counting {
            p.instructions.unwrap_or(f64::NAN)
        } else {
            p.ms_median
        }
    };
    let fit = |axis: &[Point], x: fn(&Point) -> usize| {
        exponent(
            &axis
                .iter()
                .map(|p| (x(p) as f64, cost(p)))
                .collect::<Vec<_>>(),
        )
    };
    Ok(Scaling {
        nodes_exponent: fit(&nodes, |p| p.nodes),
        largest: None,
        nodes_exponent_with_largest: None,
        features_exponent: fit(&features, |p| p.features),
        nodes,
        features,
        cost: if counting {
            "instructions of a steady frame (callgrind)"
        } else {
            "wall time of a step (median)"
        },
    })
}

impl Scaling {
    /// Carries the node axis past the band variants with the largest counted model of the
    /// mesh-resolution axis: beside the band's fit, and in a second fit over both. It is another shape with its own features;
    /// at the feature axis's rate per feature they are a small part of its cost, so the two
    /// fits differ by the shape and its finer elements.
    pub(super) fn include_largest(&mut self, largest: Option<LargestModel>) {
        let Some(largest) = largest.filter(|l| self.nodes.iter().all(|p| p.nodes < l.nodes)) else {
            return;
        };
        let mut points: Vec<(f64, f64)> = self
            .nodes
            .iter()
            .filter_map(|p| p.instructions.map(|v| (p.nodes as f64, v)))
            .collect();
        if points.len() == self.nodes.len() {
            points.push((largest.nodes as f64, largest.instructions));
            self.nodes_exponent_with_largest = exponent(&points);
        }
        self.largest = Some(largest);
    }
}

fn measure_variant(
    text: &str,
    dir: &Path,
    cells: [usize; 3],
    features: usize,
    counting: bool,
) -> Result<Point, String> {
    std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
    let edited = text
        .replacen(
            "model_cells = [16, 5, 1]",
            &format!("model_cells = [{}, {}, {}]", cells[0], cells[1], cells[2]),
            1,
        )
        .replacen("features = 300", &format!("features = {features}"), 1);
    if !edited.contains(&format!("features = {features}")) {
        return Err("the base scenario does not read `features = 300`".into());
    }
    // Room for the features and their pairs.
    let edited = format!(
        "{edited}\n[capacities]\nfeatures = {}\npairs = {}\n",
        features.max(1024),
        (features * 24).max(32768)
    );
    let path = dir.join("scenario.toml");
    std::fs::write(&path, edited).map_err(|e| e.to_string())?;
    let sim = simulate(&path, false).map_err(|e| e.to_string())?;
    write_scene(&sim, &path, dir, false).map_err(|e| e.to_string())?;
    let scene = Scene::load(dir).map_err(|e| e.to_string())?;
    let trace = run_once(&scene, true, None, false).map_err(|e| e.to_string())?;
    let ms: Vec<f64> = trace.frames.iter().skip(1).map(|r| r.ms).collect();
    let instructions = instructions::mean_of_own_setting(&scene, dir, COUNTED_FRAMES, counting)?;
    Ok(Point {
        nodes: scene.rest.len(),
        features: scene.frames.first().map_or(0, Vec::len),
        instructions,
        ms_median: super::median(&ms).unwrap_or(f64::NAN),
    })
}

/// The exponent `b` of `y = a xᵇ` by least squares on `(ln x, ln y)`; `None` with fewer than
/// two usable points.
pub(super) fn exponent(points: &[(f64, f64)]) -> Option<f64> {
    let logs: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    let n = logs.len() as f64;
    if logs.len() < 2 {
        return None;
    }
    let (mx, my) = (
        logs.iter().map(|p| p.0).sum::<f64>() / n,
        logs.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = logs.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    let sxy: f64 = logs.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

#[cfg(test)]
mod tests {
    use super::exponent;

    #[test]
    fn the_exponent_of_a_power_law_is_found() {
        let points: Vec<(f64, f64)> = [100.0, 300.0, 1000.0, 4000.0]
            .iter()
            .map(|&x: &f64| (x, 7.0 * x.powf(1.5)))
            .collect();
        assert!((exponent(&points).unwrap() - 1.5).abs() < 1e-12);
        assert_eq!(exponent(&points[..1]), None);
        assert_eq!(exponent(&[(1.0, 2.0), (1.0, 3.0)]), None);
    }
}
