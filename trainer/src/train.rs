//! The paper's training protocol (Sec. III): cross-entropy, Adam (lr 5e-4,
//! coupled L2 5e-4), learning rate x0.1 after `plateau_patience` epochs
//! without validation improvement, early stop after `early_stop_patience`,
//! per-epoch random downsampling of every class to the smallest, the best
//! checkpoint by validation loss.
//!
//! Two modes share the loop: frozen-pretrained (the paper's; heads on cached
//! features) and from-scratch (the whole MobileNetV2, with augmentation).

use crate::config::TrainConfig;
use crate::data::split::{self, Split};
use crate::data::{self, BadData, Dataset};
use crate::features::{FeatureCache, SequenceFeatures};
use crate::optim::Adam;
use anyhow::{Context, Result};
use candle_core::{DType, Device, Tensor, D};
use candle_nn::{VarBuilder, VarMap};
use grasp_model::backbone::{Architecture, Backbone, BackboneInfo, Preprocess, BACKBONE_ID};
use grasp_model::checkpoint::{self, CheckpointMeta, TrainMode};
use grasp_model::heads::{Head, HeadConfig, HeadKind};
use grasp_model::model::gather::gather_rows;
use grasp_schema::taxonomy::Class;
use image::RgbImage;
use rand::seq::SliceRandom;
use rand::Rng;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The three splits of a run.
#[derive(Debug, Clone, Default)]
pub struct Splits {
    pub train: Dataset,
    pub val: Dataset,
    pub test: Dataset,
    pub split: Split,
}

/// Reads the data and splits it: separate validation/test roots when given,
/// otherwise a stratified split of the training root.
pub fn load_splits(cfg: &TrainConfig, bad: &BadData) -> Result<Splits> {
    let read = |root: &Path| -> Result<Dataset> {
        let d = data::read_dataset(root, &cfg.reader, bad)?;
        if d.sequences.is_empty() {
            anyhow::bail!("no sequences found under {}", root.display());
        }
        Ok(d)
    };
    let all = read(&cfg.data)?;
    let (train, val, test) = match (&cfg.val_data, &cfg.test_data) {
        (Some(v), t) => {
            let test = t.as_deref().map(read).transpose()?.unwrap_or_default();
            (all, read(v)?, test)
        }
        (None, t) => {
            let mut sc = cfg.split.clone();
            let test = match t {
                Some(t) => {
                    sc.test_fraction = 0.0;
                    Some(read(t)?)
                }
                None => None,
            };
            let s = split::stratified_split(&all, &sc);
            let test = test.unwrap_or_else(|| split::select(&all, &s.test));
            (
                split::select(&all, &s.train),
                split::select(&all, &s.val),
                test,
            )
        }
    };
    let train = match cfg.sequences_per_pair {
        Some(n) => {
            let capped = split::cap_per_pair(&train, n, cfg.split.seed);
            tracing::info!(
                "at most {n} training sequence(s) per object-part pair: {} of {} kept",
                capped.sequences.len(),
                train.sequences.len()
            );
            capped
        }
        None => train,
    };
    if val.sequences.is_empty() {
        anyhow::bail!(
            "the validation split is empty: add sequences, raise split.val_fraction or pass --val-data"
        );
    }
    let ids = |d: &Dataset| d.sequences.iter().map(|s| s.id.clone()).collect();
    let split = Split {
        train: ids(&train),
        val: ids(&val),
        test: ids(&test),
    };
    Ok(Splits {
        train,
        val,
        test,
        split,
    })
}

/// One epoch's numbers, written to `history.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpochStats {
    pub epoch: usize,
    pub lr: f64,
    pub train_loss: f64,
    pub train_accuracy: f64,
    pub train_frames: usize,
    pub val_loss: f64,
    pub val_accuracy: f64,
    pub seconds: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TrainOutcome {
    pub checkpoint: PathBuf,
    pub best_epoch: usize,
    pub best_val_loss: f64,
    pub stopped_early: bool,
    pub history: Vec<EpochStats>,
}

