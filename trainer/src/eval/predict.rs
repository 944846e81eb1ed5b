//! Runs a classifier over a dataset's videos.

use super::VideoPrediction;
use crate::data::{BadData, Dataset};
use crate::error::EvalError;
use crate::features::FeatureCache;
use candle_core::Tensor;
use grasp_model::checkpoint::{Classifier, TrainMode};
use grasp_model::extractor::FeatureExtractor;

/// Per-frame probabilities of every video of `data`. Frozen-pretrained
/// checkpoints read features through `cache` (shared with training);
/// from-scratch ones run their own backbone. A sequence head reads each
/// video at the frame rate it was trained at (`HeadConfig::steps`), and
/// only the frames it read are scored.
pub fn predict_dataset(
    clf: &Classifier,
    data: &Dataset,
    cache: &FeatureCache,
    bad: &BadData,
) -> Result<Vec<VideoPrediction>, EvalError> {
    let multi = data.multi_grasp_objects();
    let bar = crate::progress::bar(data.sequences.len() as u64, "predict");
    let mut out = Vec::with_capacity(data.sequences.len());
    for seq in &data.sequences {
        let (rows, valid) = match clf.meta.mode {
            TrainMode::FrozenPretrained | TrainMode::FineTuned => {
                let (f, _) = cache.sequence(clf.backbone(), seq, bad)?;
                let n = f.valid_count();
                (
                    Tensor::from_vec(f.rows, (n, f.dim), &candle_core::Device::Cpu)?,
                    f.valid,
                )
            }
            TrainMode::FromScratch => extract(clf, seq, cache.batch, bad)?,
        };
        let keep = |i: &usize| valid[*i];
        let readable: Vec<usize> = (0..seq.frames.len()).filter(keep).collect();
        let times: Vec<f64> = readable.iter().map(|i| seq.time_s(*i)).collect();
        let steps = clf.meta.head.steps(&times);
        let (rows, idx) = if steps.len() == readable.len() {
            (rows, readable)
        } else {
            let at = Tensor::new(
                steps.iter().map(|s| *s as u32).collect::<Vec<_>>(),
                rows.device(),
            )?;
            let idx = steps.iter().map(|s| readable[*s]).collect();
            (rows.index_select(&at, 0)?, idx)
        };
        let probs = if idx.is_empty() {
            Vec::new()
        } else {
            let times: Vec<f64> = idx.iter().map(|i| seq.time_s(*i)).collect();
            clf.predict_video(&rows, &times)?
        };
        out.push(VideoPrediction {
            id: seq.id.clone(),
            object: seq.object.clone(),
            part: seq.part.clone(),
            preshape: seq.preshape,
            multi_grasp: multi.contains(&seq.object),
            labels: idx.iter().map(|i| seq.labels[*i]).collect(),
            times_s: idx.iter().map(|i| seq.time_s(*i)).collect(),
            probs,
        });
        bar.inc(1);
    }
    bar.finish();
    Ok(out)
}

fn extract(
    clf: &Classifier,
    seq: &crate::data::Sequence,
    batch: usize,
    bad: &BadData,
) -> Result<(Tensor, Vec<bool>), EvalError> {
    let mut parts = Vec::new();
    let mut valid = Vec::new();
    let indices: Vec<usize> = (0..seq.frames.len()).collect();
    for chunk in indices.chunks(batch.max(1)) {
        let mut images = Vec::new();
        for &i in chunk {
            let img = seq.load_frame(i, bad)?;
            valid.push(img.is_some());
            images.extend(img);
        }
        if !images.is_empty() {
            parts.push(clf.backbone().extract(&images)?);
        }
    }
    let dim = clf.backbone().feature_dim();
    let rows = if parts.is_empty() {
        Tensor::zeros((0, dim), candle_core::DType::F32, &candle_core::Device::Cpu)?
    } else {
        Tensor::cat(&parts, 0)?
    };
    Ok((rows, valid))
}
