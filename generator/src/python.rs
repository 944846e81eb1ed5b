//! Finding and initialising the embedded Python environment.
//!
//! `grasp-gen` embeds CPython 3.11 (through pyo3) to call trimesh for geometric
//! queries and Blender's `bpy` module for rendering. The packages live in the
//! project's virtual environment, found by [`grasp_support::venv`] (the
//! trainer finds pretrained weights in it the same way); `scripts/setup.sh`
//! creates it.

use anyhow::{Context, Result};
use pyo3::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

pub use grasp_support::venv::{setup_hint, venv_dir, workspace_root, VENV_ENV_VAR};

/// `site-packages` of the venv, checked to exist.
pub fn site_packages(venv: &Path) -> Result<PathBuf> {
    Ok(grasp_support::venv::site_packages(venv)?)
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