/// Where a split's frame features come from.
pub enum FrameSource {
    /// Frozen mode: cached features, one row per valid frame.
    Cached(Tensor),
    /// From scratch: decoded frames, run through the trained backbone.
    Images(Vec<RgbImage>),
}

/// A split's valid frames, indexed by row.
pub struct SplitFrames {
    pub labels: Vec<u32>,
    /// Rows of each sequence, in frame order.
    pub seq_rows: Vec<Vec<usize>>,
    pub seq_class: Vec<u32>,
    pub seq_ids: Vec<String>,
    pub source: FrameSource,
}

impl SplitFrames {
    pub fn from_features(data: &Dataset, feats: &[SequenceFeatures], dev: &Device) -> Result<Self> {
        let table = crate::features::FrameTable::build(data, feats);
        let x = Tensor::from_vec(table.x, (table.labels.len(), table.dim.max(1)), dev)?;
        Ok(Self::index(
            data,
            |si, fi| feats[si].valid[fi],
            FrameSource::Cached(x),
        ))
    }

    /// Decodes every frame of `data` at `size` (unreadable ones per policy).
    pub fn from_images(data: &Dataset, size: u32, bad: &BadData) -> Result<Self> {
        let bar = crate::progress::bar(data.sequences.len() as u64, "frames");
        let mut images = Vec::new();
        let mut valid = Vec::new();
        for seq in &data.sequences {
            let mut v = Vec::with_capacity(seq.frames.len());
            for f in &seq.frames {
                let img = data::images::load_frame_cropped(f, seq.center_crop, bad)?;
                v.push(img.is_some());
                images.extend(img.map(|i| data::augment::resize(&i, size)));
            }
            valid.push(v);
            bar.inc(1);
        }
        bar.finish_and_clear();
        Ok(Self::index(
            data,
            |si, fi| valid[si][fi],
            FrameSource::Images(images),
        ))
    }

    fn index(data: &Dataset, valid: impl Fn(usize, usize) -> bool, source: FrameSource) -> Self {
        let mut s = SplitFrames {
            labels: Vec::new(),
            seq_rows: Vec::new(),
            seq_class: Vec::new(),
            seq_ids: Vec::new(),
            source,
        };
        for (si, seq) in data.sequences.iter().enumerate() {
            let mut rows = Vec::new();
            for (fi, label) in seq.labels.iter().enumerate() {
                if valid(si, fi) {
                    rows.push(s.labels.len());
                    s.labels.push(label.index() as u32);
                }
            }
            s.seq_rows.push(rows);
            s.seq_class.push(seq.grasp_class().index() as u32);
            s.seq_ids.push(seq.id.clone());
        }
        s
    }

    pub fn frames(&self) -> usize {
        self.labels.len()
    }
}

/// The trainable network: a head, plus the backbone in from-scratch mode.
pub struct Net {
    pub head: Head,
    pub head_vars: VarMap,
    /// From-scratch backbone and its variables.
    pub backbone: Option<(Backbone, VarMap)>,
    pub augment: crate::data::augment::AugmentConfig,
    pub tbptt: usize,
}

impl Net {
    fn trainable(&self) -> Vec<candle_core::Var> {
        let mut v = crate::init::trainable_vars(&self.head_vars);
        if let Some((_, vm)) = &self.backbone {
            v.extend(crate::init::trainable_vars(vm));
        }
        v
    }

