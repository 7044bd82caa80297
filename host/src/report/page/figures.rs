//! The report's figures (SVG): error against cost per scene, and instructions per frame.

use std::path::Path;

use plotters::prelude::*;

use super::{SceneReport, SettingResult};

/// The colour of a strategy.
fn colour(strategy: &str) -> RGBColor {
    match strategy {
        "frozen" => RGBColor(214, 39, 40),
        "factor-once" => RGBColor(44, 160, 44),
        "quasi-newton" => RGBColor(148, 103, 189),
        _ => RGBColor(31, 119, 180),
    }
}

/// The cost of a setting on the figure's axis: instructions in millions, or milliseconds.
fn cost(s: &SettingResult, counting: bool) -> f64 {
    if counting {
        s.instructions_median.map_or(f64::NAN, |i| i / 1e6)
    } else {
        s.ms_median
    }
}

/// Dice and target error against the cost of a steady frame, one point per setting (colour:
/// strategy), the Pareto front joined by a line, the recommended setting ringed and the
/// scene's own setting marked with a cross.
///
/// # Errors
/// If the figure cannot be written.
pub(super) fn error_vs_cost(
    scene: &SceneReport,
    counting: bool,
    path: &Path,
) -> Result<(), String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let root = SVGBackend::new(path, (1000, 400)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let (left, right) = root.split_horizontally(500);
    let x_desc = if counting {
        "instructions per steady frame, millions (median, callgrind)"
    } else {
        "step time, ms (median)"
    };
    let costs: Vec<f64> = scene.settings.iter().map(|s| cost(s, counting)).collect();
    let x_max = costs
        .iter()
        .copied()
        .filter(|c| c.is_finite())
        .fold(0.0, f64::max)
        * 1.1
        + 1e-6;
    type Metric = fn(&SettingResult) -> f64;
    let panels: [(&str, &str, Metric); 2] = [
        ("Dice, last frame", "Dice", |s| s.dice_final),
        ("target error, last frame", "target error, mm", |s| {
            s.tre_mm_final
        }),
    ];
    for (area, (title, y_desc, metric)) in [left, right].iter().zip(panels) {
        let values: Vec<f64> = scene
            .settings
            .iter()
            .map(metric)
            .filter(|v| v.is_finite())
            .collect();
        let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let pad = ((hi - lo) * 0.15).max(1e-3);
        // Room above the points for the legend.
        let (lo, hi) = if lo.is_finite() {
            (lo - pad, hi + 5.0 * pad)
        } else {
            (0.0, 1.0)
        };
        let mut chart = ChartBuilder::on(area)
            .caption(format!("{}: {title}", scene.name), ("sans-serif", 16))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..x_max, lo..hi)
            .map_err(|x| e(&x))?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .draw()
            .map_err(|x| e(&x))?;
        let front: Vec<(f64, f64)> = scene
            .front
            .iter()
            .map(|&i| (costs[i], metric(&scene.settings[i])))
            .collect();
        chart
            .draw_series(LineSeries::new(front, BLACK.mix(0.5).stroke_width(1)))
            .map_err(|x| e(&x))?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], BLACK.mix(0.5)));
        for strategy in ["refactor", "frozen", "factor-once", "quasi-newton"] {
            let c = colour(strategy);
            let points: Vec<(f64, f64)> = scene
                .settings
                .iter()
                .zip(&costs)
                .filter(|(s, c)| s.strategy == strategy && c.is_finite() && metric(s).is_finite())
                .map(|(s, &c)| (c, metric(s)))
                .collect();
            if points.is_empty() {
                continue;
            }
            chart
                .draw_series(points.into_iter().map(|p| Circle::new(p, 4, c.filled())))
                .map_err(|x| e(&x))?
                .label(strategy)
                .legend(move |(x, y)| Circle::new((x + 8, y), 4, c.filled()));
        }
        if let Some(r) = scene.recommended {
            let p = (costs[r], metric(&scene.settings[r]));
            chart
                .draw_series(std::iter::once(Circle::new(p, 9, BLACK.stroke_width(2))))
                .map_err(|x| e(&x))?
                .label("recommended")
                .legend(|(x, y)| Circle::new((x + 8, y), 6, BLACK.stroke_width(2)));
        }
        if let Some(own) = scene.settings.iter().position(|s| s.own) {
            let p = (costs[own], metric(&scene.settings[own]));
            if p.0.is_finite() && p.1.is_finite() {
                let square = |(x, y): (i32, i32), r: i32| {
                    Rectangle::new([(x - r, y - r), (x + r, y + r)], BLACK.stroke_width(2))
                };
                chart
                    .draw_series(std::iter::once(EmptyElement::at(p) + square((0, 0), 7)))
                    .map_err(|x| e(&x))?
                    .label("the scene's own setting")
                    .legend(move |(x, y)| square((x + 8, y), 5));
            }
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .border_style(BLACK)
            .background_style(WHITE.mix(0.85))
            .draw()
            .map_err(|x| e(&x))?;
    }
    root.present().map_err(|x| e(&x))
}

