use clap::Parser;

fn main() {
    let cli = incise::cli::Cli::parse();
    std::process::exit(incise::cli::run(cli));
}