    /// Features `(rows, D)` of `rows` of `frames` (`None`: a zero padding
    /// row, for sequence batches).
    fn features(
        &self,
        frames: &SplitFrames,
        rows: &[Option<usize>],
        train: bool,
        rng: &mut impl Rng,
    ) -> Result<Tensor> {
        match (&frames.source, &self.backbone) {
            (FrameSource::Cached(x), _) => Ok(gather_rows(x, rows)?),
            (FrameSource::Images(images), Some((bb, _))) => {
                let size = bb.preprocess.size;
                let present: Vec<usize> = rows.iter().flatten().copied().collect();
                let batch: Vec<RgbImage> = present
                    .iter()
                    .map(|r| {
                        if train {
                            data::augment::augment(&images[*r], size, &self.augment, rng)
                        } else {
                            data::augment::resize(&images[*r], size)
                        }
                    })
                    .collect();
                let x = bb.input(&batch)?;
                let f = bb.net.features(&x, train)?;
                if present.len() == rows.len() {
                    return Ok(f);
                }
                // Padding rows: a zero row appended after the features.
                let zero = Tensor::zeros((1, f.dim(1)?), f.dtype(), f.device())?;
                let with_zero = Tensor::cat(&[&f, &zero], 0)?;
                let mut next = 0u32;
                let index: Vec<u32> = rows
                    .iter()
                    .map(|r| match r {
                        Some(_) => {
                            next += 1;
                            next - 1
                        }
                        None => present.len() as u32,
                    })
                    .collect();
                let index = Tensor::from_vec(index, rows.len(), f.device())?;
                Ok(with_zero.index_select(&index, 0)?)
            }
            (FrameSource::Images(_), None) => {
                anyhow::bail!("image frames need a trainable backbone")
            }
        }
    }

    /// Logits and targets (and a padding mask for sequences) of one batch of
    /// units: rows for the FC head, sequences for the LSTM head.
    fn forward(
        &self,
        frames: &SplitFrames,
        units: &[usize],
        train: bool,
        rng: &mut impl Rng,
    ) -> Result<Batch> {
        let dev = Device::Cpu;
        match self.head.cfg.kind {
            HeadKind::Fc => {
                let rows: Vec<Option<usize>> = units.iter().map(|r| Some(*r)).collect();
                let x = self.features(frames, &rows, train, rng)?;
                let targets: Vec<u32> = units.iter().map(|r| frames.labels[*r]).collect();
                Ok(Batch {
                    logits: self.head.forward_frames(&x)?,
                    features: x,
                    targets: Tensor::from_vec(targets, units.len(), &dev)?,
                    mask: None,
                })
            }
            HeadKind::Lstm => self.forward_sequences(frames, units, train, rng),
        }
    }

    /// A batch of sequences padded at the end to the longest, `(B, T, D)`.
    fn forward_sequences(
        &self,
        frames: &SplitFrames,
        seqs: &[usize],
        train: bool,
        rng: &mut impl Rng,
    ) -> Result<Batch> {
        let dev = Device::Cpu;
        let t_max = seqs
            .iter()
            .map(|s| frames.seq_rows[*s].len())
            .max()
            .unwrap_or(0);
        let (mut rows, mut targets, mut mask) = (Vec::new(), Vec::new(), Vec::new());
        for s in seqs {
            let r = &frames.seq_rows[*s];
            let pad = t_max - r.len();
            rows.extend(r.iter().map(|row| Some(*row)));
            rows.extend(std::iter::repeat_n(None, pad));
            targets.extend(r.iter().map(|row| frames.labels[*row]));
            targets.extend(std::iter::repeat_n(0, pad));
            mask.extend(std::iter::repeat_n(1f32, r.len()));
            mask.extend(std::iter::repeat_n(0f32, pad));
        }
        let x = self.features(frames, &rows, train, rng)?;
        let xs = x.reshape((seqs.len(), t_max, x.dim(1)?))?;
        let logits = self.lstm_logits(&xs, train)?;
        let n = seqs.len() * t_max;
        Ok(Batch {
            logits: logits.reshape((n, ()))?,
            features: x,
            targets: Tensor::from_vec(targets, n, &dev)?,
            mask: Some(Tensor::from_vec(mask, n, &dev)?),
        })
    }

    /// LSTM logits `(B, T, C)`; in training with `tbptt > 0` the sequence is
    /// run in chunks whose state is detached, so gradients flow back at most
    /// `tbptt` steps.
    fn lstm_logits(&self, xs: &Tensor, train: bool) -> Result<Tensor> {
        let (b, t, _) = xs.dims3()?;
        let k = self.tbptt;
        if !train || k == 0 || t <= k {
            return Ok(self.head.forward_sequences(xs)?);
        }
        let mut state = self.head.zero_state(b, xs)?.context("LSTM state")?;
        let mut outs = Vec::new();
        for start in (0..t).step_by(k) {
            let len = k.min(t - start);
            let (l, s) = self
                .head
                .forward_chunk(&xs.narrow(1, start, len)?, &state)?;
            outs.push(l);
            state = s.detach();
        }
        Ok(Tensor::cat(&outs, 1)?)
    }

