//! What the detector's pairs carry, read with what the detector cannot know (`incise eval
//! --evidence`): which pairs cross the true cut.
//!
//! The detector splits a pair whose `μ` stands `κ` robust deviations above what the frame
//! explains for `persistence` frames in a row, and starts a line on six such separation points
//! along one line. An oracle that reads the same pairs but knows which of them cross the true
//! cut needs no line and no search: it declares the cut in the first frame from the opening on
//! in which enough *crossing* pairs stand above a level in enough frames in a row: the
//! reference for any test of that kind on that level (not a strict bound: a detector may find
//! a cut sooner on pairs beside it, which the oracle does not count); the same test counted
//! over *every* pair of an intact variant says how often
//! that level holds where there is nothing to find, the price a detector without the oracle's
//! knowledge would pay in false cuts. The levels go down to [`EXCESS_FLOOR`] deviations.
//!
//! The same knowledge bounds the line: the crossing pairs that stand above a level in a frame,
//! projected onto the true cut, span a stretch of it, and a line drawn from the first of them
//! to the last leaves the cut's ends beyond uncovered ([`end_gap`]); the best frame of the run
//! is about the nearest a line grown on that evidence comes to covering the cut (the detected
//! line's ends reach one feature spacing past their evidence).
//!
//! The pairs are read on a pass whose cuts are held ([`crate::run::Cutting::Held`]) and whose
//! temporal filter is off: the detector runs, but the mesh is never cut, so the residuals
//! across the cut keep what it shows in every frame (cut, the model follows the lips and the
//! pairs across them stop standing out), and every tracked feature is read (the filter takes
//! genuine features out along an opening cut, and their pairs with them). The features the
//! generator made jump are left out while they are off ([`without_jumps`]): the oracle knows
//! them too. What it reads is what the tracked features carry, whatever a detector's filter
//! and rules make of it.

use serde::Serialize;

use super::{FamilySummary, Spread, VariantResult};
use crate::generate::family::Kind;
use crate::metrics::{arc_position, distance_2d, point_at_arc};
use crate::run::{Cutting, Trace, TrackSource, Truth, run_pass};
use crate::run::{EXCESS_FLOOR, PairExcess};
use crate::scene::{Scene, TrueOutlier};

/// One test on the pairs: `pairs` pairs standing more than `deviations` robust deviations above
/// what the frame explains, each in `frames` frames in a row.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct EvidenceTest {
    /// The level, robust deviations of the frame's `μ` (the detector's `outlier_sigmas`).
    pub deviations: f64,
    /// Frames in a row (the detector's `persistence`).
    pub frames: usize,
    /// Pairs at once (the detector's line start takes six separation points).
    pub pairs: usize,
}

/// The tests tried: the detector's own first (six deviations, two frames, six pairs), then
/// lower levels, one frame and three pairs, down to [`EXCESS_FLOOR`].
pub const TESTS: [EvidenceTest; 9] = {
    const fn t(deviations: f64, frames: usize, pairs: usize) -> EvidenceTest {
        EvidenceTest {
            deviations,
            frames,
            pairs,
        }
    }
    [
        t(6.0, 2, 6),
        t(6.0, 1, 6),
        t(6.0, 1, 3),
        t(4.0, 2, 6),
        t(4.0, 1, 6),
        t(4.0, 1, 3),
        t(3.0, 1, 3),
        t(EXCESS_FLOOR, 2, 6),
        t(EXCESS_FLOOR, 1, 3),
    ]
};

/// Whether `test` holds at `frame` of `excess` (per frame, the pairs that stood out), counting
/// only pairs that cross the true cut in every frame read when `crossing` is set.
pub fn holds(
    excess: &[Vec<PairExcess>],
    frame: usize,
    test: &EvidenceTest,
    crossing: bool,
) -> bool {
    let Some(first) = (frame + 1).checked_sub(test.frames) else {
        return false;
    };
    let above =
        |f: usize| {
            excess.get(f).into_iter().flatten().filter(move |p| {
                f64::from(p.deviations) > test.deviations && (p.crosses || !crossing)
            })
        };
    // The pairs above the level in the frame itself that were above it in every frame before.
    let count = above(frame)
        .filter(|p| (first..frame).all(|f| above(f).any(|q| q.pair == p.pair)))
        .count();
    count >= test.pairs
}

