//! Checkpoints and the runtime-facing classifier.
//!
//! A checkpoint is a directory with `best.safetensors` (the head's tensors
//! under `head.`, plus the backbone's under `backbone.` when it was trained
//! from scratch, or its fine-tuned last blocks under `tail.`) and `best.json` ([`CheckpointMeta`]: classes, mode,
//! preprocessing, backbone, training config). Both are written atomically.

use crate::backbone::{resolve, Backbone, BackboneInfo, Preprocess};
use crate::error::{ModelError, Result};
use crate::extractor::FeatureExtractor;
use crate::hashing::file_sha256;
use crate::heads::{Head, HeadConfig, HeadKind};
use crate::model::preprocess::center_crop;
use candle_core::{DType, Device, Tensor};
use candle_nn::VarBuilder;
use grasp_schema::atomic::{write_atomic, write_atomic_with};
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
    /// A pretrained EfficientNet-Lite whose last blocks (batch norm frozen)
    /// are trained with the head, on cached activations of the blocks
    /// before them; the checkpoint holds them as `tail.*`.
    FineTuned,
}

impl TrainMode {
    pub fn name(self) -> &'static str {
        match self {
            TrainMode::FrozenPretrained => "frozen-pretrained",
            TrainMode::FromScratch => "from-scratch",
            TrainMode::FineTuned => "fine-tuned",
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
        let text =
            std::fs::read_to_string(&json).map_err(|e| ModelError::read("checkpoint", &json, e))?;
        let meta: CheckpointMeta =
            serde_json::from_str(&text).map_err(|e| ModelError::Corrupt {
                path: json.clone(),
                reason: format!("invalid checkpoint metadata: {e}"),
            })?;
        if !(OLDEST_FORMAT_VERSION..=FORMAT_VERSION).contains(&meta.format_version) {
            return Err(ModelError::UnsupportedVersion {
                path: json,
                found: meta.format_version,
                oldest: OLDEST_FORMAT_VERSION,
                newest: FORMAT_VERSION,
            });
        }
        let dir = json.parent().unwrap_or(Path::new(".")).to_path_buf();
        Ok((meta, dir))
    }
}

impl BackboneInfo {
    /// A checkpoint's backbone, to be used frozen: the `backbone.*` tensors
    /// of a from-scratch checkpoint, or the pretrained file a frozen one was
    /// trained on. Also returns the checkpoint's preprocessing, which the
    /// backbone was trained with and must keep.
    pub fn from_checkpoint(dir_or_json: &Path) -> Result<(BackboneInfo, Preprocess)> {
        if dir_or_json.is_dir() && !dir_or_json.join(META_FILE).is_file() {
            return Err(ModelError::Invalid(format!(
                "{} is not a checkpoint (no {META_FILE}){}",
                dir_or_json.display(),
                seed_hint(dir_or_json)
            )));
        }
        let (meta, dir) = CheckpointMeta::load(dir_or_json)?;
        let info = match meta.mode {
            TrainMode::FromScratch => {
                let weights = dir.join(WEIGHTS_FILE);
                BackboneInfo {
                    id: meta.backbone.id.clone(),
                    arch: meta.backbone.arch,
                    weights_sha256: Some(file_sha256(&weights)?),
                    weights_path: Some(weights),
                    width_mult: meta.backbone.width_mult,
                    num_classes: meta.backbone.num_classes,
                    weights_prefix: Some("backbone".to_string()),
                    source_checkpoint: Some(dir),
                    tuned: None,
                    pooled_blocks: Vec::new(),
                }
            }
            TrainMode::FrozenPretrained => {
                let mut info = meta.backbone.clone();
                info.weights_path = info.weights_path.map(|p| resolve(&p, &dir));
                info
            }
            TrainMode::FineTuned => {
                let mut info = tuned_backbone(&meta, &dir)?;
                info.source_checkpoint = Some(dir);
                info
            }
        };
        Ok((info, meta.preprocessing))
    }
}