    /// Tensors of the checkpoint: `head.*`, plus `backbone.*` from scratch.
    pub fn tensors(&self) -> Vec<(String, Tensor)> {
        let mut out = Vec::new();
        let mut add = |prefix: &str, vm: &VarMap| {
            let data = vm.data().lock().expect("varmap");
            for (name, var) in data.iter() {
                out.push((format!("{prefix}.{name}"), var.as_tensor().detach()));
            }
        };
        add("head", &self.head_vars);
        if let Some((_, vm)) = &self.backbone {
            add("backbone", vm);
        }
        out.sort_by(|a, b| a.0.cmp(&b.0));
        out
    }
}

struct Batch {
    logits: Tensor,
    features: Tensor,
    targets: Tensor,
    mask: Option<Tensor>,
}

impl Batch {
    fn loss(&self) -> Result<Tensor> {
        Ok(match &self.mask {
            None => crate::loss::cross_entropy(&self.logits, &self.targets)?,
            Some(m) => crate::loss::masked_cross_entropy(&self.logits, &self.targets, m)?,
        })
    }

    /// (correct, counted) frames.
    fn correct(&self) -> Result<(usize, usize)> {
        let pred: Vec<u32> = self.logits.argmax(D::Minus1)?.to_vec1()?;
        let tgt: Vec<u32> = self.targets.to_vec1()?;
        let mask: Vec<f32> = match &self.mask {
            Some(m) => m.to_vec1()?,
            None => vec![1.0; tgt.len()],
        };
        let mut c = (0, 0);
        for ((p, t), m) in pred.iter().zip(&tgt).zip(&mask) {
            if *m > 0.0 {
                c.1 += 1;
                c.0 += usize::from(p == t);
            }
        }
        Ok(c)
    }

    fn frames(&self) -> Result<usize> {
        Ok(match &self.mask {
            Some(m) => m.sum_all()?.to_scalar::<f32>()? as usize,
            None => self.targets.dim(0)?,
        })
    }
}

/// The units of one epoch: every class randomly downsampled to the size of
/// the smallest present class (frames by label for FC, sequences by
/// pre-shape for LSTM), then shuffled.
pub fn epoch_units(classes: &[u32], balance: bool, rng: &mut impl Rng) -> Vec<usize> {
    let mut by_class: Vec<Vec<usize>> = vec![Vec::new(); Class::COUNT];
    for (i, c) in classes.iter().enumerate() {
        by_class[*c as usize].push(i);
    }
    let mut units = Vec::new();
    if balance {
        let min = by_class
            .iter()
            .map(Vec::len)
            .filter(|n| *n > 0)
            .min()
            .unwrap_or(0);
        for mut members in by_class {
            members.shuffle(rng);
            units.extend(members.into_iter().take(min));
        }
    } else {
        units.extend(0..classes.len());
    }
    units.shuffle(rng);
    units
}

/// PyTorch's ReduceLROnPlateau (mode min, relative threshold 1e-4) plus
/// early stopping on the same improvement test.
#[derive(Debug, Clone)]
pub struct Plateau {
    pub best: f64,
    bad_epochs: usize,
    since_best: usize,
    patience: usize,
    factor: f64,
    stop_after: usize,
}

/// What the scheduler decided after an epoch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlateauStep {
    pub improved: bool,
    pub new_lr: Option<f64>,
    pub stop: bool,
}

impl Plateau {
    pub fn new(patience: usize, factor: f64, stop_after: usize) -> Self {
        Plateau {
            best: f64::INFINITY,
            bad_epochs: 0,
            since_best: 0,
            patience,
            factor,
            stop_after,
        }
    }

