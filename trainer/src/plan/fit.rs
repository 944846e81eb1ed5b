//! How each seed trains: the network built, the batches, the optimizers,
//! the schedule, which epoch is kept and what its checkpoint records.

use crate::config::{Selection, TrainConfig};
use crate::data::augment::AugmentConfig;
use crate::error::Result;
use crate::optim::AdamConfig;
use grasp_model::checkpoint::TrainMode;
use grasp_model::heads::HeadKind;
use grasp_model::input::Crop;

/// The training section of a run, the same for every seed.
#[derive(Debug, Clone)]
pub struct FitPlan {
    pub net: NetPlan,
    /// Units per batch on synthetic and on real data
    /// ([`TrainConfig::batch_size_for`]).
    pub batch: (usize, usize),
    pub max_epochs: usize,
    pub optimizer: AdamConfig,
    pub schedule: Schedule,
    pub select: Selection,
    pub balance_classes: bool,
    /// Fine-tuned mode's blocks (unused without them).
    pub tuning: Tuning,
    pub record: CheckpointRecord,
}

/// The network a seed builds.
#[derive(Debug, Clone)]
pub struct NetPlan {
    pub head: HeadKind,
    pub lstm_hidden: usize,
    /// The trace head's time constant.
    pub trace_s: Option<f64>,
    /// From scratch: the MobileNetV2's width multiplier.
    pub width_mult: f64,
    pub augment: AugmentConfig,
    pub tbptt: usize,
    pub start_crop: f64,
}

/// The plateau schedule and the early stop.
#[derive(Debug, Clone, Copy)]
pub struct Schedule {
    pub plateau_patience: usize,
    pub plateau_factor: f64,
    pub early_stop_patience: usize,
}

/// The tuned blocks' optimizer (the head's settings with their own rate
/// and decay) and the linear probe's epochs before them.
#[derive(Debug, Clone, Copy)]
pub struct Tuning {
    pub optimizer: AdamConfig,
    pub probe_epochs: usize,
}

/// What every checkpoint of the run records besides its weights.
#[derive(Debug, Clone)]
pub struct CheckpointRecord {
    pub mode: TrainMode,
    pub crop: Crop,
    pub denoise: bool,
    /// The config as run.
    pub train_config: serde_json::Value,
}

impl FitPlan {
    /// The training section of `cfg` (validated; for a run, as resolved).
    pub fn of(cfg: &TrainConfig) -> Result<FitPlan> {
        Ok(FitPlan {
            net: NetPlan {
                head: cfg.head,
                lstm_hidden: cfg.lstm_hidden,
                trace_s: (cfg.head == HeadKind::Trace).then_some(cfg.trace_s),
                width_mult: cfg.width_mult,
                augment: cfg.augment.clone(),
                tbptt: cfg.tbptt,
                start_crop: cfg.lstm_start_crop,
            },
            batch: (cfg.batch_size_for(false), cfg.batch_size_for(true)),
            max_epochs: cfg.max_epochs,
            optimizer: cfg.optimizer,
            schedule: Schedule {
                plateau_patience: cfg.plateau_patience,
                plateau_factor: cfg.plateau_factor,
                early_stop_patience: cfg.early_stop_patience,
            },
            select: cfg.select,
            balance_classes: cfg.balance_classes,
            tuning: Tuning {
                optimizer: AdamConfig {
                    lr: cfg.fine_tune.lr,
                    weight_decay: cfg.fine_tune.weight_decay,
                    ..cfg.optimizer
                },
                probe_epochs: cfg.fine_tune.probe_epochs,
            },
            record: CheckpointRecord {
                mode: cfg.mode,
                crop: cfg.reader.crop,
                denoise: cfg.reader.denoise,
                train_config: serde_json::to_value(cfg)?,
            },
        })
    }

    /// Units per batch (never 0).
    pub fn batch_size(&self, real_data: bool) -> usize {
        match real_data {
            true => self.batch.1,
            false => self.batch.0,
        }
        .max(1)
    }
}
