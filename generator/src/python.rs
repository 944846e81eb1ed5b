//! Finding and initialising the embedded Python environment.
//!
//! `grasp-gen` embeds CPython 3.11 (through pyo3) to call trimesh for geometric
//! queries and Blender's `bpy` module for rendering. The packages live in a
//! virtual environment built from the repository's `pyproject.toml`:
//!
//! 1. `$GRASP_VENV`, if set;
//! 2. otherwise `.venv` in the nearest ancestor of the current directory that
//!    holds `pyproject.toml`;
//! 3. otherwise `.venv` next to the workspace this binary was built from.
//!
//! `scripts/setup.sh` creates it.

use anyhow::{bail, Context, Result};
use pyo3::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

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
        for dir in cwd.ancestors() {
            if dir.join("pyproject.toml").is_file() && dir.join(".venv").is_dir() {
                return dir.join(".venv");
            }
        }
    }
    workspace_root().join(".venv")
}

/// Root of the workspace this binary was built from.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// `site-packages` of the venv, checked to exist.
pub fn site_packages(venv: &Path) -> Result<PathBuf> {
    let dir = venv
        .join("lib")
        .join(PYTHON_VERSION_DIR)
        .join("site-packages");
    if !dir.is_dir() {
        bail!(
            "Python environment not found: {} does not exist; {}",
            dir.display(),
            setup_hint()
        );
    }
    Ok(dir)
}

static INITIALISED: OnceLock<Result<PathBuf, String>> = OnceLock::new();

/// Makes the venv's packages importable in the embedded interpreter (once per
/// process) and checks that the required modules import.
pub fn init(required_modules: &[&str]) -> Result<()> {
    let site = INITIALISED
        .get_or_init(|| {
            let venv = venv_dir();
            let site = site_packages(&venv).map_err(|e| format!("{e:#}"))?;
            Python::attach(|py| -> PyResult<()> {
                // addsitedir also processes .pth files, which is how the
                // editable install of `blender_scripts` is found.
                py.import("site")?
                    .call_method1("addsitedir", (site.to_string_lossy().as_ref(),))?;
                Ok(())
            })
            .map_err(|e| format!("cannot add {} to Python's path: {e}", site.display()))?;
            Ok(site)
        })
        .as_ref()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    Python::attach(|py| -> Result<()> {
        for module in required_modules {
            py.import(*module).map_err(|e| {
                anyhow::anyhow!(
                    "cannot import Python module '{module}' from {}: {e}; {}",
                    site.display(),
                    setup_hint()
                )
            })?;
        }
        Ok(())
    })
    .context("checking the Python environment")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_venv_names_the_path_and_the_fix() {
        let err = site_packages(Path::new("/nonexistent/venv")).unwrap_err();
        let msg = format!("{err:#}");
        assert!(msg.contains("/nonexistent/venv/lib/python3.11/site-packages"));
        assert!(msg.contains("scripts/setup.sh"));
    }
}