    pub fn step(&mut self, val_loss: f64, lr: f64) -> PlateauStep {
        let improved = val_loss < self.best * (1.0 - 1e-4) || self.best.is_infinite();
        let mut new_lr = None;
        if improved {
            self.best = val_loss;
            self.bad_epochs = 0;
            self.since_best = 0;
        } else {
            self.bad_epochs += 1;
            self.since_best += 1;
            if self.bad_epochs > self.patience {
                new_lr = Some(lr * self.factor);
                self.bad_epochs = 0;
            }
        }
        PlateauStep {
            improved,
            new_lr,
            stop: self.since_best >= self.stop_after,
        }
    }
}

/// Everything a run needs besides its seed.
pub struct Prepared {
    pub train: SplitFrames,
    pub val: SplitFrames,
    pub real_data: bool,
    /// Frozen mode: the pretrained backbone's description.
    pub backbone: Option<BackboneInfo>,
    pub feature_dim: usize,
    /// The input preprocessing the checkpoints record.
    pub preprocess: Preprocess,
}

/// The frozen backbone of `cfg`: a checkpoint named by `cfg.weights`, whose
/// backbone and preprocessing are reused as they are; a pretrained weights
/// file named by `cfg.weights`, its architecture detected from its tensor
/// names; or, without `cfg.weights`, the venv's ImageNet file of
/// `cfg.backbone` (EfficientNet-Lite0 by default). Pretrained files get
/// their architecture's preprocessing at `cfg.input_size`.
pub fn frozen_backbone(cfg: &TrainConfig) -> Result<(BackboneInfo, Preprocess)> {
    let Some(path) = cfg.weights.as_ref() else {
        let arch = cfg.backbone.unwrap_or(Architecture::EfficientNetLite0);
        let variant = arch
            .lite()
            .with_context(|| format!("a frozen {} needs --weights FILE", arch.name()))?;
        let path = grasp_model::backbone::venv_weights(variant)?;
        return Ok((
            BackboneInfo::pretrained(&path, arch, cfg.width_mult)?,
            arch.preprocess(cfg.input_size),
        ));
    };
    if grasp_model::backbone::is_checkpoint(path) {
        return BackboneInfo::from_checkpoint(path)
            .with_context(|| format!("cannot use checkpoint {} as a backbone", path.display()));
    }
    let arch = detect_architecture(path)?;
    if let Some(asked) = cfg.backbone.filter(|a| *a != arch) {
        anyhow::bail!(
            "--backbone {} does not match the weights file {}, which is {}",
            asked.name(),
            path.display(),
            arch.name()
        );
    }
    Ok((
        BackboneInfo::pretrained(path, arch, cfg.width_mult)?,
        arch.preprocess(cfg.input_size),
    ))
}

/// The architecture of a pretrained weights file, from its tensor names.
pub fn detect_architecture(path: &Path) -> Result<Architecture> {
    let vb = grasp_model::model::weights::var_builder(path, &Device::Cpu)?;
    Architecture::detect(&vb).with_context(|| {
        format!(
            "weights file {}: neither torchvision's MobileNetV2 (features.0.0.weight) nor \
             EfficientNet-Lite0/1/2 (_conv_stem.weight and the Lite blocks)",
            path.display()
        )
    })
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
    match cfg.mode {
        TrainMode::FrozenPretrained => {
            let (info, pre) = frozen_backbone(cfg)?;
            let bb = Backbone::load_pretrained(&info, pre, dev)?;
            let cache = FeatureCache::new(&cfg.cache_dir, cfg.feature_batch);
            let tf = cache.dataset(&bb, &splits.train, bad)?;
            let vf = cache.dataset(&bb, &splits.val, bad)?;
            Ok(Prepared {
                train: SplitFrames::from_features(&splits.train, &tf, dev)?,
                val: SplitFrames::from_features(&splits.val, &vf, dev)?,
                real_data,
                feature_dim: grasp_model::extractor::FeatureExtractor::feature_dim(&bb),
                preprocess: bb.preprocess,
                backbone: Some(bb.info),
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
                backbone: None,
                feature_dim: 0,
                preprocess: Preprocess::imagenet(cfg.input_size),
            })
        }
    }
}

