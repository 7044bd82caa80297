//! Scene families run end to end (`incise eval`): every variant of a family is generated
//! (`generate::family`), run with the detection defaults (`run`), and the family is summed
//! up the way issue 11's acceptance reads: false cuts on the intact variants, detection
//! latency after the cut opens, the line's Hausdorff distance to the true cut as a share of
//! the image diagonal, and Dice and target error without and with cutting.
//!
//! The scenes are written to a work directory and kept there; a later run reuses a variant
//! whose `scenario.toml` is the one the family draws now (so changing the detector does not
//! mean simulating again), and regenerates it otherwise or with `fresh`.

pub mod evidence;
pub mod sweep;

use std::path::{Path, PathBuf};

use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use crate::generate::family::{Family, Kind, variants};
use crate::generate::pipeline::{ModelMesh, generate_scenario, header_prefix, rebase_mesh_paths};
use crate::generate::scenario::Scenario;
use image::{RgbImage, imageops};

use crate::render::Canvas;
use crate::run::{
    FilterTruth, FrameSink, RunError, RunOptions, Summary, TrackSource, run_scene_with,
};
use crate::scene::{DetectionSetting, Scene};

/// The acceptance of issue 11, per family: what [`FamilySummary::passes`] checks.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Acceptance {
    /// False cuts allowed over the intact variants.
    pub false_cuts: usize,
    /// Cuts never detected allowed over the cut variants.
    pub missed: usize,
    /// Median latency (frames after the cut opens), at most.
    pub latency_median: f64,
    /// Largest latency, at most.
    pub latency_max: i64,
    /// Median Hausdorff distance of the line to the cut, percent of the image diagonal.
    pub hausdorff_median_percent: f64,
    /// Largest Hausdorff distance, percent of the diagonal.
    pub hausdorff_max_percent: f64,
}

/// Issue 11's numbers: no false cut, none missed, latency ≤ 3 frames median and ≤ 5 max,
/// Hausdorff ≤ 3 % of the diagonal median and ≤ 5 % max.
pub const ACCEPTANCE: Acceptance = Acceptance {
    false_cuts: 0,
    missed: 0,
    latency_median: 3.0,
    latency_max: 5,
    hausdorff_median_percent: 3.0,
    hausdorff_max_percent: 5.0,
};

/// One variant's results.
#[derive(Clone, Debug, Serialize)]
pub struct VariantResult {
    /// Variant (scene) name.
    pub name: String,
    /// Intact, pre-cut or live.
    pub kind: Kind,
    /// The tracks' noise (`[tracking] noise_px`), pixels.
    pub noise_px: f64,
    /// How far its jumping features jump (`[tracking] outlier_jump_px`), pixels.
    pub jump_px: f64,
    /// Frame the cut opens (ground truth), none when intact.
    pub open_frame: Option<u32>,
    /// Frame the cut was detected, if it was.
    pub detected_frame: Option<u32>,
    /// `detected − open` in frames (negative: detected before it opened).
    pub latency: Option<i64>,
    /// Of the latency, the frames from the opening until the detector held the separation
    /// points the line's start needs (`Summary::cut_evidence_frame`), for a detected cut.
    pub evidence_wait: Option<i64>,
    /// The rest of the latency: from that evidence to the line's start.
    pub start_wait: Option<i64>,
    /// A cut detected on an intact variant.
    pub false_cut: bool,
    /// A cut variant whose cut was never detected.
    pub missed: bool,
    /// Hausdorff distance of the last frame's line to the true cut, percent of the diagonal.
    pub hausdorff_percent: Option<f64>,
    /// The same to the stretches of the true cut whose lips are a pixel or more apart.
    pub open_hausdorff_percent: Option<f64>,
    /// Of the Hausdorff distance, the farthest the line strays from the true cut.
    pub line_to_cut_percent: Option<f64>,
    /// And the farthest a point of the true cut lies from the line (the stretch of the cut
    /// the line leaves uncovered); the Hausdorff distance is the larger of the two.
    pub cut_to_line_percent: Option<f64>,
    /// The whole summary of the run.
    pub summary: Summary,
    /// What its pairs carried under each test of [`evidence::TESTS`] (with `--evidence`).
    pub evidence: Option<evidence::VariantEvidence>,
}

/// Median and largest of some numbers (`None` for none).
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Spread {
    /// Median (the mean of the middle two for an even count).
    pub median: f64,
    /// Largest.
    pub max: f64,
}

