//! Reports: a human summary, an overview picture of a run, and plots; `page`, the page of
//! `incise report`.

pub mod page;

use std::path::Path;

use image::{RgbImage, imageops};
use plotters::prelude::*;

use crate::render::Canvas;
use crate::run::{Summary, Trace};
use crate::scene::{Precision, Scene, SolverSection};

/// A few lines a person reads after a run.
pub fn human_summary(s: &Summary) -> String {
    let opt = |v: Option<u32>| v.map_or("none".to_string(), |f| format!("frame {f}"));
    format!(
        "scene {}: {} frames, {} features ({} missed the model)\n\
         cut: opens at {} (truth), detected at {}, mesh cut {} time(s) ({} nodes, {} tetrahedra at the end){}\n\
         {}Dice last frame {:.3} (uncut {:.3}), mean after the cut opens {:.3}\n\
         surface RMS {:.2} mm, target error {:.2} mm (uncut {:.2} mm, rest model {:.2} mm) at the last frame\n\
         step time median {:.2} ms, max {:.2} ms{}; model storage {:.1} KiB\n{}",
        s.scene,
        s.frames,
        s.features,
        s.features_missed,
        opt(s.cut_open_frame),
        opt(s.cut_detected_frame),
        s.cut_events,
        s.nodes_final,
        s.tets_final,
        s.cut_refused
            .as_ref()
            .map_or(String::new(), |r| format!("; a cut was refused at {r}")),
        line_distance(s),
        s.dice_final,
        s.dice_final_uncut,
        s.dice_mean_after_cut,
        s.surface_rmse_mm_final,
        s.tre_mm_final,
        s.tre_mm_final_uncut,
        s.tre_mm_final_rest,
        s.ms_per_frame_median,
        s.ms_per_frame_max,
        s.ms_cut_frame_max.map_or(String::new(), |m| format!(
            " (a frame that cuts: {m:.2} ms)"
        )),
        s.model_bytes as f64 / 1024.0,
        s.first_rejected.as_ref().map_or(String::new(), |r| format!(
            "{} frame(s) refused by the core and skipped (the model kept its state), the first at {r}\n",
            s.frames_rejected
        )),
    )
}

/// How far the last frame's cut line ended from the true cut, and which of its two halves
/// that is: the line straying from the cut, or the cut left uncovered by it. Empty without a
/// line or a true cut.
fn line_distance(s: &Summary) -> String {
    match (
        s.cut_hausdorff_px,
        s.cut_hausdorff_percent,
        s.cut_line_to_cut_percent,
        s.cut_to_line_percent,
    ) {
        (Some(px), Some(h), Some(line), Some(cut)) => format!(
            "cut line at the last frame: {px:.1} px from the true cut (Hausdorff, {h:.1} % of the \
             image diagonal); the line strays up to {line:.1} % from the cut, the cut lies up to \
             {cut:.1} % from the line\n"
        ),
        _ => String::new(),
    }
}

/// The results of several runs as a Markdown table.
pub fn markdown_table(rows: &[Summary]) -> String {
    let opt = |v: Option<u32>| v.map_or("–".to_string(), |f| f.to_string());
    let optf =
        |v: Option<f64>, digits: usize| v.map_or("–".to_string(), |x| format!("{x:.digits$}"));
    let mut out = String::from(
        "| scene | features | cut opens | cut detected | mesh cut | Hausdorff px | Dice uncut | Dice | TRE rest mm | TRE uncut mm | TRE mm | surface mm | ms/frame steady | ms/frame cutting | nodes |\n\
         | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    for s in rows {
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {:.3} | {:.3} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} | {} | {} |\n",
            s.scene,
            s.features,
            opt(s.cut_open_frame),
            opt(s.cut_detected_frame),
            s.cut_first_frame
                .map_or("–".to_string(), |f| format!("{f} ({}×)", s.cut_events)),
            optf(s.cut_hausdorff_px, 1),
            s.dice_final_uncut,
            s.dice_final,
            s.tre_mm_final_rest,
            s.tre_mm_final_uncut,
            s.tre_mm_final,
            s.surface_rmse_mm_final,
            s.ms_steady_median,
            optf(s.ms_cut_frame_max, 1),
            if s.cut_events > 0 {
                format!("{} → {}", s.nodes_initial, s.nodes_final)
            } else {
                s.nodes_final.to_string()
            },
        ));
    }
    out
}

