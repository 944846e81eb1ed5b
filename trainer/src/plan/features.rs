//! How a run turns frames into the head's input: the frozen backbone
//! (a checkpoint's, a pretrained file, or the venv's ImageNet weights)
//! settled and loaded once, what fine-tuning starts from, the views and
//! their damping; or, from scratch, the frames themselves.

use crate::config::TrainConfig;
use crate::data::view::ViewConfig;
use crate::error::{ConfigError, Result, TrainError};
use crate::train::{BlockActivations, TailStart};
use candle_core::Device;
use grasp_model::backbone::{Architecture, Backbone, BackboneInfo, Preprocess};
use grasp_model::checkpoint::TrainMode;
use grasp_model::extractor::FeatureExtractor;
use grasp_model::heads::HeadKind;
use std::path::{Path, PathBuf};

/// The feature section of a run.
pub struct FeaturePlan {
    pub head: HeadKind,
    pub extraction: Extraction,
    /// What the config left to resolution about the backbone, as resolved.
    pub settled: Option<Settled>,
}

/// Where the head's input comes from, by mode.
pub enum Extraction {
    /// Cached features of the frozen backbone (the trace head's traced).
    Frozen {
        backbone: Backbone,
        views: Views,
        /// `view_damping` (0: off).
        damping: f64,
        /// The trace head's time constant.
        trace_s: Option<f64>,
    },
    /// Cached activations in front of `start`'s blocks, which train.
    FineTuned {
        backbone: Backbone,
        start: TailStart,
        views: Views,
    },
    /// Decoded frames, `load_size` px (larger than the input when
    /// augmentation crops).
    FromScratch {
        load_size: u32,
        preprocess: Preprocess,
    },
}

/// The extra, seeded views of each training sequence.
#[derive(Debug, Clone)]
pub struct Views {
    pub config: ViewConfig,
    pub seed: u64,
}

/// The backbone as resolved, recorded in the run's config so that
/// `config.toml` says what was run.
#[derive(Debug, Clone, PartialEq)]
pub enum Settled {
    /// A checkpoint's backbone works only at its own width and input size.
    Checkpoint { width_mult: f64, input_size: u32 },
    /// A pretrained file (or the venv's default) and its architecture.
    Pretrained {
        arch: Architecture,
        weights: Option<PathBuf>,
    },
}

impl Settled {
    pub fn record(&self, cfg: &mut TrainConfig) {
        match self {
            Settled::Checkpoint {
                width_mult,
                input_size,
            } => {
                cfg.width_mult = *width_mult;
                cfg.input_size = *input_size;
            }
            Settled::Pretrained { arch, weights } => {
                cfg.backbone = Some(*arch);
                cfg.weights = weights.clone();
            }
        }
    }
}

impl FeaturePlan {
    /// Settles and loads the backbone of a validated `cfg`, refusing what
    /// only the loaded network can tell (its block count, its blocks'
    /// channels for style views, the tail's pooled blocks).
    pub fn resolve(cfg: &TrainConfig) -> Result<FeaturePlan> {
        if cfg.mode == TrainMode::FromScratch {
            let load_size = match cfg.augment.enabled {
                true => cfg.input_size * 8 / 7,
                false => cfg.input_size,
            };
            let extraction = Extraction::FromScratch {
                load_size,
                preprocess: Preprocess::imagenet(cfg.input_size),
            };
            return Ok(FeaturePlan {
                head: cfg.head,
                extraction,
                settled: None,
            });
        }
        let (info, pre) = frozen_backbone(cfg)?;
        let settled = settle(cfg, &info, &pre);
        let backbone = Backbone::load_pretrained(&info, pre, &Device::Cpu)?;
        Ok(FeaturePlan {
            head: cfg.head,
            extraction: pretrained_extraction(cfg, backbone)?,
            settled: Some(settled),
        })
    }
}

/// Frozen or fine-tuned: what is cached of the loaded `backbone`.
fn pretrained_extraction(cfg: &TrainConfig, backbone: Backbone) -> Result<Extraction> {
    let views = Views {
        config: cfg.views.clone(),
        seed: cfg.split.seed,
    };
    if cfg.mode != TrainMode::FineTuned {
        check_style_blocks(&cfg.views, &backbone)?;
        return Ok(Extraction::Frozen {
            backbone,
            views,
            damping: cfg.view_damping,
            trace_s: (cfg.head == HeadKind::Trace).then_some(cfg.trace_s),
        });
    }
    let acts = BlockActivations::new(&backbone, cfg.fine_tune.blocks)?;
    tracing::info!(
        "fine-tuning blocks {}.. of {}; caching the activations before them ({:?})",
        acts.first_tuned_block(),
        backbone.info.arch.name(),
        acts.shape
    );
    check_style_blocks(&cfg.views, &acts)?;
    let start = TailStart::new(&backbone, &acts)?;
    Ok(Extraction::FineTuned {
        backbone,
        start,
        views,
    })
}

/// What resolution decided about the backbone, logged: with a checkpoint,
/// its width multiplier and input size replace the configured ones; with a
/// pretrained file or the venv's default, its architecture and file.
fn settle(cfg: &TrainConfig, info: &BackboneInfo, pre: &Preprocess) -> Settled {
    if cfg
        .weights
        .as_deref()
        .is_some_and(grasp_model::backbone::is_checkpoint)
    {
        tracing::info!(
            "{}: width multiplier {}, input {} px",
            info.describe(),
            info.width_mult,
            pre.size
        );
        return Settled::Checkpoint {
            width_mult: info.width_mult,
            input_size: pre.size,
        };
    }
    let tuned = match cfg.mode {
        TrainMode::FineTuned => format!(", its last {} blocks fine-tuned", cfg.fine_tune.blocks),
        _ => String::new(),
    };
    tracing::info!("{}{tuned}, input {} px", info.describe(), pre.size);
    Settled::Pretrained {
        arch: info.arch,
        weights: info.weights_path.clone(),
    }
}

/// Style views restyle blocks the extractor runs: refused before anything
/// is cached, not at the first style view.
fn check_style_blocks(views: &ViewConfig, extractor: &dyn FeatureExtractor) -> Result<()> {
    if views.style > 0.0 {
        let channels = extractor.block_channels();
        for &block in &views.style_blocks {
            crate::data::style::restylable(block, &channels)?;
        }
    }
    Ok(())
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
