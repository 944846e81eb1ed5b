//! The MobileNetV2 backbone as used by training, the feature cache and the
//! classifier: how it was made (pretrained file or from scratch), its
//! preprocessing, and feature extraction.

use crate::features::FeatureExtractor;
use crate::model::{MobileNetV2, MobileNetV2Config};
use anyhow::{Context, Result};
use candle_core::{Device, Tensor};
use candle_nn::VarBuilder;
use image::RgbImage;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub const BACKBONE_ID: &str = "torchvision.mobilenet_v2";

/// Input preprocessing: squash to `size`x`size`, scale to [0, 1], then
/// normalise per channel.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Preprocess {
    pub size: u32,
    pub mean: [f32; 3],
    pub std: [f32; 3],
}

impl Preprocess {
    pub fn imagenet(size: u32) -> Preprocess {
        Preprocess {
            size,
            mean: crate::model::preprocess::IMAGENET_MEAN,
            std: crate::model::preprocess::IMAGENET_STD,
        }
    }
}

/// What the backbone is: enough to rebuild it and to key the feature cache.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BackboneInfo {
    pub id: String,
    /// Pretrained weights file (frozen mode); `None` when the weights were
    /// trained from scratch and live in the checkpoint.
    pub weights_path: Option<PathBuf>,
    pub weights_sha256: Option<String>,
    pub width_mult: f64,
    /// Size of the backbone's own classifier (1000 for ImageNet files).
    pub num_classes: usize,
}

impl BackboneInfo {
    /// Describes a pretrained weights file (hashing its bytes).
    pub fn pretrained(path: &Path, width_mult: f64) -> Result<BackboneInfo> {
        Ok(BackboneInfo {
            id: BACKBONE_ID.to_string(),
            weights_path: Some(path.to_path_buf()),
            weights_sha256: Some(crate::features::file_sha256(path)?),
            width_mult,
            num_classes: 1000,
        })
    }

    pub fn config(&self) -> MobileNetV2Config {
        MobileNetV2Config {
            width_mult: self.width_mult as _,
            num_classes: self.num_classes,
            dropout: 0.2,
        }
    }
}

pub struct Backbone {
    pub net: MobileNetV2,
    pub info: BackboneInfo,
    pub preprocess: Preprocess,
    pub device: Device,
}

impl Backbone {
    /// Loads a pretrained file (`.pth` or `.safetensors`), checking that its
    /// bytes still hash to the recorded value when one is given.
    pub fn load_pretrained(info: &BackboneInfo, pre: Preprocess, device: &Device) -> Result<Self> {
        let path = info
            .weights_path
            .as_ref()
            .context("the backbone has no pretrained weights file")?;
        if let Some(expected) = &info.weights_sha256 {
            let actual = crate::features::file_sha256(path)?;
            if &actual != expected {
                anyhow::bail!(
                    "{} has SHA-256 {actual}, but the checkpoint was made with {expected}",
                    path.display()
                );
            }
        }
        let vb = crate::model::weights::var_builder(path, device)
            .with_context(|| format!("cannot load backbone weights {}", path.display()))?;
        Self::from_vb(info.clone(), pre, vb, device)
    }

    pub fn from_vb(
        info: BackboneInfo,
        pre: Preprocess,
        vb: VarBuilder,
        device: &Device,
    ) -> Result<Self> {
        let net = MobileNetV2::new(vb, &info.config()).context("cannot build MobileNetV2")?;
        Ok(Backbone {
            net,
            info,
            preprocess: pre,
            device: device.clone(),
        })
    }

    pub fn input(&self, images: &[RgbImage]) -> Result<Tensor> {
        Ok(crate::model::preprocess::to_tensor(
            images,
            self.preprocess.size,
            &self.device,
        )?)
    }
}

impl FeatureExtractor for Backbone {
    fn id(&self) -> String {
        serde_json::json!({
            "backbone": self.info.id,
            "weights_sha256": self.info.weights_sha256,
            "width_mult": self.info.width_mult,
            "preprocess": self.preprocess,
        })
        .to_string()
    }

    fn feature_dim(&self) -> usize {
        self.net.feature_dim()
    }

    fn extract(&self, images: &[RgbImage]) -> Result<Tensor> {
        let x = self.input(images)?;
        Ok(self.net.features(&x, false)?)
    }
}