/// `excess` without the pairs of a feature the generator made jump, in the frames it is off
/// its true position (`gt/outliers.csv`).
pub fn without_jumps(excess: &[Vec<PairExcess>], jumps: &[TrueOutlier]) -> Vec<Vec<PairExcess>> {
    excess
        .iter()
        .enumerate()
        .map(|(f, pairs)| {
            let off: Vec<u32> = jumps
                .iter()
                .filter(|j| u32::try_from(f).is_ok_and(|f| j.is_off_at(f)))
                .map(|j| j.id)
                .collect();
            pairs
                .iter()
                .filter(|p| !p.ids.iter().any(|id| off.contains(id)))
                .copied()
                .collect()
        })
        .collect()
}

/// The levels the line's evidence is read at ([`end_gap`]), robust deviations.
pub const LEVELS: [f64; 4] = [6.0, 4.0, 3.0, EXCESS_FLOOR];

/// How far the cut's ends lie beyond its evidence in one frame, pixels: the pairs of `pairs`
/// crossing the true cut `parts` above `level` deviations, each taken to the part its midpoint
/// is nearest, span a stretch of that part from the first to the last along it; a part's gap
/// is the larger distance from one of its ends to that stretch, and a part no pair is taken to
/// has its farthest point from any of them as its gap. The frame's is the largest over its
/// parts; `None` without such a pair.
pub fn end_gap(pairs: &[PairExcess], parts: &[Vec<[f64; 2]>], level: f64) -> Option<f64> {
    let lines: Vec<&Vec<[f64; 2]>> = parts.iter().filter(|line| !line.is_empty()).collect();
    let midpoints: Vec<[f64; 2]> = pairs
        .iter()
        .filter(|p| p.crosses && f64::from(p.deviations) > level)
        .map(|p| p.midpoint.map(f64::from))
        .collect();
    if midpoints.is_empty() || lines.is_empty() {
        return None;
    }
    // Each midpoint's part and its arc length along it.
    let mut spans: Vec<Option<(f64, f64)>> = vec![None; lines.len()];
    for &m in &midpoints {
        let (k, (s, _)) = lines
            .iter()
            .filter_map(|line| arc_position(m, line))
            .enumerate()
            .min_by(|a, b| a.1.1.total_cmp(&b.1.1))?;
        let span = spans.get_mut(k)?;
        *span = Some(span.map_or((s, s), |(lo, hi)| (lo.min(s), hi.max(s))));
    }
    lines
        .iter()
        .zip(&spans)
        .map(|(line, span)| match span {
            Some((lo, hi)) => {
                let (first, last) = (*line.first()?, *line.last()?);
                let (lo, hi) = (point_at_arc(line, *lo)?, point_at_arc(line, *hi)?);
                Some(distance_2d(first, lo).max(distance_2d(last, hi)))
            }
            None => line
                .iter()
                .map(|&p| {
                    midpoints
                        .iter()
                        .map(|&m| distance_2d(p, m))
                        .fold(f64::INFINITY, f64::min)
                })
                .reduce(f64::max),
        })
        .try_fold(0.0_f64, |worst, gap| gap.map(|g| worst.max(g)))
}

/// One variant under every test of [`TESTS`], in order.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct VariantEvidence {
    /// A cut variant: per test, the frames from the opening until the test first holds on
    /// the pairs crossing the true cut (`None`: never in the run).
    pub oracle_latency: Vec<Option<i64>>,
    /// An intact variant: per test, the frames in which it holds on any pairs.
    pub frames_held: Vec<usize>,
    /// A cut variant: per level of [`LEVELS`], the smallest [`end_gap`] over the frames from
    /// the opening on, percent of the image diagonal (`None`: no crossing pair above it).
    pub end_gap_percent: Vec<Option<f64>>,
}

