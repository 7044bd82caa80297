//! What several test files of the host share.

use std::path::{Path, PathBuf};

/// Every committed scene's directory (those holding a `scene.toml`), sorted.
pub fn committed_scenes() -> Vec<PathBuf> {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures");
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(&fixtures)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("scene.toml").exists())
        .collect();
    dirs.sort();
    dirs
}