impl Spread {
    /// The spread of `values`, none for an empty list; NaNs are left out.
    pub fn of(values: impl IntoIterator<Item = f64>) -> Option<Spread> {
        let mut v: Vec<f64> = values.into_iter().filter(|x| !x.is_nan()).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        };
        Some(Spread {
            median,
            max: v[n - 1],
        })
    }
}

/// A family summed up.
#[derive(Clone, Debug, Serialize)]
pub struct FamilySummary {
    /// Family name.
    pub family: String,
    /// Intact variants run.
    pub intact: usize,
    /// Cut variants run (pre-cut and live).
    pub cut: usize,
    /// Of them live.
    pub live: usize,
    /// Cuts detected on intact variants.
    pub false_cuts: usize,
    /// Cut variants never detected.
    pub missed: usize,
    /// Cut variants detected before their cut opened.
    pub early: usize,
    /// Latency over the detected cut variants, frames.
    pub latency: Option<Spread>,
    /// Of it, the wait for the detector's evidence ([`VariantResult::evidence_wait`]).
    pub evidence_wait: Option<Spread>,
    /// And the wait for the line's start to accept it ([`VariantResult::start_wait`]).
    pub start_wait: Option<Spread>,
    /// Hausdorff distance over the detected cut variants, percent of the diagonal (what
    /// [`ACCEPTANCE`] judges).
    pub hausdorff_percent: Option<Spread>,
    /// The same to the stretches of the true cut whose lips are a pixel or more apart.
    pub open_hausdorff_percent: Option<Spread>,
    /// Of the Hausdorff distance, the line's distance to the cut
    /// ([`VariantResult::line_to_cut_percent`]).
    pub line_to_cut_percent: Option<Spread>,
    /// And the cut's distance to the line ([`VariantResult::cut_to_line_percent`]).
    pub cut_to_line_percent: Option<Spread>,
    /// Dice at the last frame over the cut variants, without cutting the mesh.
    pub dice_uncut: Option<Spread>,
    /// The same with cutting.
    pub dice: Option<Spread>,
    /// Target error (mm) at the last frame over the cut variants, without cutting.
    pub tre_uncut_mm: Option<Spread>,
    /// The same with cutting.
    pub tre_mm: Option<Spread>,
    /// Target error of the rest model (not registered), the reference.
    pub tre_rest_mm: Option<Spread>,
    /// The temporal filter against the features the generator made jump, summed over every
    /// variant (intact and cut) that lists them.
    pub filter: Option<FilterTruth>,
    /// Whether [`ACCEPTANCE`] holds.
    pub passes: bool,
    /// Per test of [`evidence::TESTS`], what an oracle that knows the true cut reads from the
    /// pairs, and how often the test holds on the intact variants (with `--evidence`).
    pub evidence: Option<evidence::FamilyEvidence>,
    /// Every variant.
    pub variants: Vec<VariantResult>,
}

/// Which variants of a family to run.
#[derive(Clone, Copy, Debug, Default)]
pub struct Selection {
    /// At most this many of each kind (intact, pre-cut, live), the first ones drawn; all when
    /// `None`.
    pub per_kind: Option<usize>,
}

/// Options of an evaluation.
#[derive(Clone, Debug)]
pub struct EvalOptions {
    /// Where the variants' scenes are written (and reused from).
    pub work: PathBuf,
    /// Which variants.
    pub selection: Selection,
    /// Regenerate every variant even if its scene is there.
    pub fresh: bool,
    /// Show a progress bar.
    pub progress: bool,
    /// The model's strain energy law in place of each variant's (`None`: the variant's own).
    pub law: Option<crate::scene::ModelLaw>,
    /// A seed in place of each family's own: other variants drawn from the same ranges, to
    /// check that what the committed seeds show holds on variants nothing was tried on.
    pub seed: Option<u64>,
    /// The mesh that models each variant's object ([`ModelMesh`]): a finer model of the same
    /// truth, to see whether what the detection does carries over to it.
    pub model_mesh: ModelMesh,
    /// Where each variant's last overlay and the family's sheet of them go, if anywhere.
    pub pictures: Option<PathBuf>,
    /// Fields of `[detection]` set on every variant, in order (none: the defaults, or what a
    /// variant's own section says).
    pub detection: Vec<DetectionSetting>,
    /// Also record the pairs that stand out in every frame and read them under
    /// [`evidence::TESTS`] ([`VariantResult::evidence`]).
    pub evidence: bool,
}