impl VariantEvidence {
    /// The tests on a run's recorded `excess` (`Trace::excess`), for a variant of `kind` whose
    /// cut opens at `open`, with its true cut per frame `cut` (each part a polyline) in an image
    /// whose diagonal is `diagonal` pixels.
    pub fn new(
        excess: &[Vec<PairExcess>],
        kind: Kind,
        open: Option<u32>,
        cut: &[Vec<Vec<[f64; 2]>>],
        diagonal: f64,
    ) -> Self {
        let frames = 0..excess.len();
        match (kind, open) {
            (Kind::Intact, _) | (_, None) => VariantEvidence {
                oracle_latency: vec![],
                frames_held: TESTS
                    .iter()
                    .map(|t| {
                        frames
                            .clone()
                            .filter(|&f| holds(excess, f, t, false))
                            .count()
                    })
                    .collect(),
                end_gap_percent: vec![],
            },
            (_, Some(open)) => {
                let after = open as usize..excess.len();
                VariantEvidence {
                    oracle_latency: TESTS
                        .iter()
                        .map(|t| {
                            after
                                .clone()
                                .find(|&f| holds(excess, f, t, true))
                                .map(|f| f as i64 - i64::from(open))
                        })
                        .collect(),
                    frames_held: vec![],
                    end_gap_percent: LEVELS
                        .iter()
                        .map(|&level| {
                            after
                                .clone()
                                .filter_map(|f| end_gap(excess.get(f)?, cut.get(f)?, level))
                                .reduce(f64::min)
                                .map(|gap| 100.0 * gap / diagonal)
                        })
                        .collect(),
                }
            }
        }
    }
}

/// Reads a variant of `kind` (its `scene`, its cut opening at `open`) as the oracle does: the
/// observations of its product run `trace` replayed on a pass whose cuts are held and whose
/// temporal filter is off, recording the pairs that stand out; the generator's jumping
/// features left out while they are off; against the true cut of each frame.
///
/// # Errors
/// The pass's, or a ground truth that cannot be read, naming the file.
pub fn read_variant(
    scene: &Scene,
    trace: &Trace,
    kind: Kind,
    open: Option<u32>,
) -> Result<VariantEvidence, String> {
    let mut watched = scene.clone();
    watched.record_excess = true;
    watched.file.detection.temporal_sigmas = f64::INFINITY;
    let held = run_pass(
        &watched,
        &mut TrackSource::new(&trace.observations),
        Cutting::Held,
        None,
        None,
        false,
    )
    .map_err(|e| e.to_string())?;
    let truth = Truth::load(scene).map_err(|e| e.to_string())?;
    let cut: Vec<Vec<Vec<[f64; 2]>>> = (0..held.excess.len())
        .map(|f| truth.as_ref().and_then(|t| t.cut_at(f)).unwrap_or_default())
        .collect();
    let jumps = Truth::load_outliers(scene)
        .map_err(|e| e.to_string())?
        .unwrap_or_default();
    let camera = &scene.file.camera;
    Ok(VariantEvidence::new(
        &without_jumps(&held.excess, &jumps),
        kind,
        open,
        &cut,
        f64::from(camera.width).hypot(f64::from(camera.height)),
    ))
}

/// One test over a family's variants.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct EvidenceRow {
    /// The test.
    pub test: EvidenceTest,
    /// The oracle's latency over the cut variants where the test held, frames.
    pub oracle_latency: Option<Spread>,
    /// Cut variants where it never held on the crossing pairs.
    pub never: usize,
    /// Intact variants where it held in some frame (on any pairs).
    pub intact_held: usize,
    /// Intact variants read.
    pub intact: usize,
    /// The frames it held in, over the intact variants.
    pub intact_frames: Option<Spread>,
}

/// One level of [`LEVELS`] over a family's cut variants: how near a line grown on the
/// crossing pairs above it could come to covering the cut.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct CoverageRow {
    /// The level, robust deviations.
    pub level: f64,
    /// The best frame's [`end_gap`] over the cut variants with a crossing pair above the
    /// level, percent of the image diagonal.
    pub end_gap_percent: Option<Spread>,
    /// Cut variants with no crossing pair above it in any frame.
    pub none: usize,
}

/// A family read by the oracle: one row per test of [`TESTS`], one per level of [`LEVELS`].
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct FamilyEvidence {
    /// Per test, its latency and how often it holds on the intact variants.
    pub tests: Vec<EvidenceRow>,
    /// Per level, how much of the cut its evidence leaves uncovered.
    pub coverage: Vec<CoverageRow>,
}