/// Refuses a checkpoint whose head reads features of another width than its
/// backbone gives, naming both (a hand-edited `pooled_blocks`, or a
/// checkpoint written before pooled blocks were recorded), instead of
/// failing later at the first frame with bare tensor shapes.
fn check_head_width(meta: &CheckpointMeta, backbone_width: usize, dir: &Path) -> Result<()> {
    if meta.head.feature_dim == backbone_width {
        return Ok(());
    }
    Err(ModelError::Corrupt {
        path: dir.join(META_FILE),
        reason: format!(
            "its head reads {} features per frame, but its backbone ({}, backbone.pooled_blocks \
             {:?}) gives {backbone_width}: the recorded pooled blocks are not the ones it was \
             trained with",
            meta.head.feature_dim, meta.backbone.id, meta.backbone.pooled_blocks
        ),
    })
}

/// The backbone of a fine-tuned checkpoint in `dir`: the pretrained file it
/// recorded, with its tuned blocks read from the checkpoint's weights.
fn tuned_backbone(meta: &CheckpointMeta, dir: &Path) -> Result<BackboneInfo> {
    let mut info = meta.backbone.clone();
    info.weights_path = info.weights_path.map(|p| resolve(&p, dir));
    let tuned = info.tuned.as_mut().ok_or_else(|| ModelError::Corrupt {
        path: dir.join(META_FILE),
        reason: "mode fine-tuned without backbone.tuned (the first tuned block)".into(),
    })?;
    tuned.weights_path = Some(dir.join(WEIGHTS_FILE));
    tuned.weights_sha256 = None;
    Ok(info)
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

/// Writes the checkpoint atomically: tensors first, metadata last, so a
/// `best.json` always describes a complete `best.safetensors`.
pub fn save(dir: &Path, meta: &CheckpointMeta, tensors: &[(String, Tensor)]) -> Result<()> {
    let map: std::collections::HashMap<String, Tensor> = tensors.iter().cloned().collect();
    write_atomic_with(&dir.join(WEIGHTS_FILE), |tmp| -> Result<()> {
        Ok(candle_core::safetensors::save(&map, tmp)?)
    })?;
    let json = serde_json::to_string_pretty(meta).map_err(|e| {
        ModelError::Invalid(format!("cannot serialize the checkpoint metadata: {e}"))
    })?;
    Ok(write_atomic(&dir.join(META_FILE), json.as_bytes())?)
}

/// The centre crop a head was trained on, applied to every camera frame
/// before the backbone.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CentreCrop {
    /// A fixed fraction of the frame's shorter side (`--center-crop`).
    Fraction(f64),
    /// The square spanning a fixed angle, in degrees (`--crop-angle-deg`):
    /// its fraction of a frame follows from the camera's focal length.
    AngleDeg(f64),
}

/// A trained pre-shape classifier: backbone plus head, for inference.
pub struct Classifier {
    pub meta: CheckpointMeta,
    backbone: Backbone,
    head: Head,
    crop: Option<CentreCrop>,
    /// The crop is denoised before the backbone (`--denoise`).
    denoise: bool,
    /// Focal length in pixels, along the frames' shorter side, of the
    /// camera whose frames `predict` is given ([`Classifier::set_focal_px`]).
    focal_px: Option<f64>,
}

