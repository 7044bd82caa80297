//! The stability envelope in brief, as Markdown (`stability.md`, spliced into the README by
//! `docs/readme-report.sh`): what the cells came to, counted and compared from the data, so
//! that no figure of the README's "Stability" section is typed by hand.

use std::fmt::Write as _;

use super::Report;
use super::stability::{
    Block, CONVERGED_FRAMES, CONVERGED_REDUCTION, Cell, SCALES, Status, UNCUT_CHECK,
};
use crate::scene::Precision;

/// Typed errors listed one by one; the rest are counted.
const LISTED_ERRORS: usize = 8;

/// Mixed precision "matches" `f64` in a cell when its residual is within this factor of it.
const RESIDUAL_FACTOR: f64 = 10.0;

/// The target error of a cell over the rest model's.
fn ratio(c: &Cell) -> f64 {
    c.tre_mm_final / c.tre_mm_rest
}

/// `(min, max)` of `values` ignoring NaN; `None` if none is left.
fn range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values
        .filter(|v| !v.is_nan())
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((f64::min(lo, v), f64::max(hi, v))),
        })
}

/// A scale on the grid as a power of ten, `10⁻³` (or as it is, if it is none).
fn scale_label(s: f64) -> String {
    let exponent = s.log10().round();
    if s == 1.0 || (s / 10f64.powf(exponent) - 1.0).abs() > 1e-9 {
        return format!("{s}");
    }
    let digits: String = format!("{exponent}")
        .chars()
        .map(|c| match c {
            '-' => '⁻',
            '0' => '⁰',
            '1' => '¹',
            '2' => '²',
            '3' => '³',
            '4' => '⁴',
            '5' => '⁵',
            '6' => '⁶',
            '7' => '⁷',
            '8' => '⁸',
            _ => '⁹',
        })
        .collect();
    format!("10{digits}")
}

/// The whole of `stability.md`.
pub(super) fn stability_markdown(report: &Report) -> String {
    let cells: Vec<(&str, &Cell)> = report
        .scenes
        .iter()
        .flat_map(|s| s.stability.iter().map(move |c| (s.name.as_str(), c)))
        .collect();
    let mut s = String::new();
    let of = |block: Block| cells.iter().filter(move |(_, c)| c.block == block);
    let _ = writeln!(
        s,
        "{} cells on {} scenes ({} material, {} precision, {} tracking, {} deformation).\n",
        cells.len(),
        report.scenes.len(),
        of(Block::Material).count(),
        of(Block::Precision).count(),
        of(Block::Tracking).count(),
        of(Block::Deformation).count()
    );
    outcomes(&mut s, &cells);
    above_the_line(&mut s, &cells);
    material(&mut s, &cells);
    precision(&mut s, report);
    tracking(&mut s, report);
    deformation(&mut s, report);
    s
}

/// Failures and typed errors.
fn outcomes(s: &mut String, cells: &[(&str, &Cell)]) {
    let failures: Vec<_> = cells
        .iter()
        .filter(|(_, c)| c.status == Status::Failure)
        .collect();
    let typed: Vec<_> = cells
        .iter()
        .filter(|(_, c)| c.status == Status::TypedError)
        .collect();
    let _ = writeln!(
        s,
        "- **Failures (a NaN or ∞ position, or a panic): {}.** Typed errors (the core refused \
         frames and went on from where it was): {}.",
        failures.len(),
        typed.len()
    );
    for (scene, c) in failures.iter().chain(&typed).take(LISTED_ERRORS) {
        let _ = writeln!(
            s,
            "  - `{scene}`, {} block{}, E {:e} Pa, ν {}, springs × {}, {}, noise {} px, \
             outliers {:.0} %: {} ({} frames refused{})",
            c.block.label(),
            if c.barrier { "" } else { " (SVK alone)" },
            c.young,
            c.poisson,
            scale_label(c.k_scale),
            c.precision.name(),
            c.noise_px,
            100.0 * c.outliers,
            c.status.label(),
            c.frames_rejected,
            c.first_error
                .as_deref()
                .map_or(String::new(), |e| format!("; first: {e}"))
        );
    }
    let more = (failures.len() + typed.len()).saturating_sub(LISTED_ERRORS);
    if more > 0 {
        let _ = writeln!(s, "  - and {more} more (`stability.csv`).");
    }
}