/// For the scenes run with `--true-cut`: the last frame's Dice and target error with the mesh
/// cut where the core detected the cut and along the true cut, and the share of the uncut
/// model's Dice deficit each closes, `(Dice − Dice uncut) / (1 − Dice uncut)`.
pub fn true_cut_table(rows: &[Summary]) -> String {
    let mut out = String::from(
        "| scene | Dice uncut | Dice, detected cut | Dice, true cut | deficit closed, detected | deficit closed, true | TRE uncut mm | TRE mm, detected cut | TRE mm, true cut |\n\
         | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    let closed = |dice: f64, uncut: f64| 100.0 * (dice - uncut) / (1.0 - uncut);
    for s in rows {
        let (Some(dice), Some(tre)) = (s.dice_final_true_cut, s.tre_mm_final_true_cut) else {
            continue;
        };
        out.push_str(&format!(
            "| {} | {:.3} | {:.3} | {:.3} | {:.0}% | {:.0}% | {:.2} | {:.2} | {:.2} |\n",
            s.scene,
            s.dice_final_uncut,
            s.dice_final,
            dice,
            closed(s.dice_final, s.dice_final_uncut),
            closed(dice, s.dice_final_uncut),
            s.tre_mm_final_uncut,
            s.tre_mm_final,
            tre,
        ));
    }
    out
}

/// For the scenes that list the features their generator made jump (`gt/outliers.csv`): what
/// the temporal filter took out against that list. A jump the tracker never reported does not
/// count; a feature taken out that was never reported off its place is genuine (for instance a
/// lip of a cut opening under the camera).
pub fn filter_table(rows: &[Summary]) -> String {
    let mut out = String::from(
        "| scene | features | taken out | jumps made | jumps taken out | genuine taken out | genuine, before the cut is detected |\n\
         | --- | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    for s in rows {
        let Some(t) = s.filter_truth else {
            continue;
        };
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} |\n",
            s.scene,
            s.features,
            s.features_filtered,
            t.outliers,
            t.outliers_filtered,
            t.genuine_filtered,
            t.genuine_before_detection,
        ));
    }
    out
}

/// The four frames of a run that tell its story, with a caption under each: for a cut scene,
/// before the cut opens, the cut detected, the mesh cut (or the model opening), and the last
/// frame; for an intact one, the first, a third, two thirds and the last frame.
pub fn story_frames(trace: &Trace, open: Option<u32>) -> Vec<(usize, String)> {
    let n = trace.frames.len();
    let last = n.saturating_sub(1);
    let dice = |f: usize| {
        trace
            .frames
            .get(f)
            .map_or(String::new(), |r| format!(", Dice {:.3}", r.dice))
    };
    let Some(open) = open.map(|o| (o as usize).min(last)) else {
        return [0, n / 3, 2 * n / 3, last]
            .into_iter()
            .map(|f| (f, format!("frame {f}{}", dice(f))))
            .collect();
    };
    let before = open.saturating_sub(1);
    let mut picks = vec![(before, format!("before the cut opens (frame {before})"))];
    match trace.detection.detected_frame.map(|f| f as usize) {
        Some(det) => {
            let cut_at_detection = trace.cuts.frames.first() == Some(&det);
            picks.push((
                det,
                if cut_at_detection {
                    format!("cut detected, mesh cut (frame {det})")
                } else {
                    format!("cut detected (frame {det})")
                },
            ));
            // A later cut event shows the line growing; one right after detection looks
            // like panel 2, and the model opening says more.
            let third = match trace.cuts.frames.iter().find(|&&f| f > det + 3) {
                Some(&f) if f < last => (f, format!("the mesh cut further (frame {f})")),
                _ => {
                    let f = det + (last - det.min(last)) / 2;
                    (f, format!("the model opens (frame {f})"))
                }
            };
            picks.push(third);
        }
        None => {
            let f = open + (last - open) / 3;
            picks.push((f, format!("cut open, not detected (frame {f})")));
            let g = open + 2 * (last - open) / 3;
            picks.push((g, format!("frame {g}")));
        }
    }
    picks.push((last, format!("last frame ({last}){}", dice(last))));
    picks
}

/// The overview of a run: the four frames of [`story_frames`] from the overlay pictures in
/// `frames_dir`, two by two, each captioned.
///
/// # Errors
/// If a picture cannot be read or the result written.
pub fn contact_sheet(
    frames_dir: &Path,
    trace: &Trace,
    open: Option<u32>,
    out: &Path,
) -> Result<(), String> {
    if trace.frames.is_empty() {
        return Ok(());
    }
    let picks = story_frames(trace, open);
    let mut tiles = vec![];
    for (f, _) in &picks {
        let p = frames_dir.join(format!("frame_{f:04}.png"));
        tiles.push(
            image::open(&p)
                .map_err(|e| format!("{}: {e}", p.display()))?
                .to_rgb8(),
        );
    }
    const CAPTION: u32 = 30;
    let (w, h) = tiles[0].dimensions();
    let mut sheet = Canvas {
        image: RgbImage::from_pixel(2 * w, 2 * (h + CAPTION), image::Rgb([12, 12, 14])),
    };
    for (k, (tile, (_, caption))) in tiles.iter().zip(&picks).enumerate() {
        let (x, y) = ((k as u32 % 2) * w, (k as u32 / 2) * (h + CAPTION));
        imageops::overlay(&mut sheet.image, tile, i64::from(x), i64::from(y));
        let label = format!("{}. {caption}", k + 1);
        // Large where it fits in the tile, small where it does not.
        let scale = if Canvas::text_width(&label, 2) + 16 <= w {
            2
        } else {
            1
        };
        let top = i64::from(y + h) + if scale == 2 { 7 } else { 11 };
        sheet.text(i64::from(x) + 8, top, &label, [240, 240, 240], scale);
    }
    sheet
        .save(out)
        .map_err(|e| format!("{}: {e}", out.display()))
}

