//! Shared vocabulary of the toolkit: the grasp taxonomy of Vasile et al.
//! (IROS 2022, Table 1), sequence plans, appearances and the dataset
//! layout. Data types only: the programs' process support (logging, atomic
//! writes, config layers, the Python environment) is `grasp-support`.

pub mod appearance;
pub mod dataset;
pub mod plan;
pub mod taxonomy;

pub use plan::{Condition, SequenceKey, SequencePlan};
pub use taxonomy::{Class, GraspType, HandConfiguration, Preshape, Thumb};
