//! The detection's operating curve (`incise eval --sweep`): the same families run under each
//! combination of some `[detection]` fields' values, so that what one default trades against
//! another (false cuts against detection latency and the line's distance to the cut) is
//! measured rather than argued.

use std::path::{Path, PathBuf};

use plotters::prelude::*;
use serde::Serialize;

use super::{EvalOptions, FamilySummary, eval_family, summarise};
use crate::scene::{DetectionSection, DetectionSetting};

/// One setting of a sweep and what the families gave under it.
#[derive(Clone, Debug, Serialize)]
pub struct SweepRow {
    /// The fields set, as `key = value`, in order (the fixed `--set` ones first).
    pub settings: Vec<String>,
    /// Whether they leave the detection at its defaults.
    pub defaults: bool,
    /// Every family's variants pooled into one summary (its `family` is `all`).
    pub all: FamilySummary,
    /// Each family on its own.
    pub families: Vec<FamilySummary>,
}

/// Every combination of the swept fields' values (the first field's varying slowest), each
/// after the fixed settings.
pub fn combinations(
    fixed: &[DetectionSetting],
    swept: &[Vec<DetectionSetting>],
) -> Vec<Vec<DetectionSetting>> {
    let mut all = vec![fixed.to_vec()];
    for values in swept {
        all = all
            .iter()
            .flat_map(|settings| {
                values.iter().map(move |v| {
                    let mut s = settings.clone();
                    s.push(v.clone());
                    s
                })
            })
            .collect();
    }
    all
}

/// Whether `settings` leave the detection defaults as they are.
///
/// # Errors
/// The first setting that is not a field of `[detection]` or out of its range.
pub fn are_defaults(settings: &[DetectionSetting]) -> Result<bool, String> {
    let defaults = DetectionSection::default();
    Ok(defaults.with_all(settings)? == defaults)
}

/// Runs `families` under every combination of `swept` (after `options.detection`).
///
/// # Errors
/// A setting that is not a field of `[detection]` or out of its range (checked before anything
/// runs), or the first family that fails.
pub fn sweep(
    families: &[PathBuf],
    options: &EvalOptions,
    swept: &[Vec<DetectionSetting>],
) -> Result<Vec<SweepRow>, String> {
    let settings = combinations(&options.detection, swept);
    let defaults = settings
        .iter()
        .map(|s| are_defaults(s))
        .collect::<Result<Vec<bool>, String>>()?;
    let total = settings.len();
    let mut rows = Vec::with_capacity(total);
    for (k, (settings, defaults)) in settings.into_iter().zip(defaults).enumerate() {
        let labels: Vec<String> = settings.iter().map(ToString::to_string).collect();
        if options.progress {
            eprintln!("setting {}/{}: {}", k + 1, total, label(&labels, defaults));
        }
        let run = EvalOptions {
            detection: settings,
            ..options.clone()
        };
        let families = families
            .iter()
            .map(|f| eval_family(f, &run))
            .collect::<Result<Vec<FamilySummary>, String>>()?;
        let pooled = families.iter().flat_map(|f| f.variants.clone()).collect();
        rows.push(SweepRow {
            settings: labels,
            defaults,
            all: summarise("all", pooled),
            families,
        });
    }
    Ok(rows)
}

/// A row's setting as the table prints it.
fn label(settings: &[String], defaults: bool) -> String {
    let text = if settings.is_empty() {
        "the defaults".to_string()
    } else {
        settings.join(", ")
    };
    if defaults && !settings.is_empty() {
        format!("{text} (the defaults)")
    } else {
        text
    }
}

/// The sweep as a table: one row per setting, every family pooled, and the families that meet
/// issue 11's acceptance on their own.
pub fn sweep_table(rows: &[SweepRow]) -> String {
    let mut t = String::from(
        "| setting | false cuts (of intact) | per family | missed (of cut) | latency median / max (frames) \
         | Hausdorff median / max (% diag.) | families meeting the acceptance |\n\
         |---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let per_family: Vec<String> = r
            .families
            .iter()
            .map(|f| format!("{} {}", f.family, f.false_cuts))
            .collect();
        let met: Vec<&str> = r
            .families
            .iter()
            .filter(|f| f.passes)
            .map(|f| f.family.as_str())
            .collect();
        t.push_str(&format!(
            "| {} | {} ({}) | {} | {} ({}) | {} | {} | {} |\n",
            label(&r.settings, r.defaults),
            r.all.false_cuts,
            r.all.intact,
            per_family.join(", "),
            r.all.missed,
            r.all.cut,
            super::spread(r.all.latency, 1),
            super::spread(r.all.hausdorff_percent, 1),
            if met.is_empty() {
                "none".to_string()
            } else {
                met.join(", ")
            }
        ));
    }
    t
}

