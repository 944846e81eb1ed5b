//! Shared vocabulary of the toolkit: the grasp taxonomy of Vasile et al.
//! (IROS 2022, Table 1), sequence plans, the dataset layout, and where the
//! project's Python environment is.

pub mod appearance;
pub mod atomic;
pub mod cli;
pub mod dataset;
pub mod layers;
pub mod plan;
pub mod prerequisite;
pub mod taxonomy;
pub mod venv;

pub use plan::{Condition, SequenceKey, SequencePlan};
pub use taxonomy::{Class, GraspType, HandConfiguration, Preshape, Thumb};