fn build_net(
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
            };
            let vm = VarMap::new();
            let vb = VarBuilder::from_varmap(&vm, DType::F32, dev);
            let bb = Backbone::from_vb(info.clone(), prep.preprocess.clone(), vb, dev)?;
            crate::init::reinit_backbone(&vm, seed)?;
            let dim = grasp_model::extractor::FeatureExtractor::feature_dim(&bb);
            (Some((bb, vm)), info, dim)
        }
    };
    let head_cfg = HeadConfig {
        kind: cfg.head,
        feature_dim,
        classes: Class::COUNT,
        lstm_hidden: cfg.lstm_hidden,
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
            augment: cfg.augment.clone(),
            tbptt: cfg.tbptt,
        },
        info,
    ))
}

/// Trains one model with `seed` into `out` (checkpoint, history).
pub fn train(cfg: &TrainConfig, prep: &Prepared, seed: u64, out: &Path) -> Result<TrainOutcome> {
    let dev = Device::Cpu;
    let (net, backbone_info) = build_net(cfg, prep, seed, &dev)?;
    let mut opt = Adam::new(net.trainable(), cfg.optimizer)?;
    let batch = cfg.batch_size_for(prep.real_data).max(1);
    let mut plateau = Plateau::new(
        cfg.plateau_patience,
        cfg.plateau_factor,
        cfg.early_stop_patience,
    );
    let mut history = Vec::new();
    let mut outcome = TrainOutcome {
        checkpoint: out.to_path_buf(),
        best_epoch: 0,
        best_val_loss: f64::INFINITY,
        stopped_early: false,
        history: Vec::new(),
    };
    let unit_classes: Vec<u32> = match cfg.head {
        HeadKind::Fc => prep.train.labels.clone(),
        HeadKind::Lstm => prep.train.seq_class.clone(),
    };
    for epoch in 1..=cfg.max_epochs {
        let start = Instant::now();
        let mut rng = crate::rng::stream(seed, &format!("epoch/{epoch}"));
        let units = epoch_units(&unit_classes, cfg.balance_classes, &mut rng);
        let (train_loss, train_acc, frames) =
            train_epoch(&net, &prep.train, &units, batch, &mut opt, &mut rng, epoch)?;
        let (val_loss, val_acc) = evaluate_split(&net, &prep.val, batch)?;
        if !val_loss.is_finite() {
            anyhow::bail!("non-finite validation loss ({val_loss}) after epoch {epoch}");
        }
        let lr = opt.learning_rate();
        history.push(EpochStats {
            epoch,
            lr,
            train_loss,
            train_accuracy: train_acc,
            train_frames: frames,
            val_loss,
            val_accuracy: val_acc,
            seconds: start.elapsed().as_secs_f64(),
        });
        let decision = plateau.step(val_loss, lr);
        if decision.improved {
            outcome.best_epoch = epoch;
            outcome.best_val_loss = val_loss;
            let meta = CheckpointMeta {
                format_version: checkpoint::FORMAT_VERSION,
                classes: Class::ALL.to_vec(),
                mode: cfg.mode,
                head: net.head.cfg,
                preprocessing: prep.preprocess.clone(),
                backbone: backbone_info.clone(),
                seed,
                epoch,
                val_loss,
                val_accuracy: val_acc,
                train_sequences: Some(prep.train.seq_rows.len()),
                train_config: serde_json::to_value(cfg)?,
            };
            checkpoint::save(out, &meta, &net.tensors())?;
        }
        grasp_schema::atomic::write_atomic(
            &out.join("history.json"),
            serde_json::to_string_pretty(&history)?.as_bytes(),
        )?;
        tracing::info!(
            "epoch {epoch}: loss {train_loss:.4} acc {:.1}% | val loss {val_loss:.4} acc {:.1}% | lr {lr:.1e}{}",
            train_acc * 100.0,
            val_acc * 100.0,
            if decision.improved { " | saved" } else { "" }
        );
        if let Some(new_lr) = decision.new_lr {
            tracing::info!("validation loss plateaued: learning rate {lr:.1e} -> {new_lr:.1e}");
            opt.set_learning_rate(new_lr);
        }
        if decision.stop {
            tracing::info!(
                "early stop: no validation improvement for {} epochs",
                cfg.early_stop_patience
            );
            outcome.stopped_early = true;
            break;
        }
    }
    outcome.history = history;
    Ok(outcome)
}