/// The cells whose targets end above [`UNCUT_CHECK`] times the rest model's error: where,
/// and what the same runs reach with cutting off (the elastic solve alone).
fn above_the_line(s: &mut String, cells: &[(&str, &Cell)]) {
    let above: Vec<&(&str, &Cell)> = cells
        .iter()
        .filter(|(_, c)| c.tre_mm_final.is_nan() || ratio(c) > UNCUT_CHECK)
        .collect();
    let mut scenes: Vec<&str> = above.iter().map(|(n, _)| *n).collect();
    scenes.dedup();
    let _ = write!(
        s,
        "- **Above {UNCUT_CHECK} times the rest model's target error: {} of {} cells**",
        above.len(),
        cells.len()
    );
    if above.is_empty() {
        s.push_str(
            ".
",
        );
        return;
    }
    let names: Vec<String> = scenes.iter().map(|n| format!("`{n}`")).collect();
    let _ = write!(s, ", on {}", names.join(", "));
    let cut: Vec<&&(&str, &Cell)> = above
        .iter()
        .filter(|(_, c)| c.cut_detected_frame.is_some())
        .collect();
    let _ = write!(
        s,
        " ({} of them cut their mesh: a cut detected at frame {}",
        cut.len(),
        range(
            cut.iter()
                .map(|(_, c)| f64::from(c.cut_detected_frame.unwrap_or(0)))
        )
        .map_or("–".to_string(), |(lo, hi)| if lo == hi {
            format!("{lo}")
        } else {
            format!("{lo}–{hi}")
        })
    );
    let uncut = range(
        cut.iter()
            .map(|(_, c)| c.tre_mm_final_uncut / c.tre_mm_rest),
    );
    match uncut {
        Some((lo, hi)) => {
            let _ = write!(
                s,
                "; the same runs with cutting off end at {lo:.2}–{hi:.2} times the rest model's \
                 error"
            );
            s.push_str(if hi <= UNCUT_CHECK {
                ", so what puts them above the line is where their mesh was cut).\n"
            } else {
                ").\n"
            });
        }
        None => s.push_str(").\n"),
    }
}

/// The material block: `E` alone, the springs' scale, convergence by ν.
fn material(s: &mut String, cells: &[(&str, &Cell)]) {
    let block: Vec<&(&str, &Cell)> = cells
        .iter()
        .filter(|(_, c)| c.block == Block::Material)
        .collect();
    if block.is_empty() {
        return;
    }
    // The largest spread of the target error over E at one scene, ν and scale (`None` when
    // no scene has two values of E there).
    let mut spread: Option<f64> = None;
    for (scene, c) in &block {
        if let Some((lo, hi)) = range(
            block
                .iter()
                .filter(|(n, o)| {
                    n == scene
                        && o.poisson == c.poisson
                        && o.k_scale == c.k_scale
                        && o.young != c.young
                })
                .map(|(_, o)| o.tre_mm_final)
                .chain([c.tre_mm_final]),
        )
        .filter(|_| block.iter().any(|(n, o)| n == scene && o.young != c.young))
        {
            spread = Some(spread.unwrap_or(0.0).max(hi / lo - 1.0));
        }
    }
    let youngs = range(block.iter().map(|(_, c)| c.young));
    if let (Some(spread), Some((lo, hi))) = (spread, youngs) {
        let _ = writeln!(
            s,
            "- **Young's modulus alone** ({lo:e} to {hi:e} Pa, the springs following it): at one \
             scene, ν and spring scale, the target errors differ by at most {:.1} %.",
            100.0 * spread
        );
    }
    let _ = write!(
        s,
        "- **The springs' stiffness relative to the material** (target error over the rest \
         model's, smallest to largest over the scenes, E and ν):"
    );
    for scale in SCALES {
        if let Some((lo, hi)) = range(
            block
                .iter()
                .filter(|(_, c)| c.k_scale == scale)
                .map(|(_, c)| ratio(c)),
        ) {
            let _ = write!(s, " × {}: {lo:.2}–{hi:.2};", scale_label(scale));
        }
    }
    s.pop();
    s.push_str(".\n");
    let mut poissons: Vec<f64> = block.iter().map(|(_, c)| c.poisson).collect();
    poissons.sort_by(f64::total_cmp);
    poissons.dedup();
    let converged = block
        .iter()
        .filter(|(_, c)| c.status == Status::Converged)
        .count();
    let _ = write!(
        s,
        "- **Convergence** (at least {:.0} % of the frames reduce the gradient to {} of its \
         start, with the scene's own solver setting): {converged} of {} cells;",
        100.0 * CONVERGED_FRAMES,
        CONVERGED_REDUCTION,
        block.len()
    );
    for nu in poissons {
        let at: Vec<_> = block.iter().filter(|(_, c)| c.poisson == nu).collect();
        let _ = write!(
            s,
            " {} of {} at ν = {nu},",
            at.iter()
                .filter(|(_, c)| c.status == Status::Converged)
                .count(),
            at.len()
        );
    }
    s.pop();
    s.push_str(".\n");
}

