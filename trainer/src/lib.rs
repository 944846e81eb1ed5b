//! Training and evaluation of the pre-shape classifier (Vasile et al., IROS
//! 2022): a MobileNetV2 backbone in candle with an FC or LSTM head, the
//! paper's training protocol, and the evaluation report.

pub mod backbone;
pub mod bench;
pub mod checkpoint;
pub mod config;
pub mod data;
pub mod eval;
pub mod experiment;
pub mod features;
pub mod heads;
pub mod init;
pub mod loss;
pub mod model;
pub mod optim;
pub mod progress;
pub mod rng;
pub mod train;
