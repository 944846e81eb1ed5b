//! The frozen backbone's features pooled per cell of a grid over the crop
//! instead of over all of it, cached like the pooled ones.

use candle_core::Tensor;
use grasp_model::backbone::{Backbone, Network};
use grasp_model::error::{ModelError, Result};
use grasp_model::extractor::FeatureExtractor;
use grasp_model::style::ChannelStyle;
use image::RgbImage;

/// `grid` x `grid` cells, each with the pooled features' layout.
pub struct CellExtractor {
    pub backbone: Backbone,
    pub grid: usize,
}

impl CellExtractor {
    pub fn cell_dim(&self) -> usize {
        self.backbone.feature_dim()
    }

    pub fn cells(&self) -> usize {
        self.grid * self.grid
    }
}

impl FeatureExtractor for CellExtractor {
    fn id(&self) -> String {
        format!("{}|cells {}x{}", self.backbone.id(), self.grid, self.grid)
    }

    fn feature_dim(&self) -> usize {
        self.cells() * self.cell_dim()
    }

    fn extract(&self, images: &[RgbImage]) -> Result<Tensor> {
        self.extract_styled(images, &vec![Vec::new(); images.len()])
    }

    fn block_channels(&self) -> Vec<usize> {
        self.backbone.block_channels()
    }

    fn extract_styled(&self, images: &[RgbImage], styles: &[Vec<ChannelStyle>]) -> Result<Tensor> {
        let Network::EfficientNetLite(net) = &self.backbone.net else {
            return Err(ModelError::Invalid(
                "cell features need EfficientNet-Lite".into(),
            ));
        };
        let x = self.backbone.input(images)?;
        Ok(net.styled_cell_features(&x, styles, self.grid)?)
    }
}
