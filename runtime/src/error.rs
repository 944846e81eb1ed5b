//! The runtime's errors. Each concept has its own enum beside the code
//! that fails: [`crate::config::ConfigError`] (and the settings'
//! [`grasp_policy::setting::InvalidSetting`]), [`crate::model::CheckpointError`],
//! [`crate::source::SourceError`], [`crate::classifier::ClassifyError`],
//! [`crate::trigger::TriggerError`], [`crate::link::LinkError`] and
//! [`crate::link::StartError`], [`crate::ptylink::PtyError`],
//! [`crate::simhand::PtyHandError`], [`crate::session::SessionError`]. Every one names what it is about: the
//! file, the field, the device; a cause is its `source()` (one line with
//! every cause: `grasp_support::error_chain`). [`RuntimeError`] is any of
//! them, for a caller that drives the whole loop.

/// Any error of the runtime.
#[derive(Debug, thiserror::Error)]
pub enum RuntimeError {
    #[error(transparent)]
    Config(#[from] crate::config::ConfigError),
    #[error(transparent)]
    Setting(#[from] grasp_policy::setting::InvalidSetting),
    #[error(transparent)]
    Checkpoint(#[from] crate::model::CheckpointError),
    #[error(transparent)]
    Source(#[from] crate::source::SourceError),
    #[error(transparent)]
    Classify(#[from] crate::classifier::ClassifyError),
    #[error(transparent)]
    Trigger(#[from] crate::trigger::TriggerError),
    #[error(transparent)]
    Link(#[from] crate::link::LinkError),
    #[error(transparent)]
    Start(#[from] crate::link::StartError),
    #[error(transparent)]
    Pty(#[from] crate::ptylink::PtyError),
    #[error(transparent)]
    SimHand(#[from] crate::simhand::PtyHandError),
    #[error(transparent)]
    Session(#[from] crate::session::SessionError),
}

pub type Result<T, E = RuntimeError> = std::result::Result<T, E>;
