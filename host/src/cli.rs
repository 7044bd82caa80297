//! The `incise` command line.

use std::fmt;
use std::io::Write;
use std::path::{Path, PathBuf};

use clap::{Parser, Subcommand};

use crate::run::{RunOptions, run_scene};
use crate::scene::Scene;

/// incise: keeps a pre-operative organ model aligned with endoscopic video while the surgeon
/// cuts (Paulus et al., MICCAI 2015).
#[derive(Debug, Parser)]
#[command(name = "incise", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run the shipped default scene (band-side-cut) and write pictures to ./incise-demo/.
    Demo {
        /// Where to write the pictures.
        #[arg(long, default_value = "incise-demo")]
        out: PathBuf,
    },
    /// Run a scene: drive the core over its tracks and measure against its ground truth.
    Run {
        /// The scene directory (holding scene.toml).
        scene: PathBuf,
        /// Print one JSON object with the results.
        #[arg(long)]
        json: bool,
        /// Write overlay pictures (PNG) and the deformed mesh per frame (VTU) here; with
        /// --video, the overlay video (overlay.avi, Motion-JPEG) too.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Also run with the mesh cut along the true cut (ground truth) instead of the
        /// detected one: `dice_final_true_cut`, `tre_mm_final_true_cut`.
        #[arg(long, conflicts_with = "video")]
        true_cut: bool,
        // --- OpenCV video driver (options present in every build; they need `opencv`) ---
        /// Track this video (KLT) instead of reading the scene's tracks.csv, in one streaming
        /// pass (needs the `opencv` feature).
        #[arg(long)]
        video: Option<PathBuf>,
        /// Camera calibration (OpenCV YAML/XML: camera_matrix, dist_coeffs) of the video: its
        /// points are undistorted and its intrinsics replace the scene's.
        #[arg(long, requires = "video")]
        calibration: Option<PathBuf>,
        // --- end OpenCV video driver ---
    },
    // --- OpenCV video driver (present in every build; needs `opencv`) ---
    /// Track features of a video (KLT) inside the scene model's silhouette and write them as
    /// tracks.csv (needs the `opencv` feature).
    Track {
        /// The video (anything OpenCV reads; Motion-JPEG AVI always works).
        video: PathBuf,
        /// The scene directory (scene.toml and the model; tracks.csv may be missing).
        #[arg(long)]
        scene: PathBuf,
        /// Where to write the tracks.
        #[arg(short, long, default_value = "tracks.csv")]
        out: PathBuf,
        /// Camera calibration (OpenCV YAML/XML: camera_matrix, dist_coeffs) of the video.
        #[arg(long)]
        calibration: Option<PathBuf>,
    },
    // --- end OpenCV video driver ---
    /// Run several scenes and print a Markdown table of their results (as in the README).
    Table {
        /// Scene directories.
        #[arg(required = true)]
        scenes: Vec<PathBuf>,
        /// Also run each cut scene with its mesh cut along the true cut, and print a second
        /// table: Dice and target error with the detected cut against the true one.
        #[arg(long)]
        true_cut: bool,
    },
    /// Error against run time: run a scene under several solver settings (strategy, Newton
    /// steps, PCG steps) and report Dice, target error and step time for each, as a table and
    /// as plots (`--out DIR`: error_vs_time.svg).
    Sweep {
        /// The scene directory.
        scene: PathBuf,
        /// Write the plots here.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Run scene families end to end (issue 11's acceptance): generate each variant (or
    /// reuse it from --work), run it with the detection defaults, and print per family the
    /// false cuts, detection latency, the line's Hausdorff distance to the cut, and Dice and
    /// target error without and with cutting.
    Eval {
        /// Family files (see fixtures/README.md), e.g. fixtures/families/*.toml.
        #[arg(required = true)]
        families: Vec<PathBuf>,
        /// Where the variants' scenes are written and kept; a variant whose scenario is
        /// unchanged is not simulated again.
        #[arg(long, default_value = "incise-eval")]
        work: PathBuf,
        /// Run only the first N variants of each kind (intact, pre-cut, live).
        #[arg(long)]
        per_kind: Option<usize>,
        /// Simulate every variant again even if its scene is in --work.
        #[arg(long)]
        fresh: bool,
        /// Also print one line per variant.
        #[arg(long)]
        variants: bool,
        /// Print JSON (every family with every variant) instead of tables.
        #[arg(long)]
        json: bool,
    },
    /// Write one scene as a Rust module for a firmware build (`firmware/`): mesh, camera,
    /// settings, capacities and `const` buffer lengths, the uncut mesh's precomputed ordering
    /// and symbolic analysis, and the first frames of tracks. Nothing is written for a scene
    /// that does not check out.
    Codegen {
        /// The scene directory (holding scene.toml).
        scene: PathBuf,
        /// The module to write.
        #[arg(short, long)]
        out: PathBuf,
        /// Frames of tracks to include (frame 0 and the next ones).
        #[arg(long, default_value_t = 5)]
        frames: usize,
        /// Then build the firmware program with the module, once per feature set of the core,
        /// and print its static RAM and code size (needs this source tree, cargo, cc and
        /// binutils).
        #[arg(long)]
        footprint: bool,
        /// Refuse the scene (and write nothing) if its model's static RAM exceeds this many
        /// KiB, saying which buffer is too large and by how much.
        #[arg(long)]
        ram_budget_kib: Option<u64>,
    },
    /// Generate scenes: simulate each scenario's real object and write the scene beside it;
    /// or, with --family, every variant of a scene family.
    Gen {
        /// Scenario files (scenario.toml).
        #[arg(required_unless_present = "family", conflicts_with = "family")]
        scenarios: Vec<PathBuf>,
        /// A scene family file (see fixtures/README.md): write each of its variants as
        /// OUT/<variant name>/ (its scenario.toml and the scene); needs --out.
        #[arg(long, requires = "out", conflicts_with = "video")]
        family: Option<PathBuf>,
        /// Write the scene here instead of the scenario's directory (one scenario only); with
        /// --family, the directory of the variants.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Also render the textured video of the real object, `video.avi` in the scene
        /// (MJPG, 25 frames per second; needs the opencv feature).
        #[arg(long)]
        video: bool,
    },
}