/// Instructions of each frame with the scene's own setting (millions), the frames that cut
/// the mesh in red, and the steady median as a dashed line.
///
/// # Errors
/// If the figure cannot be written.
pub(super) fn instructions_per_frame(
    scene: &SceneReport,
    median: Option<f64>,
    path: &Path,
) -> Result<(), String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let root = SVGBackend::new(path, (1000, 320)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let counts: Vec<(f64, f64)> = scene
        .instructions_per_frame
        .iter()
        .enumerate()
        .map(|(k, &c)| ((k + 1) as f64, c as f64 / 1e6))
        .collect();
    let y_max = counts.iter().map(|c| c.1).fold(0.0, f64::max) * 1.1 + 1e-6;
    let x_max = counts.len() as f64 + 1.0;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{}: instructions per frame (its own setting)", scene.name),
            ("sans-serif", 16),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..x_max, 0.0..y_max)
        .map_err(|x| e(&x))?;
    chart
        .configure_mesh()
        .x_desc("frame")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_desc("instructions, millions")
        .draw()
        .map_err(|x| e(&x))?;
    chart
        .draw_series(LineSeries::new(counts.clone(), RGBColor(31, 119, 180)))
        .map_err(|x| e(&x))?
        .label("a frame (the solve, detection, cut line and any cut event)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], RGBColor(31, 119, 180)));
    let cuts: Vec<(f64, f64)> = counts
        .iter()
        .copied()
        .filter(|(f, _)| scene.cut_frames.contains(&(*f as usize)))
        .collect();
    if !cuts.is_empty() {
        chart
            .draw_series(cuts.into_iter().map(|p| Circle::new(p, 5, RED.filled())))
            .map_err(|x| e(&x))?
            .label("a frame that cuts the mesh")
            .legend(|(x, y)| Circle::new((x + 8, y), 5, RED.filled()));
    }
    if let Some(m) = median {
        let m = m / 1e6;
        chart
            .draw_series(DashedLineSeries::new(
                vec![(0.0, m), (x_max, m)],
                6,
                4,
                BLACK.stroke_width(1),
            ))
            .map_err(|x| e(&x))?
            .label("median of the steady frames")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], BLACK));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .border_style(BLACK)
        .background_style(WHITE.mix(0.85))
        .draw()
        .map_err(|x| e(&x))?;
    root.present().map_err(|x| e(&x))
}

/// The values 1, 2 and 5 times a power of ten within `lo..=hi` (`0 < lo`): a logarithmic
/// axis's ticks, labelled even where the range lies within one decade (plotters' own log ticks
/// start at the first power of ten inside the range, and a range of 15 to 94 has none).
fn one_two_five(lo: f64, hi: f64) -> Vec<f64> {
    let mut ticks = vec![];
    if !(lo > 0.0 && hi >= lo && hi.is_finite()) {
        return ticks;
    }
    let mut exponent = lo.log10().floor() as i32;
    while 10f64.powi(exponent) <= hi {
        for m in [1.0, 2.0, 5.0] {
            let v = m * 10f64.powi(exponent);
            if (lo..=hi).contains(&v) {
                ticks.push(v);
            }
        }
        exponent += 1;
    }
    ticks
}