/// Whether `dir` holds the scene of scenario `s` (drawn relative to `base`) already.
fn is_generated(s: &Scenario, base: &Path, dir: &Path) -> bool {
    // A scene written before the generator wrote `gt/outliers.csv` is written again, so that
    // every variant's filter is measured.
    if !dir.join("scene.toml").is_file() || !dir.join("gt").join("outliers.csv").is_file() {
        return false;
    }
    // Nor is one an earlier generator wrote (its ground truth measured otherwise).
    let current = std::fs::read_to_string(dir.join("scene.toml"))
        .is_ok_and(|text| text.starts_with(&header_prefix()));
    if !current {
        return false;
    }
    let mut expected = s.clone();
    rebase_mesh_paths(&mut expected, base, dir);
    Scenario::load(&dir.join("scenario.toml")).is_ok_and(|written| written == expected)
}

/// Generates (or reuses) and runs the selected variants of the family at `family_path`, and
/// sums them up.
///
/// # Errors
/// A message naming the family, or the variant whose generation or run failed.
pub fn eval_family(family_path: &Path, options: &EvalOptions) -> Result<FamilySummary, String> {
    let mut family = Family::load(family_path).map_err(|e| e.to_string())?;
    // Variants of another seed are kept apart from the family's own.
    let work_name = match options.seed {
        Some(seed) if seed != family.seed => {
            family.seed = seed;
            format!("{}-seed-{seed}", family.name)
        }
        _ => family.name.clone(),
    };
    // Remodelled variants too, each mesh in a directory of its own.
    let work_name = match options.model_mesh.option() {
        Some(mesh) => format!("{work_name}-{mesh}"),
        None => work_name,
    };
    let scenarios = variants(&family, family_path).map_err(|e| e.to_string())?;
    let base = family.base_dir(family_path);
    let kinds = family.kinds();
    let mut taken = [0usize; 3];
    let chosen: Vec<(&Scenario, Kind)> = scenarios
        .iter()
        .zip(kinds.iter().copied())
        .filter(|(_, k)| {
            let slot = &mut taken[*k as usize];
            *slot += 1;
            options.selection.per_kind.is_none_or(|n| *slot <= n)
        })
        .collect();
    let work = options.work.join(&work_name);
    std::fs::create_dir_all(&work).map_err(|e| format!("{}: {e}", work.display()))?;
    let bar = if options.progress {
        let b = ProgressBar::new(chosen.len() as u64);
        b.set_style(
            ProgressStyle::with_template("{prefix:>10} [{bar:30}] {pos}/{len} variants {msg}")
                .map_err(|e| e.to_string())?
                .progress_chars("=> "),
        );
        b.set_prefix(family.name.clone());
        b
    } else {
        ProgressBar::hidden()
    };
    let mut results = Vec::with_capacity(chosen.len());
    let mut pictures = vec![];
    // Without a terminal the bar draws nothing: a line per variant says where a long run is.
    let plain = options.progress && !std::io::IsTerminal::is_terminal(&std::io::stderr());
    let total = chosen.len();
    for (k, (s, kind)) in chosen.into_iter().enumerate() {
        if plain {
            eprintln!("{}: {} ({}/{total})", family.name, s.name, k + 1);
        }
        let dir = work.join(&s.name);
        if options.fresh || !is_generated(s, &base, &dir) {
            bar.set_message(format!("{} (generating)", s.name));
            generate_scenario(s, &base, &dir, options.model_mesh, false)
                .map_err(|e| format!("{}: {e}", s.name))?;
        }
        bar.set_message(format!("{} (running)", s.name));
        let mut scene = Scene::load(&dir).map_err(|e| format!("{}: {e}", s.name))?;
        if let Some(law) = options.law {
            scene.file.model.law = law;
        }
        scene.file.detection = scene
            .file
            .detection
            .with_all(&options.detection)
            .map_err(|e| format!("{}: {e}", s.name))?;
        // With pictures asked for, the overlays (with the detector's pairs) are drawn and the
        // last one kept; without, none is drawn.
        let drawing = options.pictures.is_some();
        scene.overlay_pairs = drawing;
        let mut last = LastPicture(None);
        let (summary, trace) = run_scene_with(
            &scene,
            &mut TrackSource::new(&scene.frames),
            drawing.then_some(&mut last as &mut dyn FrameSink),
            &RunOptions::default(),
        )
        .map_err(|e| format!("{}: {e}", s.name))?;
        let mut result = variant_result(s, kind, summary);
        if options.evidence {
            result.evidence = Some(
                evidence::read_variant(&scene, &trace, kind, result.open_frame)
                    .map_err(|e| format!("{}: {e}", s.name))?,
            );
        }
        if let Some(picture) = last.0 {
            pictures.push((picture, caption(&result)));
        }
        results.push(result);
        bar.inc(1);
    }
    bar.finish_and_clear();
    if let Some(dir) = &options.pictures {
        write_pictures(&dir.join(&work_name), &pictures)?;
    }
    Ok(summarise(&family.name, results))
}

