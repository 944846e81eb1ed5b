//! Checkpoints and the runtime-facing classifier.
//!
//! A checkpoint is a directory with `best.safetensors` (the head's tensors
//! under `head.`, plus the backbone's under `backbone.` when it was trained
//! from scratch) and `best.json` ([`CheckpointMeta`]: classes, mode,
//! preprocessing, backbone, training config). Both are written atomically.

use crate::backbone::{Backbone, BackboneInfo, Preprocess};
use crate::features::FeatureExtractor;
use crate::heads::{Head, HeadConfig, HeadKind};
use anyhow::{Context, Result};
use candle_core::{DType, Device, Tensor};
use candle_nn::VarBuilder;
use grasp_schema::taxonomy::Class;
use image::RgbImage;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// 2: the backbone records its architecture and the preprocessing its
/// resize filter. Version 1 (MobileNetV2, bilinear) still loads.
pub const FORMAT_VERSION: u32 = 2;
const OLDEST_FORMAT_VERSION: u32 = 1;
pub const META_FILE: &str = "best.json";
pub const WEIGHTS_FILE: &str = "best.safetensors";

/// How the backbone of a model was obtained. Every report states it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum TrainMode {
    /// The paper's: a pretrained backbone, frozen; only the head is trained,
    /// on cached features.
    FrozenPretrained,
    /// No pretrained weights: the whole network is trained, with augmentation.
    FromScratch,
}

impl TrainMode {
    pub fn name(self) -> &'static str {
        match self {
            TrainMode::FrozenPretrained => "frozen-pretrained",
            TrainMode::FromScratch => "from-scratch",
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CheckpointMeta {
    pub format_version: u32,
    /// Class names in output order.
    pub classes: Vec<Class>,
    pub mode: TrainMode,
    pub head: HeadConfig,
    pub preprocessing: Preprocess,
    pub backbone: BackboneInfo,
    pub seed: u64,
    pub epoch: usize,
    pub val_loss: f64,
    pub val_accuracy: f64,
    /// Sequences in the training split.
    #[serde(default)]
    pub train_sequences: Option<usize>,
    /// The full training configuration of the run.
    pub train_config: serde_json::Value,
}

impl CheckpointMeta {
    /// The run's `sequences_per_pair` cap, if it had one.
    pub fn sequences_per_pair(&self) -> Option<usize> {
        self.train_config
            .get("sequences_per_pair")
            .and_then(serde_json::Value::as_u64)
            .map(|n| n as usize)
    }

    pub fn load(dir_or_json: &Path) -> Result<(CheckpointMeta, PathBuf)> {
        let json = if dir_or_json.is_dir() {
            dir_or_json.join(META_FILE)
        } else {
            dir_or_json.to_path_buf()
        };
        let text = std::fs::read_to_string(&json)
            .with_context(|| format!("cannot read checkpoint {}", json.display()))?;
        let meta: CheckpointMeta = serde_json::from_str(&text)
            .with_context(|| format!("invalid checkpoint metadata {}", json.display()))?;
        if !(OLDEST_FORMAT_VERSION..=FORMAT_VERSION).contains(&meta.format_version) {
            anyhow::bail!(
                "{}: format_version {} (this build reads {OLDEST_FORMAT_VERSION} to \
                 {FORMAT_VERSION})",
                json.display(),
                meta.format_version
            );
        }
        let dir = json.parent().unwrap_or(Path::new(".")).to_path_buf();
        Ok((meta, dir))
    }
}

/// Writes the checkpoint atomically: tensors first, metadata last, so a
/// `best.json` always describes a complete `best.safetensors`.
pub fn save(dir: &Path, meta: &CheckpointMeta, tensors: &[(String, Tensor)]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let map: std::collections::HashMap<String, Tensor> = tensors.iter().cloned().collect();
    let weights = dir.join(WEIGHTS_FILE);
    let tmp = temp_path(&weights);
    candle_core::safetensors::save(&map, &tmp)
        .with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, &weights)
        .with_context(|| format!("cannot move into {}", weights.display()))?;
    write_atomic(
        &dir.join(META_FILE),
        serde_json::to_string_pretty(meta)?.as_bytes(),
    )
}

/// A sibling temporary path, unique to this process.
pub fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp{}", std::process::id()))
}

