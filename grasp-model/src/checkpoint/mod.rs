//! Checkpoints and the runtime-facing classifier.
//!
//! A checkpoint is a directory with `best.safetensors` (the head's tensors
//! under `head.`, plus the backbone's under `backbone.` when it was trained
//! from scratch, or its fine-tuned last blocks under `tail.`) and `best.json` ([`CheckpointMeta`]: classes, mode,
//! preprocessing, backbone, training config). Both are written atomically.

mod legacy;

use crate::backbone::{resolve, Backbone, BackboneInfo, Preprocess};
use crate::error::{ModelError, Result};
use crate::extractor::FeatureExtractor;
use crate::hashing::file_sha256;
use crate::heads::{Head, HeadConfig, HeadKind};
use crate::input::{InputSpec, Lens};
use crate::trace::FeatureTrace;
use candle_core::{DType, Device, Tensor};
use candle_nn::VarBuilder;
use grasp_schema::taxonomy::Class;
use grasp_support::atomic::{write_atomic, write_atomic_with};
use image::RgbImage;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// 3: the input record (`input`: crop, denoising, preprocessing) replaces
/// `preprocessing` and the trainer's reader options. 2: the backbone
/// records its architecture and the preprocessing its resize filter.
/// Versions 1 and 2 still load, their fields mapped ([`legacy`]).
pub const FORMAT_VERSION: u32 = legacy::INPUT_RECORD_VERSION;
const OLDEST_FORMAT_VERSION: u32 = 1;
pub const META_FILE: &str = "best.json";
pub const WEIGHTS_FILE: &str = "best.safetensors";

/// How the backbone of a model was obtained. Every report states it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
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
    pub const ALL: [TrainMode; 3] = [
        TrainMode::FrozenPretrained,
        TrainMode::FromScratch,
        TrainMode::FineTuned,
    ];

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
    /// How frames become the backbone's input: training, evaluation and
    /// the hand all read it from here.
    pub input: InputSpec,
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
        let corrupt = |reason: String| ModelError::Corrupt {
            path: json.clone(),
            reason,
        };
        let mut value: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| corrupt(format!("invalid checkpoint metadata: {e}")))?;
        let found = value
            .get("format_version")
            .and_then(serde_json::Value::as_u64)
            .ok_or_else(|| corrupt("missing or invalid field `format_version`".into()))?;
        let found = u32::try_from(found).unwrap_or(u32::MAX);
        if !(OLDEST_FORMAT_VERSION..=FORMAT_VERSION).contains(&found) {
            return Err(ModelError::UnsupportedVersion {
                path: json,
                found,
                oldest: OLDEST_FORMAT_VERSION,
                newest: FORMAT_VERSION,
            });
        }
        if found < legacy::INPUT_RECORD_VERSION {
            legacy::upgrade(&mut value).map_err(&corrupt)?;
        }
        let meta: CheckpointMeta = serde_json::from_value(value)
            .map_err(|e| corrupt(format!("invalid checkpoint metadata: {e}")))?;
        meta.input.validate().map_err(|e| corrupt(e.to_string()))?;
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
        Ok((info, meta.input.preprocess))
    }
}

