//! What can go wrong when reading, checking or importing a catalog. Every
//! message names the file, the object and the field it is about; the error
//! a failure comes from is its `source`, not repeated in the message.

use crate::geometry::error::GeometryError;
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum CatalogError {
    /// A file or folder that cannot be read or written; `action` says what
    /// was being done ("reading object file").
    #[error(transparent)]
    Io(#[from] grasp_support::IoAt),
    /// A file cannot be written (atomically).
    #[error(transparent)]
    Write(#[from] grasp_support::atomic::WriteError),
    /// An object file that is not TOML of the object file's shape.
    #[error("{}: malformed object file", path.display())]
    MalformedObject {
        path: PathBuf,
        #[source]
        source: toml::de::Error,
    },
    /// A JSON file (the YCB annotations) that does not parse.
    #[error("{}: malformed JSON", path.display())]
    MalformedJson {
        path: PathBuf,
        #[source]
        source: serde_json::Error,
    },
    /// A catalog folder without object files.
    #[error("the catalog folder {} holds no *.toml object files", dir.display())]
    Empty { dir: PathBuf },
    /// Two object files with the same id.
    #[error("{}: field 'id': duplicate object id '{id}' (also in {first})", path.display())]
    DuplicateId {
        path: PathBuf,
        id: String,
        first: String,
    },
    /// A field (of an object file, a part, an annotation) that is not valid;
    /// `what` names the file, object and field.
    #[error("{what}: {reason}")]
    Invalid { what: String, reason: String },
    /// A mesh file that cannot be read.
    #[error("reading mesh {}", path.display())]
    ReadMesh {
        path: PathBuf,
        #[source]
        source: MeshError,
    },
    /// A mesh file that reads but is not a usable triangle mesh.
    #[error("mesh {}", path.display())]
    BadMesh {
        path: PathBuf,
        #[source]
        source: MeshError,
    },
    /// A failure about one object or part (`what` names it), from below.
    #[error("{what}")]
    At {
        what: String,
        #[source]
        source: Box<CatalogError>,
    },
    /// A mesh query (or convex hull) failed.
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    /// A mesh query failed for the object or field `what`.
    #[error("{what}")]
    GeometryAt {
        what: String,
        #[source]
        source: GeometryError,
    },
    /// A line of a point file (`points.xyz`) that is not three numbers.
    #[error("{}:{line}: not three numbers", path.display())]
    NotThreeNumbers {
        path: PathBuf,
        line: usize,
        #[source]
        source: Option<std::num::ParseFloatError>,
    },
    /// An object of the YCB annotations that cannot be imported.
    #[error(transparent)]
    Annotation(#[from] AnnotationError),
    /// Two catalogs that should have the same grasp types per object.
    #[error("the catalogs differ in grasp types per object:\n  {}: {a}\n  {}: {b}", a_dir.display(), b_dir.display())]
    GraspTypesDiffer {
        a_dir: PathBuf,
        a: String,
        b_dir: PathBuf,
        b: String,
    },
}

pub type Result<T, E = CatalogError> = std::result::Result<T, E>;

impl CatalogError {
    pub(crate) fn io(
        action: &'static str,
        path: impl Into<PathBuf>,
        source: std::io::Error,
    ) -> Self {
        CatalogError::Io(grasp_support::IoAt::new(action, path, source))
    }

    pub(crate) fn invalid(what: impl Into<String>, reason: impl Into<String>) -> Self {
        CatalogError::Invalid {
            what: what.into(),
            reason: reason.into(),
        }
    }

    /// This error, about the object or field `what`.
    pub(crate) fn at(self, what: impl Into<String>) -> Self {
        CatalogError::At {
            what: what.into(),
            source: Box::new(self),
        }
    }
}

/// Why a mesh file is not a usable triangle mesh.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    #[error("unsupported mesh format '.{0}' (expected .ply, .obj or .stl)")]
    UnsupportedFormat(String),
    #[error(transparent)]
    Io(#[from] std::io::Error),
    #[error("malformed PLY")]
    Ply(#[source] ply_rs_bw::parser::ParseError),
    #[error("the PLY has no '{0}' element")]
    NoElement(&'static str),
    #[error("vertex {vertex} has no numeric '{coordinate}'")]
    NoCoordinate {
        vertex: usize,
        coordinate: &'static str,
    },
    #[error("face {0} has no 'vertex_indices'")]
    NoIndices(usize),
    #[error("face {0}: 'vertex_indices' is not an integer list")]
    IndicesNotIntegers(usize),
    #[error(transparent)]
    Obj(#[from] tobj::LoadError),
    #[error("malformed STL")]
    Stl(#[source] std::io::Error),
    #[error("the mesh has no triangles")]
    NoTriangles,
    #[error("face {face} {indices:?} refers to a vertex past the {vertices} vertices")]
    FacePastVertices {
        face: usize,
        indices: [u32; 3],
        vertices: usize,
    },
    #[error("a vertex coordinate is not finite")]
    NonFinite,
}

/// Why an object or grasp of the YCB annotations cannot be imported (the
/// caller names the file, object and grasp).
#[derive(Debug, thiserror::Error)]
pub enum AnnotationError {
    #[error("no {0}")]
    Missing(&'static str),
    #[error("no '{0}'")]
    NoVector(String),
    #[error("'{0}' needs 3 numbers")]
    NotThree(String),
    #[error("{0}")]
    Shape(&'static str),
    #[error("{grasps} grasps but {boxes} boxes")]
    Count { grasps: usize, boxes: usize },
    #[error(transparent)]
    GraspType(grasp_schema::taxonomy::UnknownName),
    #[error("up_axis_in_mesh_frame {0:?} is not a direction")]
    NotADirection([f64; 3]),
    #[error("serialising the object file")]
    Serialise(#[source] toml::ser::Error),
}
