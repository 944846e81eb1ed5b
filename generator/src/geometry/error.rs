//! Why a mesh query cannot be built or answered ([`GeometryError`]), apart
//! from the queries: the catalog's and the planner's errors wrap it, and it
//! imports no more of the generator than the Python error it wraps.

use crate::python::PythonError;
use pyo3::PyErr;

/// Why a mesh query cannot be built or answered.
#[derive(Debug, thiserror::Error)]
pub enum GeometryError {
    /// The embedded Python (trimesh) is not usable.
    #[error(transparent)]
    Python(#[from] PythonError),
    #[error("the mesh has no triangles")]
    NoTriangles,
    #[error("face {face:?} indexes past the {vertices} vertices")]
    FacePastVertices { face: [u32; 3], vertices: usize },
    #[error("the mesh has a non-finite vertex coordinate")]
    NonFinite,
    /// A trimesh call raised; `what` is the call, `reason` Python's
    /// exception as text (a `PyErr` needs the interpreter to print).
    #[error("{what}: {reason}")]
    Trimesh { what: String, reason: String },
    #[error("first_hits: {origins} origins but {directions} directions")]
    RayCount { origins: usize, directions: usize },
    #[error("{what}: Python returned {got} results for {want} queries")]
    ResultCount {
        what: &'static str,
        got: usize,
        want: usize,
    },
    #[error("a convex hull needs at least 4 points, got {0}")]
    TooFewPoints(usize),
    #[error("closest_points on a mesh without triangles")]
    Empty,
}

pub type Result<T, E = GeometryError> = std::result::Result<T, E>;

impl GeometryError {
    pub(super) fn trimesh(what: impl Into<String>, e: PyErr) -> Self {
        GeometryError::Trimesh {
            what: what.into(),
            reason: e.to_string(),
        }
    }
}
