//! The object catalog: one file per object in `objects/`, each with a mesh
//! (built-in procedural or external file) and its grasp parts.

pub mod cli;
pub mod load;
pub mod mesh;
pub mod meshio;
pub mod model;
pub mod procedural;
pub mod shapes;
pub mod validate;
pub mod ycb;

pub use load::{builtin_dir, Catalog, ObjectFile, PartFile, OBJECTS_ENV_VAR};
pub use mesh::TriMesh;
pub use model::*;