/// The precision block: the residual each scalar type reaches, per scene, ν and scale.
fn precision(s: &mut String, report: &Report) {
    let mut rows = String::new();
    let (mut compared, mut mixed_match, mut single_match) = (0, 0, 0);
    let mut scales: Vec<f64> = vec![];
    for scene in &report.scenes {
        let block: Vec<&Cell> = scene
            .stability
            .iter()
            .filter(|c| c.block == Block::Precision)
            .collect();
        for c in &block {
            if !scales.contains(&c.k_scale) {
                scales.push(c.k_scale);
            }
        }
        let mut poissons: Vec<f64> = vec![];
        for c in &block {
            if !poissons.contains(&c.poisson) {
                poissons.push(c.poisson);
            }
        }
        for nu in poissons {
            let _ = write!(rows, "| {} | {nu} |", scene.name);
            for &scale in &scales {
                let find = |p: Precision| {
                    block
                        .iter()
                        .find(|c| c.poisson == nu && c.k_scale == scale && c.precision == p)
                        .map(|c| (c.relative_gradient, c.status))
                };
                let text = |v: Option<(f64, Status)>| match v {
                    Some((g, Status::Converged | Status::NotConverged)) => format!("{g:.0e}"),
                    Some((_, status)) => status.label().to_string(),
                    None => "–".into(),
                };
                let (double, mixed, single) = (
                    find(Precision::F64),
                    find(Precision::Mixed),
                    find(Precision::F32),
                );
                // Cells where `f64` solved every frame; a refused frame in the other type
                // counts as not reaching it.
                let solved =
                    |status: Status| matches!(status, Status::Converged | Status::NotConverged);
                if let Some((d, _)) = double.filter(|&(_, status)| solved(status)) {
                    let close = |v: Option<(f64, Status)>| {
                        v.is_some_and(|(g, status)| {
                            solved(status) && g <= RESIDUAL_FACTOR * d.max(f64::MIN_POSITIVE)
                        })
                    };
                    compared += 1;
                    mixed_match += usize::from(close(mixed));
                    single_match += usize::from(close(single));
                }
                let _ = write!(
                    rows,
                    " {} / {} / {} |",
                    text(double),
                    text(mixed),
                    text(single)
                );
            }
            rows.push('\n');
        }
    }
    if compared == 0 {
        return;
    }
    let _ = writeln!(
        s,
        "- **Precision** (each frame solved by {} Newton steps of `Refactor`; the median over \
         the frames of the gradient at the frame's end over its start, as the model computes \
         it in its own type): of the {compared} cells where `f64` solves every frame, mixed \
         precision ends within {RESIDUAL_FACTOR}× of its residual in {mixed_match}, plain \
         `f32` in {single_match}.\n",
        super::stability::PRECISION_NEWTON
    );
    s.push_str("| scene | ν |");
    for &scale in &scales {
        let _ = write!(s, " springs × {}: f64 / mixed / f32 |", scale_label(scale));
    }
    s.push_str("\n| --- | ---: |");
    for _ in &scales {
        s.push_str(" ---: |");
    }
    s.push('\n');
    s.push_str(&rows);
    s.push('\n');
}