/// A family's evidence (none when its variants were run without `--evidence`).
pub fn rows(variants: &[VariantResult]) -> Option<FamilyEvidence> {
    let read: Vec<(&VariantResult, &VariantEvidence)> = variants
        .iter()
        .filter_map(|v| v.evidence.as_ref().map(|e| (v, e)))
        .collect();
    if read.is_empty() {
        return None;
    }
    let intact: Vec<&VariantEvidence> = read
        .iter()
        .filter(|(v, _)| v.kind == Kind::Intact)
        .map(|(_, e)| *e)
        .collect();
    let cut: Vec<&VariantEvidence> = read
        .iter()
        .filter(|(v, _)| v.kind != Kind::Intact)
        .map(|(_, e)| *e)
        .collect();
    let tests = TESTS
        .iter()
        .enumerate()
        .map(|(k, &test)| {
            let latency: Vec<Option<i64>> = cut
                .iter()
                .map(|e| e.oracle_latency.get(k).copied().flatten())
                .collect();
            let held: Vec<usize> = intact
                .iter()
                .map(|e| e.frames_held.get(k).copied().unwrap_or(0))
                .collect();
            EvidenceRow {
                test,
                oracle_latency: Spread::of(latency.iter().flatten().map(|&l| l as f64)),
                never: latency.iter().filter(|l| l.is_none()).count(),
                intact_held: held.iter().filter(|&&n| n > 0).count(),
                intact: held.len(),
                intact_frames: Spread::of(held.iter().map(|&n| n as f64)),
            }
        })
        .collect();
    let coverage = LEVELS
        .iter()
        .enumerate()
        .map(|(k, &level)| {
            let gaps: Vec<Option<f64>> = cut
                .iter()
                .map(|e| e.end_gap_percent.get(k).copied().flatten())
                .collect();
            CoverageRow {
                level,
                end_gap_percent: Spread::of(gaps.iter().flatten().copied()),
                none: gaps.iter().filter(|g| g.is_none()).count(),
            }
        })
        .collect();
    Some(FamilyEvidence { tests, coverage })
}

/// How a test reads in a table.
fn test_name(t: &EvidenceTest) -> String {
    let frames = if t.frames == 1 {
        "1 frame".to_string()
    } else {
        format!("{} frames in a row", t.frames)
    };
    let own = if t == &TESTS[0] {
        " (the detector's)"
    } else {
        ""
    };
    format!("{} pairs above {} σ̂, {frames}{own}", t.pairs, t.deviations)
}

/// A markdown table of the families read by the oracle: a row per `labels` entry, a column
/// per family headed `FAMILY: what`, row `k`'s cell `cell(evidence, k)`.
fn per_family(
    corner: &str,
    what: &str,
    families: &[&FamilySummary],
    labels: &[String],
    cell: impl Fn(&FamilyEvidence, usize) -> String,
) -> String {
    let read: Vec<(&str, &FamilyEvidence)> = families
        .iter()
        .filter_map(|f| f.evidence.as_ref().map(|e| (f.family.as_str(), e)))
        .collect();
    let mut s = format!("| {corner} |");
    for (family, _) in &read {
        s.push_str(&format!(" {family}: {what} |"));
    }
    s.push_str("\n|---|");
    s.push_str(&"---|".repeat(read.len()));
    s.push('\n');
    for (k, label) in labels.iter().enumerate() {
        s.push_str(&format!("| {label} |"));
        for (_, evidence) in &read {
            s.push_str(&format!(" {} |", cell(evidence, k)));
        }
        s.push('\n');
    }
    s
}

/// The families' evidence as a markdown table, one row per test, one cell per family: the
/// oracle's latency (median / max over the cut variants where the test held, and how many it
/// never held on), then the intact variants on whose pairs the same test held in some frame.
pub fn evidence_table(families: &[FamilySummary]) -> String {
    let labels: Vec<String> = TESTS.iter().map(test_name).collect();
    per_family(
        "test",
        "oracle latency median / max (never); intact where it holds, frames (median)",
        &families.iter().collect::<Vec<_>>(),
        &labels,
        |e, k| {
            let Some(r) = e.tests.get(k) else {
                return "–".to_string();
            };
            let latency = r.oracle_latency.map_or("–".to_string(), |l| {
                format!("{:.1} / {:.0}", l.median, l.max)
            });
            let frames = r
                .intact_frames
                .map_or("–".to_string(), |l| format!("{:.1}", l.median));
            format!(
                "{latency} ({}); {} of {}, {frames} frames",
                r.never, r.intact_held, r.intact
            )
        },
    )
}

