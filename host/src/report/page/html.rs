//! Writing the report: `index.html` (self-contained: figures inline), the figures as SVG and
//! the data as CSV and `report.json`.

use std::fmt::Write as _;
use std::path::Path;

use super::stability::{self, Block, Cell, Status};
use super::{Report, SceneReport, figures, findings, steady_median};
use crate::scene::Precision;

/// Writes every file of `report` into `out` (which exists).
///
/// # Errors
/// A message naming the file that could not be written.
pub(super) fn write(report: &Report, out: &Path) -> Result<(), String> {
    let counting = report
        .scenes
        .iter()
        .any(|s| !s.instructions_per_frame.is_empty());
    let mut figures_of = vec![];
    for scene in &report.scenes {
        let cost = out.join(format!("error_vs_cost_{}.svg", scene.name));
        figures::error_vs_cost(scene, counting, &cost).map_err(|e| at(&cost, &e))?;
        let frames = if scene.instructions_per_frame.is_empty() {
            None
        } else {
            let path = out.join(format!("instructions_{}.svg", scene.name));
            let median = steady_median(&scene.instructions_per_frame, &scene.cut_frames);
            figures::instructions_per_frame(scene, median, &path).map_err(|e| at(&path, &e))?;
            Some(path)
        };
        figures_of.push((cost, frames));
    }
    let growth = match &report.scaling {
        Some(scaling) => {
            let path = out.join("cost_growth.svg");
            figures::cost_growth(scaling, &path).map_err(|e| at(&path, &e))?;
            Some(path)
        }
        None => None,
    };
    let files: [(&str, String); 10] = [
        ("growth.md", growth_markdown(report)),
        ("resolution.md", resolution_markdown(report)),
        ("stability.csv", stability_csv(report)),
        ("stability.md", findings::stability_markdown(report)),
        ("summary.md", summary_markdown(report)),
        ("error_vs_cost.csv", error_vs_cost_csv(report)),
        ("worst_case.csv", worst_case_csv(report)),
        ("instructions.csv", instructions_csv(report)),
        ("memory.csv", memory_csv(report)),
        (
            "report.json",
            serde_json::to_string_pretty(report).map_err(|e| e.to_string())?,
        ),
    ];
    for (name, text) in &files {
        let path = out.join(name);
        std::fs::write(&path, text).map_err(|e| at(&path, &e.to_string()))?;
    }
    let page = page(report, &figures_of, growth.as_deref())?;
    let path = out.join("index.html");
    std::fs::write(&path, page).map_err(|e| at(&path, &e.to_string()))
}

fn at(path: &Path, e: &str) -> String {
    format!("{}: {e}", path.display())
}

/// `s` with the characters HTML gives a meaning escaped.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// An SVG file's text, to put inline (its XML declaration dropped).
fn inline_svg(path: &Path) -> Result<String, String> {
    let text = std::fs::read_to_string(path).map_err(|e| at(path, &e.to_string()))?;
    let start = text.find("<svg").unwrap_or(0);
    Ok(format!(
        "<figure>{}<figcaption>{}</figcaption></figure>",
        &text[start..],
        esc(&path
            .file_name()
            .map_or(String::new(), |n| n.to_string_lossy().to_string()))
    ))
}

