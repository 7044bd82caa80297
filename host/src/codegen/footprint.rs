//! The firmware program of a generated scene (`firmware/` in the source tree), built for a
//! feature set of the core, linked into an executable with a small C `main`, and measured:
//! static RAM (`.data` + `.bss`) and code (`.text`, `.rodata`), from binutils' `size`.
//!
//! The executable also holds the C start-up and `main`; a baseline linked from the same
//! `main` without the firmware is measured too and taken off, so the figures are the
//! firmware's own. Building needs the source tree (this host finds `firmware/` beside the
//! sources it was built from), `cargo`, a C compiler (`cc`) and binutils.

use std::fmt;
use std::path::{Path, PathBuf};
use std::process::Command;

use incise_core::{Projection, Strategy};

use super::CodegenError;

/// A set of the core's features a firmware build is made with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FeatureSet {
    /// How the README and the footprint table name it.
    pub name: &'static str,
    /// Features of the `firmware` package.
    pub features: &'static [&'static str],
    /// What it leaves out.
    pub leaves_out: &'static str,
}

impl FeatureSet {
    /// A directory name for its build: the name, letters and digits kept, `-` between words.
    pub fn dir_name(&self) -> String {
        self.name
            .split(|c: char| !c.is_ascii_alphanumeric())
            .filter(|w| !w.is_empty())
            .collect::<Vec<_>>()
            .join("-")
    }
}

/// The feature sets CI builds and the README lists, from everything to the least.
pub const FEATURE_SETS: [FeatureSet; 3] = [
    FeatureSet {
        name: "cut",
        features: &["cut", "strategies", "temporal-filter", "cameras", "f64"],
        leaves_out: "nothing: detection, the cut line, and cutting the mesh (which orders and analyses each cut mesh)",
    },
    FeatureSet {
        name: "detect",
        features: &["detect", "strategies", "temporal-filter", "cameras", "f64"],
        leaves_out: "cutting the mesh: its spare topology, the mesh surgery, the minimum-degree ordering and the symbolic analysis",
    },
    FeatureSet {
        name: "register",
        features: &["strategies", "cameras", "f64"],
        leaves_out: "also the cut detection and the cut line",
    },
];

/// Everything, computing in `f32`.
pub const CUT_F32: FeatureSet = FeatureSet {
    name: "cut, f32",
    features: &["cut", "strategies", "temporal-filter", "cameras", "f32"],
    leaves_out: "f64: computes in f32, 4 bytes less per scalar of the storage",
};

/// Everything, in mixed precision: the model in `f64`, its factor and solves in `f32`.
pub const CUT_MIXED: FeatureSet = FeatureSet {
    name: "cut, mixed",
    features: &["cut", "strategies", "temporal-filter", "cameras", "mixed"],
    leaves_out: "f64 in the factor: an f32 factor refined on f64 residuals, 4 bytes less per scalar of the factor's storage",
};

/// Everything but the detection's temporal filter.
pub const CUT_NO_TEMPORAL_FILTER: FeatureSet = FeatureSet {
    name: "cut, no temporal filter",
    features: &["cut", "strategies", "cameras", "f64"],
    leaves_out: "the detection's temporal filter (no feature is taken out as a tracking failure)",
};

/// [`FEATURE_SETS`] with [`CUT_F32`], [`CUT_MIXED`] and [`CUT_NO_TEMPORAL_FILTER`] after the
/// first, and, last, registration with only the scene's linear strategy and camera projection.
pub fn feature_sets(strategy: Strategy, projection: Projection) -> [FeatureSet; 7] {
    let [cut, detect, register] = FEATURE_SETS;
    // Every pair, so that each name and feature list is a `'static` constant.
    let one = |name, features| FeatureSet {
        name,
        features,
        leaves_out: "also the other linear strategies and the other camera projection",
    };
    use Projection::{Orthographic as O, Perspective as P};
    let minimal = match (strategy, projection) {
        (Strategy::Refactor, P) => one(
            "register, refactor, perspective",
            &["refactor", "perspective", "f64"],
        ),
        (Strategy::Refactor, O) => one(
            "register, refactor, orthographic",
            &["refactor", "orthographic", "f64"],
        ),
        (Strategy::Frozen { .. }, P) => one(
            "register, frozen, perspective",
            &["frozen", "perspective", "f64"],
        ),
        (Strategy::Frozen { .. }, O) => one(
            "register, frozen, orthographic",
            &["frozen", "orthographic", "f64"],
        ),
        (Strategy::FactorOnce { .. }, P) => one(
            "register, factor-once, perspective",
            &["factor-once", "perspective", "f64"],
        ),
        (Strategy::FactorOnce { .. }, O) => one(
            "register, factor-once, orthographic",
            &["factor-once", "orthographic", "f64"],
        ),
        (Strategy::QuasiNewton, P) => one(
            "register, quasi-newton, perspective",
            &["quasi-newton", "perspective", "f64"],
        ),
        (Strategy::QuasiNewton, O) => one(
            "register, quasi-newton, orthographic",
            &["quasi-newton", "orthographic", "f64"],
        ),
    };
    [
        cut,
        CUT_F32,
        CUT_MIXED,
        CUT_NO_TEMPORAL_FILTER,
        detect,
        register,
        minimal,
    ]
}

