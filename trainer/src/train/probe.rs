//! Linear probing before fine-tuning (LP-FT, Kumar et al., ICLR 2022): the
//! head first trains alone on the pretrained tuned blocks' output, so that
//! fine-tuning starts from a head that already reads the features instead of
//! sending a random head's gradients into the blocks.

use super::{
    epoch_units, evaluate_split, train_epoch, unit_classes, Epoch, FrameSource, Net, Optimizers,
    SplitFrames,
};
use crate::error::{Result, TrainError};
use crate::plan::FitPlan;
use candle_core::Tensor;

/// Trains `net`'s head for `fit.tuning.probe_epochs` epochs on the
/// features its (untrained) tail gives `train`'s rows; the tail is left as
/// it was. Without a tail or with 0 epochs it does nothing.
pub(super) fn probe_head(
    net: &mut Net,
    fit: &FitPlan,
    (train, val): (&SplitFrames, &SplitFrames),
    batch: usize,
    seed: u64,
) -> Result<()> {
    let epochs = fit.tuning.probe_epochs;
    if epochs == 0 {
        return Ok(());
    }
    let Some(tail) = net.tail.take() else {
        return Ok(());
    };
    // The head trains alone: without its tail the net is a frozen one on
    // the tail's features (the tail goes back whatever happens).
    let result = (|| {
        let train = tail_features(&tail, train)?;
        let val = tail_features(&tail, val)?;
        let mut opt = Optimizers::new(net, fit)?;
        for epoch in 1..=epochs {
            let mut rng = crate::rng::stream(seed, &format!("probe/{epoch}"));
            let classes = unit_classes(fit.net.head, &train);
            let units = epoch_units(classes, fit.balance_classes, &mut rng);
            train_epoch(
                net,
                &train,
                &units,
                batch,
                &mut opt,
                &mut rng,
                Epoch::Probe(epoch),
            )?;
        }
        // Validation only reports where the probe ended; nothing selects on it.
        let last = evaluate_split(net, &val, batch)?;
        tracing::info!(
            "linear probe, {epochs} epochs: val loss {:.4} acc {:.1}%",
            last.0,
            last.1 * 100.0
        );
        Ok(())
    })();
    net.tail = Some(tail);
    result
}

/// `frames` with the tail's output in place of its cached activations.
fn tail_features(tail: &super::tail::Tail, frames: &SplitFrames) -> Result<SplitFrames> {
    let FrameSource::Cached(x) = &frames.source else {
        let why = "fine-tuning needs cached block activations";
        return Err(TrainError::Inconsistent(why));
    };
    let n = x.dim(0)?;
    if n == 0 {
        let why = "a split without frames cannot be probed";
        return Err(TrainError::Inconsistent(why));
    }
    let mut parts = Vec::new();
    for start in (0..n).step_by(256) {
        parts.push(
            tail.forward(&x.narrow(0, start, 256.min(n - start))?)?
                .detach(),
        );
    }
    let features = Tensor::cat(&parts, 0)?;
    Ok(SplitFrames {
        labels: frames.labels.clone(),
        seq_rows: frames.seq_rows.clone(),
        seq_times: frames.seq_times.clone(),
        seq_class: frames.seq_class.clone(),
        seq_ids: frames.seq_ids.clone(),
        source: FrameSource::Cached(features),
    })
}