/// The page in brief, as Markdown (for the README): per scene its own setting and the
/// recommended one with their cost and errors, the steady frames' spread of instructions, the
/// largest ratio of a work counter to its formula, and the model's storage.
pub(super) fn summary_markdown(report: &Report) -> String {
    let mut s = String::from(
        "| scene | own setting | instructions / frame (M) | Dice | TRE mm | recommended | instructions / frame (M) | Dice | TRE mm | own setting in f32: instructions / frame (M), Dice − f64, TRE − f64 mm | own setting in mixed precision: the same | steady max / median (per topology) | counted / formula (max) | stability cells: converged / not / typed error / failure | cells with TRE > 1.2 × rest | storage KiB |\n\
         | --- | --- | ---: | ---: | ---: | --- | ---: | ---: | ---: | --- | --- | ---: | ---: | ---: | ---: | ---: |\n",
    );
    let millions = |v: Option<f64>| v.map_or("–".to_string(), |v| format!("{:.1}", v / 1e6));
    for scene in &report.scenes {
        let Some(own) = scene.settings.iter().find(|r| r.own) else {
            continue;
        };
        let rec = scene.recommended.map(|r| &scene.settings[r]);
        let against_own = |precision: Precision| {
            scene
                .settings
                .iter()
                .find(|r| r.precision == precision)
                .map_or("–".to_string(), |r| {
                    format!(
                        "{}, {:+.4}, {:+.3}",
                        millions(r.instructions_median),
                        r.dice_final - own.dice_final,
                        r.tre_mm_final - own.tre_mm_final
                    )
                })
        };
        let (single, mixed) = (against_own(Precision::F32), against_own(Precision::Mixed));
        let worst = scene
            .worst_case
            .iter()
            .chain(&scene.cut_events)
            .map(|r| r.max_over_formula)
            .fold(0.0, f64::max);
        let total: usize = scene.memory.iter().map(|m| m.bytes).sum();
        let count = |status: Status| {
            scene
                .stability
                .iter()
                .filter(|c| c.status == status)
                .count()
        };
        let statuses = format!(
            "{} / {} / {} / {}",
            count(Status::Converged),
            count(Status::NotConverged),
            count(Status::TypedError),
            count(Status::Failure)
        );
        let worse = scene
            .stability
            .iter()
            .filter(|c| c.tre_mm_final.is_nan() || c.tre_mm_final > 1.2 * c.tre_mm_rest)
            .count();
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.3} | {:.2} | {} | {} | {} | {} | {single} | {mixed} | {} | {worst:.3} | {statuses} | {worse} of {} | {:.0} |",
            scene.name,
            own.label,
            millions(own.instructions_median),
            own.dice_final,
            own.tre_mm_final,
            rec.map_or("–".to_string(), |r| r.label.clone()),
            millions(rec.and_then(|r| r.instructions_median)),
            rec.map_or("–".to_string(), |r| format!("{:.3}", r.dice_final)),
            rec.map_or("–".to_string(), |r| format!("{:.2}", r.tre_mm_final)),
            scene
                .steady_max_over_median
                .map_or("–".to_string(), |r| format!("{r:.3}")),
            scene.stability.len(),
            total as f64 / 1024.0
        );
    }
    s
}

fn stability_csv(report: &Report) -> String {
    let mut s = String::from(
        "scene,block,young_pa,poisson,k_scale,precision,noise_px,outliers,compression,mirrored_frames,barrier,spring_stiffness,status,frames_rejected,first_error,converged_frames,relative_gradient,min_pivot,pivot_ratio,inverted_max,inverted_final,dice_final,tre_mm_final,tre_mm_rest,cut_detected_frame,tre_mm_final_uncut\n",
    );
    for scene in &report.scenes {
        for c in &scene.stability {
            let _ = writeln!(
                s,
                "{},{},{:e},{},{:e},{},{},{},{},{},{},{:e},{},{},\"{}\",{:.3},{:e},{:e},{:e},{},{},{:.5},{:.4},{:.4},{},{:.4}",
                scene.name,
                c.block.label(),
                c.young,
                c.poisson,
                c.k_scale,
                c.precision.name(),
                c.noise_px,
                c.outliers,
                c.compression,
                c.mirrored_frames,
                c.barrier,
                c.spring_stiffness,
                c.status.label(),
                c.frames_rejected,
                c.first_error.as_deref().unwrap_or("").replace('"', "'"),
                c.converged_frames,
                c.relative_gradient,
                c.min_pivot,
                c.pivot_ratio,
                c.inverted_max,
                c.inverted_final,
                c.dice_final,
                c.tre_mm_final,
                c.tre_mm_rest,
                c.cut_detected_frame
                    .map_or(String::new(), |f| f.to_string()),
                c.tre_mm_final_uncut
            );
        }
    }
    s
}

/// A row's or a column's label of a cell.
type CellKey = fn(&Cell) -> String;