/// Section sizes of a firmware build, bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Footprint {
    /// Code.
    pub text: u64,
    /// Constants: the scene's mesh, analysis and tracks.
    pub rodata: u64,
    /// Initialised statics.
    pub data: u64,
    /// Zeroed statics: the model's storage.
    pub bss: u64,
}

impl Footprint {
    /// Static RAM: `.data` + `.bss`.
    pub fn ram(&self) -> u64 {
        self.data + self.bss
    }

    /// What the program's image holds: `.text` + `.rodata` + `.data`.
    pub fn flash(&self) -> u64 {
        self.text + self.rodata + self.data
    }

    fn minus(&self, base: &Footprint) -> Footprint {
        Footprint {
            text: self.text.saturating_sub(base.text),
            rodata: self.rodata.saturating_sub(base.rodata),
            data: self.data.saturating_sub(base.data),
            bss: self.bss.saturating_sub(base.bss),
        }
    }
}

impl fmt::Display for Footprint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "RAM {} KiB (.data {} B, .bss {} B), code {} KiB (.text), constants {} KiB (.rodata)",
            kib(self.ram()),
            self.data,
            self.bss,
            kib(self.text),
            kib(self.rodata)
        )
    }
}

/// Bytes as KiB, one decimal.
pub fn kib(bytes: u64) -> String {
    format!("{:.1}", bytes as f64 / 1024.0)
}

/// The firmware program's sources, beside the sources this host was built from.
pub fn firmware_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("firmware")
}

/// The C `main` of the firmware executable: runs the firmware and prints each node's position
/// as `node x y z`, the coordinates as the hexadecimal bits of their `f64`. With `BASELINE`
/// defined it stands alone (the firmware replaced by a stub), to measure what `main` and the C
/// start-up take.
const MAIN_C: &str = r#"#include <stdint.h>
#include <stdio.h>
#include <string.h>

typedef void (*emit_fn)(uint32_t, double, double, double);
#ifdef BASELINE
int incise_firmware_run(emit_fn emit) { emit(0, 0.0, 0.0, 0.0); return 0; }
#else
int incise_firmware_run(emit_fn emit);
#endif

static void emit(uint32_t v, double x, double y, double z) {
    uint64_t b[3];
    memcpy(&b[0], &x, 8);
    memcpy(&b[1], &y, 8);
    memcpy(&b[2], &z, 8);
    printf("%u %016llx %016llx %016llx\n", v, (unsigned long long)b[0],
           (unsigned long long)b[1], (unsigned long long)b[2]);
}

int main(void) {
    int r = incise_firmware_run(emit);
    if (r != 0) fprintf(stderr, "the firmware stopped: %d\n", r);
    return r;
}
"#;

/// A built firmware executable.
#[derive(Clone, Debug)]
pub struct Firmware {
    /// The executable.
    pub exe: PathBuf,
    /// Its sections, less the baseline's.
    pub footprint: Footprint,
}

fn run(cmd: &mut Command, what: &str) -> Result<std::process::Output, CodegenError> {
    let out = cmd
        .output()
        .map_err(|e| CodegenError(format!("{what}: cannot run: {e}")))?;
    if !out.status.success() {
        return Err(CodegenError(format!(
            "{what} failed:\n{}",
            String::from_utf8_lossy(&out.stderr)
        )));
    }
    Ok(out)
}

/// `cargo build --release --locked --no-default-features` of the crate in `crate_dir` with
/// `features`, into `target_dir`, with nothing of an outer build leaking in (the
/// `CARGO_FEATURE_*` and rust flags cargo sets for a build script or a test): how the
/// firmware program and the no-heap check (`tests/no_heap.rs`) are built on their own, so that
/// the outer build's feature unification cannot switch on `std` in their dependencies.
pub fn isolated_release_build(
    crate_dir: &Path,
    features: &[impl AsRef<str>],
    target_dir: &Path,
) -> Command {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut cmd = Command::new(cargo);
    cmd.current_dir(crate_dir)
        .args([
            "build",
            "--release",
            "--locked",
            "--no-default-features",
            "--target-dir",
        ])
        .arg(target_dir);
    if !features.is_empty() {
        let list: Vec<&str> = features.iter().map(AsRef::as_ref).collect();
        cmd.arg("--features").arg(list.join(","));
    }
    for (key, _) in std::env::vars() {
        if key.starts_with("CARGO_FEATURE_")
            || key == "RUSTFLAGS"
            || key == "CARGO_ENCODED_RUSTFLAGS"
        {
            cmd.env_remove(key);
        }
    }
    cmd
}

