//! The paper's training protocol (Sec. III): cross-entropy, Adam (lr 5e-4,
//! coupled L2 5e-4), learning rate x0.1 after `plateau_patience` epochs
//! without validation improvement, early stop after `early_stop_patience`,
//! per-epoch random downsampling of every class to the smallest, the best
//! checkpoint by validation loss (or another [`Selection`]).
//!
//! Three modes share the loop: frozen-pretrained (the paper's; heads on
//! cached features), from-scratch (the whole MobileNetV2, with
//! augmentation) and fine-tuned (EfficientNet-Lite's last blocks on cached
//! activations, after an optional linear probe of the head).
//!
//! One module per concept: [`splits`] (loading and splitting the data),
//! [`frames`] (the frame index), [`net`] (the network's forward pass and
//! loss), [`balance`] (class balancing), [`plateau`] (the learning-rate
//! schedule), [`prepare`] (the features of the run plan's backbone, or frames), [`damping`] (view
//! damping), [`tail`] (the tuned blocks), [`probe`] (the linear probe);
//! this file holds the loop.

mod balance;
mod damping;
mod frames;
mod net;
mod plateau;
mod prepare;
mod probe;
mod splits;
mod tail;

pub use balance::epoch_units;
pub use damping::ViewDamping;
pub use frames::{FrameSource, SplitFrames};
pub use net::Net;
pub use plateau::{Plateau, PlateauStep};
use prepare::build_net;
pub use prepare::{prepare, Prepared};
pub use splits::{load_splits, Splits};
pub use tail::{lite, BlockActivations, TailStart};

use crate::config::Selection;
use crate::error::{NonFinite, Result};
use crate::optim::Adam;
use crate::plan::FitPlan;
use candle_core::{Device, Tensor};
use grasp_model::checkpoint::{self, CheckpointMeta};
use grasp_model::heads::HeadKind;
use grasp_schema::taxonomy::Class;
use rand::Rng;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;
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
    /// The epoch the checkpoint holds (chosen by the config's `select`).
    pub best_epoch: usize,
    /// Its validation loss.
    pub best_val_loss: f64,
    pub stopped_early: bool,
    pub history: Vec<EpochStats>,
}

/// Trains one model with `seed` into `out` (checkpoint, history).
pub fn train(fit: &FitPlan, prep: &Prepared, seed: u64, out: &Path) -> Result<TrainOutcome> {
    let dev = Device::Cpu;
    let (mut net, backbone_info) = build_net(&fit.net, prep, seed, &dev)?;
    let batch = fit.batch_size(prep.real_data);
    probe::probe_head(&mut net, fit, (&prep.train, &prep.val), batch, seed)?;
    let mut opt = Optimizers::new(&net, fit)?;
    let s = fit.schedule;
    let mut plateau = Plateau::new(s.plateau_patience, s.plateau_factor, s.early_stop_patience);
    let mut history = Vec::new();
    let mut best_val_accuracy = f64::NEG_INFINITY;
    let mut outcome = TrainOutcome {
        checkpoint: out.to_path_buf(),
        best_epoch: 0,
        best_val_loss: f64::INFINITY,
        stopped_early: false,
        history: Vec::new(),
    };
    for epoch in 1..=fit.max_epochs {
        let start = Instant::now();
        let mut rng = crate::rng::stream(seed, &format!("epoch/{epoch}"));
        let units = epoch_units(
            unit_classes(fit.net.head, &prep.train),
            fit.balance_classes,
            &mut rng,
        );
        let (train_loss, train_acc, frames) = train_epoch(
            &net,
            &prep.train,
            &units,
            batch,
            &mut opt,
            &mut rng,
            Epoch::Main(epoch),
        )?;
        let (val_loss, val_acc) = evaluate_split(&net, &prep.val, batch)?;
        if !val_loss.is_finite() {
            let at = format!("after epoch {epoch}");
            return Err(non_finite("validation loss", val_loss, at));
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
        let keep = match fit.select {
            Selection::ValLoss => decision.improved,
            Selection::ValAccuracy => val_acc >= best_val_accuracy,
            Selection::Last => true,
        };
        best_val_accuracy = best_val_accuracy.max(val_acc);
        if keep {
            outcome.best_epoch = epoch;
            outcome.best_val_loss = val_loss;
            let meta = CheckpointMeta {
                format_version: checkpoint::FORMAT_VERSION,
                classes: Class::ALL.to_vec(),
                mode: fit.record.mode,
                head: net.head.cfg,
                input: grasp_model::input::InputSpec {
                    crop: fit.record.crop,
                    denoise: fit.record.denoise,
                    preprocess: prep.preprocess.clone(),
                },
                backbone: backbone_info.clone(),
                seed,
                epoch,
                val_loss,
                val_accuracy: val_acc,
                train_sequences: Some(prep.train_sequences),
                train_config: fit.record.train_config.clone(),
            };
            let tensors = match &prep.damping {
                Some(d) => d.fold(net.tensors(), net.feature_weight_name())?,
                None => net.tensors(),
            };
            checkpoint::save(out, &meta, &tensors)?;
        }
        grasp_support::atomic::write_atomic(
            &out.join("history.json"),
            serde_json::to_string_pretty(&history)?.as_bytes(),
        )?;
        tracing::info!(
            "epoch {epoch}: loss {train_loss:.4} acc {:.1}% | val loss {val_loss:.4} acc {:.1}% | lr {lr:.1e}{}",
            train_acc * 100.0,
            val_acc * 100.0,
            if keep { " | saved" } else { "" }
        );
        if let Some(new_lr) = decision.new_lr {
            tracing::info!("validation loss plateaued: learning rate {lr:.1e} -> {new_lr:.1e}");
            opt.set_learning_rate(new_lr);
        }
        if decision.stop {
            tracing::info!(
                "early stop: no validation improvement for {} epochs",
                s.early_stop_patience
            );
            outcome.stopped_early = true;
            break;
        }
    }
    outcome.history = history;
    Ok(outcome)
}

/// The class of each unit an epoch draws: frames for the FC and trace
/// heads, sequences for the LSTM head.
fn unit_classes(head: HeadKind, frames: &SplitFrames) -> &[u32] {
    match head {
        HeadKind::Fc | HeadKind::Trace => &frames.labels,
        HeadKind::Lstm => &frames.seq_class,
    }
}

/// The head's optimizer and, fine-tuned, the tuned blocks' (the head's
/// settings with their own rate and decay).
struct Optimizers {
    head: Adam,
    tail: Option<Adam>,
}

impl Optimizers {
    fn new(net: &Net, fit: &FitPlan) -> Result<Self> {
        Ok(Optimizers {
            head: Adam::new(net.trainable(), fit.optimizer)?,
            tail: net
                .tail_trainable()
                .map(|vars| Adam::new(vars, fit.tuning.optimizer))
                .transpose()?,
        })
    }

    fn learning_rate(&self) -> f64 {
        self.head.learning_rate()
    }

    /// Sets the head's rate (exactly, as before there were two) and scales
    /// the tuned blocks' by the same factor.
    fn set_learning_rate(&mut self, lr: f64) {
        let factor = lr / self.head.learning_rate();
        self.head.set_learning_rate(lr);
        if let Some(t) = &mut self.tail {
            t.set_learning_rate(t.learning_rate() * factor);
        }
    }

    fn step(&mut self, grads: &candle_core::backprop::GradStore) -> Result<()> {
        self.head.step(grads)?;
        if let Some(t) = &mut self.tail {
            t.step(grads)?;
        }
        Ok(())
    }
}

/// Which pass over the training frames a progress bar or an error names:
/// the main loop's, or the linear probe's before it.
#[derive(Clone, Copy, Debug)]
enum Epoch {
    Main(usize),
    Probe(usize),
}

impl std::fmt::Display for Epoch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Epoch::Main(n) => write!(f, "epoch {n}"),
            Epoch::Probe(n) => write!(f, "probe epoch {n}"),
        }
    }
}

