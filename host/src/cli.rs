//! The `incise` command line.

use std::path::{Path, PathBuf};

use clap::{Parser, Subcommand};

use crate::generate::pipeline::generate;
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
        /// Write overlay pictures (PNG) and the deformed mesh per frame (VTU) here.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Run several scenes and print a Markdown table of their results (as in the README).
    Table {
        /// Scene directories.
        #[arg(required = true)]
        scenes: Vec<PathBuf>,
    },
    /// Generate scenes: simulate each scenario's real object and write the scene beside it.
    Gen {
        /// Scenario files (scenario.toml).
        #[arg(required = true)]
        scenarios: Vec<PathBuf>,
        /// Write the scene here instead of the scenario's directory (one scenario only).
        #[arg(long)]
        out: Option<PathBuf>,
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

/// Runs the parsed command line; returns the process exit code.
pub fn run(cli: Cli) -> i32 {
    let result = match cli.command {
        Command::Demo { out } => demo(&out),
        Command::Run { scene, json, out } => run_command(&scene, json, out),
        Command::Gen { scenarios, out } => gen_command(&scenarios, out),
        Command::Table { scenes } => table_command(&scenes),
    };
    match result {
        Ok(()) => 0,
        Err(message) => {
            eprintln!("incise: {message}");
            1
        }
    }
}

fn run_command(dir: &Path, json: bool, out: Option<PathBuf>) -> Result<(), String> {
    let scene = Scene::load(dir).map_err(|e| e.to_string())?;
    let options = RunOptions {
        out: out.clone(),
        progress: !json,
    };
    let (summary, _) = run_scene(&scene, &options).map_err(|e| e.to_string())?;
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?
        );
    } else {
        print!("{}", crate::report::human_summary(&summary));
        if let Some(out) = out {
            println!("pictures and meshes: {}", out.display());
        }
    }
    Ok(())
}

fn table_command(dirs: &[PathBuf]) -> Result<(), String> {
    let mut rows = vec![];
    for dir in dirs {
        let scene = Scene::load(dir).map_err(|e| e.to_string())?;
        let (summary, _) = run_scene(&scene, &RunOptions::default()).map_err(|e| e.to_string())?;
        rows.push(summary);
    }
    print!("{}", crate::report::markdown_table(&rows));
    Ok(())
}

fn gen_command(scenarios: &[PathBuf], out: Option<PathBuf>) -> Result<(), String> {
    if out.is_some() && scenarios.len() > 1 {
        return Err("--out takes one scenario at a time".into());
    }
    for path in scenarios {
        let dir = match &out {
            Some(o) => o.clone(),
            None => path
                .parent()
                .map_or_else(|| PathBuf::from("."), Path::to_path_buf),
        };
        let g = generate(path, &dir, true).map_err(|e| format!("{}: {e}", path.display()))?;
        println!(
            "{}: {} frames, {} features, real mesh {} nodes / {} tets, model {} nodes / {} tets, cut opens at frame {}",
            g.dir.display(),
            g.frames,
            g.features,
            g.fine_size.0,
            g.fine_size.1,
            g.model_size.0,
            g.model_size.1,
            g.cut_open_frame.map_or("-".to_string(), |f| f.to_string())
        );
    }
    Ok(())
}

fn demo(out: &Path) -> Result<(), String> {
    let dir = fixtures_dir().join("band-side-cut");
    let scene = Scene::load(&dir).map_err(|e| e.to_string())?;
    println!(
        "incise demo: {} ({})",
        scene.file.name, scene.file.description
    );
    let frames_dir = out.join("frames");
    let options = RunOptions {
        out: Some(frames_dir.clone()),
        progress: true,
    };
    let (summary, trace) = run_scene(&scene, &options).map_err(|e| e.to_string())?;
    print!("{}", crate::report::human_summary(&summary));
    let sheet = out.join("overview.png");
    crate::report::contact_sheet(&frames_dir, &trace, &sheet).map_err(|e| e.to_string())?;
    let plot = out.join("dice.svg");
    crate::report::plot_dice(&trace, &summary, &plot).map_err(|e| e.to_string())?;
    println!(
        "pictures: {} (frames), {} (overview), {} (Dice per frame)",
        frames_dir.display(),
        sheet.display(),
        plot.display()
    );
    Ok(())
}
