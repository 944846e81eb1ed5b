//! A training run's config resolved once, before any data is read, into
//! the part each step of [`crate::experiment::run`] needs: the data and its
//! split ([`DataPlan`]), how frames become the head's input
//! ([`FeaturePlan`]: the backbone settled, loaded and checked), the feature
//! cache ([`CachePlan`]) and how each seed trains ([`FitPlan`]). No step
//! reads the whole [`TrainConfig`]; only [`RunPlan::recorded`], what was
//! run, is written whole (`config.toml`, each checkpoint's `train_config`).

mod features;
mod fit;

pub use features::{detect_architecture, frozen_backbone, Extraction, FeaturePlan, Settled, Views};
pub use fit::{CheckpointRecord, FitPlan, NetPlan, Schedule, Tuning};

use crate::config::TrainConfig;
use crate::data::split::SplitConfig;
use crate::data::{OnBadData, ReaderOptions};
use crate::error::Result;
use std::path::{Path, PathBuf};

/// Everything a run does, section by section.
pub struct RunPlan {
    /// The config as run: dataset paths absolute, the backbone settled.
    pub recorded: TrainConfig,
    /// The run's folder; seed `k` trains into `out/seed-(first_seed + k)`.
    pub out: PathBuf,
    pub first_seed: u64,
    pub on_bad_data: OnBadData,
    pub data: DataPlan,
    pub cache: CachePlan,
    pub features: FeaturePlan,
    pub fit: FitPlan,
}

impl RunPlan {
    /// Validates `cfg`, then settles and loads the backbone and checks what
    /// only it can tell (a block count, a style block), all before any
    /// dataset is read or any file written.
    pub fn resolve(cfg: &TrainConfig) -> Result<RunPlan> {
        cfg.validate()?;
        let mut recorded = absolute_data_paths(cfg);
        let features = FeaturePlan::resolve(&recorded)?;
        if let Some(settled) = &features.settled {
            settled.record(&mut recorded);
        }
        Ok(RunPlan {
            out: recorded.out.clone(),
            first_seed: recorded.seed,
            on_bad_data: recorded.on_bad_data,
            data: DataPlan::of(&recorded),
            cache: CachePlan::of(&recorded),
            fit: FitPlan::of(&recorded)?,
            features,
            recorded,
        })
    }
}

/// Where the run's sequences come from and how they are split.
#[derive(Debug, Clone)]
pub struct DataPlan {
    pub train: PathBuf,
    pub val: Option<PathBuf>,
    pub test: Option<PathBuf>,
    pub reader: ReaderOptions,
    pub split: SplitConfig,
    pub sequences_per_pair: Option<usize>,
    pub allow_missing_classes: bool,
}

impl DataPlan {
    pub fn of(cfg: &TrainConfig) -> DataPlan {
        DataPlan {
            train: cfg.data.clone(),
            val: cfg.val_data.clone(),
            test: cfg.test_data.clone(),
            reader: cfg.reader.clone(),
            split: cfg.split.clone(),
            sequences_per_pair: cfg.sequences_per_pair,
            allow_missing_classes: cfg.allow_missing_classes,
        }
    }
}

/// The feature cache training fills and the run's evaluation reads.
#[derive(Debug, Clone)]
pub struct CachePlan {
    pub dir: PathBuf,
    /// Frames per backbone forward pass.
    pub batch: usize,
}

impl CachePlan {
    pub fn of(cfg: &TrainConfig) -> CachePlan {
        CachePlan {
            dir: cfg.cache_dir.clone(),
            batch: cfg.feature_batch,
        }
    }

    pub fn open(&self) -> crate::features::FeatureCache {
        crate::features::FeatureCache::new(&self.dir, self.batch)
    }
}

/// The dataset paths made absolute, so that the run's `config.toml` and its
/// checkpoints name the data that was used whatever the directory `eval` is
/// later run from.
fn absolute_data_paths(cfg: &TrainConfig) -> TrainConfig {
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let mut cfg = cfg.clone();
    cfg.data = abs(&cfg.data);
    cfg.val_data = cfg.val_data.as_deref().map(abs);
    cfg.test_data = cfg.test_data.as_deref().map(abs);
    cfg
}
