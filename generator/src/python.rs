//! Finding and initialising the embedded Python environment.
//!
//! `grasp-gen` embeds CPython 3.11 (through pyo3) to call trimesh for geometric
//! queries and Blender's `bpy` module for rendering. The packages live in the
//! project's virtual environment, found by [`grasp_support::venv`] (the
//! trainer finds pretrained weights in it the same way); `scripts/setup.sh`
//! creates it.

use pyo3::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

pub use grasp_support::venv::{setup_hint, venv_dir, workspace_root, MissingVenv, VENV_ENV_VAR};

/// Why the embedded Python cannot be used. Each message says what to fix:
/// the venv's path, or the module that does not import and from where.
#[derive(Debug, Clone, thiserror::Error)]
pub enum PythonError {
    /// The venv (its `site-packages`) is not there, or could not be added
    /// to Python's path; kept as text because the first failure is
    /// remembered for the whole process and reported to every caller.
    #[error("{0}")]
    Environment(String),
    /// A required module does not import.
    #[error(
        "checking the Python environment: cannot import Python module '{module}' from {}: \
         {reason}; {}",
        site.display(),
        setup_hint()
    )]
    Import {
        module: String,
        site: PathBuf,
        /// Python's exception, as text (a `PyErr` needs the interpreter).
        reason: String,
    },
}

pub type Result<T, E = PythonError> = std::result::Result<T, E>;

/// `site-packages` of the venv, checked to exist.
pub fn site_packages(venv: &Path) -> std::result::Result<PathBuf, MissingVenv> {
    grasp_support::venv::site_packages(venv)
}

static INITIALISED: OnceLock<Result<PathBuf, String>> = OnceLock::new();

/// Makes the venv's packages importable in the embedded interpreter (once per
/// process) and checks that the required modules import.
pub fn init(required_modules: &[&str]) -> Result<()> {
    let site = INITIALISED
        .get_or_init(|| {
            let venv = venv_dir();
            let site = site_packages(&venv).map_err(|e| e.to_string())?;
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
        .map_err(|e| PythonError::Environment(e.clone()))?;
    Python::attach(|py| -> Result<()> {
        for module in required_modules {
            py.import(*module).map_err(|e| PythonError::Import {
                module: module.to_string(),
                site: site.clone(),
                reason: e.to_string(),
            })?;
        }
        Ok(())
    })
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
