//! The commands of the `incise` program, one function each: read the arguments' files, call
//! the library, print or write the results.

use super::*;

pub(super) fn run_command(
    dir: &Path,
    json: bool,
    out: Option<PathBuf>,
    true_cut: bool,
    (real, law, pairs): (Precision, Option<ModelLaw>, bool),
) -> Result<(), Failure> {
    let mut scene = Scene::load(dir).map_err(|e| e.to_string())?;
    scene.precision = real;
    scene.overlay_pairs = pairs;
    if let Some(law) = law {
        scene.file.model.law = law;
    }
    let options = RunOptions {
        out: out.clone(),
        progress: !json,
        true_cut,
    };
    let (summary, _) = run_scene(&scene, &options).map_err(|e| e.to_string())?;
    print_summary(&summary, json, out.as_deref())
}

/// Prints what `incise run` found: one JSON object, or a human summary.
pub(super) fn print_summary(
    summary: &crate::run::Summary,
    json: bool,
    out: Option<&Path>,
) -> Result<(), Failure> {
    if json {
        outln!(
            "{}",
            serde_json::to_string_pretty(summary).map_err(|e| e.to_string())?
        )?;
    } else {
        out!("{}", crate::report::human_summary(summary))?;
        if let Some(out) = out {
            outln!("pictures and meshes: {}", out.display())?;
        }
    }
    Ok(())
}

pub(super) fn table_command(
    dirs: &[PathBuf],
    (true_cut, filter): (bool, bool),
    (real, law): (Precision, Option<ModelLaw>),
    detection: &[crate::scene::DetectionSetting],
) -> Result<(), Failure> {
    // A setting that is not a field or out of its range, before anything runs.
    crate::scene::DetectionSection::default().with_all(detection)?;
    let mut rows = vec![];
    let options = RunOptions {
        true_cut,
        ..RunOptions::default()
    };
    for dir in dirs {
        let mut scene = Scene::load(dir).map_err(|e| e.to_string())?;
        scene.precision = real;
        if let Some(law) = law {
            scene.file.model.law = law;
        }
        scene.file.detection = scene
            .file
            .detection
            .with_all(detection)
            .map_err(|e| format!("{}: {e}", dir.display()))?;
        let (summary, _) = run_scene(&scene, &options).map_err(|e| e.to_string())?;
        rows.push(summary);
    }
    out!("{}", crate::report::markdown_table(&rows))?;
    if true_cut {
        out!("\n{}", crate::report::true_cut_table(&rows))?;
    }
    if filter {
        out!("\n{}", crate::report::filter_table(&rows))?;
    }
    Ok(())
}

pub(super) fn codegen_command(
    dir: &Path,
    out: &Path,
    frames: usize,
    footprint: bool,
    ram_budget_kib: Option<u64>,
) -> Result<(), Failure> {
    use crate::codegen::{self, CodegenOptions, footprint as fp};
    let scene = Scene::load(dir).map_err(|e| e.to_string())?;
    let generated =
        codegen::generate(&scene, &CodegenOptions { frames }).map_err(|e| e.to_string())?;
    if let Some(kib) = ram_budget_kib {
        codegen::check_budget(&generated, kib.saturating_mul(1024)).map_err(|e| e.to_string())?;
    }
    codegen::write(&generated, out).map_err(|e| e.to_string())?;
    outln!(
        "wrote {} ({} nodes, {} tetrahedra, {} frames of tracks)",
        out.display(),
        scene.rest.len(),
        scene.tets.len(),
        generated.frames
    )?;
    if footprint {
        let w = &generated.worst_case;
        outln!(
            "\nWorst case of a steady frame (uncut, {} features): factorizations {} ({:.2e} \
             flops), solves {} ({:.2e} flops), PCG products {} ({:.2e} flops), element \
             tangents {}, element energies {}, feature energies {}.",
            scene.frames[0].len(),
            w.factorizations,
            w.factor_flops as f64,
            w.solves,
            w.solve_flops as f64,
            w.matvecs,
            w.matvec_flops as f64,
            w.element_tangents,
            w.element_evaluations,
            w.feature_evaluations
        )?;
        outln!(
            "\n{}",
            codegen::storage_table(&generated).map_err(|e| e.to_string())?
        )?;
        outln!(
            "| feature set | static RAM, KiB | code (.text), KiB | constants (.rodata), KiB | leaves out |"
        )?;
        outln!("|---|---:|---:|---:|---|")?;
        let target = fp::firmware_dir().join("target");
        for set in &fp::feature_sets(generated.strategy, generated.projection) {
            let built = fp::build(out, set, generated.law, &target).map_err(|e| e.to_string())?;
            let f = built.footprint;
            outln!(
                "| {} | {} | {} | {} | {} |",
                set.name,
                fp::kib(f.ram()),
                fp::kib(f.text),
                fp::kib(f.rodata),
                set.leaves_out
            )?;
        }
    }
    Ok(())
}

