//! What can go wrong when rendering: the sources of plans, meshes and part
//! boxes, the sensor effects and part labels a worker applies, and the
//! dataset and plans it writes and reads. Messages name the file, the
//! sequence and the object; the error a failure comes from is its `source`.

use crate::catalog::CatalogError;
use crate::config::error::ConfigError;
use crate::dataset::DatasetError;
use crate::plan::PlanError;
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// A file or folder operation failed; `action` says which ("cannot
    /// read", "cannot create", ...).
    #[error(transparent)]
    Io(#[from] grasp_support::IoAt),
    /// A file cannot be written atomically.
    #[error(transparent)]
    Write(#[from] grasp_support::atomic::WriteError),
    /// Encoding, decoding or writing an image failed; `what` says which.
    #[error("{what}")]
    Image {
        what: String,
        #[source]
        source: image::ImageError,
    },
    /// A pixel buffer whose length does not match its image size.
    #[error("{0}")]
    BufferSize(&'static str),
    /// A multilayer EXR that cannot be read.
    #[error("cannot read {}", path.display())]
    Exr {
        path: PathBuf,
        #[source]
        source: exr::error::Error,
    },
    /// A multilayer EXR without the channels the part labels need.
    #[error("{}: {reason}", path.display())]
    BadExr { path: PathBuf, reason: String },
    /// Part labels cannot be made (a degenerate box, too many parts, a
    /// depth image that does not match the camera).
    #[error("{0}")]
    Labels(String),
    /// A source without the mesh or the part boxes of an object.
    #[error("no {what} for object '{object}'")]
    NoObjectData { what: &'static str, object: String },
    /// An object the catalog does not have.
    #[error("unknown object '{object}'")]
    UnknownObject { object: String },
    /// An object's mesh cannot be had from the source.
    #[error("loading the mesh of object '{object}'")]
    Mesh {
        object: String,
        #[source]
        source: Box<RenderError>,
    },
    /// A value that cannot be turned into JSON or back.
    #[error("{what}")]
    Json {
        what: &'static str,
        #[source]
        source: serde_json::Error,
    },
    /// `--resume` into a folder whose finished sequences sit where this
    /// config plans others (`first` describes one).
    #[error(
        "{first} ({more} more such folder(s)): the dataset was rendered with other settings \
         (sequences per pair, objects, parts or conditions number the folders); render into \
         a new folder, or back to the old settings"
    )]
    OtherSequences { first: String, more: usize },
    /// `--resume` into a folder rendered with other pixel-changing
    /// `[render]` settings (`first` describes one).
    #[error(
        "{first} ({more} more finished sequence(s) differ); resuming would mix two renders in \
         one dataset: set the render settings back, or render into a new folder"
    )]
    OtherRender { first: String, more: usize },
    /// A finished sequence cannot be planned again to compare.
    #[error("re-planning finished sequence {id}")]
    Replan {
        id: String,
        #[source]
        source: Box<RenderError>,
    },
    /// `--resume` into a folder whose finished sequence has another plan.
    #[error(
        "{}: {what}; resuming would mix two datasets in one folder: set the settings back, or \
         render into a new folder",
        dir.display()
    )]
    OtherPlan { dir: PathBuf, what: String },
    /// The embedded Python cannot be used.
    #[error(transparent)]
    Python(#[from] crate::python::PythonError),
    /// A Python call failed, with nothing more to say than its exception.
    #[error(transparent)]
    Py(#[from] PyFailure),
    /// A Python (Blender) call failed; `doing` says what was being done.
    #[error("{doing}")]
    Blender {
        doing: String,
        #[source]
        source: PyFailure,
    },
    /// The configured `[render] device` is not available.
    #[error(transparent)]
    Device(#[from] super::device::DeviceUnavailable),
    /// A step of a sequence failed; `what` names the step, the sequence
    /// and the camera.
    #[error("{what}")]
    Step {
        what: String,
        #[source]
        source: Box<RenderError>,
    },
    /// A plan a worker cannot render as it is; `reason` says why.
    #[error("sequence {id}: {reason}")]
    BadPlan { id: String, reason: String },
    /// The source planned another sequence than the one asked for.
    #[error("the planner returned sequence {got} for {want}")]
    WrongSequence { got: String, want: String },
    /// Planning a sequence for rendering failed.
    #[error("planning sequence {id}")]
    Planning {
        id: String,
        #[source]
        source: Box<PlanError>,
    },
    /// The part pass on an object without parts.
    #[error("object '{object}' has no parts to label")]
    NoParts { object: String },
    /// `render` into a folder that holds finished sequences, without
    /// `--resume`.
    #[error(
        "{} already holds {finished} finished sequences of this dataset; pass \
         --resume to keep them and render the rest, or choose an empty folder",
        out.display()
    )]
    AlreadyRendered { out: PathBuf, finished: usize },
    /// Reading the parent's messages (in a worker) failed.
    #[error("{what}")]
    Stdin {
        what: &'static str,
        #[source]
        source: std::io::Error,
    },
    /// Writing to the parent (in a worker) failed.
    #[error("cannot write to the parent")]
    Parent(#[source] std::io::Error),
    /// A message out of the worker protocol's order.
    #[error("{0}")]
    Protocol(&'static str),
    /// A worker process's pipe that was not set up.
    #[error("{0}")]
    WorkerPipe(&'static str),
    /// A worker process that could not start; `fatal` when every retry
    /// would fail the same way (a `[render] device` Blender does not offer).
    #[error("worker failed to start: {message}")]
    WorkerStart { message: String, fatal: bool },
    /// A worker's answer that is not the one expected.
    #[error("unexpected worker answer {answer}")]
    UnexpectedAnswer { answer: String },
    /// A worker's answer that does not parse.
    #[error("invalid worker answer '{answer}'")]
    InvalidAnswer {
        answer: String,
        #[source]
        source: serde_json::Error,
    },
    /// A worker process that died; its log says why.
    #[error("worker process died ({status}); see {}", log.display())]
    WorkerDied { status: String, log: PathBuf },
    /// A worker that failed to render a sequence (its message names it).
    #[error("{message}")]
    WorkerFailed { message: String },
    /// A worker slot's thread panicked.
    #[error("a worker thread panicked")]
    WorkerPanicked,
    /// The config is refused.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The catalog or an object's mesh does not load.
    #[error(transparent)]
    Catalog(Box<CatalogError>),
    /// A plan cannot be made.
    #[error(transparent)]
    Plan(Box<PlanError>),
    /// The dataset cannot be read or written.
    #[error(transparent)]
    Dataset(Box<DatasetError>),
}

pub type Result<T, E = RenderError> = std::result::Result<T, E>;

impl From<CatalogError> for RenderError {
    fn from(e: CatalogError) -> Self {
        RenderError::Catalog(Box::new(e))
    }
}

impl From<PlanError> for RenderError {
    fn from(e: PlanError) -> Self {
        RenderError::Plan(Box::new(e))
    }
}

impl From<DatasetError> for RenderError {
    fn from(e: DatasetError) -> Self {
        RenderError::Dataset(Box::new(e))
    }
}

impl RenderError {
    pub(crate) fn io(
        action: &'static str,
        path: impl Into<PathBuf>,
        source: std::io::Error,
    ) -> Self {
        RenderError::Io(grasp_support::IoAt::new(action, path, source))
    }

    pub(crate) fn image(what: impl Into<String>, source: image::ImageError) -> Self {
        RenderError::Image {
            what: what.into(),
            source,
        }
    }
}

/// A Python exception, as text with its traceback (a `PyErr` needs the
/// interpreter to be printed).
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct PyFailure {
    pub message: String,
}
