//! The hand's decision: how the frames of an approach become the pre-shape
//! the prosthesis is commanded, in one place for the runtime that drives
//! the hand (`hannes-run`) and the trainer that scores it (`grasp-train
//! eval`).
//!
//! - [`probabilities`]: the validation every model output goes through
//!   before it may vote;
//! - [`vote`]: the paper's demo policy (window, majority vote over the
//!   pre-shapes, early decision, confidence checks, fallback);
//! - [`recorded`]: the policy over a recorded approach, with its frames'
//!   own time stamps;
//! - [`setting`]: the error of a setting outside its range.

pub mod probabilities;
pub mod recorded;
pub mod setting;
pub mod vote;

pub use probabilities::{InvalidOutput, Probabilities};
pub use recorded::{decide_recorded, RecordedDecision};
pub use vote::*;