pub(super) fn sweep_command(dir: &Path, out: Option<&Path>) -> Result<(), Failure> {
    let base = Scene::load(dir).map_err(|e| e.to_string())?;
    // Made before the runs, so that a directory that cannot be made costs no sweep.
    if let Some(out) = out {
        std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    }
    let settings = crate::report::sweep_settings();
    let bar = indicatif::ProgressBar::new(settings.len() as u64);
    let mut rows = vec![];
    for setting in settings {
        let mut scene = base.clone();
        setting.apply(&mut scene);
        let (summary, _) = run_scene(&scene, &RunOptions::default()).map_err(|e| e.to_string())?;
        rows.push((setting, summary));
        bar.inc(1);
    }
    bar.finish_and_clear();
    out!("{}", crate::report::sweep_table(&rows))?;
    if let Some(out) = out {
        let plot = out.join("error_vs_time.svg");
        crate::report::plot_sweep(&base.file.name, &rows, &plot)?;
        outln!("plot: {}", plot.display())?;
    }
    Ok(())
}

pub(super) fn report_command(dirs: &[PathBuf], out: &Path, quick: bool) -> Result<(), Failure> {
    let scenes = dirs
        .iter()
        .map(|d| Scene::load(d).map_err(|e| e.to_string()))
        .collect::<Result<Vec<_>, _>>()?;
    let options = crate::report::page::ReportOptions {
        quick,
        progress: true,
    };
    let report = crate::report::page::write_report(&scenes, out, options)?;
    outln!(
        "{}: {} scenes; instructions {}",
        out.join("index.html").display(),
        report.scenes.len(),
        report.instructions
    )?;
    Ok(())
}

pub(super) fn count_frames_command(args: &super::CountFramesArgs) -> Result<(), Failure> {
    let strategy = crate::report::SweepSetting::strategy_name(&args.strategy)
        .ok_or_else(|| format!("unknown strategy {:?}", args.strategy))?;
    let setting = crate::report::SweepSetting {
        strategy,
        newton: args.newton,
        pcg: args.pcg,
        precision: args.real,
        line_search: args.line_search,
    };
    crate::report::page::count_frames(&args.scene, &setting, args.frames)?;
    Ok(())
}

pub(super) fn gen_command(
    scenarios: &[PathBuf],
    out: Option<PathBuf>,
    video: bool,
    model_mesh: ModelMesh,
    intact: bool,
) -> Result<(), Failure> {
    if out.is_some() && scenarios.len() > 1 {
        return Err("--out takes one scenario at a time".into());
    }
    #[cfg(not(feature = "opencv"))]
    if video {
        return Err(NO_OPENCV.into());
    }
    for path in scenarios {
        let own = path
            .parent()
            .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
        let dir = out.clone().unwrap_or_else(|| own.clone());
        // An object left whole or another model mesh is another scene: written over the
        // scenario's own, it would replace the committed scene (and, left whole, the scenario
        // itself, rewritten without its slit). Refused before anything is simulated.
        if (intact || model_mesh != ModelMesh::Scenario) && same_directory(&dir, &own) {
            let what = if intact { "--intact" } else { "--model-mesh" };
            return Err(format!(
                "{}: {what} writes another scene, and --out {} is the scenario's own directory, \
                 whose scene (and scenario) it would overwrite; give another --out",
                path.display(),
                dir.display()
            )
            .into());
        }
        if intact {
            // `--intact` needs `--out` and refuses `--video` (clap): the scenario without its
            // slit goes beside the scene, so that `incise gen` on it regenerates the scene.
            let mut s =
                crate::generate::scenario::Scenario::load(path).map_err(|e| e.to_string())?;
            s.slit = None;
            let base = path.parent().unwrap_or(Path::new("."));
            let g = crate::generate::pipeline::generate_scenario(&s, base, &dir, model_mesh, true)
                .map_err(|e| format!("{}: {e}", path.display()))?;
            print_generated(&g)?;
            continue;
        }
        // Their errors name the file at fault.
        let mut sim = crate::generate::pipeline::simulate(path, true).map_err(|e| e.to_string())?;
        sim.remodel(model_mesh);
        let g = crate::generate::pipeline::write_scene(&sim, path, &dir, true)
            .map_err(|e| e.to_string())?;
        #[cfg(feature = "opencv")]
        if video {
            let file = dir.join("video.avi");
            write_video(&sim, &file)?;
            outln!("{}: textured video", file.display())?;
        }
        print_generated(&g)?;
    }
    Ok(())
}