/// A backbone record the checkpoint's `best.json` holds but no backbone can
/// be built from (a pooled block the network lacks): corrupt, naming it.
fn in_checkpoint(e: ModelError, dir: &Path) -> ModelError {
    match e {
        ModelError::Invalid(reason) => ModelError::Corrupt {
            path: dir.join(META_FILE),
            reason: format!("backbone: {reason}"),
        },
        other => other,
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

/// A trained pre-shape classifier: backbone plus head, for inference.
pub struct Classifier {
    pub meta: CheckpointMeta,
    backbone: Backbone,
    head: Head,
    /// The lens of the camera whose frames `predict` is given
    /// ([`Classifier::set_lens`]); a fixed-angle crop needs it.
    lens: Option<Lens>,
    /// A trace head's history of the current approach
    /// ([`Classifier::predict_at`]).
    trace: Option<FeatureTrace>,
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
                meta.input.preprocess.clone(),
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
                Backbone::load_pretrained(&info, meta.input.preprocess.clone(), device)
                    .map_err(|e| in_checkpoint(e, &dir))?
            }
            TrainMode::FineTuned => Backbone::load_pretrained(
                &tuned_backbone(&meta, &dir)?,
                meta.input.preprocess.clone(),
                device,
            )
            .map_err(|e| in_checkpoint(e, &dir))?,
        };
        check_head_width(&meta, backbone.net.feature_dim(), &dir)?;
        check_finite(&weights)?;
        let trace = meta.head.new_trace().map_err(|e| ModelError::Corrupt {
            path: dir.join(META_FILE),
            reason: e.to_string(),
        })?;
        Ok(Classifier {
            meta,
            backbone,
            head: head.detached(),
            lens: None,
            trace,
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

    /// How frames become the backbone's input, as recorded at training.
    pub fn input(&self) -> &InputSpec {
        &self.meta.input
    }

    /// Tells the classifier the lens of the camera whose frames it will be
    /// given. A checkpoint that crops a fixed angle needs it; the others
    /// ignore it.
    pub fn set_lens(&mut self, lens: Lens) {
        self.lens = Some(lens);
    }

    pub fn lens(&self) -> Option<&Lens> {
        self.lens.as_ref()
    }

    /// The fraction of the shorter side of `width` x `height` frames that
    /// the crop takes (`None`: whole frames); see [`InputSpec::crop_fraction`].
    pub fn crop_fraction(&self, width: u32, height: u32) -> Result<Option<f64>> {
        Ok(self
            .meta
            .input
            .crop_fraction(self.lens.as_ref(), width, height)?)
    }

    /// A whole camera frame as the backbone is fed it ([`InputSpec::prepare`]).
    pub fn prepare(&self, frame: &RgbImage) -> Result<RgbImage> {
        Ok(self.meta.input.prepare(frame, self.lens.as_ref())?)
    }

    /// Per-frame class probabilities of whole camera frames (softmax by
    /// log-sum-exp), prepared first as the checkpoint was trained
    /// ([`Classifier::prepare`]). The FC head treats frames independently;
    /// an LSTM head reads them as one sequence in the given order, from a
    /// zero state. A trace head needs the frames' times:
    /// [`Classifier::predict_at`] or [`Classifier::predict_video`].
    pub fn predict(&self, frames: &[RgbImage]) -> Result<Vec<[f32; Class::COUNT]>> {
        if frames.is_empty() {
            return Ok(Vec::new());
        }
        if self.head.cfg.kind == HeadKind::Trace {
            return Err(ModelError::Invalid(
                "a trace head reads frames with their times (predict_at)".into(),
            ));
        }
        // On a worker of the tensor kernels' pool: every parallel kernel of
        // the frame then splits its work there, instead of waking the pool
        // and putting the caller to sleep once per layer.
        rayon::scope(|_| {
            let prepared = frames
                .iter()
                .map(|f| self.prepare(f))
                .collect::<Result<Vec<_>>>()?;
            let feats = self.backbone.extract(&prepared)?;
            self.predict_features(&feats)
        })
    }

    /// The network's input (1, 3, size, size) of one camera frame: the
    /// crop, the denoiser, the resize and the normalisation, as
    /// [`Classifier::predict_at`] runs them (one stage of its frame, for
    /// benchmarks).
    pub fn frame_input(&self, frame: &RgbImage) -> Result<Tensor> {
        rayon::scope(|_| {
            let prepared = self.prepare(frame)?;
            self.backbone.input(std::slice::from_ref(&prepared))
        })
    }

    /// The backbone's features (1, D) of a [`Classifier::frame_input`], as
    /// [`Classifier::predict_at`] computes them (the network alone, for
    /// benchmarks).
    pub fn network_features(&self, input: &Tensor) -> Result<Tensor> {
        rayon::scope(|_| Ok(self.backbone.net.features(input, false)?))
    }

    /// Starts a new approach: a trace head forgets the last one's frames.
    pub fn begin_approach(&mut self) {
        if let Some(t) = &mut self.trace {
            t.reset();
        }
    }

    /// The probabilities of one camera frame seen at `time_s` (s) in the
    /// current approach ([`Classifier::begin_approach`]), as the hand's
    /// loop classifies: a trace head adds the frame to its history first.
    pub fn predict_at(&mut self, frame: &RgbImage, time_s: f64) -> Result<[f32; Class::COUNT]> {
        let probs = rayon::scope(|_| -> Result<Vec<[f32; Class::COUNT]>> {
            let prepared = self.prepare(frame)?;
            let feats = self.backbone.extract(std::slice::from_ref(&prepared))?;
            let input = match &mut self.trace {
                None => feats,
                Some(trace) => {
                    let row: Vec<f32> = feats.flatten_all()?.to_vec1()?;
                    let traced = trace.push(time_s, &row);
                    Tensor::from_slice(traced, (1, traced.len()), feats.device())?
                }
            };
            self.predict_rows(&input)
        })?;
        probs
            .into_iter()
            .next()
            .ok_or_else(|| ModelError::Invalid("no output for one frame".into()))
    }

    /// Per-frame probabilities of one video from its precomputed features
    /// `(T, D)` at times `times_s`: a trace head traces them first.
    pub fn predict_video(
        &self,
        feats: &Tensor,
        times_s: &[f64],
    ) -> Result<Vec<[f32; Class::COUNT]>> {
        match self.head.cfg.kind {
            HeadKind::Trace => {
                let (t, dim) = feats.dims2()?;
                let tau = self.head.cfg.trace_s.unwrap_or(f64::NAN);
                let rows: Vec<f32> = feats.flatten_all()?.to_vec1()?;
                let traced = crate::trace::traced_rows(times_s, &rows, dim, tau);
                self.predict_rows(&Tensor::from_vec(traced, (t, 2 * dim), feats.device())?)
            }
            _ => self.predict_features(feats),
        }
    }

    /// Per-frame probabilities from precomputed features `(T, D)` (an FC or
    /// LSTM head; a trace head's need times, [`Classifier::predict_video`]).
    pub fn predict_features(&self, feats: &Tensor) -> Result<Vec<[f32; Class::COUNT]>> {
        match self.head.cfg.kind {
            HeadKind::Lstm => probabilities(
                &self
                    .head
                    .forward_sequences(&feats.unsqueeze(0)?)?
                    .squeeze(0)?,
            ),
            HeadKind::Fc => self.predict_rows(feats),
            HeadKind::Trace => Err(ModelError::Invalid(
                "a trace head reads features with their times (predict_video)".into(),
            )),
        }
    }

    /// Probabilities of the head's input rows, frame by frame.
    fn predict_rows(&self, rows: &Tensor) -> Result<Vec<[f32; Class::COUNT]>> {
        probabilities(&self.head.forward_frames(rows)?)
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

/// Refuses a weights file with a non-finite value (a diverged training, a
/// corrupted copy): its every output would be NaN, which the hand must never
/// be driven by, and a report would look normal.
fn check_finite(weights: &Path) -> Result<()> {
    let tensors = candle_core::safetensors::load(weights, &Device::Cpu).map_err(|e| {
        ModelError::Unreadable {
            path: weights.to_path_buf(),
            what: "not a readable safetensors file",
            source: Box::new(e),
        }
    })?;
    let mut names: Vec<&String> = tensors.keys().collect();
    names.sort();
    for name in names {
        let t = tensors[name].to_dtype(DType::F32)?.flatten_all()?;
        if t.to_vec1::<f32>()?.iter().any(|v| !v.is_finite()) {
            return Err(ModelError::Corrupt {
                path: weights.to_path_buf(),
                reason: format!("tensor {name} holds non-finite values (NaN or infinity)"),
            });
        }
    }
    Ok(())
}