fn train_epoch(
    net: &Net,
    frames: &SplitFrames,
    units: &[usize],
    batch: usize,
    opt: &mut Adam,
    rng: &mut impl Rng,
    epoch: usize,
) -> Result<(f64, f64, usize)> {
    let bar = crate::progress::bar(
        units.len().div_ceil(batch) as u64,
        &format!("epoch {epoch}"),
    );
    let (mut loss_sum, mut correct, mut counted) = (0.0, 0usize, 0usize);
    for (bi, chunk) in units.chunks(batch).enumerate() {
        let b = net.forward(frames, chunk, true, rng)?;
        let name = || batch_name(frames, chunk, net.head.cfg.kind, epoch, bi);
        check_finite(&b.features, "feature", &name)?;
        let loss = b.loss()?;
        let v = loss.to_scalar::<f32>()?;
        if !v.is_finite() {
            anyhow::bail!("non-finite training loss ({v}) in {}", name());
        }
        opt.step(&loss.backward()?)?;
        let (c, n) = b.correct()?;
        let frames_in = b.frames()?;
        loss_sum += f64::from(v) * frames_in as f64;
        correct += c;
        counted += n;
        bar.set_message(format!(
            "loss {:.4} acc {:.1}% lr {:.1e}",
            loss_sum / counted.max(1) as f64,
            100.0 * correct as f64 / counted.max(1) as f64,
            opt.learning_rate()
        ));
        bar.inc(1);
    }
    bar.finish_and_clear();
    let n = counted.max(1) as f64;
    Ok((loss_sum / n, correct as f64 / n, counted))
}

fn batch_name(
    frames: &SplitFrames,
    chunk: &[usize],
    kind: HeadKind,
    epoch: usize,
    bi: usize,
) -> String {
    let first = chunk.first().map(|u| match kind {
        HeadKind::Lstm => frames.seq_ids[*u].clone(),
        HeadKind::Fc => {
            let seq = frames
                .seq_rows
                .iter()
                .position(|r| r.contains(u))
                .unwrap_or(0);
            frames.seq_ids.get(seq).cloned().unwrap_or_default()
        }
    });
    format!(
        "epoch {epoch}, batch {bi} ({} units, first from sequence {})",
        chunk.len(),
        first.unwrap_or_default()
    )
}

fn check_finite(t: &Tensor, what: &str, name: &dyn Fn() -> String) -> Result<()> {
    if let Some(bad) = grasp_model::model::first_non_finite(t)? {
        anyhow::bail!("non-finite {what} value ({bad}) in {}", name());
    }
    Ok(())
}

/// Mean per-frame loss and accuracy over a whole split (no downsampling).
pub fn evaluate_split(net: &Net, frames: &SplitFrames, batch: usize) -> Result<(f64, f64)> {
    let units: Vec<usize> = match net.head.cfg.kind {
        HeadKind::Fc => (0..frames.frames()).collect(),
        HeadKind::Lstm => (0..frames.seq_rows.len()).collect(),
    };
    let mut rng = crate::rng::stream(0, "eval");
    let (mut loss_sum, mut correct, mut counted) = (0.0, 0usize, 0usize);
    let batch = if net.backbone.is_some() {
        batch
    } else {
        batch.max(1024)
    };
    for chunk in units.chunks(batch) {
        let b = net.forward(frames, chunk, false, &mut rng)?;
        let n = b.frames()?;
        loss_sum += f64::from(b.loss()?.to_scalar::<f32>()?) * n as f64;
        let (c, k) = b.correct()?;
        correct += c;
        counted += k;
    }
    let n = counted.max(1) as f64;
    Ok((loss_sum / n, correct as f64 / n))
}