/// Whether `a` and `b` name the same directory (after resolving links and `..`; a directory
/// that does not exist yet is not the other, which exists).
fn same_directory(a: &Path, b: &Path) -> bool {
    let resolve = |p: &Path| {
        let p = if p.as_os_str().is_empty() {
            Path::new(".")
        } else {
            p
        };
        std::fs::canonicalize(p).ok()
    };
    matches!((resolve(a), resolve(b)), (Some(x), Some(y)) if x == y)
}

/// One line on a scene `gen` wrote.
fn print_generated(g: &crate::generate::pipeline::Generated) -> Result<(), Failure> {
    outln!(
        "{}: {} frames, {} features, real mesh {} nodes / {} tets, model {} nodes / {} tets, cut opens at frame {}, real object stretched by at most {:.0} % (frame {}; 1 % of its volume by more than {:.0} %)",
        g.dir.display(),
        g.frames,
        g.features,
        g.fine_size.0,
        g.fine_size.1,
        g.model_size.0,
        g.model_size.1,
        g.cut_open_frame.map_or("-".to_string(), |f| f.to_string()),
        100.0 * (g.stretch.largest - 1.0),
        g.stretch.frame,
        100.0 * (g.stretch.one_percent - 1.0),
    )?;
    Ok(())
}

pub(super) fn eval_command(
    families: &[PathBuf],
    options: &crate::eval::EvalOptions,
    per_variant: bool,
    json: bool,
    plot: Option<&Path>,
) -> Result<(), Failure> {
    // A setting that is not a field or out of its range, before anything runs.
    crate::scene::DetectionSection::default().with_all(&options.detection)?;
    let mut done = vec![];
    for f in families {
        done.push(crate::eval::eval_family(f, options)?);
    }
    if let Some(file) = plot {
        crate::eval::evidence::plot_evidence(&done, file)?;
    }
    if json {
        let text = serde_json::to_string_pretty(&done).map_err(|e| e.to_string())?;
        return outln!("{text}");
    }
    out!("{}", crate::eval::markdown_table(&done))?;
    if options.evidence {
        outln!("\nWhat the pairs carry, read by an oracle that knows the true cut:\n")?;
        out!("{}", crate::eval::evidence::evidence_table(&done))?;
        outln!("\nHow much of the cut the crossing pairs cover (their best frame):\n")?;
        out!("{}", crate::eval::evidence::coverage_table(&done))?;
        if let Some(file) = plot {
            outln!("plot: {}", file.display())?;
        }
    }
    if per_variant {
        for f in &done {
            outln!("\n{}:\n", f.family)?;
            out!("{}", crate::eval::variant_table(f))?;
            if options.evidence {
                outln!(
                    "\n{}, read by the oracle (per test, a cut variant's latency, an intact one's frames where it holds):\n",
                    f.family
                )?;
                out!("{}", crate::eval::evidence::variant_evidence_table(f))?;
            }
        }
    }
    Ok(())
}

pub(super) fn eval_sweep_command(
    families: &[PathBuf],
    options: &crate::eval::EvalOptions,
    swept: &[Vec<crate::scene::DetectionSetting>],
    plot: Option<&Path>,
    json: bool,
) -> Result<(), Failure> {
    let rows = crate::eval::sweep::sweep(families, options, swept)?;
    if let Some(file) = plot {
        crate::eval::sweep::plot_sweep(&rows, file)?;
    }
    if json {
        let text = serde_json::to_string_pretty(&rows).map_err(|e| e.to_string())?;
        return outln!("{text}");
    }
    out!("{}", crate::eval::sweep::sweep_table(&rows))?;
    if let Some(file) = plot {
        outln!("plot: {}", file.display())?;
    }
    Ok(())
}