/// Dice per frame, with the frame at which the true cut opens marked.
///
/// # Errors
/// If the plot cannot be written.
pub fn plot_dice(trace: &Trace, summary: &Summary, out: &Path) -> Result<(), String> {
    let root = SVGBackend::new(out, (720, 400)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let n = trace.frames.len() as f64;
    let lo = trace
        .frames
        .iter()
        .map(|r| r.dice)
        .fold(1.0, f64::min)
        .min(0.8);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{}: Dice of silhouettes per frame", summary.scene),
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(48)
        .build_cartesian_2d(0.0..n, lo..1.0)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc("frame")
        .y_desc("Dice")
        .draw()
        .map_err(|e| e.to_string())?;
    chart
        .draw_series(LineSeries::new(
            trace.frames.iter().map(|r| (r.frame as f64, r.dice)),
            &BLUE,
        ))
        .map_err(|e| e.to_string())?
        .label("model")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], BLUE));
    if let Some(open) = summary.cut_open_frame {
        let x = f64::from(open);
        chart
            .draw_series(LineSeries::new(vec![(x, lo), (x, 1.0)], &RED))
            .map_err(|e| e.to_string())?
            .label("true cut opens")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], RED));
    }
    chart
        .configure_series_labels()
        .border_style(BLACK)
        .background_style(WHITE.mix(0.8))
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())
}

/// One solver setting of an error-against-run-time sweep.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweepSetting {
    /// `"refactor"`, `"frozen"`, `"factor-once"` or `"quasi-newton"`.
    pub strategy: &'static str,
    /// Newton steps per frame.
    pub newton: u32,
    /// PCG steps per Newton step (`"frozen"`; per later Newton step for `"factor-once"`).
    pub pcg: u32,
    /// The scalar type the core computes in.
    pub precision: Precision,
    /// Trial steps of each Newton step's line search.
    pub line_search: u32,
}

/// The line-search trials of the sweep's settings but those of its line-search axis: the
/// committed scenes' own.
pub const SWEEP_LINE_SEARCH: u32 = 4;

impl SweepSetting {
    /// The strategy name as a setting holds it, or `None` for a name that is none of the four.
    pub fn strategy_name(name: &str) -> Option<&'static str> {
        ["refactor", "frozen", "factor-once", "quasi-newton"]
            .into_iter()
            .find(|&s| s == name)
    }

    /// The setting a scene's solver section holds (a strategy name the scene would refuse is
    /// read as `"refactor"`; a loaded scene holds none).
    pub fn of(solver: &SolverSection) -> Self {
        SweepSetting {
            strategy: Self::strategy_name(&solver.strategy).unwrap_or("refactor"),
            newton: solver.newton_iterations,
            pcg: solver.pcg_iterations,
            precision: Precision::F64,
            line_search: solver.line_search_steps,
        }
    }

    /// Puts this setting into a scene: its solver section and its precision.
    pub fn apply(&self, scene: &mut Scene) {
        let solver = &mut scene.file.solver;
        solver.strategy = self.strategy.to_string();
        solver.newton_iterations = self.newton;
        solver.pcg_iterations = self.pcg;
        solver.line_search_steps = self.line_search;
        scene.precision = self.precision;
    }

    /// A short label.
    pub fn label(&self) -> String {
        let label = match self.strategy {
            "frozen" => format!("frozen, {} Newton × {} PCG", self.newton, self.pcg),
            "factor-once" => format!("factor once, {} Newton, {} PCG", self.newton, self.pcg),
            "quasi-newton" => format!("quasi-Newton, {} Newton", self.newton),
            _ => format!("refactor, {} Newton", self.newton),
        };
        let label = match self.line_search {
            SWEEP_LINE_SEARCH => label,
            1 => format!("{label}, 1 line-search trial"),
            n => format!("{label}, {n} line-search trials"),
        };
        match self.precision {
            Precision::F64 => label,
            Precision::F32 => format!("{label}, f32"),
            Precision::Mixed => format!("{label}, mixed"),
        }
    }
}

