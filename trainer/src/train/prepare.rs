//! What a run needs besides its seed: the frozen backbone (checkpoint,
//! pretrained file, or the venv's ImageNet weights), the splits' frames
//! or cached features, and the network built for a seed.

use super::damping::ViewDamping;
use super::tail::{BlockActivations, Tail, TailStart};
use super::{Net, SplitFrames, Splits};
use crate::config::TrainConfig;
use crate::data::BadData;
use crate::error::{ConfigError, Result, TrainError};
use crate::features::FeatureCache;
use candle_core::{DType, Device};
use candle_nn::{VarBuilder, VarMap};
use grasp_model::backbone::{
    Architecture, Backbone, BackboneInfo, Preprocess, TunedTail, BACKBONE_ID,
};
use grasp_model::checkpoint::TrainMode;
use grasp_model::extractor::FeatureExtractor;
use grasp_model::heads::{Head, HeadConfig, HeadKind};
use grasp_schema::taxonomy::Class;
use std::path::Path;

/// Everything a run needs besides its seed.
pub struct Prepared {
    pub train: SplitFrames,
    pub val: SplitFrames,
    pub real_data: bool,
    /// Training sequences, not counting their augmented views.
    pub train_sequences: usize,
    /// Frozen mode: the pretrained backbone's description.
    pub backbone: Option<BackboneInfo>,
    pub feature_dim: usize,
    /// The input preprocessing the checkpoints record.
    pub preprocess: Preprocess,
    /// Fine-tuned mode: the blocks that train, as pretrained.
    pub tail: Option<TailStart>,
    /// Frozen mode with `view_damping`: the map the features went through.
    pub damping: Option<ViewDamping>,
    /// A sequence head's step rate: the training sequences' frame rate.
    pub step_hz: Option<f64>,
}

/// The frozen backbone of `cfg`: a checkpoint named by `cfg.weights`, whose
/// backbone and preprocessing are reused as they are; a pretrained weights
/// file named by `cfg.weights`, its architecture detected from its tensor
/// names; or, without `cfg.weights`, the venv's ImageNet file of
/// `cfg.backbone` (EfficientNet-Lite0 by default). Pretrained files get
/// their architecture's preprocessing at `cfg.input_size`.
pub fn frozen_backbone(cfg: &TrainConfig) -> Result<(BackboneInfo, Preprocess)> {
    let (mut info, pre) = unpooled_backbone(cfg)?;
    if !cfg.pooled_blocks.is_empty() {
        info.pooled_blocks = cfg.pooled_blocks.clone();
    }
    Ok((info, pre))
}

/// The backbone of [`frozen_backbone`] before `cfg.pooled_blocks` apply (a
/// checkpoint keeps its own when none are asked for).
fn unpooled_backbone(cfg: &TrainConfig) -> Result<(BackboneInfo, Preprocess)> {
    let Some(path) = cfg.weights.as_ref() else {
        let arch = cfg.backbone.unwrap_or(Architecture::EfficientNetLite0);
        let variant = arch.lite().ok_or_else(|| {
            let reason = format!("a frozen {} needs --weights FILE", arch.name());
            ConfigError::invalid("weights", reason)
        })?;
        let path = grasp_model::backbone::venv_weights(variant)?;
        return Ok((
            BackboneInfo::pretrained(&path, arch, cfg.width_mult)?,
            arch.preprocess(cfg.input_size),
        ));
    };
    if grasp_model::backbone::is_checkpoint(path) {
        return BackboneInfo::from_checkpoint(path).map_err(|source| {
            TrainError::CheckpointBackbone {
                path: path.clone(),
                model: Box::new(source),
            }
        });
    }
    let arch = detect_architecture(path)?;
    if let Some(asked) = cfg.backbone.filter(|a| *a != arch) {
        let reason = format!(
            "backbone {} does not match the weights file {}, which is {}",
            asked.name(),
            path.display(),
            arch.name()
        );
        return Err(ConfigError::invalid("backbone", reason).into());
    }
    Ok((
        BackboneInfo::pretrained(path, arch, cfg.width_mult)?,
        arch.preprocess(cfg.input_size),
    ))
}

/// The architecture of a pretrained weights file, from its tensor names.
pub fn detect_architecture(path: &Path) -> Result<Architecture> {
    let vb = grasp_model::weights::var_builder(path, &Device::Cpu)?;
    Architecture::detect(&vb).ok_or_else(|| TrainError::UnknownArchitecture {
        path: path.to_path_buf(),
    })
}

