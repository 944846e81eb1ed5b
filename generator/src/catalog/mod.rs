//! The object catalog: one file per object in `objects/`, each with a mesh
//! (built-in procedural or external file) and its grasp parts.

pub mod model;
pub mod procedural;

pub use model::*;