/// The cost of a steady frame against the model's nodes and against the features, on
/// logarithmic axes, with the fitted exponents in the titles.
///
/// # Errors
/// If the figure cannot be written.
pub(super) fn cost_growth(scaling: &super::scaling::Scaling, path: &Path) -> Result<(), String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let root = SVGBackend::new(path, (1000, 380)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let (left, right) = root.split_horizontally(500);
    let counted = scaling.nodes.iter().all(|p| p.instructions.is_some());
    let cost = |p: &super::scaling::Point| {
        if counted {
            p.instructions.unwrap_or(f64::NAN) / 1e6
        } else {
            p.ms_median
        }
    };
    let y_desc = if counted {
        "instructions per steady frame, millions"
    } else {
        "step time, ms (median)"
    };
    type Axis = fn(&super::scaling::Point) -> usize;
    let panels: [(&str, &[super::scaling::Point], Option<f64>, Axis); 2] = [
        ("model nodes", &scaling.nodes, scaling.nodes_exponent, |p| {
            p.nodes
        }),
        (
            "features",
            &scaling.features,
            scaling.features_exponent,
            |p| p.features,
        ),
    ];
    // The largest model of the mesh-resolution axis carries the node axis past the band
    // variants (counted only: its wall time is measured under another load).
    let largest = scaling
        .largest
        .as_ref()
        .filter(|_| counted)
        .map(|l| (l.nodes as f64, l.instructions / 1e6, l));
    for (panel, (area, (name, points, b, x))) in [left, right].iter().zip(panels).enumerate() {
        let beyond = largest.filter(|_| panel == 0);
        let mut xs: Vec<f64> = points.iter().map(|p| x(p) as f64).collect();
        let mut ys: Vec<f64> = points.iter().map(cost).filter(|v| v.is_finite()).collect();
        if let Some((lx, ly, _)) = beyond {
            xs.push(lx);
            ys.push(ly);
        }
        let (x_lo, x_hi) = (
            xs.iter().copied().fold(f64::INFINITY, f64::min) * 0.8,
            xs.iter().copied().fold(1.0, f64::max) * 1.25,
        );
        let (y_lo, y_hi) = (
            ys.iter().copied().fold(f64::INFINITY, f64::min) * 0.7,
            ys.iter().copied().fold(1e-9, f64::max) * 1.4,
        );
        if !(x_lo.is_finite() && y_lo.is_finite() && x_lo > 0.0 && y_lo > 0.0) {
            continue;
        }
        let with_largest = beyond.zip(scaling.nodes_exponent_with_largest);
        let title = match (b, with_largest) {
            (Some(b), Some(((_, _, l), with))) => format!(
                "cost against {name}: exponent {b:.2} ({with:.2} with {})",
                l.scene
            ),
            (Some(b), None) => format!("cost against {name}: exponent {b:.2}"),
            _ => format!("cost against {name}"),
        };
        let mut chart = ChartBuilder::on(area)
            .caption(title, ("sans-serif", 16))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(
                (x_lo..x_hi)
                    .log_scale()
                    .with_key_points(one_two_five(x_lo, x_hi)),
                (y_lo..y_hi)
                    .log_scale()
                    .with_key_points(one_two_five(y_lo, y_hi)),
            )
            .map_err(|x| e(&x))?;
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .x_labels(20)
            .y_labels(20)
            .x_label_formatter(&|v| format!("{v}"))
            .y_label_formatter(&|v| format!("{v}"))
            .x_desc(format!("{name} (logarithmic)"))
            .y_desc(y_desc)
            .draw()
            .map_err(|x| e(&x))?;
        let series: Vec<(f64, f64)> = points.iter().map(|p| (x(p) as f64, cost(p))).collect();
        let blue = RGBColor(31, 119, 180);
        chart
            .draw_series(LineSeries::new(series.clone(), blue))
            .map_err(|x| e(&x))?;
        chart
            .draw_series(series.into_iter().map(|p| Circle::new(p, 4, blue.filled())))
            .map_err(|x| e(&x))?
            .label(format!("{} variants", super::scaling::BASE))
            .legend(move |(x, y)| Circle::new((x + 10, y), 4, blue.filled()));
        if let Some((lx, ly, l)) = beyond {
            let orange = RGBColor(255, 127, 14);
            chart
                .draw_series(std::iter::once(TriangleMarker::new(
                    (lx, ly),
                    7,
                    orange.filled(),
                )))
                .map_err(|x| e(&x))?
                .label(format!("{}, {} mesh", l.scene, l.mesh))
                .legend(move |(x, y)| TriangleMarker::new((x + 10, y), 6, orange.filled()));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 12))
            .draw()
            .map_err(|x| e(&x))?;
    }
    root.present().map_err(|x| e(&x))
}

#[cfg(test)]
mod tests {
    use super::super::scaling::{LargestModel, Point, Scaling};
    use super::*;

    fn point(nodes: usize, features: usize, millions: f64) -> Point {
        Point {
            nodes,
            features,
            instructions: Some(millions * 1e6),
            ms_median: 1.0,
        }
    }

    /// The cost-growth figure labels its axes inside one decade too (the feature axis of the
    /// committed scenes' report spans 22 to 67 million instructions), and marks the largest
    /// model apart, in its legend.
    #[test]
    fn cost_growth_labels_ticks_within_a_decade_and_the_largest_model() {
        let scaling = Scaling {
            nodes: vec![point(204, 300, 26.3), point(2132, 300, 598.0)],
            features: vec![point(204, 100, 21.9), point(204, 2000, 66.9)],
            nodes_exponent: Some(1.31),
            largest: Some(LargestModel {
                scene: "liver-lobe".into(),
                mesh: "the real object's".into(),
                nodes: 4293,
                instructions: 4.867e9,
            }),
            nodes_exponent_with_largest: Some(1.64),
            features_exponent: Some(0.37),
            cost: "instructions",
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("growth.svg");
        cost_growth(&scaling, &path).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        // plotters writes a text element's content on a line of its own.
        let labelled = |text: &str| svg.contains(&format!(">\n{text}\n</text>"));
        // The feature panel's cost axis (15 to 94 million) and its feature axis.
        for tick in ["20", "50", "100", "200", "500", "1000", "2000"] {
            assert!(labelled(tick), "no tick labelled {tick}");
        }
        assert!(
            svg.contains("liver-lobe, the real object"),
            "no legend entry"
        );
        assert!(
            svg.contains("1.64 with liver-lobe"),
            "no exponent with the largest model"
        );
    }
}