/// One block of a scene's stability grid as a table: a row per `row` key, a column per
/// `column` key (each in the order first met); each cell coloured by its status and showing the
/// target error over the rest model's and, in the precision block, the median relative
/// gradient at the frames' end.
fn stability_table(h: &mut String, scene: &SceneReport, block: Block) {
    let cells: Vec<&Cell> = scene
        .stability
        .iter()
        .filter(|c| c.block == block)
        .collect();
    if cells.is_empty() {
        return;
    }
    let (corner, row, column): (&str, CellKey, CellKey) = match block {
        Block::Material => (
            "E Pa, ν \\ k / k<sub>scene</sub>",
            |c| format!("{:e}, {}", c.young, c.poisson),
            |c| format!("{:e}", c.k_scale),
        ),
        Block::Precision => (
            "scalar type, ν \\ k / k<sub>scene</sub>",
            |c| format!("{}, {}", c.precision.name(), c.poisson),
            |c| format!("{:e}", c.k_scale),
        ),
        Block::Tracking => (
            "scalar type, noise px \\ outliers",
            |c| format!("{}, {}", c.precision.name(), c.noise_px),
            |c| format!("{:.0} %", 100.0 * c.outliers),
        ),
        Block::Deformation => (
            "scalar type \\ deformation",
            |c| c.precision.name().to_string(),
            |c| {
                if !c.barrier {
                    format!(
                        "{} frames mirrored, k × {:e}, SVK alone",
                        c.mirrored_frames, c.k_scale
                    )
                } else if c.compression.is_nan() {
                    format!("{} frames mirrored, k × {:e}", c.mirrored_frames, c.k_scale)
                } else {
                    format!("squeezed to {:.0} %", 100.0 * c.compression)
                }
            },
        ),
    };
    let mut rows: Vec<String> = vec![];
    let mut columns: Vec<String> = vec![];
    for c in &cells {
        for (keys, key) in [(&mut rows, row(c)), (&mut columns, column(c))] {
            if !keys.contains(&key) {
                keys.push(key);
            }
        }
    }
    let _ = write!(h, "<table><tr><th>{corner}</th>");
    for k in &columns {
        let _ = write!(h, "<th>{k}</th>");
    }
    h.push_str("</tr>");
    for r in &rows {
        let _ = write!(h, "<tr><td>{r}</td>");
        for k in &columns {
            let Some(c) = cells.iter().find(|c| &row(c) == r && &column(c) == k) else {
                h.push_str("<td></td>");
                continue;
            };
            let colour = match c.status {
                Status::Converged => "#d8f0d8",
                Status::NotConverged => "#fff2c0",
                Status::TypedError => "#d8e4f8",
                Status::Failure => "#f8c8c8",
            };
            let residual = match block {
                Block::Precision => format!("<br>gradient {:.0e}", c.relative_gradient),
                Block::Deformation => {
                    format!("<br>inverted {} → {}", c.inverted_max, c.inverted_final)
                }
                Block::Material | Block::Tracking => String::new(),
            };
            let _ = write!(
                h,
                "<td style=\"background:{colour}\" title=\"{}; converged frames {:.0} %; \
                 median gradient at the end over the start {:.1e}; smallest pivot {:.2e}; \
                 pivot ratio {:.2e}; Dice {:.3}; target error {:.2} mm (rest {:.2} mm){}{}\">{}\
                 <br>{:.2}× rest{residual}</td>",
                c.status.label(),
                100.0 * c.converged_frames,
                c.relative_gradient,
                c.min_pivot,
                c.pivot_ratio,
                c.dice_final,
                c.tre_mm_final,
                c.tre_mm_rest,
                if c.tre_mm_final_uncut.is_nan() {
                    String::new()
                } else {
                    format!("; cutting off: {:.2} mm", c.tre_mm_final_uncut)
                },
                c.first_error
                    .as_deref()
                    .map_or(String::new(), |e| format!("; {}", esc(e))),
                c.status.label(),
                c.tre_mm_final / c.tre_mm_rest
            );
        }
        h.push_str("</tr>");
    }
    h.push_str("</table>");
}

