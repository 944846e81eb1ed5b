//! The MobileNetV2 backbone as used by training, the feature cache and the
//! classifier: how it was made (pretrained file or from scratch), its
//! preprocessing, and feature extraction.

use crate::checkpoint::{CheckpointMeta, TrainMode, META_FILE, WEIGHTS_FILE};
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
    /// Prefix of the backbone's tensors in the weights file (`backbone` when
    /// the file is another model's checkpoint).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weights_prefix: Option<String>,
    /// The checkpoint whose trained backbone this is, when it is one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source_checkpoint: Option<PathBuf>,
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
            weights_prefix: None,
            source_checkpoint: None,
        })
    }

    /// Stands for the backbone of features that were generated rather than
    /// computed (tests and benchmarks of the heads).
    pub fn generated(id: &str) -> BackboneInfo {
        BackboneInfo {
            id: id.to_string(),
            weights_path: None,
            weights_sha256: None,
            width_mult: 1.0,
            num_classes: 1000,
            weights_prefix: None,
            source_checkpoint: None,
        }
    }

    /// A checkpoint's backbone, to be used frozen: the `backbone.*` tensors
    /// of a from-scratch checkpoint, or the pretrained file a frozen one was
    /// trained on. Also returns the checkpoint's preprocessing, which the
    /// backbone was trained with and must keep.
    pub fn from_checkpoint(dir_or_json: &Path) -> Result<(BackboneInfo, Preprocess)> {
        if dir_or_json.is_dir() && !dir_or_json.join(META_FILE).is_file() {
            anyhow::bail!(
                "{} is not a checkpoint (no {META_FILE}){}",
                dir_or_json.display(),
                seed_hint(dir_or_json)
            );
        }
        let (meta, dir) = CheckpointMeta::load(dir_or_json)?;
        let info = match meta.mode {
            TrainMode::FromScratch => {
                let weights = dir.join(WEIGHTS_FILE);
                BackboneInfo {
                    id: meta.backbone.id.clone(),
                    weights_sha256: Some(crate::features::file_sha256(&weights)?),
                    weights_path: Some(weights),
                    width_mult: meta.backbone.width_mult,
                    num_classes: meta.backbone.num_classes,
                    weights_prefix: Some("backbone".to_string()),
                    source_checkpoint: Some(dir),
                }
            }
            TrainMode::FrozenPretrained => {
                let mut info = meta.backbone.clone();
                info.weights_path = info.weights_path.map(|p| resolve(&p, &dir));
                info
            }
        };
        Ok((info, meta.preprocessing))
    }

    /// How a report names this backbone.
    pub fn describe(&self) -> String {
        match (&self.source_checkpoint, &self.weights_path) {
            (Some(c), _) => format!("frozen backbone from {}", c.display()),
            (None, Some(w)) => format!("frozen backbone {}", w.display()),
            (None, None) => "backbone trained from scratch".to_string(),
        }
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
        let vb = match &info.weights_prefix {
            Some(prefix) => vb.pp(prefix),
            None => vb,
        };
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
        let mut id = serde_json::json!({
            "backbone": self.info.id,
            "weights_sha256": self.info.weights_sha256,
            "width_mult": self.info.width_mult,
            "preprocess": self.preprocess,
        });
        // Only when set, so that pretrained files keep their cache entries.
        if let Some(prefix) = &self.info.weights_prefix {
            id["weights_prefix"] = prefix.clone().into();
        }
        id.to_string()
    }

    fn feature_dim(&self) -> usize {
        self.net.feature_dim()
    }

    fn extract(&self, images: &[RgbImage]) -> Result<Tensor> {
        let x = self.input(images)?;
        Ok(self.net.features(&x, false)?)
    }
}

/// ", e.g. RUN/seed-0" when `run` is a training run's directory.
fn seed_hint(run: &Path) -> String {
    let mut seeds: Vec<String> = std::fs::read_dir(run)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.path().join(META_FILE).is_file())
        .map(|e| e.path().display().to_string())
        .collect();
    seeds.sort();
    match seeds.first() {
        Some(s) => format!("; its checkpoints are in seed folders, e.g. {s}"),
        None => String::new(),
    }
}

/// Whether `--weights` names a checkpoint (its directory or `best.json`)
/// rather than a weights file.
pub fn is_checkpoint(path: &Path) -> bool {
    path.is_dir()
        || path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"))
}

/// A path recorded in a checkpoint: as given when it exists from the current
/// directory (or is absolute), otherwise relative to the checkpoint.
pub fn resolve(p: &Path, dir: &Path) -> PathBuf {
    if p.is_absolute() || p.exists() {
        p.to_path_buf()
    } else {
        dir.join(p)
    }
}