impl Classifier {
    /// Loads `best.json` (or the directory holding it) and its weights. In
    /// frozen-pretrained mode the backbone is read from the weights file
    /// recorded in the JSON (relative paths are tried against the current
    /// directory, then the checkpoint directory), and its hash is checked.
    pub fn load(dir_or_json: &Path, device: &Device) -> Result<Classifier> {
        let (meta, dir) = CheckpointMeta::load(dir_or_json)?;
        let weights = dir.join(WEIGHTS_FILE);
        if !weights.is_file() {
            return Err(ModelError::Missing {
                what: "checkpoint weights",
                path: weights,
            });
        }
        // SAFETY: the file is mapped read-only and not modified while mapped
        // (checkpoints are replaced by rename, never rewritten in place).
        let vb = unsafe { VarBuilder::from_mmaped_safetensors(&[&weights], DType::F32, device) }
            .map_err(|e| ModelError::Unreadable {
                path: weights.clone(),
                what: "not a readable safetensors file",
                source: Box::new(e),
            })?;
        let head = Head::new(meta.head, vb.pp("head"))
            .map_err(|e| ModelError::tensors(format!("{}: head tensors", weights.display()), e))?;
        let backbone = match meta.mode {
            TrainMode::FromScratch => Backbone::from_vb(
                meta.backbone.clone(),
                meta.preprocessing.clone(),
                vb.pp("backbone"),
                device,
            )
            .map_err(|e| match e {
                ModelError::Tensors { context, source } => ModelError::tensors(
                    format!("{}: backbone tensors: {context}", weights.display()),
                    source,
                ),
                other => other,
            })?,
            TrainMode::FrozenPretrained => {
                let mut info = meta.backbone.clone();
                info.weights_path = info.weights_path.map(|p| resolve(&p, &dir));
                Backbone::load_pretrained(&info, meta.preprocessing.clone(), device)?
            }
            TrainMode::FineTuned => Backbone::load_pretrained(
                &tuned_backbone(&meta, &dir)?,
                meta.preprocessing.clone(),
                device,
            )?,
        };
        check_head_width(&meta, backbone.net.feature_dim(), &dir)?;
        let crop = trained_crop(&meta, &dir)?;
        let denoise = trained_denoise(&meta, &dir)?;
        Ok(Classifier {
            meta,
            backbone,
            head: head.detached(),
            crop,
            denoise,
            focal_px: None,
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

    /// The centre crop applied to camera frames, as recorded at training;
    /// `None`: whole frames.
    pub fn crop(&self) -> Option<CentreCrop> {
        self.crop
    }

    /// Whether the crop is denoised before the backbone, as at training.
    pub fn denoises(&self) -> bool {
        self.denoise
    }

    /// Tells the classifier the focal length, in pixels along the frames'
    /// shorter side, of the camera whose frames it will be given. A
    /// checkpoint that crops a fixed angle needs it; the others ignore it.
    pub fn set_focal_px(&mut self, focal_px: f64) -> Result<()> {
        if !(focal_px.is_finite() && focal_px > 0.0) {
            return Err(ModelError::Invalid(format!(
                "the camera's focal length must be a positive number of pixels, got {focal_px}"
            )));
        }
        self.focal_px = Some(focal_px);
        Ok(())
    }

    /// The fraction of the shorter side of `width` x `height` frames that
    /// the crop takes (`None`: whole frames). A fixed-angle crop without a
    /// focal length ([`Classifier::set_focal_px`]) is an error; through a
    /// lens too narrow to hold the angle it is the whole frame, as the
    /// trainer cuts it down to what it has.
    pub fn crop_fraction(&self, width: u32, height: u32) -> Result<Option<f64>> {
        match self.crop {
            None => Ok(None),
            Some(CentreCrop::Fraction(f)) => Ok(Some(f)),
            Some(CentreCrop::AngleDeg(angle)) => {
                let focal = self.focal_px.ok_or_else(|| {
                    ModelError::Invalid(format!(
                        "the checkpoint crops a fixed angle of {angle} degrees: it needs the \
                         camera's focal length (from the recording's sequence.json, or given \
                         for a live camera)"
                    ))
                })?;
                match grasp_schema::dataset::angle_crop_fraction(angle, focal, width, height) {
                    Some(f) => Ok(Some(f.min(1.0))),
                    None => Err(ModelError::Invalid(format!(
                        "no crop of {angle} degrees in a {width}x{height} frame at a focal \
                         length of {focal} px"
                    ))),
                }
            }
        }
    }

    /// A whole camera frame as the backbone is fed it: centre-cropped, then
    /// denoised, as the checkpoint was trained.
    pub fn prepare(&self, frame: &RgbImage) -> Result<RgbImage> {
        let cropped = match self.crop_fraction(frame.width(), frame.height())? {
            Some(fraction) => center_crop(frame, fraction),
            None => frame.clone(),
        };
        Ok(if self.denoise {
            crate::model::denoise::denoise(&cropped)
        } else {
            cropped
        })
    }

    /// Per-frame class probabilities of whole camera frames (softmax by
    /// log-sum-exp), prepared first as the checkpoint was trained
    /// ([`Classifier::prepare`]). The FC head treats frames independently;
    /// an LSTM head reads them as one sequence in the given order, from a
    /// zero state.
    pub fn predict(&self, frames: &[RgbImage]) -> Result<Vec<[f32; Class::COUNT]>> {
        if frames.is_empty() {
            return Ok(Vec::new());
        }
        let feats = if self.crop.is_none() && !self.denoise {
            self.backbone.extract(frames)?
        } else {
            let prepared = frames
                .iter()
                .map(|f| self.prepare(f))
                .collect::<Result<Vec<_>>>()?;
            self.backbone.extract(&prepared)?
        };
        self.predict_features(&feats)
    }

    /// Per-frame probabilities from precomputed features `(T, D)`.
    pub fn predict_features(&self, feats: &Tensor) -> Result<Vec<[f32; Class::COUNT]>> {
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
pub fn probabilities(logits: &Tensor) -> Result<Vec<[f32; Class::COUNT]>> {
    let p: Vec<Vec<f32>> = crate::softmax::softmax(logits)?.to_vec2()?;
    p.into_iter()
        .map(|row| {
            row.try_into().map_err(|r: Vec<f32>| {
                ModelError::Invalid(format!(
                    "expected {} classes, got {}",
                    Class::COUNT,
                    r.len()
                ))
            })
        })
        .collect()
}

/// The trainer records its reader options in `train_config.reader`; a crop
/// outside (0, 1], an angle outside (0, 180) degrees or both crops at once
/// is a corrupt checkpoint, not a silent whole-frame model.
fn trained_crop(meta: &CheckpointMeta, dir: &Path) -> Result<Option<CentreCrop>> {
    let reader = &meta.train_config["reader"];
    let corrupt = |field: &str, want: &str, value: &serde_json::Value| {
        ModelError::Invalid(format!(
            "{}: train_config.reader.{field} must be {want}, got {value}",
            dir.join(META_FILE).display()
        ))
    };
    let fraction = match &reader["center_crop"] {
        serde_json::Value::Null => None,
        value => match value.as_f64() {
            Some(f) if f > 0.0 && f <= 1.0 => Some(CentreCrop::Fraction(f)),
            _ => return Err(corrupt("center_crop", "a fraction in (0, 1]", value)),
        },
    };
    let angle = match &reader["crop_angle_deg"] {
        serde_json::Value::Null => None,
        value => match value.as_f64() {
            Some(a) if a > 0.0 && a < 180.0 => Some(CentreCrop::AngleDeg(a)),
            _ => {
                return Err(corrupt(
                    "crop_angle_deg",
                    "an angle in (0, 180) degrees",
                    value,
                ))
            }
        },
    };
    match (fraction, angle) {
        (Some(_), Some(_)) => Err(ModelError::Invalid(format!(
            "{}: train_config.reader sets both center_crop and crop_angle_deg",
            dir.join(META_FILE).display()
        ))),
        (crop, None) | (None, crop) => Ok(crop),
    }
}

/// `train_config.reader.denoise`: absent (checkpoints from before it) is
/// false; anything but a boolean is a corrupt checkpoint.
fn trained_denoise(meta: &CheckpointMeta, dir: &Path) -> Result<bool> {
    match &meta.train_config["reader"]["denoise"] {
        serde_json::Value::Null => Ok(false),
        serde_json::Value::Bool(b) => Ok(*b),
        value => Err(ModelError::Invalid(format!(
            "{}: train_config.reader.denoise must be true or false, got {value}",
            dir.join(META_FILE).display()
        ))),
    }
}
