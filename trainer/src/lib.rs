//! Training and evaluation of the pre-shape classifier (Vasile et al., IROS
//! 2022): the paper's training protocol for the networks of `grasp-model`
//! (a MobileNetV2 or EfficientNet-Lite backbone with an FC, LSTM or trace head),
//! and the evaluation report.

pub mod config;
pub mod data;
pub mod error;
pub mod eval;
pub mod experiment;
pub mod features;
pub mod init;
pub mod loss;
pub mod optim;
pub mod plan;
pub mod progress;
pub mod recipe;
pub mod rng;
pub mod stand_in;
pub mod train;
