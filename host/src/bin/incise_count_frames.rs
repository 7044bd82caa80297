//! `incise-count-frames`: the hidden `incise count-frames` as a program of its own, which
//! `incise report` and `incise instructions` run under callgrind when it lies beside the
//! `incise` binary. It links nothing of the video driver: a build with the `opencv` feature
//! loads some 250 shared libraries at start-up, which took valgrind about 6 s on every counted
//! run (8.2 s against 3.0 s for the two frames of `band-no-cut`).

use clap::Parser;

/// Steps a scene's model with one solver setting and prints nothing (see `incise
/// count-frames`).
#[derive(Parser)]
#[command(name = "incise-count-frames")]
struct Cli {
    #[command(flatten)]
    args: incise::cli::CountFramesArgs,
}

fn main() {
    incise::vtu::quiet_reader_panics();
    let cli = Cli::parse();
    std::process::exit(incise::cli::count_frames(&cli.args));
}