/// The settings a sweep tries, with [`SWEEP_LINE_SEARCH`] line-search trials: `Refactor` with
/// 1 to 4 Newton steps, `Frozen` with 1 to 3 Newton steps of 3, 10 or 30 PCG steps,
/// `FactorOnce` with 2 or 3 Newton steps of 3 or 10 PCG steps after the first, `QuasiNewton`
/// with 1 to 3 steps; and the line-search axis: `Refactor` with 1 Newton step (the setting
/// most scenes' reports recommended before `QuasiNewton`) of 1 or 2 trials, and `QuasiNewton`
/// with 1 or 2 steps of 1 trial.
pub fn sweep_settings() -> Vec<SweepSetting> {
    let setting = |strategy, newton, pcg| SweepSetting {
        strategy,
        newton,
        pcg,
        precision: Precision::F64,
        line_search: SWEEP_LINE_SEARCH,
    };
    let mut v: Vec<SweepSetting> = (1..=4)
        .map(|newton| setting("refactor", newton, 10))
        .collect();
    for newton in 1..=3 {
        for pcg in [3, 10, 30] {
            v.push(setting("frozen", newton, pcg));
        }
    }
    for newton in 2..=3 {
        for pcg in [3, 10] {
            v.push(setting("factor-once", newton, pcg));
        }
    }
    for newton in 1..=3 {
        v.push(setting("quasi-newton", newton, 0));
    }
    for trials in [1, 2] {
        v.push(SweepSetting {
            line_search: trials,
            ..setting("refactor", 1, 10)
        });
    }
    for newton in [1, 2] {
        v.push(SweepSetting {
            line_search: 1,
            ..setting("quasi-newton", newton, 0)
        });
    }
    v
}

/// The sweep as a Markdown table.
pub fn sweep_table(rows: &[(SweepSetting, Summary)]) -> String {
    let mut out = String::from(
        "| solver | ms/frame median | ms/frame max | Dice last | Dice after cut | TRE mm | surface mm | cut detected |\n\
         | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    for (setting, s) in rows {
        out.push_str(&format!(
            "| {} | {:.2} | {:.2} | {:.3} | {:.3} | {:.2} | {:.2} | {} |\n",
            setting.label(),
            s.ms_per_frame_median,
            s.ms_per_frame_max,
            s.dice_final,
            s.dice_mean_after_cut,
            s.tre_mm_final,
            s.surface_rmse_mm_final,
            s.cut_detected_frame
                .map_or("–".to_string(), |f| f.to_string())
        ));
    }
    out
}

/// Two plots side by side: mean Dice after the cut and target error against the median step
/// time, one point per setting (refactor blue, frozen red).
///
/// # Errors
/// If the plot cannot be written.
pub fn plot_sweep(scene: &str, rows: &[(SweepSetting, Summary)], out: &Path) -> Result<(), String> {
    let root = SVGBackend::new(out, (960, 400)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (left, right) = root.split_horizontally(480);
    let t_max = rows
        .iter()
        .map(|r| r.1.ms_per_frame_median)
        .fold(0.0, f64::max)
        * 1.1
        + 1e-3;
    type Metric = fn(&Summary) -> f64;
    let panels: [(&str, Metric); 2] = [
        ("mean Dice after the cut", |s| s.dice_mean_after_cut),
        ("target error at the last frame, mm", |s| s.tre_mm_final),
    ];
    for (area, (name, metric)) in [left, right].iter().zip(panels) {
        let values: Vec<f64> = rows
            .iter()
            .map(|r| metric(&r.1))
            .filter(|v| v.is_finite())
            .collect();
        let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let pad = ((hi - lo) * 0.1).max(1e-3);
        let (lo, hi) = if lo.is_finite() {
            (lo - pad, hi + pad)
        } else {
            (0.0, 1.0)
        };
        let mut chart = ChartBuilder::on(area)
            .caption(format!("{scene}: {name}"), ("sans-serif", 15))
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(52)
            .build_cartesian_2d(0.0..t_max, lo..hi)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("step time, ms (median)")
            .draw()
            .map_err(|e| e.to_string())?;
        for (setting, s) in rows {
            let colour = match setting.strategy {
                "frozen" => RED,
                "factor-once" => GREEN,
                "quasi-newton" => MAGENTA,
                _ => BLUE,
            };
            let v = metric(s);
            if v.is_finite() {
                chart
                    .draw_series(std::iter::once(Circle::new(
                        (s.ms_per_frame_median, v),
                        4,
                        colour.filled(),
                    )))
                    .map_err(|e| e.to_string())?;
            }
        }
    }
    root.present().map_err(|e| e.to_string())
}