/// How much of the cut the crossing pairs cover, as a markdown table: per level, per family
/// with cut variants, the best frame's [`end_gap`] (median / max over the cut variants,
/// percent of the image diagonal; and how many variants had no crossing pair above the level).
pub fn coverage_table(families: &[FamilySummary]) -> String {
    let labels: Vec<String> = LEVELS.iter().map(|l| format!("{l} σ̂")).collect();
    per_family(
        "crossing pairs above",
        "cut left beyond them, median / max (% diag.; none)",
        &families.iter().filter(|f| f.cut > 0).collect::<Vec<_>>(),
        &labels,
        |e, k| {
            e.coverage.get(k).map_or("–".to_string(), |r| {
                let gap = r.end_gap_percent.map_or("–".to_string(), |g| {
                    format!("{:.1} / {:.1}", g.median, g.max)
                });
                format!("{gap} ({})", r.none)
            })
        },
    )
}

/// A family's variants read by the oracle, one row each: per test of [`TESTS`] (headed `pairs
/// > level × frames`), the oracle's latency on a cut variant (`–`: never) or the frames in which
/// the test holds on an intact one (any pairs); then, for a cut variant, the cut left beyond its crossing
/// pairs per level of [`LEVELS`] (percent of the diagonal). Empty when the family was run without
/// `--evidence`.
pub fn variant_evidence_table(f: &FamilySummary) -> String {
    if f.evidence.is_none() {
        return String::new();
    }
    let mut s = String::from("| variant | kind | ");
    let tests: Vec<String> = TESTS
        .iter()
        .map(|t| format!("{} > {} σ̂ × {}", t.pairs, t.deviations, t.frames))
        .collect();
    s.push_str(&tests.join(" | "));
    for level in LEVELS {
        s.push_str(&format!(" | cut beyond pairs > {level} σ̂ (%)"));
    }
    s.push_str(" |\n|---|---|");
    s.push_str(&"---|".repeat(TESTS.len() + LEVELS.len()));
    s.push('\n');
    let dash = || "–".to_string();
    for v in &f.variants {
        let Some(e) = &v.evidence else { continue };
        let mut cells: Vec<String> = if v.kind == Kind::Intact {
            e.frames_held.iter().map(ToString::to_string).collect()
        } else {
            e.oracle_latency
                .iter()
                .map(|l| l.map_or_else(dash, |l| l.to_string()))
                .collect()
        };
        cells.resize(TESTS.len(), dash());
        let mut gaps: Vec<String> = e
            .end_gap_percent
            .iter()
            .map(|g| g.map_or_else(dash, |g| format!("{g:.1}")))
            .collect();
        gaps.resize(LEVELS.len(), dash());
        cells.extend(gaps);
        s.push_str(&format!(
            "| {} | {} | {} |\n",
            v.name,
            v.kind.name(),
            cells.join(" | ")
        ));
    }
    s
}