fn train_epoch(
    net: &Net,
    frames: &SplitFrames,
    units: &[usize],
    batch: usize,
    opt: &mut Optimizers,
    rng: &mut impl Rng,
    epoch: Epoch,
) -> Result<(f64, f64, usize)> {
    let bar = crate::progress::bar(units.len().div_ceil(batch) as u64, &epoch.to_string());
    let (mut loss_sum, mut correct, mut counted) = (0.0, 0usize, 0usize);
    for (bi, chunk) in units.chunks(batch).enumerate() {
        let b = net.forward(frames, chunk, true, rng)?;
        let name = || batch_name(frames, chunk, net.head.cfg.kind, epoch, bi);
        check_finite(&b.features, "feature value", &name)?;
        let loss = b.loss()?;
        let v = loss.to_scalar::<f32>()?;
        if !v.is_finite() {
            let at = format!("in {}", name());
            return Err(non_finite("training loss", f64::from(v), at));
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
    bar.finish();
    let n = counted.max(1) as f64;
    Ok((loss_sum / n, correct as f64 / n, counted))
}

fn batch_name(
    frames: &SplitFrames,
    chunk: &[usize],
    kind: HeadKind,
    epoch: Epoch,
    bi: usize,
) -> String {
    let first = chunk.first().map(|u| match kind {
        HeadKind::Lstm => frames.seq_ids[*u].clone(),
        HeadKind::Fc | HeadKind::Trace => {
            let seq = frames
                .seq_rows
                .iter()
                .position(|r| r.contains(u))
                .unwrap_or(0);
            frames.seq_ids.get(seq).cloned().unwrap_or_default()
        }
    });
    format!(
        "{epoch}, batch {bi} ({} units, first from sequence {})",
        chunk.len(),
        first.unwrap_or_default()
    )
}

fn check_finite(t: &Tensor, what: &'static str, name: &dyn Fn() -> String) -> Result<()> {
    match grasp_model::ops::first_non_finite(t)? {
        Some(bad) => Err(non_finite(what, f64::from(bad), format!("in {}", name()))),
        None => Ok(()),
    }
}

fn non_finite(what: &'static str, value: f64, at: String) -> crate::error::TrainError {
    NonFinite { what, value, at }.into()
}

/// Mean per-frame loss and accuracy over a whole split (no downsampling).
pub fn evaluate_split(net: &Net, frames: &SplitFrames, batch: usize) -> Result<(f64, f64)> {
    let units: Vec<usize> = match net.head.cfg.kind {
        HeadKind::Fc | HeadKind::Trace => (0..frames.frames()).collect(),
        HeadKind::Lstm => (0..frames.seq_rows.len()).collect(),
    };
    let mut rng = crate::rng::stream(0, "eval");
    let (mut loss_sum, mut correct, mut counted) = (0.0, 0usize, 0usize);
    let batch = match (&net.backbone, &net.tail) {
        (Some(_), _) => batch,
        (None, Some(_)) => batch.max(256),
        (None, None) => batch.max(1024),
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

#[cfg(test)]
mod tests {
    use super::Epoch;

    #[test]
    fn an_epoch_names_the_pass_it_belongs_to() {
        assert_eq!(Epoch::Main(3).to_string(), "epoch 3");
        assert_eq!(Epoch::Probe(3).to_string(), "probe epoch 3");
    }
}
