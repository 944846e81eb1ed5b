//! A whole experiment: split the data, train one model per seed, evaluate
//! each on the test split and write the aggregated report (mean ± std over
//! seeds).

use crate::checkpoint::{CheckpointMeta, Classifier, TrainMode};
use crate::config::TrainConfig;
use crate::data::{split, BadData, Dataset};
use crate::eval::report::RunReport;
use crate::eval::{compute_metrics, write_report, Report};
use crate::features::FeatureCache;
use crate::train::{self, TrainOutcome};
use anyhow::{Context, Result};
use candle_core::Device;
use std::path::{Path, PathBuf};

/// Width of the accuracy-against-time bins, in seconds.
pub const TIME_BIN_S: f64 = 0.1;

pub struct ExperimentOutcome {
    pub runs: Vec<TrainOutcome>,
    pub report: Option<Report>,
}

/// Trains `seeds` models (seeds `cfg.seed`, `cfg.seed + 1`, ...) into
/// `cfg.out/seed-N/`, then evaluates them on the test split into
/// `cfg.out/report/` when there is one.
pub fn run(cfg: &TrainConfig, seeds: usize) -> Result<ExperimentOutcome> {
    cfg.validate()?;
    let cfg = &resolve_backbone(cfg)?;
    let dev = Device::Cpu;
    let bad = BadData::new(cfg.on_bad_data);
    let splits = train::load_splits(cfg, &bad)?;
    std::fs::create_dir_all(&cfg.out)
        .with_context(|| format!("cannot create {}", cfg.out.display()))?;
    splits.split.save(&cfg.out.join("split.json"))?;
    crate::checkpoint::write_atomic(
        &cfg.out.join("config.toml"),
        toml::to_string(cfg)?.as_bytes(),
    )?;
    tracing::info!(
        "{} train / {} val / {} test sequences ({} mode, {} head)",
        splits.train.sequences.len(),
        splits.val.sequences.len(),
        splits.test.sequences.len(),
        cfg.mode.name(),
        cfg.head.name()
    );
    let prep = train::prepare(cfg, &splits, &bad, &dev)?;
    let mut runs = Vec::new();
    for k in 0..seeds.max(1) as u64 {
        let seed = cfg.seed + k;
        let out = cfg.out.join(format!("seed-{seed}"));
        tracing::info!("training seed {seed} into {}", out.display());
        runs.push(train::train(cfg, &prep, seed, &out)?);
    }
    let report = if splits.test.sequences.is_empty() {
        None
    } else {
        let ckpts: Vec<PathBuf> = runs.iter().map(|r| r.checkpoint.clone()).collect();
        let r = evaluate(
            &ckpts,
            &splits.test,
            &cfg.cache_dir,
            cfg.feature_batch,
            &bad,
        )?;
        write_report(&r, &cfg.out.join("report"))?;
        Some(r)
    };
    write_problems(&bad, &cfg.out)?;
    Ok(ExperimentOutcome { runs, report })
}

/// Evaluates checkpoints on `data` and aggregates them into one report.
pub fn evaluate(
    checkpoints: &[PathBuf],
    data: &Dataset,
    cache_dir: &Path,
    batch: usize,
    bad: &BadData,
) -> Result<Report> {
    let dev = Device::Cpu;
    let cache = FeatureCache::new(cache_dir, batch);
    let mut runs = Vec::new();
    let (mut mode, mut head, mut backbone) = (String::new(), String::new(), String::new());
    for ckpt in checkpoints {
        let clf = Classifier::load(ckpt, &dev)?;
        let this_mode = clf.meta.mode.name().to_string();
        if !mode.is_empty() && mode != this_mode {
            anyhow::bail!(
                "cannot aggregate {} with {mode} checkpoints ({})",
                this_mode,
                ckpt.display()
            );
        }
        mode = this_mode;
        let this_backbone = clf.meta.backbone.describe();
        if !backbone.is_empty() && backbone != this_backbone {
            anyhow::bail!(
                "cannot aggregate checkpoints with different backbones: {backbone} and {this_backbone} ({})",
                ckpt.display()
            );
        }
        backbone = this_backbone;
        head = clf.meta.head.kind.name().to_string();
        let preds = crate::eval::predict::predict_dataset(&clf, data, &cache, bad)?;
        runs.push(RunReport {
            checkpoint: ckpt.clone(),
            seed: clf.meta.seed,
            metrics: compute_metrics(&preds, TIME_BIN_S),
        });
    }
    let mut report = Report::new(&mode, &head, &data.root, runs);
    report.backbone = backbone;
    Ok(report)
}

/// With a checkpoint as the frozen backbone, its width multiplier and input
/// size replace the configured ones (the backbone only works with those),
/// so that the saved `config.toml` says what was run.
fn resolve_backbone(cfg: &TrainConfig) -> Result<TrainConfig> {
    let mut cfg = cfg.clone();
    let from_checkpoint = cfg
        .weights
        .as_deref()
        .is_some_and(crate::backbone::is_checkpoint);
    if cfg.mode == TrainMode::FrozenPretrained && from_checkpoint {
        let (info, pre) = train::frozen_backbone(&cfg)?;
        tracing::info!(
            "{}: width multiplier {}, input {} px",
            info.describe(),
            info.width_mult,
            pre.size
        );
        cfg.width_mult = info.width_mult;
        cfg.input_size = pre.size;
    }
    Ok(cfg)
}

/// The test split of the run a checkpoint belongs to: its training config's
/// data root, and `split.json` next to the `seed-N` folder.
pub fn test_split_of(checkpoint: &Path, bad: &BadData) -> Result<Dataset> {
    let (meta, dir) = CheckpointMeta::load(checkpoint)?;
    let cfg: TrainConfig = serde_json::from_value(meta.train_config.clone())
        .context("the checkpoint's train_config is not readable")?;
    let split_file = dir.parent().unwrap_or(&dir).join("split.json");
    let root = cfg.test_data.clone().unwrap_or(cfg.data.clone());
    let data = crate::data::read_dataset(&root, &cfg.reader, bad)?;
    if cfg.test_data.is_some() {
        return Ok(data);
    }
    let s = split::Split::load(&split_file)
        .with_context(|| "pass --data to evaluate on a dataset of your choice")?;
    Ok(split::select(&data, &s.test))
}

fn write_problems(bad: &BadData, out: &Path) -> Result<()> {
    let problems = bad.problems();
    if !problems.is_empty() {
        tracing::warn!(
            "{} bad-data problem(s) skipped; listed in {}",
            problems.len(),
            out.join("problems.json").display()
        );
        crate::checkpoint::write_atomic(
            &out.join("problems.json"),
            serde_json::to_string_pretty(&problems)?.as_bytes(),
        )?;
    }
    Ok(())
}
