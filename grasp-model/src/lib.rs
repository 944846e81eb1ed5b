//! The pre-shape classifier for inference, shared by the trainer
//! (`grasp-train`) and the prosthesis runtime (`hannes-run`): the backbones
//! (MobileNetV2, EfficientNet-Lite0/1/2) with their CPU kernels, weight
//! loading (safetensors, zip and legacy `.pth`) and preprocessing, the FC
//! and LSTM heads, softmax, and the checkpoint format. Training lives in the
//! trainer; nothing here depends on it.
//!
//! Errors are typed ([`ModelError`]): a caller can tell a missing file from
//! a corrupt one.

pub mod backbone;
pub mod checkpoint;
pub mod error;
pub mod extractor;
pub mod hashing;
pub mod heads;
pub mod input;
pub mod model;
pub mod names;
pub mod softmax;

pub use error::{ModelError, Result};
pub use names::UnknownName;
