//! The `incise` command line.

use std::fmt;
use std::io::Write;
use std::path::{Path, PathBuf};

use clap::{Args, Parser, Subcommand};

use crate::generate::pipeline::ModelMesh;
use crate::run::{RunOptions, run_scene};
use crate::scene::{DetectionSetting, ModelLaw, Precision, Scene};

/// The values of one `--sweep` field (an alias, so that clap takes each `--sweep` for one
/// value rather than for a list of them).
type SweptValues = Vec<DetectionSetting>;

/// incise: keeps a pre-operative organ model aligned with endoscopic video while the surgeon
/// cuts (Paulus et al., MICCAI 2015).
#[derive(Debug, Parser)]
#[command(name = "incise", version)]
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
        /// detected one: `dice_final_true_cut`, `tre_mm_final_true_cut` (with --out, its
        /// pictures and meshes go to OUT/true-cut/).
        #[arg(long, conflicts_with = "video")]
        true_cut: bool,
        /// The scalar type the core computes in (the host measures in f64 either way).
        #[arg(long, value_enum, default_value_t = Precision::F64)]
        real: Precision,
        /// The model's strain energy law, in place of the scene's `[model] law`.
        #[arg(long, value_enum)]
        law: Option<ModelLaw>,
        /// Also draw the detector's evidence on the overlays (with --out or --video): the
        /// neighbour pairs that are outliers in the frame (magenta) and those counted as split
        /// (orange), between their features; with --out, also write OUT/pairs.csv: every pair
        /// measured in every frame, what its outlier test read (difference, smooth share,
        /// level, margin), whether it was an outlier and is split, and whether it crosses the
        /// true cut.
        #[arg(long)]
        pairs: bool,
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
        /// Also print a table of the temporal filter against the features each scene's
        /// generator made jump (`gt/outliers.csv`): jumps taken out, genuine features taken out.
        #[arg(long)]
        filter: bool,
        /// The scalar type the core computes in (the host measures in f64 either way).
        #[arg(long, value_enum, default_value_t = Precision::F64)]
        real: Precision,
        /// The model's strain energy law, in place of each scene's `[model] law`.
        #[arg(long, value_enum)]
        law: Option<ModelLaw>,
        /// Set a field of every scene's `[detection]` section, as the scene file would write it
        /// (repeatable), e.g. `--set persistence=1`: what a detection setting does to the
        /// committed scenes (`incise eval --set` does the same on the families).
        #[arg(long = "set", value_name = "KEY=VALUE", value_parser = DetectionSetting::parse)]
        set: Vec<DetectionSetting>,
    },
    /// Write one page (index.html, with its figures as SVG and its data as CSV and JSON) on
    /// the scenes: error against run time over solver settings with the Pareto front and a
    /// recommended setting, the worst case (every work counter against its formula, and
    /// instructions per frame counted by callgrind if valgrind is installed) and the memory.
    Report {
        /// Scene directories.
        #[arg(required = true)]
        scenes: Vec<PathBuf>,
        /// Where to write the page and its files.
        #[arg(long)]
        out: PathBuf,
        /// Two settings per scene and a few frames counted: a check that the page is made,
        /// in about a minute.
        #[arg(long)]
        quick: bool,
    },
    /// Steps a scene's model with one solver setting and prints nothing: what `report` counts
    /// under callgrind (the `incise-count-frames` program does the same, linking less).
    #[command(hide = true)]
    CountFrames(CountFramesArgs),
    /// Count the instructions of every frame of a scene with callgrind (needs valgrind), with
    /// the scene's own solver setting: one CSV line per frame (frame, instructions, whether it
    /// cut the mesh, whether it ran a cut event at all, one that found nothing new to cut
    /// included). Deterministic: the numbers a worst-case timing test can assert.
    Instructions {
        /// The scene directory.
        scene: PathBuf,
        /// Frames to count after frame 0 (all by default).
        #[arg(long)]
        frames: Option<usize>,
        /// The scalar type the core computes in.
        #[arg(long, value_enum, default_value_t = Precision::F64)]
        real: Precision,
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
        /// The model's strain energy law in place of each variant's `[model] law`.
        #[arg(long, value_enum)]
        law: Option<ModelLaw>,
        /// Draw the variants with this seed instead of each family's own: variants that no
        /// setting was tried on (kept in their own folders under --work).
        #[arg(long)]
        seed: Option<u64>,
        /// Model each variant's object by this mesh (as `incise gen --model-mesh`; kept in
        /// their own folders under --work).
        #[arg(long, value_enum, default_value_t = ModelMesh::Scenario)]
        model_mesh: ModelMesh,
        /// Also write each variant's last frame (the overlay with the detector's pairs) to
        /// DIR/FAMILY/VARIANT.png, and one sheet of them all per family, DIR/FAMILY.png, each
        /// captioned with its kind, detection and line distance.
        #[arg(long, value_name = "DIR")]
        pictures: Option<PathBuf>,
        /// Set a field of every variant's `[detection]` section, as the scene file would write
        /// it (repeatable), e.g. `--set persistence=1`: to study a setting, not to tune one.
        #[arg(long = "set", value_name = "KEY=VALUE", value_parser = DetectionSetting::parse)]
        set: Vec<DetectionSetting>,
        /// Run the families under each of these values of a `[detection]` field
        /// (repeatable: every combination, the first field varying slowest), and print one row
        /// per setting, every family pooled: false cuts against latency and line distance.
        #[arg(long, value_name = "KEY=V1,V2,...", value_parser = DetectionSetting::parse_list)]
        sweep: Vec<SweptValues>,
        /// With --sweep, draw false cuts against latency and line distance, one point per
        /// setting, to this SVG file; with --evidence, the oracle's latency against the intact
        /// frames where its test holds, one point per test, a panel per family.
        #[arg(long, value_name = "FILE")]
        plot: Option<PathBuf>,
        /// Also read the detector's pairs as an oracle that knows the true cut would: per
        /// test (a level in robust deviations, frames in a row, pairs at once), how soon after
        /// the opening enough pairs across the cut stand out, and on how many intact variants
        /// the same test holds on some pairs (a second table, after the families').
        #[arg(long, conflicts_with = "sweep")]
        evidence: bool,
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
        /// `OUT/<variant name>/` (its scenario.toml and the scene); needs --out.
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
        /// The mesh that models the object, with the same truth and tracks: the scenario's,
        /// that mesh refined (every tetrahedron into eight) or the real object's own fine
        /// mesh (what the report's mesh-resolution axis runs); needs --out.
        #[arg(long, value_enum, default_value_t = ModelMesh::Scenario, requires = "out", conflicts_with = "family")]
        model_mesh: ModelMesh,
        /// The same scene with its object left whole: the scenario without its `[slit]` (the
        /// same motion, camera and tracking), written with its scenario to --out. What the
        /// model reaches when nothing is cut, the baseline of a cut scene's Dice deficit.
        #[arg(long, requires = "out", conflicts_with_all = ["family", "video"])]
        intact: bool,
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

mod commands;
use commands::*;

/// What the hidden `count-frames` subcommand and the `incise-count-frames` program take: one
/// scene and one solver setting, stepped with nothing printed, for callgrind to count.
#[derive(Args, Debug)]
pub struct CountFramesArgs {
    /// The scene directory.
    pub scene: PathBuf,
    /// `refactor`, `frozen`, `factor-once` or `quasi-newton`.
    #[arg(long)]
    pub strategy: String,
    /// Newton steps per frame.
    #[arg(long)]
    pub newton: u32,
    /// PCG steps.
    #[arg(long)]
    pub pcg: u32,
    /// Line-search trials per Newton step.
    #[arg(long)]
    pub line_search: u32,
    /// Frames to step after frame 0.
    #[arg(long)]
    pub frames: usize,
    /// The scalar type the core computes in.
    #[arg(long, value_enum, default_value_t = Precision::F64)]
    pub real: Precision,
}

/// Runs `count-frames` with `args` and returns the exit status (0, or 1 after a message on
/// standard error): the whole of the `incise-count-frames` program, which calls this alone so
/// that it links neither the video driver nor the rest of the command line.
pub fn count_frames(args: &CountFramesArgs) -> i32 {
    match count_frames_command(args) {
        Ok(()) => 0,
        Err(Failure::BrokenPipe) => BROKEN_PIPE_STATUS,
        Err(Failure::Message(message)) => {
            let _ = writeln!(std::io::stderr(), "incise-count-frames: {message}");
            1
        }
    }
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
            real,
            law,
            pairs,
            video: None,
            calibration: _,
        } => run_command(&scene, json, out, true_cut, (real, law, pairs)),
        Command::Run {
            scene,
            json,
            out,
            pairs,
            video: Some(video),
            calibration,
            ..
        } => run_video_command(&scene, &video, calibration.as_deref(), json, (out, pairs)),
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
            law,
            seed,
            model_mesh,
            pictures,
            set,
            sweep,
            plot,
            evidence,
        } => {
            let options = crate::eval::EvalOptions {
                work,
                selection: crate::eval::Selection { per_kind },
                fresh,
                progress: true,
                law,
                seed,
                model_mesh,
                pictures,
                detection: set,
                evidence,
            };
            if sweep.is_empty() {
                if plot.is_some() && !evidence {
                    Err(String::from("--plot needs --sweep or --evidence").into())
                } else {
                    eval_command(&families, &options, variants, json, plot.as_deref())
                }
            } else {
                eval_sweep_command(&families, &options, &sweep, plot.as_deref(), json)
            }
        }
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
            model_mesh,
            intact,
        } => gen_command(&scenarios, out, video, model_mesh, intact),
        Command::Codegen {
            scene,
            out,
            frames,
            footprint,
            ram_budget_kib,
        } => codegen_command(&scene, &out, frames, footprint, ram_budget_kib),
        Command::Table {
            scenes,
            true_cut,
            filter,
            real,
            law,
            set,
        } => table_command(&scenes, (true_cut, filter), (real, law), &set),
        Command::Sweep { scene, out } => sweep_command(&scene, out.as_deref()),
        Command::Instructions {
            scene,
            frames,
            real,
        } => instructions_command(&scene, frames, real),
        Command::Report { scenes, out, quick } => report_command(&scenes, &out, quick),
        Command::CountFrames(args) => count_frames_command(&args),
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
