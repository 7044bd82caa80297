//! Running a benchmark's own binary under callgrind (`valgrind --tool=callgrind`), as the
//! instruction-count tables of the benchmarks do.

use std::path::Path;
use std::process::Command;

/// Runs `exe` with `args` under callgrind with one `option` (`--dump-after=…`,
/// `--toggle-collect=…`), its counts written to `out` (and `out.N` for dumps), and returns what
/// the program printed.
///
/// # Panics
/// If valgrind cannot be started or the run fails, with valgrind's error output: a benchmark
/// harness has no one to hand the error to.
pub fn run(exe: &Path, option: &str, out: &Path, args: &[&str]) -> String {
    let output = Command::new("valgrind")
        .arg("--tool=callgrind")
        .arg(option)
        .arg(format!("--callgrind-out-file={}", out.display()))
        .arg(exe)
        .args(args)
        .output()
        .expect("valgrind runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}
