//! The interface between frames and heads: anything that turns images into
//! feature vectors (a backbone; in tests, a stand-in).

use crate::error::Result;
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
}