/// The operating curve: false cuts (every family pooled) against the median detection latency
/// (left) and against the median Hausdorff distance (right), one point per setting, the
/// defaults ringed, and issue 11's acceptance shaded.
///
/// # Errors
/// If the plot cannot be written.
pub fn plot_sweep(rows: &[SweepRow], out: &Path) -> Result<(), String> {
    let root = SVGBackend::new(out, (960, 440)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    // The fields the points are labelled with, in their order.
    let keys: Vec<&str> = rows
        .first()
        .map(|r| {
            r.settings
                .iter()
                .map(|s| s.split_once(" = ").map_or(s.as_str(), |(k, _)| k))
                .collect()
        })
        .unwrap_or_default();
    let root = root
        .titled(
            &format!(
                "each point a setting ({}), the defaults red; green: issue 11's acceptance",
                keys.join(", ")
            ),
            ("sans-serif", 14),
        )
        .map_err(|e| e.to_string())?;
    let (left, right) = root.split_horizontally(480);
    type Metric = fn(&FamilySummary) -> Option<f64>;
    let a = super::ACCEPTANCE;
    let panels: [(&str, Metric, f64); 2] = [
        (
            "detection latency, frames (median)",
            |f| f.latency.map(|s| s.median),
            a.latency_median,
        ),
        (
            "line's Hausdorff distance, % of the diagonal (median)",
            |f| f.hausdorff_percent.map(|s| s.median),
            a.hausdorff_median_percent,
        ),
    ];
    let most_false = rows.iter().map(|r| r.all.false_cuts).max().unwrap_or(0) as f64;
    for (area, (name, metric, accepted)) in [left, right].iter().zip(panels) {
        let hi = rows
            .iter()
            .filter_map(|r| metric(&r.all))
            .filter(|v| v.is_finite())
            .fold(accepted, f64::max)
            * 1.15;
        let mut chart = ChartBuilder::on(area)
            .caption("false cuts against ".to_string() + name, ("sans-serif", 13))
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(44)
            .build_cartesian_2d(0.0..hi, -0.5..most_false + 1.0)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc(name)
            .y_desc("false cuts, every family")
            .draw()
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(0.0, -0.5), (accepted, 0.5)],
                GREEN.mix(0.2).filled(),
            )))
            .map_err(|e| e.to_string())?;
        for r in rows {
            let Some(x) = metric(&r.all).filter(|v| v.is_finite()) else {
                continue;
            };
            let y = r.all.false_cuts as f64;
            let colour = if r.defaults { RED } else { BLUE };
            let text = r
                .settings
                .iter()
                .map(|s| s.split_once(" = ").map_or(s.as_str(), |(_, v)| v))
                .collect::<Vec<_>>()
                .join(", ");
            // The label beside its point, in pixels, so that it stays legible at any scale.
            chart
                .draw_series(std::iter::once(
                    EmptyElement::at((x, y))
                        + Circle::new((0, 0), 4, colour.filled())
                        + Text::new(text, (6, -12), ("sans-serif", 10).into_font()),
                ))
                .map_err(|e| e.to_string())?;
        }
    }
    root.present().map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set(text: &str) -> DetectionSetting {
        DetectionSetting::parse(text).unwrap()
    }

    #[test]
    fn combinations_vary_the_first_field_slowest_after_the_fixed_ones() {
        let fixed = [set("init_points=6")];
        let swept = [
            DetectionSetting::parse_list("persistence=1,2").unwrap(),
            DetectionSetting::parse_list("outlier_sigmas=5,6,7").unwrap(),
        ];
        let all = combinations(&fixed, &swept);
        assert_eq!(all.len(), 6);
        assert!(all.iter().all(|c| c.len() == 3 && c[0] == fixed[0]));
        assert_eq!(all[0][1], set("persistence=1"));
        assert_eq!(all[2][2], set("outlier_sigmas=7"));
        assert_eq!(all[3][1], set("persistence=2"));
        assert_eq!(combinations(&[], &[]), vec![vec![]]);
    }

    #[test]
    fn a_setting_is_checked_like_the_scene_file() {
        let d = DetectionSection::default();
        assert_eq!(d.with(&set("persistence=1")).unwrap().persistence, 1);
        // An integer for a float field, as a person would type it.
        assert_eq!(
            d.with(&set("outlier_sigmas=5")).unwrap().outlier_sigmas,
            5.0
        );
        assert!(
            d.with(&set("persistance=1"))
                .unwrap_err()
                .contains("persistance")
        );
        assert!(d.with(&set("persistence=0")).is_err());
        assert!(d.with(&set("persistence=true")).is_err());
        assert!(DetectionSetting::parse("persistence").is_err());
        assert!(DetectionSetting::parse("persistence=").is_err());
        assert!(are_defaults(&[]).unwrap());
        assert!(are_defaults(&[set("persistence=2")]).unwrap());
        assert!(!are_defaults(&[set("persistence=1")]).unwrap());
    }
}
