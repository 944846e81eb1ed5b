//! Procedural meshes of the built-in objects. (Owned by the catalog work; to be filled in.)

use serde::{Deserialize, Serialize};

/// Parameters of a built-in procedural shape.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ProceduralShape {
    Box { size: [f64; 3] },
}
