//! The symbols of a built program, from binutils' `nm`: what the no-heap and firmware tests
//! check is (or is not) linked.

use std::path::Path;
use std::process::Command;

/// Symbol names (defined or referenced) of a library or executable, mangled as linked.
pub fn names(file: &Path) -> Vec<String> {
    let out = Command::new("nm")
        .arg("--format=posix")
        .arg(file)
        .output()
        .expect("nm (binutils) runs");
    assert!(out.status.success(), "nm failed on {}", file.display());
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|line| line.split_whitespace().next())
        .map(str::to_owned)
        .collect()
}

/// Allocator symbols (defined or referenced) of a library or executable, by name: Rust's
/// allocator shims and `alloc`'s raw vectors, and the C heap.
pub fn allocator_symbols(file: &Path) -> Vec<String> {
    const PARTS: [&str; 9] = [
        "rust_alloc",
        "rust_dealloc",
        "rust_realloc",
        "rg_alloc",
        "rdl_alloc",
        "alloc_error_handler",
        "no_alloc_shim",
        "5alloc7raw_vec",
        "GlobalAlloc",
    ];
    const C_HEAP: [&str; 7] = [
        "malloc",
        "calloc",
        "realloc",
        "free",
        "posix_memalign",
        "aligned_alloc",
        "memalign",
    ];
    let mut found: Vec<String> = names(file)
        .into_iter()
        .filter(|sym| {
            PARTS.iter().any(|p| sym.contains(p))
                || C_HEAP.contains(&sym.split('@').next().unwrap_or(sym))
        })
        .collect();
    found.sort();
    found.dedup();
    found
}