/// Keeps the last overlay of a run.
struct LastPicture(Option<RgbImage>);

impl FrameSink for LastPicture {
    fn write(&mut self, picture: &RgbImage) -> Result<(), RunError> {
        self.0 = Some(picture.clone());
        Ok(())
    }
}

/// What is written under a variant's picture: its name and kind, then when its cut opened
/// and was detected, and how far the line ended from the true cut.
struct Caption {
    name: String,
    lines: [String; 2],
}

fn caption(v: &VariantResult) -> Caption {
    let detection = match (v.open_frame, v.detected_frame) {
        (None, None) => "no cut".to_string(),
        (None, Some(d)) => format!("FALSE CUT at {d}"),
        (Some(o), None) => format!("opens {o}, MISSED"),
        (Some(o), Some(d)) => format!("opens {o}, detected {d}"),
    };
    let detection = match v.hausdorff_percent {
        Some(h) => format!("{detection}, line {h:.1} %"),
        None => detection,
    };
    Caption {
        name: v.name.clone(),
        lines: [format!("{} {}", v.name, v.kind.name()), detection],
    }
}

/// Writes each variant's picture as `dir/NAME.png` and a sheet of them all at half size, five
/// to a row, each captioned, as `dir.png`.
///
/// # Errors
/// A message naming the file that could not be written.
fn write_pictures(dir: &Path, pictures: &[(RgbImage, Caption)]) -> Result<(), String> {
    let Some((first, _)) = pictures.first() else {
        return Ok(());
    };
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    const COLUMNS: u32 = 5;
    // Two lines of the 8-pixel font.
    const CAPTION: u32 = 24;
    let (w, h) = (first.width() / 2, first.height() / 2);
    let rows = (pictures.len() as u32).div_ceil(COLUMNS);
    let mut sheet = Canvas {
        image: RgbImage::from_pixel(COLUMNS * w, rows * (h + CAPTION), image::Rgb([12, 12, 14])),
    };
    for (k, (picture, caption)) in pictures.iter().enumerate() {
        let file = dir.join(format!("{}.png", caption.name));
        picture
            .save(&file)
            .map_err(|e| format!("{}: {e}", file.display()))?;
        let tile = imageops::resize(picture, w, h, imageops::FilterType::Triangle);
        let (x, y) = (
            (k as u32 % COLUMNS) * w,
            (k as u32 / COLUMNS) * (h + CAPTION),
        );
        imageops::overlay(&mut sheet.image, &tile, i64::from(x), i64::from(y));
        for (line, text) in caption.lines.iter().enumerate() {
            let top = i64::from(y + h) + 3 + 10 * line as i64;
            sheet.text(i64::from(x) + 4, top, text, [240, 240, 240], 1);
        }
    }
    let file = dir.with_extension("png");
    sheet
        .save(&file)
        .map_err(|e| format!("{}: {e}", file.display()))
}

