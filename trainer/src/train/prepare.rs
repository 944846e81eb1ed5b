//! What a run needs besides its seed: the splits' cached features (of
//! the plan's frozen backbone or blocks) or decoded frames, and the
//! network built for a seed.

use super::damping::ViewDamping;
use super::tail::{BlockActivations, Tail, TailStart};
use super::{Net, SplitFrames, Splits};
use crate::data::BadData;
use crate::error::{ConfigError, Result};
use crate::plan::{CachePlan, Extraction, FeaturePlan, NetPlan, Views};
use candle_core::{DType, Device};
use candle_nn::{VarBuilder, VarMap};
use grasp_model::backbone::{
    Architecture, Backbone, BackboneInfo, Preprocess, TunedTail, BACKBONE_ID,
};
use grasp_model::extractor::FeatureExtractor;
use grasp_model::heads::{Head, HeadConfig, HeadKind};
use grasp_schema::taxonomy::Class;

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

/// The frame rate a sequence head steps at: the one rate of the training
/// sequences, which evaluation and any later reader resample to
/// (`HeadConfig::steps`). None for a head that classifies frames.
fn step_rate(head: HeadKind, splits: &Splits) -> Result<Option<f64>> {
    if head.classifies_frames() {
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
                head.name(),
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

/// The splits' cached features (frozen backbone or blocks) or decoded
/// frames (from scratch), as `features` says.
pub fn prepare(
    features: FeaturePlan,
    cache: &CachePlan,
    splits: &Splits,
    bad: &BadData,
    dev: &Device,
) -> Result<Prepared> {
    let step_hz = step_rate(features.head, splits)?;
    let mut prep = prepare_frames(features.extraction, cache, splits, bad, dev)?;
    prep.step_hz = step_hz;
    // A sequence head is validated as it will be evaluated: each validation
    // video read at the training rate (training's own videos are at it).
    if let Some(hz) = step_hz {
        prep.val.keep_steps_at(hz);
    }
    Ok(prep)
}

/// [`prepare`] by mode, every frame of both splits kept.
fn prepare_frames(
    extraction: Extraction,
    cache: &CachePlan,
    splits: &Splits,
    bad: &BadData,
    dev: &Device,
) -> Result<Prepared> {
    let real_data = splits.train.is_real();
    let train_sequences = splits.train.sequences.len();
    match extraction {
        Extraction::Frozen {
            backbone: bb,
            views,
            damping,
            trace_s,
        } => {
            let (mut train, mut val) = cached_frames(cache, &views, splits, &bb, bad, dev)?;
            let damping = damp_views(damping, &mut train, &mut val, train_sequences)?;
            if let Some(trace_s) = trace_s {
                train.trace(trace_s)?;
                val.trace(trace_s)?;
            }
            Ok(Prepared {
                train,
                val,
                real_data,
                train_sequences,
                feature_dim: bb.feature_dim(),
                preprocess: bb.preprocess,
                backbone: Some(bb.info),
                tail: None,
                damping,
                step_hz: None,
            })
        }
        Extraction::FineTuned {
            backbone: bb,
            start,
            views,
        } => {
            let acts = BlockActivations::before(&bb, &start);
            let (train, val) = cached_frames(cache, &views, splits, &acts, bad, dev)?;
            let mut info = bb.info.clone();
            info.tuned = Some(TunedTail::new(start.from));
            Ok(Prepared {
                train,
                val,
                real_data,
                train_sequences,
                feature_dim: bb.feature_dim(),
                preprocess: bb.preprocess.clone(),
                backbone: Some(info),
                tail: Some(start),
                damping: None,
                step_hz: None,
            })
        }
        Extraction::FromScratch {
            load_size,
            preprocess,
        } => Ok(Prepared {
            train: SplitFrames::from_images(&splits.train, load_size, bad)?,
            val: SplitFrames::from_images(&splits.val, load_size, bad)?,
            real_data,
            train_sequences,
            backbone: None,
            feature_dim: 0,
            preprocess,
            tail: None,
            damping: None,
            step_hz: None,
        }),
    }
}

/// With a damping strength, the damping of what the training views
/// change, applied to both splits' features.
fn damp_views(
    strength: f64,
    train: &mut SplitFrames,
    val: &mut SplitFrames,
    originals: usize,
) -> Result<Option<ViewDamping>> {
    if strength <= 0.0 {
        return Ok(None);
    }
    let damping = ViewDamping::from_views(train, originals, strength)?;
    match &damping {
        Some(d) => {
            tracing::info!(
                "view damping {strength}: the views' largest feature change holds {:.1} % of them",
                100.0 * d.leading_share
            );
            d.apply_to_frames(train)?;
            d.apply_to_frames(val)?;
        }
        None => tracing::warn!("view damping: the views change no feature, nothing to damp"),
    }
    Ok(damping)
}

/// The training split (with its views) and the validation split as rows
/// of `extractor`'s cached output, computing what is missing.
fn cached_frames(
    cache: &CachePlan,
    views: &Views,
    splits: &Splits,
    extractor: &dyn FeatureExtractor,
    bad: &BadData,
    dev: &Device,
) -> Result<(SplitFrames, SplitFrames)> {
    let cache = cache.open();
    let train = crate::data::view::with_views(&splits.train, &views.config, views.seed);
    let tf = cache.dataset(extractor, &train, bad)?;
    let vf = cache.dataset(extractor, &splits.val, bad)?;
    Ok((
        SplitFrames::from_features(&train, &tf, dev)?,
        SplitFrames::from_features(&splits.val, &vf, dev)?,
    ))
}

pub(super) fn build_net(
    plan: &NetPlan,
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
                width_mult: plan.width_mult,
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
        kind: plan.head,
        feature_dim,
        classes: Class::COUNT,
        lstm_hidden: plan.lstm_hidden,
        step_hz: prep.step_hz,
        trace_s: plan.trace_s,
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
            augment: plan.augment.clone(),
            tbptt: plan.tbptt,
            start_crop: plan.start_crop,
        },
        info,
    ))
}
