//! The object catalog: one file per object in `objects/`, each with a mesh
//! (built-in procedural or external file) and its grasp parts.

pub mod error;
pub mod load;
pub mod mesh;
pub mod meshio;
pub mod model;
pub mod procedural;
pub mod shapes;
pub mod validate;
pub mod ycb;

pub use error::{AnnotationError, CatalogError, MeshError, Result};
pub use load::{builtin_dir, compare_grasp_types, Catalog, ObjectFile, PartFile, OBJECTS_ENV_VAR};

/// The comparison `grasp-gen objects check --mesh-dir` makes, where it
/// was before the command moved into the binary.
pub mod cli {
    pub use super::load::compare_grasp_types;
}
pub use mesh::TriMesh;
pub use model::*;
