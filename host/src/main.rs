//! The `incise` program: parses the command line and runs the command ([`incise::cli`]).

use clap::Parser;

fn main() {
    incise::vtu::quiet_reader_panics();
    let cli = incise::cli::Cli::parse();
    std::process::exit(incise::cli::run(cli));
}