/// The tracking block: target error over the rest model's against noise and outliers.
fn tracking(s: &mut String, report: &Report) {
    let mut columns: Vec<(f64, f64)> = vec![];
    for c in report
        .scenes
        .iter()
        .flat_map(|s| &s.stability)
        .filter(|c| c.block == Block::Tracking)
    {
        if !columns.contains(&(c.noise_px, c.outliers)) {
            columns.push((c.noise_px, c.outliers));
        }
    }
    if columns.is_empty() {
        return;
    }
    s.push_str(
        "- **Tracking** (the scene's own material, springs and solver; Gaussian noise on every \
         tracked position, a fraction of the observations of every frame after the first \
         moved 20 to 60 px, positions leaving the image dropped): target error over the rest \
         model's, `f64` / `f32`.\n\n| scene |",
    );
    for (noise, outliers) in &columns {
        let _ = write!(s, " {noise} px, {:.0} % |", 100.0 * outliers);
    }
    push_rule(s, columns.len());
    for scene in &report.scenes {
        let _ = write!(s, "| {} |", scene.name);
        for &(noise, outliers) in &columns {
            let find = |p: Precision| {
                scene
                    .stability
                    .iter()
                    .find(|c| {
                        c.block == Block::Tracking
                            && c.noise_px == noise
                            && c.outliers == outliers
                            && c.precision == p
                    })
                    .map_or("–".to_string(), |c| match c.status {
                        Status::Converged | Status::NotConverged => format!("{:.2}", ratio(c)),
                        status => status.label().to_string(),
                    })
            };
            let _ = write!(s, " {} / {} |", find(Precision::F64), find(Precision::F32));
        }
        s.push('\n');
    }
}

/// The deformation block: mirrored frames (elements pulled inside out) and compression.
fn deformation(s: &mut String, report: &Report) {
    let label = |c: &Cell| {
        if !c.barrier {
            format!("mirrored, springs × {}, SVK alone", scale_label(c.k_scale))
        } else if c.compression.is_nan() {
            format!("mirrored, springs × {}", scale_label(c.k_scale))
        } else {
            format!("squeezed to {:.0} %", 100.0 * c.compression)
        }
    };
    let mut columns: Vec<String> = vec![];
    for c in report
        .scenes
        .iter()
        .flat_map(|s| &s.stability)
        .filter(|c| c.block == Block::Deformation)
    {
        if !columns.contains(&label(c)) {
            columns.push(label(c));
        }
    }
    if columns.is_empty() {
        return;
    }
    let mirrored = report
        .scenes
        .iter()
        .flat_map(|s| &s.stability)
        .find(|c| c.block == Block::Deformation && c.mirrored_frames > 0)
        .map_or(0, |c| c.mirrored_frames);
    let _ = write!(
        s,
        "- **Deformation** (the scene's own material and solver; *mirrored*: the observations \
         of the {mirrored} frames after frame 0 mirrored left to right, so that the springs pull \
         the model through itself, then the true tracks again, with cutting off (with it on, \
         every scene's detector starts a false cut from those frames); *squeezed*: variants of `{}` \
         generated with the block pushed to a fraction of its length; every column with the \
         inversion barrier but *SVK alone*): target error over the rest model's, and the most \
         tetrahedra inside out after any frame → after the last, `f64` / `f32`.\n\n| scene |",
        super::stability::COMPRESSION_BASE
    );
    for c in &columns {
        let _ = write!(s, " {c} |");
    }
    push_rule(s, columns.len());
    for scene in &report.scenes {
        let _ = write!(s, "| {} |", scene.name);
        for column in &columns {
            let find = |p: Precision| {
                scene
                    .stability
                    .iter()
                    .find(|c| {
                        c.block == Block::Deformation && &label(c) == column && c.precision == p
                    })
                    .map_or("–".to_string(), |c| match c.status {
                        Status::Converged | Status::NotConverged => format!(
                            "{:.2} ({} → {})",
                            ratio(c),
                            c.inverted_max,
                            c.inverted_final
                        ),
                        status => status.label().to_string(),
                    })
            };
            let _ = write!(s, " {} / {} |", find(Precision::F64), find(Precision::F32));
        }
        s.push('\n');
    }
}

/// Ends a table's header row and writes its rule: the scene column, then `columns` numeric ones.
fn push_rule(s: &mut String, columns: usize) {
    s.push_str("\n| --- |");
    s.push_str(&" ---: |".repeat(columns));
    s.push('\n');
}
