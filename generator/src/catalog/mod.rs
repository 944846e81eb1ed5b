//! The object catalog: one file per object in `objects/`, each with a mesh
//! (built-in procedural or external file) and its grasp parts.

pub mod bench;
pub mod cli;
pub mod load;
pub mod meshio;
pub mod model;
pub mod procedural;
pub mod shapes;
pub mod validate;
pub mod ycb;

pub use load::{builtin_dir, Catalog, ObjectFile, PartFile, OBJECTS_ENV_VAR};
pub use model::*;

use anyhow::{Context, Result};
use std::path::Path;

/// Writes a file atomically: a temporary file in the same folder, then a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    std::fs::write(&tmp, bytes).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("renaming to {}", path.display()))?;
    Ok(())
}
