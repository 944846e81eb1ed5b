//! What can go wrong when checking a config against the catalog, setting up
//! the planner or planning a sequence. Messages name the config field, the
//! object and the part; the error a failure comes from is its `source`.

use crate::catalog::CatalogError;
use crate::config::error::ConfigError;
use crate::geometry::error::GeometryError;
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// A section of the config is refused.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The `[plan]` section is refused (checked before the rest).
    #[error("invalid [plan] section of the config")]
    PlanSection(#[source] ConfigError),
    /// The catalog (or an object's mesh) does not load.
    #[error(transparent)]
    Catalog(Box<CatalogError>),
    /// The built-in catalog does not load.
    #[error("loading the built-in catalog")]
    BuiltinCatalog(#[source] Box<CatalogError>),
    /// A mesh query failed.
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    /// `dataset.objects` or `dataset.parts` name what the catalog does not
    /// have (each problem with its near matches).
    #[error("{} (the catalog {} has: {})", problems.join("; "), catalog.display(), objects.join(", "))]
    Selection {
        problems: Vec<String>,
        catalog: PathBuf,
        objects: Vec<String>,
    },
    /// The config selects no sequence; `reason` names the fields.
    #[error("{reason}")]
    NothingSelected { reason: &'static str },
    /// The config asks for more than a size limit allows: "FIELD: REASON".
    #[error("{field}: {reason}")]
    TooBig { field: String, reason: String },
    /// A sequence with more frames than the limit.
    #[error(
        "{field} x plan.trajectory.fps = {seconds} s x {fps} fps = {frames} frames per {} \
         sequence; the limit is {limit} frames per sequence",
        condition.name()
    )]
    TooManyFrames {
        /// The duration field of the condition.
        field: &'static str,
        seconds: f64,
        fps: f64,
        frames: f64,
        condition: grasp_schema::Condition,
        limit: u64,
    },
    /// An object's mesh does not load.
    #[error("loading the mesh of object {object}")]
    Mesh {
        object: String,
        #[source]
        source: Box<CatalogError>,
    },
    /// An object's mesh query cannot be built.
    #[error("building the mesh query of object {object}")]
    MeshQuery {
        object: String,
        #[source]
        source: GeometryError,
    },
    /// An object or part the planner cannot use: "object X: REASON" or
    /// "object X, part P: REASON".
    #[error("object {object}{}: {reason}", part.as_ref().map(|p| format!(", part {p}")).unwrap_or_default())]
    BadObject {
        object: String,
        part: Option<String>,
        reason: String,
    },
    /// A key names an object the planner (or catalog) does not have;
    /// `known` lists them, when the message should.
    #[error("unknown object '{object}'{}", known.as_ref().map(|k| format!(" (planner has: {k})")).unwrap_or_default())]
    UnknownObject {
        object: String,
        known: Option<String>,
    },
    /// A key names a part its object does not have.
    #[error("object {} has no part '{part}'{}", if *quoted { format!("'{object}'") } else { object.clone() }, parts.as_ref().map(|p| format!(" (parts: {p})")).unwrap_or_default())]
    UnknownPart {
        object: String,
        part: String,
        /// Whether the message quotes the object id.
        quoted: bool,
        parts: Option<String>,
    },
    /// No valid approach was found within the attempts.
    #[error(
        "object {object}, part {part}: no valid {condition} approach in {attempts} attempts ({reasons})"
    )]
    NoApproach {
        object: String,
        part: String,
        condition: grasp_schema::Condition,
        attempts: u32,
        /// "N x REASON; ..." per rejection reason.
        reasons: String,
    },
    /// Planning the sequence `id` failed.
    #[error("planning {id}")]
    Planning {
        id: String,
        #[source]
        source: Box<PlanError>,
    },
    /// A straight approach that has no direction, or starts within the
    /// stand-off.
    #[error("{0}")]
    DegenerateApproach(String),
    /// A source without a plan for the sequence `id`.
    #[error("no plan for sequence {id}")]
    NoPlan { id: String },
    /// The planner thread stopped (it panicked or was dropped).
    #[error("the planner thread stopped")]
    PlannerStopped,
    /// The planner could not be set up (on its thread).
    #[error("setting up the planner")]
    Setup(#[source] Box<PlanError>),
    /// `plan --plot` got no plans.
    #[error("no plans to draw")]
    NothingToDraw,
    /// A picture (`plan --plot`) cannot be written.
    #[error("writing {}", path.display())]
    Image {
        path: PathBuf,
        #[source]
        source: Box<image::ImageError>,
    },
    /// A plans file cannot be read.
    #[error("cannot read {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A line of a plans file that is not a sequence plan.
    #[error("{}:{line}: not a sequence plan", path.display())]
    NotAPlan {
        path: PathBuf,
        line: usize,
        #[source]
        source: serde_json::Error,
    },
    /// A file cannot be written atomically.
    #[error(transparent)]
    Write(#[from] grasp_support::atomic::WriteError),
}

pub type Result<T, E = PlanError> = std::result::Result<T, E>;

impl From<CatalogError> for PlanError {
    fn from(e: CatalogError) -> Self {
        PlanError::Catalog(Box::new(e))
    }
}
