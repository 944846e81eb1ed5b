//! Lab tool (issue 41): test-time feature alignment. Every frame's class
//! probabilities of each test set, as `dump_predictions` writes them, but
//! with the frozen features moved to training's statistics first: each
//! feature standardised by the test set's own per-dimension mean and
//! deviation, then given the training set's (a calibration on the
//! camera's footage, not on its labels).
//!
//!   cargo run --release -p trainer --example aligned_predictions -- \
//!       CHECKPOINT TRAIN_DATA CACHE_DIR OUT_DIR TEST_DATA...
//!
//! Writes OUT_DIR/aligned-SET.jsonl and OUT_DIR/plain-SET.jsonl.
use anyhow::{Context, Result};
use candle_core::{Device, Tensor};
use grasp_model::checkpoint::{CheckpointMeta, Classifier};
use std::io::Write;
use std::path::{Path, PathBuf};
use trainer::data::{BadData, Dataset, OnBadData, ReaderOptions};
use trainer::eval::VideoPrediction;
use trainer::features::FeatureCache;

/// Per-dimension mean and standard deviation of a set's frames.
struct Stats {
    mean: Vec<f64>,
    std: Vec<f64>,
}

/// A sequence's readable frames' features (rows of `dim`), which frames
/// are readable, and `dim`.
type Rows = (Vec<f32>, Vec<bool>, usize);

/// Each sequence's [`Rows`].
fn features(
    clf: &Classifier,
    data: &Dataset,
    cache: &FeatureCache,
    bad: &BadData,
) -> Result<Vec<Rows>> {
    let mut out = Vec::new();
    for seq in &data.sequences {
        let (f, _) = cache.sequence(clf.backbone(), seq, bad)?;
        out.push((f.rows, f.valid, f.dim));
    }
    Ok(out)
}

fn stats(all: &[Rows]) -> Stats {
    let dim = all.iter().map(|s| s.2).next().unwrap_or(0);
    let (mut sum, mut sq, mut n) = (vec![0f64; dim], vec![0f64; dim], 0f64);
    for (rows, _, _) in all {
        for row in rows.chunks_exact(dim) {
            for (k, &v) in row.iter().enumerate() {
                sum[k] += f64::from(v);
                sq[k] += f64::from(v) * f64::from(v);
            }
            n += 1.0;
        }
    }
    let mean: Vec<f64> = sum.iter().map(|s| s / n).collect();
    let std = sq
        .iter()
        .zip(&mean)
        .map(|(q, m)| (q / n - m * m).max(0.0).sqrt())
        .collect();
    Stats { mean, std }
}

fn read(data: &Path, meta: &CheckpointMeta, bad: &BadData) -> Result<Dataset> {
    let opts = ReaderOptions {
        crop: meta.input.crop,
        denoise: meta.input.denoise,
        camera: trainer::config::trained_camera_folder(meta),
        ..Default::default()
    };
    let mut dataset = trainer::data::read_dataset(data, &opts, bad)?;
    dataset.trim_lead_ins();
    Ok(dataset)
}

fn main() -> Result<()> {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let [checkpoint, train, cache, out, tests @ ..] = args.as_slice() else {
        anyhow::bail!(
            "usage: aligned_predictions CHECKPOINT TRAIN_DATA CACHE_DIR OUT_DIR TEST_DATA..."
        );
    };
    let bad = BadData::new(OnBadData::Skip);
    let (meta, _) = CheckpointMeta::load(checkpoint)?;
    let clf = Classifier::load(checkpoint, &Device::Cpu)?;
    let cache = FeatureCache::new(cache, 32);
    let source = stats(&features(&clf, &read(train, &meta, &bad)?, &cache, &bad)?);
    std::fs::create_dir_all(out)?;
    for test in tests {
        let data = read(test, &meta, &bad)?;
        let feats = features(&clf, &data, &cache, &bad)?;
        let target = stats(&feats);
        let multi = data.multi_grasp_objects();
        let set = test
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or("set")
            .trim_start_matches("test-");
        for aligned in [false, true] {
            let name = if aligned { "aligned" } else { "plain" };
            let path = out.join(format!("{name}-{set}.jsonl"));
            let mut w = std::io::BufWriter::new(std::fs::File::create(&path)?);
            for (seq, (rows, valid, dim)) in data.sequences.iter().zip(&feats) {
                let mut rows = rows.clone();
                if aligned {
                    for row in rows.chunks_exact_mut(*dim) {
                        for (k, v) in row.iter_mut().enumerate() {
                            let z = (f64::from(*v) - target.mean[k]) / target.std[k].max(1e-6);
                            *v = (z * source.std[k] + source.mean[k]) as f32;
                        }
                    }
                }
                let idx: Vec<usize> = (0..seq.frames.len()).filter(|i| valid[*i]).collect();
                let n = rows.len() / dim;
                let probs = if n == 0 {
                    Vec::new()
                } else {
                    clf.predict_features(&Tensor::from_vec(rows, (n, *dim), &Device::Cpu)?)?
                };
                let v = VideoPrediction {
                    id: seq.id.clone(),
                    object: seq.object.clone(),
                    part: seq.part.clone(),
                    preshape: seq.preshape,
                    multi_grasp: multi.contains(&seq.object),
                    labels: idx.iter().map(|i| seq.labels[*i]).collect(),
                    times_s: idx.iter().map(|i| seq.time_s(*i)).collect(),
                    probs,
                };
                serde_json::to_writer(&mut w, &v).context("writing")?;
                writeln!(w)?;
            }
            w.flush()?;
        }
        eprintln!("{set}: done");
    }
    Ok(())
}
