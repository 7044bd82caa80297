//! What several test files of the host share.

use std::path::{Path, PathBuf};

/// Every committed scene's directory (those holding a `scene.toml`), sorted.
#[allow(dead_code)] // not every test file that shares this module uses each function
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

/// Copies the directory `from`, and those under it, to `to`.
#[allow(dead_code)]
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        let q = to.join(p.file_name().unwrap());
        if p.is_dir() {
            copy_dir(&p, &q);
        } else {
            std::fs::copy(&p, &q).unwrap();
        }
    }
}