pub(super) fn gen_family_command(family: &Path, out: Option<&Path>) -> Result<(), Failure> {
    let out = out.ok_or("--family needs --out")?;
    let generated =
        crate::generate::family::generate_family(family, out, true).map_err(|e| e.to_string())?;
    for g in &generated {
        outln!(
            "{}: {} frames, {} features, real mesh {} nodes, cut opens at frame {}",
            g.dir.display(),
            g.frames,
            g.features,
            g.fine_size.0,
            g.cut_open_frame.map_or("-".to_string(), |f| f.to_string())
        )?;
    }
    Ok(())
}

/// Renders every frame of a simulation into an MJPG video.
#[cfg(feature = "opencv")]
pub(super) fn write_video(
    sim: &crate::generate::pipeline::Simulation,
    file: &Path,
) -> Result<(), String> {
    let cam = sim.camera.intrinsics();
    let mut sink = crate::video::VideoSink::create(file, cam.width, cam.height, 25.0)
        .map_err(|e| e.to_string())?;
    for f in 0..sim.positions.len() {
        sink.write(&crate::generate::texture::render_frame(sim, f))
            .map_err(|e| e.to_string())?;
    }
    sink.finish().map_err(|e| e.to_string())
}

pub(super) fn demo(out: &Path) -> Result<(), Failure> {
    let dir = fixtures_dir().join("band-side-cut");
    let scene = Scene::load(&dir).map_err(|e| e.to_string())?;
    outln!(
        "incise demo: {} ({})",
        scene.file.name,
        scene.file.description
    )?;
    let frames_dir = out.join("frames");
    let options = RunOptions {
        out: Some(frames_dir.clone()),
        progress: true,
        true_cut: false,
    };
    let (summary, trace) = run_scene(&scene, &options).map_err(|e| e.to_string())?;
    out!("{}", crate::report::human_summary(&summary))?;
    let sheet = out.join("overview.png");
    crate::report::contact_sheet(&frames_dir, &trace, summary.cut_open_frame, &sheet)
        .map_err(|e| e.to_string())?;
    let plot = out.join("dice.svg");
    crate::report::plot_dice(&trace, &summary, &plot).map_err(|e| e.to_string())?;
    outln!(
        "pictures: {} (frames), {} (overview), {} (Dice per frame)",
        frames_dir.display(),
        sheet.display(),
        plot.display()
    )?;
    Ok(())
}

// --- OpenCV video driver: `incise track` and `incise run --video` ---

#[cfg(not(feature = "opencv"))]
pub(super) const NO_OPENCV: &str =
    "built without the opencv feature; rebuild with --features opencv";

#[cfg(not(feature = "opencv"))]
pub(super) fn run_video_command(
    _: &Path,
    video: &Path,
    _: Option<&Path>,
    _: bool,
    _: (Option<PathBuf>, bool),
) -> Result<(), Failure> {
    Err(format!("--video {}: {NO_OPENCV}", video.display()).into())
}

#[cfg(not(feature = "opencv"))]
pub(super) fn track_command(
    video: &Path,
    _: &Path,
    _: &Path,
    _: Option<&Path>,
) -> Result<(), Failure> {
    Err(format!("track {}: {NO_OPENCV}", video.display()).into())
}

/// The scene for a video (tracks.csv optional) with the calibration's intrinsics, if any.
#[cfg(feature = "opencv")]
pub(super) fn video_scene(
    dir: &Path,
    calibration: Option<&Path>,
) -> Result<(Scene, Option<crate::calibration::Calibration>), String> {
    let mut scene = crate::scene::Scene::load_model(dir).map_err(|e| e.to_string())?;
    let Some(path) = calibration else {
        return Ok((scene, None));
    };
    let calibration = crate::calibration::Calibration::load(path).map_err(|e| e.to_string())?;
    let before = scene.file.camera.clone();
    calibration
        .apply_to(&mut scene.file.camera)
        .map_err(|e| e.to_string())?;
    let c = &scene.file.camera;
    eprintln!(
        "incise: {} replaces the scene's intrinsics: fx {:.1} fy {:.1} cx {:.1} cy {:.1} (scene: {:.1} {:.1} {:.1} {:.1})",
        path.display(),
        c.fx,
        c.fy,
        c.cx,
        c.cy,
        before.fx,
        before.fy,
        before.cx,
        before.cy
    );
    Ok((scene, Some(calibration)))
}

