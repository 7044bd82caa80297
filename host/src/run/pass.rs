//! One pass of the frame loop: stepping the model over a frame, cutting it along the true cut
//! ([`super::Cutting::AlongTruth`]), reading its cut line, and what it gathers on the way.

use std::time::Instant;

use incise_core::{CutWork, Model, Observation, Real};

use super::truth::Truth;
use super::{
    CutTrace, DetectionTrace, FilteredFeature, FrameHealth, FrameRecord, FrameWork, PairExcess,
    RunError, cast_point, core, known_observations, to_f64,
};
use crate::generate::object::signed_volume6;

/// What the frame loop gathers over one pass.
pub(super) struct Pass {
    /// Per-frame records.
    pub(super) frames: Vec<FrameRecord>,
    /// The observations of every frame, as used.
    pub(super) observations: Vec<Vec<Observation<f64>>>,
    pub(super) detection: DetectionTrace,
    pub(super) cuts: CutTrace,
    /// Frames the core refused, with its reason.
    pub(super) rejected: Vec<(usize, String)>,
    /// Room the whole cut line needs: `cut_vertices` entries.
    pub(super) cut_vertices: usize,
    /// Dice and target error (metres) of the last frame.
    pub(super) last: (f64, f64),
    /// Length of the true cut line last cut into the mesh ([`super::Cutting::AlongTruth`]), pixels.
    pub(super) true_cut_px: f64,
    /// Per frame, the pairs that stood out (when the scene asks for them).
    pub(super) excess: Vec<Vec<PairExcess>>,
}

impl Pass {
    pub(super) fn new(cut_vertices: usize) -> Self {
        Pass {
            frames: vec![],
            observations: vec![],
            detection: DetectionTrace::default(),
            cuts: CutTrace::default(),
            rejected: vec![],
            cut_vertices: cut_vertices.max(1),
            last: (0.0, 0.0),
            true_cut_px: 0.0,
            excess: vec![],
        }
    }

    /// Steps the model over frame `f`'s observations (frame 0 only placed the features) and
    /// returns the frame's record, its measures still to fill.
    pub(super) fn step<T: Real, F: Real>(
        &mut self,
        model: &mut Model<'_, T, F>,
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
            difference_median_px: f64::NAN,
            difference_deviation_px: f64::NAN,
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
                if report.detection.pairs_active > 0 {
                    record.difference_median_px = report.detection.median_difference_px.to_f64();
                    record.difference_deviation_px = report.detection.deviation_px.to_f64();
                }
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
                    inverted: inverted_tets(model),
                });
                self.cuts.record(f, &report.cut);
                let d = &mut self.detection;
                d.pairs = report.detection.pairs;
                d.pairs_lost = report.detection.pairs_lost;
                d.features_filtered = report.detection.features_filtered;
                if d.filtered.len() < d.features_filtered {
                    let detector = model.detector();
                    let features = model.features();
                    for slot in 0..features.len() {
                        if let Some(id) = features.id_of(slot)
                            && detector.is_filtered(slot)
                            && !d.filtered.iter().any(|x| x.id == id)
                        {
                            d.filtered.push(FilteredFeature {
                                id,
                                frame: f as u32,
                            });
                        }
                    }
                }
                d.spacing_px = model.detector().spacing().to_f64();
                if d.detected_frame.is_none() {
                    d.detected_frame = report.cut_line.detected_frame.map(|_| f as u32);
                }
            }
        }
        record
    }

    /// [`super::Cutting::AlongTruth`]: after frame `f`'s step, cuts the mesh along the true cut's
    /// straight line if the cut has opened (`open`) and its line is new or has grown by 5 %.
    pub(super) fn cut_along_truth<T: Real, F: Real>(
        &mut self,
        model: &mut Model<'_, T, F>,
        f: usize,
        truth: &Truth,
        open: Option<u32>,
    ) {
        if open.is_none_or(|o| f <= o as usize) {
            return;
        }
        let Some(line) = straight_line(&truth.cut_points_at(f)) else {
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
    pub(super) fn read_cut_line<T: Real, F: Real>(
        &mut self,
        model: &Model<'_, T, F>,
        f: usize,
    ) -> Result<(), RunError> {
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

/// Tetrahedra of `model` whose signed volume in the current positions is not positive (turned
/// inside out, or flat).
fn inverted_tets<T: Real, F: Real>(model: &Model<'_, T, F>) -> usize {
    let x = model.positions();
    let at = |v: u32| x.get(v as usize).map_or([f64::NAN; 3], to_f64);
    model
        .mesh()
        .tets()
        .iter()
        .filter(|t| {
            let [a, b, c, d] = t.map(at);
            // NaN compares false: a tetrahedron with a non-finite corner counts as inverted.
            !(signed_volume6(a, b, c, d) > 0.0)
        })
        .count()
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
