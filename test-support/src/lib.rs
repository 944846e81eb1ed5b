//! What the workspace's tests repeat: running a program as a user does and
//! checking its command-line conventions ([`program`]), the prerequisites
//! that live outside the repository ([`prerequisite`]), opening a page in
//! headless Chromium ([`browser`]), and listing the files a program wrote
//! ([`files_under`]).
//! A dev-dependency only: nothing the programs ship links it.

pub mod browser;
pub mod prerequisite;
pub mod program;

pub use program::Program;

use std::path::{Path, PathBuf};

/// Every file under `dir`, recursively, in path order.
pub fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let p = entry.path();
        if p.is_dir() {
            out.extend(files_under(&p));
        } else {
            out.push(p);
        }
    }
    out.sort();
    out
}