/// Where the shipped fixtures are: `./fixtures` if run from the repository, else beside the
/// source tree this binary was built from.
fn fixtures_dir() -> PathBuf {
    let here = PathBuf::from("fixtures");
    if here.join("band-side-cut").join("scene.toml").exists() {
        return here;
    }
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("fixtures")
}

/// Exit status when standard output is a closed pipe (`incise demo | head -1`): what a shell
/// reports for a program ended by `SIGPIPE`, 128 + 13, as for `yes | head -1`.
pub const BROKEN_PIPE_STATUS: i32 = 141;

/// Why a command stopped.
#[derive(Debug)]
enum Failure {
    /// An error to print.
    Message(String),
    /// Standard output was closed (the reader of a pipe has gone): stop quietly.
    BrokenPipe,
}

impl From<String> for Failure {
    fn from(m: String) -> Self {
        Failure::Message(m)
    }
}

impl From<&str> for Failure {
    fn from(m: &str) -> Self {
        Failure::Message(m.to_string())
    }
}

/// Writes to standard output. Unlike `print!`, which panics when the reader of a pipe has
/// gone, a closed pipe becomes [`Failure::BrokenPipe`].
fn write_stdout(args: fmt::Arguments<'_>) -> Result<(), Failure> {
    let mut stdout = std::io::stdout().lock();
    stdout
        .write_fmt(args)
        .and_then(|()| stdout.flush())
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::BrokenPipe => Failure::BrokenPipe,
            _ => Failure::Message(format!("standard output: {e}")),
        })
}

/// `print!` through [`write_stdout`]: evaluates to `Result<(), Failure>`.
macro_rules! out {
    ($($arg:tt)*) => {
        write_stdout(format_args!($($arg)*))
    };
}