fn error_vs_cost_csv(report: &Report) -> String {
    let mut s = String::from(
        "scene,setting,strategy,newton,pcg,line_search,precision,own,on_front,recommended,dice_final,dice_mean_after_cut,tre_mm_final,surface_mm_final,ms_median,ms_max,instructions_median,instructions_frames\n",
    );
    for scene in &report.scenes {
        for (i, r) in scene.settings.iter().enumerate() {
            let _ = writeln!(
                s,
                "{},\"{}\",{},{},{},{},{},{},{},{},{:.5},{:.5},{:.4},{:.4},{:.4},{:.4},{},{}",
                scene.name,
                r.label,
                r.strategy,
                r.newton,
                r.pcg,
                r.line_search,
                r.precision.name(),
                r.own,
                scene.front.contains(&i),
                scene.recommended == Some(i),
                r.dice_final,
                r.dice_mean_after_cut,
                r.tre_mm_final,
                r.surface_mm_final,
                r.ms_median,
                r.ms_max,
                r.instructions_median
                    .map_or(String::new(), |v| format!("{v:.0}")),
                r.instructions_frames
            );
        }
    }
    s
}

fn worst_case_csv(report: &Report) -> String {
    let mut s = String::from("scene,kind,stage,counter,formula,max,median,max_over_formula\n");
    for scene in &report.scenes {
        for (kind, rows) in [
            ("frame", &scene.worst_case),
            ("cut event", &scene.cut_events),
        ] {
            for r in rows {
                let _ = writeln!(
                    s,
                    "{},{kind},{},{},{},{},{:.1},{:.4}",
                    scene.name, r.stage, r.counter, r.formula, r.max, r.median, r.max_over_formula
                );
            }
        }
    }
    s
}

fn instructions_csv(report: &Report) -> String {
    let mut s = String::from("scene,frame,instructions,cuts_the_mesh\n");
    for scene in &report.scenes {
        for (k, c) in scene.instructions_per_frame.iter().enumerate() {
            let _ = writeln!(
                s,
                "{},{},{c},{}",
                scene.name,
                k + 1,
                scene.cut_frames.contains(&(k + 1))
            );
        }
    }
    s
}

