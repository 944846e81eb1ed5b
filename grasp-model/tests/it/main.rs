//! grasp-model's integration tests, one binary: a module per concern.

mod checkpoint_crop;
mod checkpoint_errors;
mod common;
mod legacy_pth_faults;
mod lite_parity;
mod model_kernels;
mod model_parity;
mod model_weights;
