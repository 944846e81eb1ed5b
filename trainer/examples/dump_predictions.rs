//! Lab tool (issue 41): every frame's class probabilities of a test set, as
//! `grasp-train eval` computes them (same reader, crop, lead-in trim and
//! feature cache), written as JSON lines for studying vote rules offline.
//!
//!   cargo run --release -p trainer --example dump_predictions -- \
//!       CHECKPOINT DATA CACHE_DIR OUT.jsonl
use anyhow::{Context, Result};
use grasp_model::checkpoint::{CheckpointMeta, Classifier};
use std::io::Write;
use std::path::PathBuf;
use trainer::data::{BadData, OnBadData, ReaderOptions};

fn main() -> Result<()> {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let [checkpoint, data, cache, out] = args.as_slice() else {
        anyhow::bail!("usage: dump_predictions CHECKPOINT DATA CACHE_DIR OUT.jsonl");
    };
    let bad = BadData::new(OnBadData::Skip);
    let (meta, _) = CheckpointMeta::load(checkpoint)?;
    let opts = ReaderOptions {
        crop: meta.input.crop,
        denoise: meta.input.denoise,
        camera: trainer::config::trained_camera_folder(&meta),
        ..Default::default()
    };
    let mut dataset = trainer::data::read_dataset(data, &opts, &bad)?;
    dataset.trim_lead_ins();
    let clf = Classifier::load(checkpoint, &candle_core::Device::Cpu)?;
    let cache = trainer::features::FeatureCache::new(cache, 32);
    let videos = trainer::eval::predict::predict_dataset(&clf, &dataset, &cache, &bad)
        .context("prediction failed")?;
    let mut w = std::io::BufWriter::new(std::fs::File::create(out)?);
    for v in &videos {
        serde_json::to_writer(&mut w, v)?;
        writeln!(w)?;
    }
    w.flush()?;
    Ok(())
}