fn variant_result(s: &Scenario, kind: Kind, summary: Summary) -> VariantResult {
    let intact = kind == Kind::Intact;
    let detected = summary.cut_detected_frame;
    let open = summary.cut_open_frame;
    // The evidence is looked for from the opening on: a cut found before it opened (early)
    // has it counted at its start, so that the two waits still add up to the latency.
    let evidence = summary
        .cut_evidence_frame
        .zip(detected)
        .map(|(e, d)| e.min(d));
    let frames = |a: Option<u32>, b: Option<u32>| match (a, b) {
        (Some(a), Some(b)) if !intact => Some(i64::from(b) - i64::from(a)),
        _ => None,
    };
    VariantResult {
        name: s.name.clone(),
        kind,
        noise_px: s.tracking.noise_px,
        jump_px: s.tracking.outlier_jump_px,
        open_frame: open,
        detected_frame: detected,
        latency: match (detected, open) {
            (Some(d), Some(o)) if !intact => Some(i64::from(d) - i64::from(o)),
            _ => None,
        },
        evidence_wait: frames(open, evidence),
        start_wait: frames(evidence, detected),
        false_cut: intact && detected.is_some(),
        missed: !intact && detected.is_none(),
        hausdorff_percent: if intact {
            None
        } else {
            summary.cut_hausdorff_percent
        },
        open_hausdorff_percent: if intact {
            None
        } else {
            summary.cut_open_hausdorff_percent
        },
        line_to_cut_percent: if intact {
            None
        } else {
            summary.cut_line_to_cut_percent
        },
        cut_to_line_percent: if intact {
            None
        } else {
            summary.cut_to_line_percent
        },
        summary,
        evidence: None,
    }
}

/// Sums up a family's variant results and checks [`ACCEPTANCE`].
pub fn summarise(family: &str, variants: Vec<VariantResult>) -> FamilySummary {
    let cut: Vec<&VariantResult> = variants.iter().filter(|v| v.kind != Kind::Intact).collect();
    let detected: Vec<&&VariantResult> = cut.iter().filter(|v| !v.missed).collect();
    let over = |f: &dyn Fn(&VariantResult) -> f64| Spread::of(cut.iter().map(|v| f(v)));
    let latency = Spread::of(detected.iter().filter_map(|v| v.latency.map(|l| l as f64)));
    let evidence_wait = Spread::of(
        detected
            .iter()
            .filter_map(|v| v.evidence_wait.map(|l| l as f64)),
    );
    let start_wait = Spread::of(
        detected
            .iter()
            .filter_map(|v| v.start_wait.map(|l| l as f64)),
    );
    // A distance over the detected cut variants, a variant without one as infinitely far.
    let distance = |f: fn(&VariantResult) -> Option<f64>| {
        Spread::of(detected.iter().map(|v| f(v).unwrap_or(f64::INFINITY)))
    };
    let hausdorff = distance(|v| v.hausdorff_percent);
    let open_hausdorff = distance(|v| v.open_hausdorff_percent);
    let line_to_cut = distance(|v| v.line_to_cut_percent);
    let cut_to_line = distance(|v| v.cut_to_line_percent);
    let false_cuts = variants.iter().filter(|v| v.false_cut).count();
    let missed = cut.iter().filter(|v| v.missed).count();
    let a = ACCEPTANCE;
    let passes = false_cuts <= a.false_cuts
        && missed <= a.missed
        && latency.is_none_or(|l| l.median <= a.latency_median && l.max <= a.latency_max as f64)
        && hausdorff.is_none_or(|h| {
            h.median <= a.hausdorff_median_percent && h.max <= a.hausdorff_max_percent
        });
    FamilySummary {
        family: family.to_string(),
        intact: variants.len() - cut.len(),
        cut: cut.len(),
        live: cut.iter().filter(|v| v.kind == Kind::Live).count(),
        false_cuts,
        missed,
        early: detected
            .iter()
            .filter(|v| v.latency.is_some_and(|l| l < 0))
            .count(),
        latency,
        evidence_wait,
        start_wait,
        hausdorff_percent: hausdorff,
        open_hausdorff_percent: open_hausdorff,
        line_to_cut_percent: line_to_cut,
        cut_to_line_percent: cut_to_line,
        dice_uncut: over(&|v| v.summary.dice_final_uncut),
        dice: over(&|v| v.summary.dice_final),
        tre_uncut_mm: over(&|v| v.summary.tre_mm_final_uncut),
        tre_mm: over(&|v| v.summary.tre_mm_final),
        tre_rest_mm: over(&|v| v.summary.tre_mm_final_rest),
        filter: variants
            .iter()
            .filter_map(|v| v.summary.filter_truth)
            .reduce(|a, b| FilterTruth {
                outliers: a.outliers + b.outliers,
                outliers_filtered: a.outliers_filtered + b.outliers_filtered,
                genuine_filtered: a.genuine_filtered + b.genuine_filtered,
                genuine_before_detection: a.genuine_before_detection + b.genuine_before_detection,
            }),
        passes,
        evidence: evidence::rows(&variants),
        variants,
    }
}