/// `println!` through [`write_stdout`]: evaluates to `Result<(), Failure>`.
macro_rules! outln {
    ($($arg:tt)*) => {
        write_stdout(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// Runs the parsed command line; returns the process exit code: 0, 1 after an error (printed
/// on standard error), or [`BROKEN_PIPE_STATUS`] if standard output was closed early.
pub fn run(cli: Cli) -> i32 {
    let result = match cli.command {
        Command::Demo { out } => demo(&out),
        Command::Run {
            scene,
            json,
            out,
            true_cut,
            video: None,
            calibration: _,
        } => run_command(&scene, json, out, true_cut),
        Command::Run {
            scene,
            json,
            out,
            video: Some(video),
            calibration,
            ..
        } => run_video_command(&scene, &video, calibration.as_deref(), json, out),
        Command::Track {
            video,
            scene,
            out,
            calibration,
        } => track_command(&video, &scene, &out, calibration.as_deref()),
        Command::Eval {
            families,
            work,
            per_kind,
            fresh,
            variants,
            json,
        } => eval_command(
            &families,
            &crate::eval::EvalOptions {
                work,
                selection: crate::eval::Selection { per_kind },
                fresh,
                progress: true,
            },
            variants,
            json,
        ),
        Command::Gen {
            family: Some(family),
            out,
            ..
        } => gen_family_command(&family, out.as_deref()),
        Command::Gen {
            scenarios,
            family: None,
            out,
            video,
        } => gen_command(&scenarios, out, video),
        Command::Codegen {
            scene,
            out,
            frames,
            footprint,
            ram_budget_kib,
        } => codegen_command(&scene, &out, frames, footprint, ram_budget_kib),
        Command::Table { scenes, true_cut } => table_command(&scenes, true_cut),
        Command::Sweep { scene, out } => sweep_command(&scene, out.as_deref()),
    };
    match result {
        Ok(()) => 0,
        Err(Failure::BrokenPipe) => BROKEN_PIPE_STATUS,
        Err(Failure::Message(message)) => {
            // Not `eprintln!`, which panics if standard error is closed too.
            let _ = writeln!(std::io::stderr(), "incise: {message}");
            1
        }
    }
}

fn run_command(
    dir: &Path,
    json: bool,
    out: Option<PathBuf>,
    true_cut: bool,
) -> Result<(), Failure> {
    let scene = Scene::load(dir).map_err(|e| e.to_string())?;
    let options = RunOptions {
        out: out.clone(),
        progress: !json,
        true_cut,
    };
    let (summary, _) = run_scene(&scene, &options).map_err(|e| e.to_string())?;
    print_summary(&summary, json, out.as_deref())
}

/// Prints what `incise run` found: one JSON object, or a human summary.
fn print_summary(
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

fn table_command(dirs: &[PathBuf], true_cut: bool) -> Result<(), Failure> {
    let mut rows = vec![];
    let options = RunOptions {
        true_cut,
        ..RunOptions::default()
    };
    for dir in dirs {
        let scene = Scene::load(dir).map_err(|e| e.to_string())?;
        let (summary, _) = run_scene(&scene, &options).map_err(|e| e.to_string())?;
        rows.push(summary);
    }
    out!("{}", crate::report::markdown_table(&rows))?;
    if true_cut {
        out!("\n{}", crate::report::true_cut_table(&rows))?;
    }
    Ok(())
}

fn codegen_command(
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
        for set in &fp::feature_sets(generated.strategy, generated.projection) {
            let target = fp::firmware_dir().join("target").join(set.dir_name());
            let built = fp::build(out, set, &target).map_err(|e| e.to_string())?;
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

fn sweep_command(dir: &Path, out: Option<&Path>) -> Result<(), Failure> {
    let base = Scene::load(dir).map_err(|e| e.to_string())?;
    let settings = crate::report::sweep_settings();
    let bar = indicatif::ProgressBar::new(settings.len() as u64);
    let mut rows = vec![];
    for setting in settings {
        let mut scene = base.clone();
        setting.apply(&mut scene.file.solver);
        let (summary, _) = run_scene(&scene, &RunOptions::default()).map_err(|e| e.to_string())?;
        rows.push((setting, summary));
        bar.inc(1);
    }
    bar.finish_and_clear();
    out!("{}", crate::report::sweep_table(&rows))?;
    if let Some(out) = out {
        std::fs::create_dir_all(out).map_err(|e| e.to_string())?;
        let plot = out.join("error_vs_time.svg");
        crate::report::plot_sweep(&base.file.name, &rows, &plot)?;
        outln!("plot: {}", plot.display())?;
    }
    Ok(())
}

fn gen_command(scenarios: &[PathBuf], out: Option<PathBuf>, video: bool) -> Result<(), Failure> {
    if out.is_some() && scenarios.len() > 1 {
        return Err("--out takes one scenario at a time".into());
    }
    #[cfg(not(feature = "opencv"))]
    if video {
        return Err(NO_OPENCV.into());
    }
    for path in scenarios {
        let dir = match &out {
            Some(o) => o.clone(),
            None => path
                .parent()
                .map_or_else(|| PathBuf::from("."), Path::to_path_buf),
        };
        // Their errors name the file at fault.
        let sim = crate::generate::pipeline::simulate(path, true).map_err(|e| e.to_string())?;
        let g = crate::generate::pipeline::write_scene(&sim, path, &dir, true)
            .map_err(|e| e.to_string())?;
        #[cfg(feature = "opencv")]
        if video {
            let file = dir.join("video.avi");
            write_video(&sim, &file)?;
            outln!("{}: textured video", file.display())?;
        }
        outln!(
            "{}: {} frames, {} features, real mesh {} nodes / {} tets, model {} nodes / {} tets, cut opens at frame {}",
            g.dir.display(),
            g.frames,
            g.features,
            g.fine_size.0,
            g.fine_size.1,
            g.model_size.0,
            g.model_size.1,
            g.cut_open_frame.map_or("-".to_string(), |f| f.to_string())
        )?;
    }
    Ok(())
}

fn eval_command(
    families: &[PathBuf],
    options: &crate::eval::EvalOptions,
    per_variant: bool,
    json: bool,
) -> Result<(), Failure> {
    let mut done = vec![];
    for f in families {
        done.push(crate::eval::eval_family(f, options)?);
    }
    if json {
        let text = serde_json::to_string_pretty(&done).map_err(|e| e.to_string())?;
        return outln!("{text}");
    }
    out!("{}", crate::eval::markdown_table(&done))?;
    if per_variant {
        for f in &done {
            outln!("\n{}:\n", f.family)?;
            out!("{}", crate::eval::variant_table(f))?;
        }
    }
    Ok(())
}

fn gen_family_command(family: &Path, out: Option<&Path>) -> Result<(), Failure> {
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
fn write_video(sim: &crate::generate::pipeline::Simulation, file: &Path) -> Result<(), String> {
    let cam = sim.camera.intrinsics();
    let mut sink = crate::video::VideoSink::create(file, cam.width, cam.height, 25.0)
        .map_err(|e| e.to_string())?;
    for f in 0..sim.positions.len() {
        sink.write(&crate::generate::texture::render_frame(sim, f))
            .map_err(|e| e.to_string())?;
    }
    sink.finish().map_err(|e| e.to_string())
}

fn demo(out: &Path) -> Result<(), Failure> {
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
const NO_OPENCV: &str = "built without the opencv feature; rebuild with --features opencv";

#[cfg(not(feature = "opencv"))]
fn run_video_command(
    _: &Path,
    video: &Path,
    _: Option<&Path>,
    _: bool,
    _: Option<PathBuf>,
) -> Result<(), Failure> {
    Err(format!("--video {}: {NO_OPENCV}", video.display()).into())
}

#[cfg(not(feature = "opencv"))]
fn track_command(video: &Path, _: &Path, _: &Path, _: Option<&Path>) -> Result<(), Failure> {
    Err(format!("track {}: {NO_OPENCV}", video.display()).into())
}

/// The scene for a video (tracks.csv optional) with the calibration's intrinsics, if any.
#[cfg(feature = "opencv")]
fn video_scene(
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
fn run_video_command(
    dir: &Path,
    video: &Path,
    calibration: Option<&Path>,
    json: bool,
    out: Option<PathBuf>,
) -> Result<(), Failure> {
    use crate::run::{FrameSink, VideoFrames, run_scene_with};
    use crate::video::VideoSink;

    let (scene, calibration) = video_scene(dir, calibration)?;
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
fn track_command(
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
