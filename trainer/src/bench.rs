//! The heads' training-epoch benchmark on generated cached features (the
//! PyTorch peer is scripts/bench_torch_heads.py, same workload).

use crate::backbone::BackboneInfo;
use crate::checkpoint::TrainMode;
use crate::config::TrainConfig;
use crate::heads::HeadKind;
use crate::train::{FrameSource, Prepared, SplitFrames};
use anyhow::Result;
use candle_core::{Device, Tensor};
use rand::Rng;

/// The workload: `sequences` sequences of `frames` frames of `dim`-d
/// features (labels cycle through the five classes by sequence, last two
/// frames `no_grasp`).
pub struct Workload {
    pub head: HeadKind,
    pub sequences: usize,
    pub val_sequences: usize,
    pub frames: usize,
    pub dim: usize,
    pub batch: usize,
    pub epochs: usize,
}

fn split(sequences: usize, frames: usize, dim: usize, seed: u64) -> Result<SplitFrames> {
    let mut rng = crate::rng::stream(seed, "bench");
    let n = sequences * frames;
    let x: Vec<f32> = (0..n * dim).map(|_| rng.gen_range(0.0f32..1.0)).collect();
    let mut labels = Vec::with_capacity(n);
    let mut seq_rows = Vec::new();
    for s in 0..sequences {
        let class = (s % 4) as u32;
        seq_rows.push((s * frames..(s + 1) * frames).collect());
        labels.extend((0..frames).map(|f| if f + 2 >= frames { 4 } else { class }));
    }
    Ok(SplitFrames {
        labels,
        seq_rows,
        seq_class: (0..sequences).map(|s| (s % 4) as u32).collect(),
        seq_ids: (0..sequences).map(|s| format!("s{s}")).collect(),
        source: FrameSource::Cached(Tensor::from_vec(x, (n, dim), &Device::Cpu)?),
    })
}

/// Seconds of each epoch (training pass plus validation pass).
pub fn heads_epoch_seconds(w: &Workload) -> Result<Vec<f64>> {
    let prep = Prepared {
        train: split(w.sequences, w.frames, w.dim, 1)?,
        val: split(w.val_sequences, w.frames, w.dim, 2)?,
        real_data: false,
        backbone: Some(BackboneInfo::generated("bench")),
        feature_dim: w.dim,
        preprocess: crate::backbone::Preprocess::imagenet(224),
    };
    let dir = std::env::temp_dir().join(format!("grasp-bench-{}", std::process::id()));
    let cfg = TrainConfig {
        data: dir.clone(),
        mode: TrainMode::FrozenPretrained,
        head: w.head,
        batch_size: Some(w.batch),
        max_epochs: w.epochs,
        early_stop_patience: usize::MAX,
        // Every epoch as in training (downsampling on), but no checkpoint
        // writes after the first: compare the training work only.
        ..Default::default()
    };
    let out = crate::train::train(&cfg, &prep, 0, &dir)?;
    let _ = std::fs::remove_dir_all(&dir);
    Ok(out.history.iter().map(|e| e.seconds).collect())
}
