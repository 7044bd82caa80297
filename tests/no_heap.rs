//! Proof that the core needs no heap: `nostd-check/` is a `#![no_std]`, `#![no_main]` program
//! (a staticlib with its own panic handler, `panic = "abort"`) that runs the core's
//! computations on stack buffers. It is built on its own with `cargo build --manifest-path`, so
//! the std host cannot switch on features of shared dependencies through feature unification.
//! The test then
//! The program factorizes a stiffness matrix, runs `Model::step` on a box held at one end, and
//! cuts a model held in `static` storage (the whole cut pipeline, rebuilt in place).
//! 1. lists every symbol of the library and fails on any allocator symbol,
//! 2. links it into an executable with a C `main` and runs it (the computation must check out),
//! 3. builds the same program with a global allocator and one `Vec` (feature `heap-control`)
//!    and checks that step 1 does see that heap, so the check cannot pass vacuously.

use std::path::{Path, PathBuf};

use incise::codegen::footprint::isolated_release_build;
use incise_validation::symbols::allocator_symbols;
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Builds the no_std program and returns the path of its static library.
fn build(features: &[&str]) -> PathBuf {
    // One target directory per feature set: both tests build the same library name, and
    // cargo copies its output to the same place, so they would race in one directory.
    let flavour = if features.is_empty() {
        "plain".to_string()
    } else {
        features.join("-")
    };
    let target_dir = root().join("target").join("nostd-check").join(flavour);
    let mut cmd = isolated_release_build(&root().join("nostd-check"), features, &target_dir);
    let status = cmd.status().expect("cargo runs");
    assert!(status.success(), "building nostd-check failed");
    target_dir.join("release").join("libincise_nostd_check.a")
}

/// Links the library with a C `main` that calls `checks` in order and runs it: 0 when every
/// computation checks out.
fn link_and_run(lib: &Path, checks: &[&str]) {
    let dir = lib.parent().expect("library directory").to_path_buf();
    let main_c = dir.join("main.c");
    let mut c = String::new();
    for name in checks {
        c.push_str(&format!("int incise_nostd_check_{name}(void);\n"));
    }
    c.push_str("int main(void) {\n");
    for (k, name) in checks.iter().enumerate() {
        c.push_str(&format!(
            "  {{ int r = incise_nostd_check_{name}(); if (r != 0) return {} + r; }}\n",
            10 * (k + 1)
        ));
    }
    c.push_str("  return 0;\n}\n");
    std::fs::write(&main_c, c).unwrap();
    let exe = dir.join("nostd-check");
    // --gc-sections drops the unwinding tables of the precompiled libcore, which nothing calls.
    let status = Command::new("cc")
        .arg("-o")
        .arg(&exe)
        .arg(&main_c)
        .arg("-Wl,--gc-sections")
        .arg(lib)
        .status()
        .expect("cc runs");
    assert!(status.success(), "linking the no_std program failed");
    let code = Command::new(&exe).status().expect("program runs").code();
    assert_eq!(
        code,
        Some(0),
        "the no_std computation failed: code 10k + r for check k of {checks:?}, r = 1 an error, \
         2 a wrong answer"
    );
}

#[test]
fn the_core_links_and_runs_without_a_heap() {
    let lib = build(&[]);
    let syms = allocator_symbols(&lib);
    assert!(syms.is_empty(), "allocator symbols linked: {syms:?}");
    link_and_run(&lib, &["sparse", "step"]);
}

#[test]
fn the_core_cuts_a_model_in_static_storage_without_a_heap() {
    let lib = build(&["cut"]);
    let syms = allocator_symbols(&lib);
    assert!(syms.is_empty(), "allocator symbols linked: {syms:?}");
    link_and_run(&lib, &["sparse", "step", "cut"]);
}

#[test]
fn the_symbol_check_sees_a_heap_when_there_is_one() {
    let lib = build(&["heap-control"]);
    let syms = allocator_symbols(&lib);
    assert!(
        syms.iter().any(|s| s.contains("rust_alloc")),
        "the negative control should link an allocator: {syms:?}"
    );
}
