//! Reports: a human summary, an overview picture of a run, and plots.

use std::path::Path;

use image::{RgbImage, imageops};
use plotters::prelude::*;

use crate::run::{Summary, Trace};

/// A few lines a person reads after a run.
pub fn human_summary(s: &Summary) -> String {
    let opt = |v: Option<u32>| v.map_or("none".to_string(), |f| format!("frame {f}"));
    format!(
        "scene {}: {} frames, {} features ({} missed the model)\n\
         cut: opens at {} (truth), detected at {}\n\
         Dice last frame {:.3} (uncut {:.3}), mean after the cut opens {:.3}\n\
         surface RMS {:.2} mm, target error {:.2} mm (uncut {:.2} mm) at the last frame\n\
         step time median {:.2} ms, max {:.2} ms; model storage {:.1} KiB\n",
        s.scene,
        s.frames,
        s.features,
        s.features_missed,
        opt(s.cut_open_frame),
        opt(s.cut_detected_frame),
        s.dice_final,
        s.dice_final_uncut,
        s.dice_mean_after_cut,
        s.surface_rmse_mm_final,
        s.tre_mm_final,
        s.tre_mm_final_uncut,
        s.ms_per_frame_median,
        s.ms_per_frame_max,
        s.model_bytes as f64 / 1024.0
    )
}

/// The results of several runs as a Markdown table.
pub fn markdown_table(rows: &[Summary]) -> String {
    let opt = |v: Option<u32>| v.map_or("–".to_string(), |f| f.to_string());
    let optf = |v: Option<f64>| v.map_or("–".to_string(), |x| format!("{x:.1}"));
    let mut out = String::from(
        "| scene | features | cut opens | cut detected | Hausdorff px | Dice uncut | Dice | Dice after cut | surface mm | TRE mm | TRE uncut mm | ms/frame (median, max) |\n\
         | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    for s in rows {
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {:.3} | {:.3} | {:.3} | {:.2} | {:.2} | {:.2} | {:.1}, {:.1} |\n",
            s.scene,
            s.features,
            opt(s.cut_open_frame),
            opt(s.cut_detected_frame),
            optf(s.cut_hausdorff_px),
            s.dice_final_uncut,
            s.dice_final,
            s.dice_mean_after_cut,
            s.surface_rmse_mm_final,
            s.tre_mm_final,
            s.tre_mm_final_uncut,
            s.ms_per_frame_median,
            s.ms_per_frame_max
        ));
    }
    out
}

/// Four frames of a run side by side (first, a third, two thirds, last), from the overlay
/// pictures in `frames_dir`.
///
/// # Errors
/// If a picture cannot be read or the result written.
pub fn contact_sheet(frames_dir: &Path, trace: &Trace, out: &Path) -> Result<(), String> {
    let n = trace.frames.len();
    if n == 0 {
        return Ok(());
    }
    let picks = [0, n / 3, 2 * n / 3, n - 1];
    let mut tiles = vec![];
    for &f in &picks {
        let p = frames_dir.join(format!("frame_{f:04}.png"));
        tiles.push(
            image::open(&p)
                .map_err(|e| format!("{}: {e}", p.display()))?
                .to_rgb8(),
        );
    }
    let (w, h) = tiles[0].dimensions();
    let mut sheet = RgbImage::new(2 * w, 2 * h);
    for (k, tile) in tiles.iter().enumerate() {
        imageops::overlay(
            &mut sheet,
            tile,
            i64::from((k as u32 % 2) * w),
            i64::from((k as u32 / 2) * h),
        );
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