/// Builds the firmware program for the generated module `module` with `set`'s features (and the
/// core's `neo-hookean` where the scene's `law` needs it) in the cargo target directory
/// `target_dir`, links it with the C `main` into `target_dir/SET` ([`FeatureSet::dir_name`])
/// and measures it. The feature sets of one module can share `target_dir`: the dependencies
/// are then built once, and each set's build stays apart (cargo keeps one artifact per feature
/// set and puts the set's library in place whenever it is asked for, built or not), so that a
/// second round over the same sets and an unchanged module builds nothing.
///
/// # Errors
/// The build, link or measurement that failed, with its output.
pub fn build(
    module: &Path,
    set: &FeatureSet,
    law: incise_core::Law,
    target_dir: &Path,
) -> Result<Firmware, CodegenError> {
    let module = std::fs::canonicalize(module)
        .map_err(|e| CodegenError(format!("{}: {e}", module.display())))?;
    let law_feature: &[&str] = match law {
        incise_core::Law::StableNeoHookean => &["neo-hookean"],
        _ => &[],
    };
    let features: Vec<&str> = set.features.iter().chain(law_feature).copied().collect();
    let mut cmd = isolated_release_build(&firmware_dir(), &features, target_dir);
    cmd.env("INCISE_FIRMWARE_SCENE", &module);
    run(&mut cmd, "building the firmware program")?;
    let lib = target_dir.join("release").join("libincise_firmware.a");
    let out = target_dir.join(set.dir_name());
    std::fs::create_dir_all(&out).map_err(|e| CodegenError(format!("{}: {e}", out.display())))?;
    let main_c = out.join("main.c");
    std::fs::write(&main_c, MAIN_C)
        .map_err(|e| CodegenError(format!("{}: {e}", main_c.display())))?;
    let exe = out.join("firmware");
    let base = out.join("baseline");
    // --gc-sections keeps only what the program reaches; no PIE, so that constants holding
    // addresses stay in .rodata rather than in relocated data.
    let link = |out: &Path, extra: &[&std::ffi::OsStr]| {
        let mut cc = Command::new("cc");
        cc.arg("-O2")
            .arg("-no-pie")
            .arg("-o")
            .arg(out)
            .arg(&main_c)
            .arg("-Wl,--gc-sections")
            .args(extra);
        run(&mut cc, "linking the firmware program")
    };
    link(&exe, &[lib.as_os_str()])?;
    link(&base, &[std::ffi::OsStr::new("-DBASELINE")])?;
    let footprint = sections(&exe)?.minus(&sections(&base)?);
    Ok(Firmware { exe, footprint })
}

/// Section sizes of an executable, from `size -A`.
///
/// # Errors
/// `size` failing.
pub fn sections(exe: &Path) -> Result<Footprint, CodegenError> {
    let out = run(Command::new("size").arg("-A").arg(exe), "size")?;
    let mut f = Footprint::default();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let mut words = line.split_whitespace();
        let (Some(name), Some(bytes)) = (words.next(), words.next()) else {
            continue;
        };
        let Ok(bytes) = bytes.parse::<u64>() else {
            continue;
        };
        match name {
            ".text" => f.text += bytes,
            ".rodata" | ".data.rel.ro" => f.rodata += bytes,
            ".data" => f.data += bytes,
            ".bss" => f.bss += bytes,
            _ => {}
        }
    }
    Ok(f)
}

/// The demangled names of an executable's symbols, from `nm -C`.
///
/// # Errors
/// `nm` failing.
pub fn symbols(exe: &Path) -> Result<Vec<String>, CodegenError> {
    let out = run(Command::new("nm").arg("-C").arg(exe), "nm")?;
    Ok(String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| {
            // `address type name`, or `type name` for an undefined symbol.
            let mut parts = l.split_whitespace();
            let first = parts.next()?;
            let rest: Vec<&str> = parts.collect();
            let name = if first.len() == 1 {
                rest.join(" ")
            } else {
                rest.get(1..)?.join(" ")
            };
            Some(name)
        })
        .collect())
}
