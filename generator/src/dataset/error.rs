//! What can go wrong when writing, reading, merging or locking a dataset.
//! Every message names the file or folder (and the sequence) it is about;
//! the error a failure comes from is its `source`.

use super::storage::StorageFull;
use crate::plan::PlanError;
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// A file or folder operation failed; `action` says which ("cannot
    /// read", "cannot create", ...).
    #[error(transparent)]
    Io(#[from] grasp_support::IoAt),
    /// A folder cannot be renamed into place.
    #[error("cannot move {} to {}", from.display(), to.display())]
    Move {
        from: PathBuf,
        to: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file cannot be written atomically.
    #[error(transparent)]
    Write(#[from] grasp_support::atomic::WriteError),
    /// A `sequence.json` that does not parse.
    #[error("invalid sequence record {}", path.display())]
    Record {
        path: PathBuf,
        #[source]
        source: serde_json::Error,
    },
    /// A lock file that does not parse.
    #[error("invalid lock file {}", path.display())]
    LockFile {
        path: PathBuf,
        #[source]
        source: serde_json::Error,
    },
    /// A record or lock that cannot be turned into JSON.
    #[error("serialising {what}")]
    Serialise {
        what: &'static str,
        #[source]
        source: serde_json::Error,
    },
    /// Going through a dataset's sequences failed.
    #[error("cannot scan dataset {}", root.display())]
    Scan {
        root: PathBuf,
        #[source]
        source: Box<DatasetError>,
    },
    /// Going through a shard's sequences (to merge them) failed.
    #[error("cannot read shard {}", shard.display())]
    Shard {
        shard: PathBuf,
        #[source]
        source: Box<DatasetError>,
    },
    /// A sequence whose plan differs between a shard and the merged output.
    #[error(
        "{rel} differs between {} and {}: were the shards made with the same config?",
        shard.display(),
        out.display()
    )]
    Differs {
        rel: String,
        shard: PathBuf,
        out: PathBuf,
    },
    /// A sequence folder that has no head camera folder next to it.
    #[error("{rel}: {reason}")]
    NoHeadFolder { rel: String, reason: String },
    /// Sequences a merge left out because their files are damaged.
    #[error(
        "{} damaged sequence(s) left out of the merge (re-render their shard with \
         --resume, then merge again): {}",
        reasons.len(),
        reasons.join("; ")
    )]
    Damaged { reasons: Vec<String> },
    /// A rendered frame that fails its integrity check; the source, when
    /// there is one, is the full disk that explains it.
    #[error("sequence {sequence}: frame {}: {damage}", path.display())]
    BadFrame {
        sequence: String,
        path: PathBuf,
        damage: String,
        #[source]
        full: Option<StorageFull>,
    },
    /// A `--shard K/N` that does not parse.
    #[error("--shard '{spec}': {reason}")]
    ShardSpec {
        spec: String,
        reason: &'static str,
        #[source]
        source: Option<std::num::ParseIntError>,
    },
    /// A lock that other processes keep re-creating.
    #[error("cannot take the lock {}: other processes keep creating it", lock.display())]
    LockContended { lock: PathBuf },
    /// A lock file that cannot be read.
    #[error(
        "{} is locked, but the lock file {} is unreadable ({reason}); if no grasp-gen is \
         writing there, remove it",
        folder.display(),
        lock.display()
    )]
    LockUnreadable {
        folder: PathBuf,
        lock: PathBuf,
        reason: String,
    },
    /// The folder is locked by a live process (`holder` describes it).
    #[error(
        "{} is in use: {holder}; {reason} (lock {}). Wait for it to finish or stop it first",
        folder.display(),
        lock.display()
    )]
    InUse {
        folder: PathBuf,
        holder: String,
        reason: String,
        lock: PathBuf,
    },
    /// The folder is locked by a process on another machine.
    #[error(
        "{} is in use: {holder}; last heartbeat {age} ago (lock {}). That host is not this \
         machine, so it cannot be checked from here. If that process is gone, run \
         again with --break-lock: it takes the lock over once the heartbeat has \
         stopped for {beats} intervals of {interval_s} s",
        folder.display(),
        lock.display()
    )]
    InUseElsewhere {
        folder: PathBuf,
        holder: String,
        age: String,
        lock: PathBuf,
        beats: u32,
        interval_s: f64,
    },
    /// The plans the dataset is checked against cannot be made.
    #[error(transparent)]
    Plan(Box<PlanError>),
}

pub type Result<T, E = DatasetError> = std::result::Result<T, E>;

impl From<PlanError> for DatasetError {
    fn from(e: PlanError) -> Self {
        DatasetError::Plan(Box::new(e))
    }
}

impl DatasetError {
    pub(crate) fn io(
        action: &'static str,
        path: impl Into<PathBuf>,
        source: std::io::Error,
    ) -> Self {
        DatasetError::Io(grasp_support::IoAt::new(action, path, source))
    }
}

/// An error and its sources on one line, for problems collected as text.
pub use grasp_support::error_chain as chain;
