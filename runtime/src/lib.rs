//! Streaming pre-shape classification and the Hannes serial link.
//!
//! - [`source`], [`feed`] (and `camera` with the `camera` feature): frames in,
//!   dropping stale frames when the classifier falls behind;
//! - [`classifier`], [`policy`], [`trigger`], [`approach`]: the paper's demo
//!   decision loop;
//! - [`protocol`], [`decoder`], [`transport`], [`link`]: the wire protocol of
//!   docs/hannes-protocol.md and its host side;
//! - [`simhand`]: the device side, as a simulated hand with injectable link
//!   faults, and [`ptylink`]: its pseudo-terminal links and their owners;
//! - [`session`]: the `run` loop (approach after approach) and its
//!   outcome, [`signals`]: stopping on SIGINT, SIGTERM and SIGHUP;
//! - [`model`]: the trained checkpoint as a [`classifier::FrameClassifier`];
//! - [`error`]: what all of it can fail with, one typed error per concept.

pub mod approach;
#[cfg(feature = "camera")]
pub mod camera;
pub mod classifier;
pub mod config;
pub mod decoder;
pub mod error;
pub mod feed;
pub mod link;
pub mod model;
pub mod protocol;
pub mod ptylink;
pub mod session;
pub mod signals;
pub mod simhand;
pub mod source;
pub mod transport;
pub mod trigger;

/// The decision policy, shared with `grasp-train eval` (`grasp-policy`).
pub use grasp_policy as policy;
