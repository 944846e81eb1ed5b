//! The pre-shape classifier for inference, shared by the trainer
//! (`grasp-train`) and the prosthesis runtime (`hannes-run`): the backbones
//! (MobileNetV2, EfficientNet-Lite0/1/2) with their CPU kernels, weight
//! loading (safetensors, zip and legacy `.pth`) and preprocessing, the FC,
//! LSTM and trace heads (with the trace of an approach, `trace`), softmax, and the checkpoint format. Training lives in the
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
pub mod names;
pub mod networks;
pub mod ops;
pub mod softmax;
pub mod style;
pub mod trace;
pub mod weights;

pub use error::{ModelError, Result};
pub use names::UnknownName;

#[cfg(test)]
pub(crate) mod test_util {
    use candle_core::Tensor;

    /// The largest absolute difference between two tensors of one shape.
    pub fn max_diff(a: &Tensor, b: &Tensor) -> f32 {
        assert_eq!(a.dims(), b.dims());
        (a - b)
            .and_then(|d| d.abs()?.flatten_all()?.max(0)?.to_scalar::<f32>())
            .expect("difference of two f32 tensors")
    }
}
