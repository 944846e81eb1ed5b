//! MobileNetV2 in candle: torchvision's architecture and parameter names,
//! fast CPU kernels for its depthwise and pointwise convolutions, checkpoint
//! loading and ImageNet preprocessing.

mod batch_norm;
mod cpu;
pub mod depthwise;
mod legacy_pth;
mod mobilenet_v2;
pub mod pointwise;
pub mod preprocess;
pub mod weights;

pub use mobilenet_v2::{make_divisible, MobileNetV2, MobileNetV2Config};