fn spread(s: Option<Spread>, digits: usize) -> String {
    s.map_or("–".to_string(), |s| {
        format!("{:.digits$} / {:.digits$}", s.median, s.max)
    })
}

/// "caught / made, genuine": the filter's jumping features taken out of those made to jump,
/// and the features it took out that never jumped.
fn filter_cell(f: Option<FilterTruth>) -> String {
    f.map_or("–".to_string(), |f| {
        format!(
            "{} / {}, {}",
            f.outliers_filtered, f.outliers, f.genuine_filtered
        )
    })
}

fn median(s: Option<Spread>, digits: usize) -> String {
    s.map_or("–".to_string(), |s| format!("{:.digits$}", s.median))
}

/// The family table of the README: one row per family.
pub fn markdown_table(families: &[FamilySummary]) -> String {
    let mut t = String::from(
        "| family | intact | cut (live) | false cuts | missed | early | latency median / max (frames) \
         | of it, waiting for evidence / for the line's start (median / max) \
         | Hausdorff median / max (% diag.) | of it, line → cut / cut → line (median) | to its open part | Dice uncut → cut (median) | target error uncut → cut, rest (mm, median) \
         | filter: jumps caught / made, genuine taken out | acceptance |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for f in families {
        t.push_str(&format!(
            "| {} | {} | {} ({}) | {} | {} | {} | {} | {}; {} | {} | {} / {} | {} | {} → {} | {} → {}, {} | {} | {} |\n",
            f.family,
            f.intact,
            f.cut,
            f.live,
            f.false_cuts,
            f.missed,
            f.early,
            spread(f.latency, 1),
            spread(f.evidence_wait, 1),
            spread(f.start_wait, 1),
            spread(f.hausdorff_percent, 1),
            median(f.line_to_cut_percent, 1),
            median(f.cut_to_line_percent, 1),
            spread(f.open_hausdorff_percent, 1),
            median(f.dice_uncut, 3),
            median(f.dice, 3),
            median(f.tre_uncut_mm, 2),
            median(f.tre_mm, 2),
            median(f.tre_rest_mm, 2),
            filter_cell(f.filter),
            if f.passes { "met" } else { "not met" }
        ));
    }
    t
}

/// One line per variant, for finding the ones that fail.
pub fn variant_table(f: &FamilySummary) -> String {
    let mut t = String::from(
        "| variant | kind | noise px | jumps px | opens | evidence | detected | Hausdorff (% diag.) | line → cut / cut → line | to its open part | Dice uncut → cut | target error uncut → cut (mm) | filter: jumps caught / made, genuine taken out |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let frame = |v: Option<u32>| v.map_or("–".to_string(), |f| f.to_string());
    for v in &f.variants {
        let flag = if v.false_cut {
            " (false cut)"
        } else if v.missed {
            " (missed)"
        } else {
            ""
        };
        t.push_str(&format!(
            "| {} | {} | {:.2} | {:.1} | {} | {} | {}{} | {} | {} / {} | {} | {:.3} → {:.3} | {:.2} → {:.2} | {} |\n",
            v.name,
            v.kind.name(),
            v.noise_px,
            v.jump_px,
            frame(v.open_frame),
            frame(v.summary.cut_evidence_frame),
            frame(v.detected_frame),
            flag,
            v.hausdorff_percent
                .map_or("–".to_string(), |h| format!("{h:.1}")),
            v.line_to_cut_percent
                .map_or("–".to_string(), |h| format!("{h:.1}")),
            v.cut_to_line_percent
                .map_or("–".to_string(), |h| format!("{h:.1}")),
            v.open_hausdorff_percent
                .map_or("–".to_string(), |h| format!("{h:.1}")),
            v.summary.dice_final_uncut,
            v.summary.dice_final,
            v.summary.tre_mm_final_uncut,
            v.summary.tre_mm_final,
            filter_cell(v.summary.filter_truth),
        ));
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_takes_the_middle_of_an_even_count_and_skips_nans() {
        assert_eq!(Spread::of([]), None);
        let s = Spread::of([4.0, f64::NAN, 1.0, 3.0, 2.0]).unwrap();
        assert_eq!(
            s,
            Spread {
                median: 2.5,
                max: 4.0
            }
        );
        let s = Spread::of([5.0, 1.0, 3.0]).unwrap();
        assert_eq!(
            s,
            Spread {
                median: 3.0,
                max: 5.0
            }
        );
    }
}