fn memory_csv(report: &Report) -> String {
    let mut s = String::from("scene,part,grows_with,bytes\n");
    for scene in &report.scenes {
        for m in &scene.memory {
            let _ = writeln!(
                s,
                "{},\"{}\",\"{}\",{}",
                scene.name, m.part, m.grows_with, m.bytes
            );
        }
    }
    s
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1060px;margin:2em auto;padding:0 1em;color:#222}\
table{border-collapse:collapse;margin:0.8em 0;font-size:0.9em}\
td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}\
td:first-child,th:first-child,td.text,th.text{text-align:left}\
tr.front td{background:#eef6ee}tr.rec td{font-weight:bold}\
figure{margin:1em 0}figcaption{font-size:0.8em;color:#666}\
.note{background:#fff8e0;border:1px solid #e0c060;padding:0.5em 1em}\
svg{max-width:100%;height:auto}";

/// The page.
fn page(
    report: &Report,
    figures_of: &[(std::path::PathBuf, Option<std::path::PathBuf>)],
    growth: Option<&Path>,
) -> Result<String, String> {
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>incise report</title><style>{STYLE}</style></head><body>\
         <h1>incise report</h1><p>Scenes: {}. {}</p>",
        report
            .scenes
            .iter()
            .map(|s| esc(&s.name))
            .collect::<Vec<_>>()
            .join(", "),
        if report.quick {
            "Made with <code>--quick</code>: two settings per scene and a few frames counted."
        } else {
            ""
        }
    );
    // 1. Error against run time.
    let _ = write!(
        h,
        "<h2 id=\"error\">1. Error against run time</h2><p>Each scene under several solver \
         settings: Dice and target error of the last frame against the cost of a steady frame. \
         Instructions are {}. The Pareto front (no other setting is cheaper, more accurate in \
         3D and in Dice at once) is shaded; the recommended setting, in bold, is {}.</p>",
        esc(&report.instructions),
        esc(report.recommendation_rule)
    );
    for (scene, (cost, _)) in report.scenes.iter().zip(figures_of) {
        let _ = write!(h, "<h3>{}</h3>", esc(&scene.name));
        if let Some(r) = scene.recommended {
            let _ = write!(
                h,
                "<p>Recommended: <b>{}</b>{}.</p>",
                esc(&scene.settings[r].label),
                if scene.settings[r].own {
                    " (the scene's own setting)"
                } else {
                    ""
                }
            );
        }
        h.push_str(&inline_svg(cost)?);
        settings_table(&mut h, scene);
    }
    if !report.resolution.is_empty() {
        h.push_str(
            "<h3 id=\"resolution\">Mesh resolution</h3><p>The same object, truth and tracks, \
             modelled by three meshes: the scene's own, that mesh refined (every tetrahedron \
             into eight, new nodes at the edge midpoints) and the real object's own fine mesh \
             (before its slit; for the liver, SOFA's fine liver), each run with the scene's \
             own setting and cut capacities grown with the cut's area in elements.</p>",
        );
        h.push_str(&html_table(&resolution_rows(report)));
    }
    // 2. Worst case.
    h.push_str(
        "<h2 id=\"worst\">2. Worst case</h2><p>With each scene's own setting: every work \
         counter of the core in every frame against its formula in the scene's sizes \
         (<code>Model::worst_case_work</code>, <code>worst_case_detection_work</code>, \
         <code>worst_case_cut_work</code>), evaluated for the topology the frame starts \
         with. A ratio above 1 would be a broken formula. Cut events are reported apart.</p>",
    );
    for (scene, (_, frames)) in report.scenes.iter().zip(figures_of) {
        let _ = write!(h, "<h3>{}</h3>", esc(&scene.name));
        if let Some(r) = scene.steady_max_over_median {
            let _ = write!(
                h,
                "<p>Instructions of a steady frame: largest / median = {r:.3} within a topology \
                 (the frames between two cut events; the largest over the topologies) over {} frames \
                 ({} cutting the mesh: {}).</p>",
                scene.instructions_per_frame.len(),
                scene.cut_frames.len(),
                scene
                    .cut_frames
                    .iter()
                    .map(ToString::to_string)
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        if let Some(path) = frames {
            h.push_str(&inline_svg(path)?);
        }
        work_table(&mut h, "A frame", &scene.worst_case);
        if !scene.cut_events.is_empty() {
            work_table(&mut h, "A cut event", &scene.cut_events);
        }
    }
    // How the cost grows.
    if let (Some(scaling), Some(path)) = (&report.scaling, growth) {
        let _ = write!(
            h,
            "<h3 id=\"growth\">How the cost grows</h3><p>Variants of <code>{}</code> \
             generated at four model resolutions (300 features) and four feature counts (the \
             committed resolution), run with the scene's own setting: the {} against the \
             model's nodes and the features, with the exponent of a power law fitted to the \
             logarithms (nodes: {}, features: {}).{}</p>",
            super::scaling::BASE,
            esc(scaling.cost),
            scaling
                .nodes_exponent
                .map_or("–".into(), |b| format!("{b:.2}")),
            scaling
                .features_exponent
                .map_or("–".into(), |b| format!("{b:.2}")),
            match (&scaling.largest, scaling.nodes_exponent_with_largest) {
                (Some(l), Some(b)) => format!(
                    " Beyond them on the node axis (the triangle): <code>{}</code> modelled by \
                     {} mesh, {} nodes, the largest model of the mesh-resolution table; with \
                     it the fitted exponent is {b:.2}.",
                    esc(&l.scene),
                    esc(&l.mesh),
                    l.nodes
                ),
                _ => String::new(),
            }
        );
        h.push_str(&inline_svg(path)?);
        h.push_str(
            "<table><tr><th>nodes</th><th>features</th><th>instructions / frame (M)</th>\
             <th>ms / frame</th></tr>",
        );
        let base = scaling.nodes.first().map(|p| (p.nodes, p.features));
        let others = scaling
            .features
            .iter()
            .filter(|p| Some((p.nodes, p.features)) != base);
        for p in scaling.nodes.iter().chain(others) {
            let _ = write!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.2}</td></tr>",
                p.nodes,
                p.features,
                p.instructions
                    .map_or("–".into(), |v| format!("{:.1}", v / 1e6)),
                p.ms_median
            );
        }
        h.push_str("</table>");
    }
    // 3. Stability.
    let _ = write!(
        h,
        "<h2 id=\"stability\">3. Stability envelope</h2><p>Each scene with cutting on, in four \
         blocks of cells. <b>Material</b>: Young's modulus E × Poisson ratio ν × spring stiffness \
         k (as a multiple of the scene's own coupling, k relative to E and the feature spacing, \
         so that E alone tests the numerics and the multiple tests the coupling), in \
         <code>f64</code>. <b>Precision</b>: the scene's own E, its own ν and 0.499, the same \
         spring multiples, in <code>f64</code>, <code>f32</code> and mixed precision (an \
         <code>f32</code> factor refined on the <code>f64</code> residual); each cell also \
         shows the median over the frames of the gradient at the frame's end over its start, \
         as the model computes it in its own type. <b>Tracking</b>: the scene's own material \
         and springs, its tracks with Gaussian noise added (σ in pixels) and a fraction of the \
         observations of every frame after the first moved 20 to 60 px (outliers), in \
         <code>f64</code> and <code>f32</code>. <b>Deformation</b>, in <code>f64</code> and \
         <code>f32</code>: the observations of the first {} frames after frame 0 mirrored left \
         to right, so that the springs pull the model through itself before the true tracks \
         return, with cutting off (with it on, every scene's detector starts a false cut from \
         those frames) (each cell shows the most elements inside out after any frame → after the \
         last; the <i>SVK alone</i> column is the same run without the inversion barrier), and \
         on <code>{}</code> variants generated with the block squeezed to 90, 75 \
         and 60 % of its length. A cell is <b>converged</b> when every position \
         stays finite, no frame is refused and the gradient falls to {} of its start in at \
         least {:.0} % of the frames; <b>not converged</b> otherwise; <b>typed error</b> when \
         the core refused frames (the model going on as it was); <b>failure</b> on a \
         non-finite position or a panic. Each cell shows the last frame's target error over the \
         rest model's (above 1: the registration places the targets worse than not moving); \
         hover for the pivots, Dice and the first error.</p>",
        stability::MIRRORED_FRAMES,
        stability::COMPRESSION_BASE,
        stability::CONVERGED_REDUCTION,
        100.0 * stability::CONVERGED_FRAMES
    );
    for scene in &report.scenes {
        let _ = write!(h, "<h3>{}</h3>", esc(&scene.name));
        for block in [
            Block::Material,
            Block::Precision,
            Block::Tracking,
            Block::Deformation,
        ] {
            let _ = write!(h, "<h4>{}</h4>", block.label());
            stability_table(&mut h, scene, block);
        }
    }
    // 4. Memory.
    h.push_str(
        "<h2 id=\"memory\">4. Memory</h2><p>The static storage of each scene's model as the \
         core sizes it (<code>ModelSize::parts</code>, f64 scalars and u32 indices), from the \
         scene's capacities: what a firmware build reserves.</p>",
    );
    memory_table(&mut h, report);
    h.push_str(
        "<p>Data: <code>error_vs_cost.csv</code>, <code>worst_case.csv</code>, \
         <code>instructions.csv</code>, <code>stability.csv</code>, <code>memory.csv</code>, \
         <code>report.json</code>; \
         in brief, <code>summary.md</code>.</p>\
         </body></html>\n",
    );
    Ok(h)
}

fn settings_table(h: &mut String, scene: &SceneReport) {
    h.push_str(
        "<table><tr><th>setting</th><th>instructions / frame (M)</th><th>ms / frame</th>\
         <th>ms max</th><th>Dice</th><th>Dice after cut</th><th>target error mm</th>\
         <th>surface mm</th></tr>",
    );
    for (i, r) in scene.settings.iter().enumerate() {
        let class = match (scene.recommended == Some(i), scene.front.contains(&i)) {
            (true, _) => " class=\"front rec\"",
            (false, true) => " class=\"front\"",
            _ => "",
        };
        let _ = write!(
            h,
            "<tr{class}><td>{}{}</td><td>{}</td><td>{:.2}</td><td>{:.2}</td><td>{:.4}</td>\
             <td>{:.4}</td><td>{:.2}</td><td>{:.2}</td></tr>",
            esc(&r.label),
            if r.own { " (own)" } else { "" },
            r.instructions_median
                .map_or("–".into(), |v| format!("{:.2}", v / 1e6)),
            r.ms_median,
            r.ms_max,
            r.dice_final,
            r.dice_mean_after_cut,
            r.tre_mm_final,
            r.surface_mm_final
        );
    }
    h.push_str("</table>");
}

fn work_table(h: &mut String, title: &str, rows: &[super::WorstCaseRow]) {
    let _ = write!(
        h,
        "<table><tr><th>{title}: stage, counter</th><th>formula</th><th>counted max</th>\
         <th>counted median</th><th>max / formula</th></tr>"
    );
    for r in rows {
        let _ = write!(
            h,
            "<tr><td>{}, {}</td><td>{}</td><td>{}</td><td>{:.0}</td><td>{:.3}</td></tr>",
            r.stage, r.counter, r.formula, r.max, r.median, r.max_over_formula
        );
    }
    h.push_str("</table>");
}

fn memory_table(h: &mut String, report: &Report) {
    let Some(first) = report.scenes.first() else {
        return;
    };
    h.push_str("<table><tr><th>part, KiB</th>");
    for s in &report.scenes {
        let _ = write!(h, "<th>{}</th>", esc(&s.name));
    }
    h.push_str("<th class=\"text\">grows with</th></tr>");
    for (k, part) in first.memory.iter().enumerate() {
        let _ = write!(h, "<tr><td>{}</td>", esc(part.part));
        for s in &report.scenes {
            let _ = write!(
                h,
                "<td>{}</td>",
                s.memory
                    .get(k)
                    .map_or("–".into(), |m| format!("{:.1}", m.bytes as f64 / 1024.0))
            );
        }
        let _ = write!(h, "<td class=\"text\">{}</td></tr>", esc(part.grows_with));
    }
    h.push_str("<tr><td>total</td>");
    for s in &report.scenes {
        let total: usize = s.memory.iter().map(|m| m.bytes).sum();
        let _ = write!(h, "<td>{:.1}</td>", total as f64 / 1024.0);
    }
    h.push_str("<td></td></tr></table>");
}

/// The mesh-resolution axis as rows of cells (a header row first).
fn resolution_rows(report: &Report) -> Vec<Vec<String>> {
    let mut rows = vec![
        [
            "scene",
            "model mesh",
            "nodes",
            "tetrahedra",
            "Dice uncut",
            "Dice",
            "TRE rest mm",
            "TRE mm",
            "surface mm",
            "ms / frame",
            "instructions / frame (M)",
            "model MB",
        ]
        .map(String::from)
        .to_vec(),
    ];
    for r in &report.resolution {
        for m in &r.models {
            rows.push(vec![
                r.scene.clone(),
                format!(
                    "{}{}",
                    m.mesh,
                    m.cut_refused
                        .as_ref()
                        .map_or(String::new(), |_| " (a cut refused)".into())
                ),
                m.nodes.to_string(),
                m.tets.to_string(),
                format!("{:.3}", m.dice_final_uncut),
                format!("{:.3}", m.dice_final),
                format!("{:.2}", m.tre_mm_rest),
                format!("{:.2}", m.tre_mm_final),
                format!("{:.2}", m.surface_mm_final),
                format!("{:.1}", m.ms_steady),
                m.instructions
                    .map_or("–".into(), |v| format!("{:.1}", v / 1e6)),
                format!("{:.1}", m.model_bytes as f64 / 1e6),
            ]);
        }
    }
    rows
}

/// `rows` (a header first) as an HTML table.
fn html_table(rows: &[Vec<String>]) -> String {
    let mut h = String::from("<table>");
    for (i, row) in rows.iter().enumerate() {
        h.push_str("<tr>");
        for cell in row {
            let tag = if i == 0 { "th" } else { "td" };
            let _ = write!(h, "<{tag}>{}</{tag}>", esc(cell));
        }
        h.push_str("</tr>");
    }
    h.push_str("</table>");
    h
}

/// `growth.md`: how the cost grows with the model's nodes and the features, in two sentences
/// (a note without the axis).
fn growth_markdown(report: &Report) -> String {
    let Some(scaling) = &report.scaling else {
        return "(no cost-growth axis in this report: made with `--quick`, or without \
                `band-no-cut`)\n"
            .into();
    };
    fn millions(p: Option<&super::scaling::Point>) -> Option<(&super::scaling::Point, f64)> {
        p.and_then(|p| p.instructions.map(|v| (p, v / 1e6)))
    }
    let mut s = String::new();
    if let (Some(b), Some((first, c0)), Some((last, c1))) = (
        scaling.nodes_exponent,
        millions(scaling.nodes.first()),
        millions(scaling.nodes.last()),
    ) {
        let _ = write!(
            s,
            "The cost ({}) grows as nodes^{b:.2}: {c0:.1} to {c1:.0} million instructions \
             from {} to {} nodes.",
            scaling.cost, first.nodes, last.nodes
        );
    }
    if let (Some((first, c0)), Some((last, c1))) = (
        millions(scaling.features.first()),
        millions(scaling.features.last()),
    ) && last.features > first.features
    {
        // Affine in the features: the slope between the ends, per feature.
        let per_feature = (c1 - c0) * 1e6 / (last.features - first.features) as f64;
        let _ = write!(
            s,
            " Against features it is affine rather than a power law: a fixed part plus about \
             {:.0} instructions per feature ({c0:.1} million at {} features, {c1:.1} at {}; \
             the fitted exponent, {}, says little).",
            per_feature,
            first.features,
            last.features,
            scaling
                .features_exponent
                .map_or("–".into(), |b| format!("{b:.2}"))
        );
    }
    // The largest model of the mesh-resolution axis (SOFA's fine liver) carries the node axis
    // past the band variants, whose largest costs a minute per frame under callgrind already.
    if let Some(largest) = &scaling.largest {
        let _ = write!(
            s,
            " Beyond the band variants, the largest model of the mesh-resolution table, `{}` \
             modelled by {} mesh ({} nodes): {:.0} million instructions per steady frame",
            largest.scene,
            largest.mesh,
            largest.nodes,
            largest.instructions / 1e6
        );
        match scaling.nodes_exponent_with_largest {
            Some(b) => {
                let _ = write!(
                    s,
                    "; fitted together with the band variants, the cost grows as nodes^{b:.2} \
                     (another shape, with its own features: at the rate per feature above they \
                     are a small part of its cost, so the two exponents differ by the shape and \
                     its finer elements)."
                );
            }
            None => s.push('.'),
        }
    }
    if s.is_empty() {
        s.push_str(
            "(no instruction counts: valgrind was not installed; the page has the wall times)",
        );
    }
    s.push('\n');
    s
}

/// `resolution.md`: the mesh-resolution axis as a Markdown table (empty without it).
fn resolution_markdown(report: &Report) -> String {
    if report.resolution.is_empty() {
        return "(no mesh-resolution axis in this report: made with `--quick`, or without \
                `band-side-cut` and `liver-lobe`)\n"
            .into();
    }
    let rows = resolution_rows(report);
    let mut s = String::new();
    for (i, row) in rows.iter().enumerate() {
        let _ = writeln!(s, "| {} |", row.join(" | "));
        if i == 0 {
            let _ = writeln!(
                s,
                "| --- | --- |{}",
                " ---: |".repeat(row.len().saturating_sub(2))
            );
        }
    }
    s
}
