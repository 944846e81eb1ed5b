//! The dataset on disk: writing finished sequences atomically, checking a
//! finished dataset, and joining shards. The layout itself is
//! [`grasp_schema::dataset`].

pub mod error;
pub mod integrity;
pub mod lock;
pub mod merge;
pub mod shard;
pub mod stats;
pub mod storage;
pub mod verify;
pub mod writer;

pub use error::{DatasetError, Result};

pub use writer::{assign_folders, Assigned, DatasetDir};