/// Writes `bytes` to a temporary file and renames it over `path`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let tmp = temp_path(path);
    std::fs::write(&tmp, bytes).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("cannot move into {}", path.display()))
}

/// A trained pre-shape classifier: backbone plus head, for inference.
pub struct Classifier {
    pub meta: CheckpointMeta,
    backbone: Backbone,
    head: Head,
}

impl Classifier {
    /// Loads `best.json` (or the directory holding it) and its weights. In
    /// frozen-pretrained mode the backbone is read from the weights file
    /// recorded in the JSON (relative paths are tried against the current
    /// directory, then the checkpoint directory), and its hash is checked.
    pub fn load(dir_or_json: &Path, device: &Device) -> Result<Classifier> {
        let (meta, dir) = CheckpointMeta::load(dir_or_json)?;
        let weights = dir.join(WEIGHTS_FILE);
        let vb = unsafe { VarBuilder::from_mmaped_safetensors(&[&weights], DType::F32, device) }
            .with_context(|| format!("cannot read {}", weights.display()))?;
        let head = Head::new(meta.head, vb.pp("head"))
            .with_context(|| format!("{}: head tensors", weights.display()))?;
        let backbone = match meta.mode {
            TrainMode::FromScratch => Backbone::from_vb(
                meta.backbone.clone(),
                meta.preprocessing.clone(),
                vb.pp("backbone"),
                device,
            )
            .with_context(|| format!("{}: backbone tensors", weights.display()))?,
            TrainMode::FrozenPretrained => {
                let mut info = meta.backbone.clone();
                info.weights_path = info
                    .weights_path
                    .map(|p| crate::backbone::resolve(&p, &dir));
                Backbone::load_pretrained(&info, meta.preprocessing.clone(), device)?
            }
        };
        Ok(Classifier {
            meta,
            backbone,
            head: head.detached(),
        })
    }

    pub fn classes(&self) -> &[Class] {
        &self.meta.classes
    }

    pub fn head(&self) -> &Head {
        &self.head
    }

    pub fn backbone(&self) -> &Backbone {
        &self.backbone
    }

    /// Per-frame class probabilities (softmax by log-sum-exp). The FC head
    /// treats frames independently; an LSTM head reads them as one sequence
    /// in the given order, from a zero state.
    pub fn predict(&self, frames: &[RgbImage]) -> Result<Vec<[f32; 5]>> {
        if frames.is_empty() {
            return Ok(Vec::new());
        }
        let feats = self.backbone.extract(frames)?;
        self.predict_features(&feats)
    }

    /// Per-frame probabilities from precomputed features `(T, D)`.
    pub fn predict_features(&self, feats: &Tensor) -> Result<Vec<[f32; 5]>> {
        let logits = match self.head.cfg.kind {
            HeadKind::Fc => self.head.forward_frames(feats)?,
            HeadKind::Lstm => self
                .head
                .forward_sequences(&feats.unsqueeze(0)?)?
                .squeeze(0)?,
        };
        probabilities(&logits)
    }
}

/// Rows of softmax probabilities as fixed arrays of the five classes.
pub fn probabilities(logits: &Tensor) -> Result<Vec<[f32; 5]>> {
    let p: Vec<Vec<f32>> = crate::loss::softmax(logits)?.to_vec2()?;
    p.into_iter()
        .map(|row| {
            row.try_into()
                .map_err(|r: Vec<f32>| anyhow::anyhow!("expected 5 classes, got {}", r.len()))
        })
        .collect()
}