/// The frame rate a sequence head steps at: the one rate of the training
/// sequences, which evaluation and any later reader resample to
/// (`HeadConfig::steps`). None for a head that classifies frames.
fn step_rate(cfg: &TrainConfig, splits: &Splits) -> Result<Option<f64>> {
    if cfg.head.classifies_frames() {
        return Ok(None);
    }
    let mut rates: Vec<f64> = Vec::new();
    for seq in &splits.train.sequences {
        if !rates.iter().any(|r| (r - seq.fps).abs() <= 1e-6 * r.abs()) {
            rates.push(seq.fps);
        }
    }
    match rates.as_slice() {
        [] => Ok(None),
        [one] => Ok(Some(*one)),
        _ => {
            rates.sort_by(f64::total_cmp);
            let reason = format!(
                "an {} head steps at one frame rate, and the training sequences have {} \
                 (frames/s): train it on sequences of one rate",
                cfg.head.name(),
                rates
                    .iter()
                    .map(|r| format!("{r}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            Err(ConfigError::invalid("head", reason).into())
        }
    }
}

/// Loads the backbone and computes (or reads cached) features in frozen
/// mode, or decodes the frames for training from scratch.
pub fn prepare(
    cfg: &TrainConfig,
    splits: &Splits,
    bad: &BadData,
    dev: &Device,
) -> Result<Prepared> {
    let real_data = splits.train.is_real();
    let step_hz = step_rate(cfg, splits)?;
    let mut prep = prepare_frames(cfg, splits, bad, dev, real_data, step_hz)?;
    // A sequence head is validated as it will be evaluated: each validation
    // video read at the training rate (training's own videos are at it).
    if let Some(hz) = step_hz {
        prep.val.keep_steps_at(hz);
    }
    Ok(prep)
}

/// [`prepare`] for `cfg.mode`, every frame of both splits kept.
fn prepare_frames(
    cfg: &TrainConfig,
    splits: &Splits,
    bad: &BadData,
    dev: &Device,
    real_data: bool,
    step_hz: Option<f64>,
) -> Result<Prepared> {
    match cfg.mode {
        TrainMode::FrozenPretrained => {
            let (info, pre) = frozen_backbone(cfg)?;
            let bb = Backbone::load_pretrained(&info, pre, dev)?;
            let (mut train, mut val) = cached_frames(cfg, splits, &bb, bad, dev)?;
            let damping = damp_views(cfg, &mut train, &mut val, splits.train.sequences.len())?;
            if cfg.head == HeadKind::Trace {
                train.trace(cfg.trace_s)?;
                val.trace(cfg.trace_s)?;
            }
            Ok(Prepared {
                train,
                val,
                real_data,
                train_sequences: splits.train.sequences.len(),
                feature_dim: bb.feature_dim(),
                preprocess: bb.preprocess,
                backbone: Some(bb.info),
                tail: None,
                damping,
                step_hz,
            })
        }
        TrainMode::FineTuned => {
            let (info, pre) = frozen_backbone(cfg)?;
            if let Some(checkpoint) = &info.source_checkpoint {
                let reason = format!(
                    "fine-tuned mode starts from a pretrained EfficientNet-Lite file, not from \
                     the checkpoint {}",
                    checkpoint.display()
                );
                return Err(ConfigError::invalid("weights", reason).into());
            }
            let bb = Backbone::load_pretrained(&info, pre, dev)?;
            let acts = BlockActivations::new(&bb, cfg.fine_tune.blocks)?;
            tracing::info!(
                "fine-tuning blocks {}.. of {}; caching the activations before them ({:?})",
                acts.first_tuned_block(),
                info.arch.name(),
                acts.shape
            );
            let start = TailStart::new(&bb, &acts)?;
            let (train, val) = cached_frames(cfg, splits, &acts, bad, dev)?;
            let mut info = bb.info.clone();
            info.tuned = Some(TunedTail::new(start.from));
            Ok(Prepared {
                train,
                val,
                real_data,
                train_sequences: splits.train.sequences.len(),
                feature_dim: bb.feature_dim(),
                preprocess: bb.preprocess.clone(),
                backbone: Some(info),
                tail: Some(start),
                damping: None,
                step_hz,
            })
        }
        TrainMode::FromScratch => {
            let load = if cfg.augment.enabled {
                cfg.input_size * 8 / 7
            } else {
                cfg.input_size
            };
            Ok(Prepared {
                train: SplitFrames::from_images(&splits.train, load, bad)?,
                val: SplitFrames::from_images(&splits.val, load, bad)?,
                real_data,
                train_sequences: splits.train.sequences.len(),
                backbone: None,
                feature_dim: 0,
                preprocess: Preprocess::imagenet(cfg.input_size),
                tail: None,
                damping: None,
                step_hz,
            })
        }
    }
}

/// With `cfg.view_damping`, the damping of what the training views change,
/// applied to both splits' features.
fn damp_views(
    cfg: &TrainConfig,
    train: &mut SplitFrames,
    val: &mut SplitFrames,
    originals: usize,
) -> Result<Option<ViewDamping>> {
    if cfg.view_damping <= 0.0 {
        return Ok(None);
    }
    let damping = ViewDamping::from_views(train, originals, cfg.view_damping)?;
    match &damping {
        Some(d) => {
            tracing::info!(
                "view damping {}: the views' largest feature change holds {:.1} % of them",
                cfg.view_damping,
                100.0 * d.leading_share
            );
            d.apply_to_frames(train)?;
            d.apply_to_frames(val)?;
        }
        None => tracing::warn!("view damping: the views change no feature, nothing to damp"),
    }
    Ok(damping)
}

/// The training split (with its configured views) and the validation
/// split as rows of `extractor`'s cached output, computing what is missing.
fn cached_frames(
    cfg: &TrainConfig,
    splits: &Splits,
    extractor: &dyn FeatureExtractor,
    bad: &BadData,
    dev: &Device,
) -> Result<(SplitFrames, SplitFrames)> {
    if cfg.views.style > 0.0 {
        // refused before anything is cached, not at the first style view
        let channels = extractor.block_channels();
        for &block in &cfg.views.style_blocks {
            crate::data::style::restylable(block, &channels)?;
        }
    }
    let cache = FeatureCache::new(&cfg.cache_dir, cfg.feature_batch);
    let train = crate::data::view::with_views(&splits.train, &cfg.views, cfg.split.seed);
    let tf = cache.dataset(extractor, &train, bad)?;
    let vf = cache.dataset(extractor, &splits.val, bad)?;
    Ok((
        SplitFrames::from_features(&train, &tf, dev)?,
        SplitFrames::from_features(&splits.val, &vf, dev)?,
    ))
}

pub(super) fn build_net(
    cfg: &TrainConfig,
    prep: &Prepared,
    seed: u64,
    dev: &Device,
) -> Result<(Net, BackboneInfo)> {
    let (backbone, info, feature_dim) = match &prep.backbone {
        Some(info) => (None, info.clone(), prep.feature_dim),
        None => {
            let info = BackboneInfo {
                id: BACKBONE_ID.to_string(),
                arch: Architecture::MobileNetV2,
                weights_path: None,
                weights_sha256: None,
                width_mult: cfg.width_mult,
                num_classes: Class::COUNT,
                weights_prefix: None,
                source_checkpoint: None,
                tuned: None,
                pooled_blocks: Vec::new(),
            };
            let vm = VarMap::new();
            let vb = VarBuilder::from_varmap(&vm, DType::F32, dev);
            let bb = Backbone::from_vb(info.clone(), prep.preprocess.clone(), vb, dev)?;
            crate::init::reinit_backbone(&vm, seed)?;
            let dim = bb.feature_dim();
            (Some((bb, vm)), info, dim)
        }
    };
    let head_cfg = HeadConfig {
        kind: cfg.head,
        feature_dim,
        classes: Class::COUNT,
        lstm_hidden: cfg.lstm_hidden,
        step_hz: prep.step_hz,
        trace_s: (cfg.head == HeadKind::Trace).then_some(cfg.trace_s),
    };
    let head_vars = crate::init::head_varmap(&head_cfg, seed, dev)?;
    let head = Head::new(
        head_cfg,
        VarBuilder::from_varmap(&head_vars, DType::F32, dev),
    )?;
    Ok((
        Net {
            head,
            head_vars,
            backbone,
            tail: prep.tail.as_ref().map(|t| Tail::new(t, dev)).transpose()?,
            augment: cfg.augment.clone(),
            tbptt: cfg.tbptt,
            start_crop: cfg.lstm_start_crop,
        },
        info,
    ))
}
