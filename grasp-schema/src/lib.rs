//! Shared vocabulary of the toolkit: the grasp taxonomy of Vasile et al.
//! (IROS 2022, Table 1), sequence plans, and the dataset layout.

pub mod appearance;
pub mod cli;
pub mod dataset;
pub mod plan;
pub mod taxonomy;

pub use plan::{Condition, SequenceKey, SequencePlan};
pub use taxonomy::{Class, GraspType, HandConfiguration, Preshape, Thumb};
