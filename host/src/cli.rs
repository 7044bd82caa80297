//! The `incise` command line.

use clap::{Parser, Subcommand};

/// incise: keeps a pre-operative organ model aligned with endoscopic video while the surgeon cuts.
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
    /// Run the shipped default scene and write pictures to ./incise-demo/.
    Demo,
}

/// Runs the parsed command line; returns the process exit code.
pub fn run(cli: Cli) -> i32 {
    match cli.command {
        Command::Demo => {
            println!(
                "incise demo: the scene pipeline is not built yet (see the open issues); \
                 the sparse LDLᵀ core is in place and tested by `cargo test --workspace`."
            );
            0
        }
    }
}