/// Draws, per family with cut variants, each test of [`TESTS`] as a point: the oracle's median
/// latency against the median frames in which the test holds on the family's intact variants,
/// with a line from the median to the largest latency; the acceptance's median latency shaded
/// (where no intact frame holds the test), the detector's own test red. SVG to `out`.
///
/// # Errors
/// The file's, as a message.
pub fn plot_evidence(families: &[FamilySummary], out: &std::path::Path) -> Result<(), String> {
    use plotters::prelude::*;
    let read: Vec<(&FamilySummary, &Vec<EvidenceRow>)> = families
        .iter()
        .filter(|f| f.cut > 0)
        .filter_map(|f| f.evidence.as_ref().map(|e| (f, &e.tests)))
        .collect();
    let width = 360 * read.len().max(1) as u32;
    let root = SVGBackend::new(out, (width, 420)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let root = root
        .titled(
            "each point a test of the pairs (pairs > level × frames), the detector's red; \
             green: issue 11's median latency where no intact frame holds it",
            ("sans-serif", 13),
        )
        .map_err(|e| e.to_string())?;
    let accepted = super::ACCEPTANCE.latency_median;
    for (area, (family, rows)) in root.split_evenly((1, read.len().max(1))).iter().zip(&read) {
        let latest = rows
            .iter()
            .filter_map(|r| r.oracle_latency.map(|l| l.max))
            .fold(accepted, f64::max)
            + 1.0;
        let frames = rows
            .iter()
            .filter_map(|r| r.intact_frames.map(|l| l.median))
            .fold(1.0, f64::max)
            * 1.1;
        let mut chart = ChartBuilder::on(area)
            .caption(family.family.clone(), ("sans-serif", 13))
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(44)
            .build_cartesian_2d(-0.5..latest, -1.0..frames)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("oracle latency, frames (median, line to max)")
            .y_desc("intact frames where it holds (median)")
            .draw()
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(-0.5, -1.0), (accepted, 0.5)],
                GREEN.mix(0.2).filled(),
            )))
            .map_err(|e| e.to_string())?;
        // Points that coincide have their labels stacked, each 11 px under the one before.
        let mut placed: Vec<(f64, f64)> = vec![];
        for r in rows.iter() {
            let (Some(latency), Some(held)) = (r.oracle_latency, r.intact_frames) else {
                continue;
            };
            let here = (latency.median, held.median);
            let below = placed.iter().filter(|&&p| p == here).count() as i32;
            placed.push(here);
            let colour = if r.test == TESTS[0] { RED } else { BLUE };
            let y = held.median;
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(latency.median, y), (latency.max, y)],
                    colour.mix(0.5).stroke_width(1),
                )))
                .map_err(|e| e.to_string())?;
            let t = r.test;
            chart
                .draw_series(std::iter::once(
                    EmptyElement::at((latency.median, y))
                        + Circle::new((0, 0), 4, colour.filled())
                        + Text::new(
                            format!("{}>{}×{}", t.pairs, t.deviations, t.frames),
                            (6, -12 + 11 * below),
                            ("sans-serif", 10).into_font(),
                        ),
                ))
                .map_err(|e| e.to_string())?;
        }
    }
    root.present().map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn above(pair: u32, deviations: f32, crosses: bool) -> PairExcess {
        PairExcess {
            pair,
            ids: [2 * pair, 2 * pair + 1],
            deviations,
            crosses,
            midpoint: [pair as f32, 0.0],
        }
    }

    /// Three pairs crossing the cut open by one deviation a frame from frame 2; a fourth,
    /// not crossing, stands at 7 deviations in every frame.
    fn opening() -> Vec<Vec<PairExcess>> {
        (0..10)
            .map(|f| {
                let mut frame = vec![above(9, 7.0, false)];
                let z = f as f32 - 2.0 + EXCESS_FLOOR as f32;
                if z >= EXCESS_FLOOR as f32 {
                    frame.extend((0..3).map(|p| above(p, z, true)));
                }
                frame
            })
            .collect()
    }

    #[test]
    fn the_oracle_counts_crossing_pairs_above_the_level_in_frames_in_a_row() {
        let excess = opening();
        let t = |deviations, frames, pairs| EvidenceTest {
            deviations,
            frames,
            pairs,
        };
        // Above 4 deviations from frame 5 (z = f), two frames in a row from frame 6.
        assert!(!holds(&excess, 4, &t(4.0, 1, 3), true));
        assert!(holds(&excess, 5, &t(4.0, 1, 3), true));
        assert!(!holds(&excess, 5, &t(4.0, 2, 3), true));
        assert!(holds(&excess, 6, &t(4.0, 2, 3), true));
        // Four pairs are never there crossing, but are with the one that does not cross.
        assert!(!holds(&excess, 9, &t(4.0, 1, 4), true));
        assert!(holds(&excess, 9, &t(4.0, 1, 4), false));
        // A test reaching back before frame 0 does not hold.
        assert!(!holds(&excess, 0, &t(2.0, 2, 1), false));
        let e = VariantEvidence::new(&excess, Kind::PreCut, Some(2), &[], 100.0);
        assert_eq!(e.oracle_latency.len(), TESTS.len());
        // The detector's test: above 6 from frame 7, in a row from frame 8: 6 pairs never.
        assert_eq!(e.oracle_latency[0], None);
        // Three pairs above 6 in one frame: frame 7, five frames after the opening.
        assert_eq!(e.oracle_latency[2], Some(5));
        // Three pairs above the floor in one frame: frame 3 (z = 3 > 2).
        assert_eq!(e.oracle_latency[8], Some(1));
        let intact = VariantEvidence::new(&excess, Kind::Intact, None, &[], 100.0);
        // The lone pair at 7 deviations makes no test of three pairs hold; the crossing ones
        // count for an intact variant's frames as any pairs do.
        assert_eq!(intact.frames_held[2], 3);
    }

    #[test]
    fn lower_levels_fewer_frames_and_fewer_pairs_hold_no_later() {
        let excess = opening();
        for a in &TESTS {
            for b in &TESTS {
                let weaker =
                    b.deviations <= a.deviations && b.frames <= a.frames && b.pairs <= a.pairs;
                if !weaker {
                    continue;
                }
                for f in 0..excess.len() {
                    if holds(&excess, f, a, true) {
                        assert!(holds(&excess, f, b, true), "{a:?} holds at {f}, {b:?} not");
                    }
                }
            }
        }
    }

    #[test]
    fn the_cut_beyond_its_evidence_is_measured_from_its_ends() {
        let line = |points: &[[f64; 2]]| points.to_vec();
        // A cut along y = 0 from x = 0 to 100 (bent at 50), and a second part from (0, 50)
        // to (0, 80) with no pair across it.
        let parts = vec![
            line(&[[0.0, 0.0], [50.0, 0.0], [100.0, 0.0]]),
            line(&[[0.0, 50.0], [0.0, 80.0]]),
        ];
        let pair = |x: f32, deviations: f32, crosses: bool| PairExcess {
            pair: 0,
            ids: [0, 1],
            deviations,
            crosses,
            midpoint: [x, 1.0],
        };
        let pairs = [
            pair(20.0, 7.0, true),
            pair(70.0, 5.0, true),
            // Not crossing, or below every level: not evidence.
            pair(99.0, 9.0, false),
            pair(1.0, 1.0, true),
        ];
        // Above 4: from x = 20 to 70, the first part's ends 20 and 30 beyond; the second part's
        // farthest point, (0, 80), is hypot(20, 79) from (20, 1).
        let second = 20.0_f64.hypot(79.0);
        assert!((end_gap(&pairs, &parts, 4.0).unwrap() - second).abs() < 1e-9);
        let first = &parts[..1];
        assert!((end_gap(&pairs, first, 4.0).unwrap() - 30.0).abs() < 1e-9);
        // Above 6 only x = 20: the far end 80 beyond it.
        assert!((end_gap(&pairs, first, 6.0).unwrap() - 80.0).abs() < 1e-9);
        assert_eq!(end_gap(&pairs, first, 8.0), None);
        // Per variant: the best frame from the opening on, in percent of the diagonal.
        let frames = vec![vec![], vec![pairs[0]], pairs.to_vec()];
        let cut = vec![parts[..1].to_vec(); 3];
        let e = VariantEvidence::new(&frames, Kind::PreCut, Some(1), &cut, 200.0);
        assert_eq!(e.end_gap_percent.len(), LEVELS.len());
        assert!((e.end_gap_percent[0].unwrap() - 40.0).abs() < 1e-9);
        assert!((e.end_gap_percent[1].unwrap() - 15.0).abs() < 1e-9);
    }

    #[test]
    fn a_jumping_feature_s_pairs_are_left_out_while_it_is_off() {
        // Pair k joins features 2k and 2k + 1; feature 3 (pair 1) is off in frames 1 and 2.
        let excess: Vec<Vec<PairExcess>> = (0..4)
            .map(|_| (0..3).map(|p| above(p, 5.0, true)).collect())
            .collect();
        let jumps = [TrueOutlier {
            id: 3,
            start: 1,
            frames: 2,
            jump: [10.0, 0.0],
        }];
        let kept = without_jumps(&excess, &jumps);
        let pairs = |f: usize| kept[f].iter().map(|p| p.pair).collect::<Vec<_>>();
        assert_eq!(pairs(0), [0, 1, 2]);
        assert_eq!(pairs(1), [0, 2]);
        assert_eq!(pairs(2), [0, 2]);
        assert_eq!(pairs(3), [0, 1, 2]);
    }
}