#[cfg(feature = "opencv")]
pub(super) fn run_video_command(
    dir: &Path,
    video: &Path,
    calibration: Option<&Path>,
    json: bool,
    (out, pairs): (Option<PathBuf>, bool),
) -> Result<(), Failure> {
    use crate::run::{FrameSink, VideoFrames, run_scene_with};
    use crate::video::VideoSink;

    let (mut scene, calibration) = video_scene(dir, calibration)?;
    scene.overlay_pairs = pairs;
    let mut frames = VideoFrames::open(video, &scene, calibration).map_err(|e| e.to_string())?;
    let mut sink = match &out {
        Some(dir) => {
            std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
            let (w, h) = frames.source().size();
            let fps = frames.source().fps();
            let fps = if fps > 0.0 { fps } else { 25.0 };
            Some(
                VideoSink::create(&dir.join("overlay.avi"), w, h, fps)
                    .map_err(|e| e.to_string())?,
            )
        }
        None => None,
    };
    let options = RunOptions {
        out: out.clone(),
        progress: !json,
        true_cut: false,
    };
    let (summary, _) = run_scene_with(
        &scene,
        &mut frames,
        sink.as_mut().map(|s| s as &mut dyn FrameSink),
        &options,
    )
    .map_err(|e| e.to_string())?;
    if let Some(sink) = sink {
        sink.finish().map_err(|e| e.to_string())?;
    }
    print_summary(&summary, json, out.as_deref())?;
    if let (Some(out), false) = (&out, json) {
        outln!("overlay video: {}", out.join("overlay.avi").display())?;
    }
    Ok(())
}

#[cfg(feature = "opencv")]
pub(super) fn track_command(
    video: &Path,
    dir: &Path,
    out: &Path,
    calibration: Option<&Path>,
) -> Result<(), Failure> {
    use crate::run::{FrameSource, VideoFrames, progress_bar, rest_silhouette};

    let (scene, calibration) = video_scene(dir, calibration)?;
    let mask = rest_silhouette(&scene).map_err(|e| e.to_string())?;
    let mut frames = VideoFrames::open(video, &scene, calibration).map_err(|e| e.to_string())?;
    let bar = progress_bar(frames.len_hint(), "tracking");
    let mut tracks = vec![];
    while let Some(frame) = frames.next(&mask).map_err(|e| e.to_string())? {
        tracks.push(frame.observations);
        bar.inc(1);
    }
    bar.finish_and_clear();
    std::fs::write(out, crate::scene::write_tracks(&tracks))
        .map_err(|e| format!("{}: {e}", out.display()))?;
    let (found, alive) = frames.tracker().map_or((0, 0), |t| (t.len(), t.alive()));
    outln!(
        "{}: {} frames, {found} features at frame 0, {alive} tracked to the last frame",
        out.display(),
        tracks.len()
    )?;
    Ok(())
}

// --- end OpenCV video driver ---

pub(super) fn instructions_command(
    dir: &Path,
    frames: Option<usize>,
    real: Precision,
) -> Result<(), Failure> {
    let mut scene = Scene::load(dir).map_err(|e| e.to_string())?;
    scene.precision = real;
    let setting = crate::report::SweepSetting {
        precision: real,
        ..crate::report::SweepSetting::of(&scene.file.solver)
    };
    let frames = frames.unwrap_or(usize::MAX);
    let counts = crate::report::page::instructions_per_frame(dir, &setting, frames)?;
    // Which frames cut the mesh: the same run, by the host.
    let trace = crate::run::run_once(&scene, true, None, false).map_err(|e| e.to_string())?;
    // `cut_event`: the frame cut the mesh; `cut_work`: it ran a cut event, one that cut or one
    // that found nothing new to cut (its geometry runs all the same). A steady frame has
    // neither; a worst-case timing test of the steady frame takes the frames without
    // `cut_work`.
    outln!("frame,instructions,cut_event,cut_work")?;
    for (k, count) in counts.iter().enumerate() {
        let f = k + 1;
        let cut_work = trace
            .frames
            .iter()
            .find(|r| r.frame == f)
            .and_then(|r| r.work.as_ref())
            .is_some_and(|w| w.cut.is_some());
        outln!("{f},{count},{},{cut_work}", trace.cuts.frames.contains(&f))?;
    }
    Ok(())
}
