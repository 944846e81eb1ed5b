//! The interface between frames and heads: anything that turns images into
//! feature vectors (a backbone; in tests, a stand-in).

use crate::error::{ModelError, Result};
use crate::style::ChannelStyle;
use candle_core::Tensor;
use image::RgbImage;

/// Turns frames into feature vectors.
pub trait FeatureExtractor {
    /// Identifies the weights and the preprocessing; features from extractors
    /// with equal ids are interchangeable.
    fn id(&self) -> String;
    fn feature_dim(&self) -> usize;
    /// Features `(N, feature_dim)`, f32, of `images`.
    fn extract(&self, images: &[RgbImage]) -> Result<Tensor>;
    /// Output channels of each block that [`Self::extract_styled`] can
    /// restyle, in order; empty when it restyles none.
    fn block_channels(&self) -> Vec<usize> {
        Vec::new()
    }
    /// [`Self::extract`] with block outputs restyled, `styles[i]` for
    /// `images[i]`.
    fn extract_styled(&self, images: &[RgbImage], styles: &[Vec<ChannelStyle>]) -> Result<Tensor> {
        let _ = (images, styles);
        Err(ModelError::Invalid(
            "this feature extractor cannot restyle its blocks (style views need a frozen \
             EfficientNet-Lite)"
                .into(),
        ))
    }
}
