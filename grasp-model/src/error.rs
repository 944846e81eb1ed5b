//! What can go wrong when loading or running a model. Every variant names
//! the file it is about, so that a caller can tell a missing file (nothing
//! there: train first, or fix the path) from a corrupt one (something there
//! that cannot be used: re-create it) without parsing messages.

use crate::weights::legacy_pth::LegacyPthError;
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// A file the model needs is not there.
    #[error("{what} {} does not exist", path.display())]
    Missing { what: &'static str, path: PathBuf },
    /// A file is there but cannot be read (permissions, I/O error).
    #[error("cannot read {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file cannot be written.
    #[error(transparent)]
    Write(#[from] grasp_support::atomic::WriteError),
    /// A file is there, but its contents are not what it should hold.
    #[error("{}: {reason}", path.display())]
    Corrupt { path: PathBuf, reason: String },
    /// A weights file whose bytes cannot be decoded as its format.
    #[error("weights file {}: {what}", path.display())]
    Unreadable {
        path: PathBuf,
        what: &'static str,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A legacy (pre-1.6) PyTorch file that does not parse.
    #[error("weights file {}: unreadable legacy (pre-1.6) PyTorch checkpoint", path.display())]
    LegacyPth {
        path: PathBuf,
        #[source]
        source: LegacyPthError,
    },
    /// A checkpoint written by a newer (or an unknown) format.
    #[error("{}: format_version {found} (this build reads {oldest} to {newest})", path.display())]
    UnsupportedVersion {
        path: PathBuf,
        found: u32,
        oldest: u32,
        newest: u32,
    },
    /// A weights file whose bytes changed since a checkpoint recorded them.
    #[error("{} has SHA-256 {actual}, but the checkpoint was made with {expected}", path.display())]
    HashMismatch {
        path: PathBuf,
        actual: String,
        expected: String,
    },
    /// A path that is not what the caller asked for (a folder that is not a
    /// checkpoint, a file with an unknown extension, no pip-installed
    /// weights).
    #[error("{0}")]
    Invalid(String),
    /// The tensors of a file do not build the network (missing or
    /// misshaped tensor), or a tensor operation failed.
    #[error("{context}")]
    Tensors {
        context: String,
        #[source]
        source: candle_core::Error,
    },
    /// A tensor operation failed.
    #[error(transparent)]
    Candle(#[from] candle_core::Error),
    /// A frame cannot become the backbone's input (no lens for a
    /// fixed-angle crop, an implausible lens, a crop too small).
    #[error(transparent)]
    Input(#[from] crate::input::InputError),
}

impl ModelError {
    /// Nothing at the path: train or install first, or fix the path.
    pub fn is_missing(&self) -> bool {
        match self {
            ModelError::Missing { .. } => true,
            ModelError::Read { source, .. } => source.kind() == std::io::ErrorKind::NotFound,
            _ => false,
        }
    }

    /// Something at the path that cannot be used as it is.
    pub fn is_corrupt(&self) -> bool {
        matches!(
            self,
            ModelError::Corrupt { .. }
                | ModelError::Unreadable { .. }
                | ModelError::LegacyPth { .. }
                | ModelError::HashMismatch { .. }
        )
    }

    /// Reading `path` failed: missing when it is not there.
    pub fn read(what: &'static str, path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        let path = path.into();
        if source.kind() == std::io::ErrorKind::NotFound {
            ModelError::Missing { what, path }
        } else {
            ModelError::Read { path, source }
        }
    }

    pub(crate) fn tensors(context: impl Into<String>, source: candle_core::Error) -> Self {
        ModelError::Tensors {
            context: context.into(),
            source,
        }
    }
}

pub type Result<T, E = ModelError> = std::result::Result<T, E>;
