//! The triangle mesh type every catalog module builds or reads: procedural
//! shapes, mesh files and the object model all depend on it, and it depends
//! on none of them.

/// A triangle mesh in the object frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    pub vertices: Vec<[f64; 3]>,
    pub faces: Vec<[u32; 3]>,
}
