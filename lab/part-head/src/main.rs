//! Lab experiment for issue 57's part-level supervision lever: a linear
//! head on each cell of the frozen backbone's map, trained on the share of
//! the cell that the generator's `part` pass gives to each pre-shape's parts
//! (or to no part), its frame read from the cells under the aim point; next
//! to a control trained the same way on the pooled features and the frame
//! labels. Each is scored on every world by the hand's decision
//! (`hannes-run`'s default policy) and the per-video vote, 3 seeds.
//!
//! ```sh
//! cargo run --release -p part-head -- --config runs/main/model-fc/config.toml \
//!   --masks runs/main/lab/parts56/train --cache-dir runs/main/lab/part-head/features \
//!   --out runs/main/lab/part-head --test default=runs/main/data/test-default ...
//! ```

mod cells;
mod fit;
mod masks;
mod score;

use anyhow::{ensure, Context, Result};
use candle_core::{Device, Tensor};
use clap::Parser;
use grasp_model::backbone::Backbone;
use grasp_schema::taxonomy::Class;
use std::path::PathBuf;
use trainer::config::TrainConfig;
use trainer::data::BadData;
use trainer::features::FeatureCache;
use trainer::train::{FrameSource, SplitFrames, ViewDamping};

#[derive(Parser)]
struct Args {
    /// The shipped FC run's resolved config (data, views, reader, damping).
    #[arg(long)]
    config: PathBuf,
    /// The mask render of the training set (same plans, `part` pass).
    #[arg(long)]
    masks: PathBuf,
    #[arg(long)]
    cache_dir: PathBuf,
    /// Test sets, NAME=DIR.
    #[arg(long)]
    test: Vec<String>,
    #[arg(long, default_value_t = 3)]
    seeds: u64,
    #[arg(long, default_value_t = 4)]
    grid: usize,
    /// The joint head's cell loss weight.
    #[arg(long, default_value_t = 1.0)]
    cell_weight: f64,
    /// Train only the control and joint heads.
    #[arg(long)]
    joint_only: bool,
    #[arg(long)]
    out: PathBuf,
}

/// Features of one split: cells (frames x cells, dim), damped.
pub(crate) struct Split {
    pub frames: SplitFrames,
    pub cells: Tensor,
}

fn main() -> Result<()> {
    tracing_subscriber::fmt().with_env_filter("info").init();
    let args = Args::parse();
    let cfg = TrainConfig::from_toml_file(&args.config)?;
    let bad = BadData::new(cfg.on_bad_data);
    let dev = Device::Cpu;
    let splits = trainer::train::load_splits(&cfg, &bad)?;
    let (info, pre) = trainer::train::frozen_backbone(&cfg)?;
    let ex = cells::CellExtractor {
        backbone: Backbone::load_pretrained(&info, pre, &dev)?,
        grid: args.grid,
    };
    let cache = FeatureCache::new(&args.cache_dir, cfg.feature_batch);
    let train_views = trainer::data::view::with_views(&splits.train, &cfg.views, cfg.split.seed);
    let originals = splits.train.sequences.len();
    let mut train = split(&ex, &cache, &train_views, &bad)?;
    let damping = damping(&mut train, &ex, originals, cfg.view_damping)?;
    damp(&mut train, &damping)?;
    let mut val = split(&ex, &cache, &splits.val, &bad)?;
    damp(&mut val, &damping)?;
    let catalog = generator::catalog::Catalog::builtin()?;
    let mut cell_y = Vec::new();
    for (si, seq) in train_views.sequences.iter().enumerate() {
        let original = &splits.train.sequences[si % originals];
        ensure!(
            train.frames.seq_rows[si].len() == seq.frames.len(),
            "unreadable frames in {}",
            seq.id
        );
        cell_y.extend(masks::cell_labels(
            original,
            &cfg.data,
            &args.masks,
            &catalog,
            args.grid,
        )?);
    }
    let models = score::Models::fit(
        &train,
        &val,
        cell_y,
        &ex,
        args.seeds,
        args.cell_weight,
        args.joint_only,
    )?;
    let mut table = score::Table::default();
    for t in &args.test {
        let (name, dir) = t.split_once('=').context("--test NAME=DIR")?;
        let mut data = trainer::data::read_dataset(std::path::Path::new(dir), &cfg.reader, &bad)?;
        data.trim_lead_ins();
        let set = split(&ex, &cache, &data, &bad)?;
        let mut set = set;
        damp(&mut set, &damping)?;
        table.add(name, &models.score(&set, &data, ex.cells())?);
        println!("{}", table.markdown());
    }
    std::fs::create_dir_all(&args.out)?;
    std::fs::write(args.out.join("result.md"), table.markdown())?;
    Ok(())
}

fn split(
    ex: &cells::CellExtractor,
    cache: &FeatureCache,
    data: &trainer::data::Dataset,
    bad: &BadData,
) -> Result<Split> {
    let feats = cache.dataset(ex, data, bad)?;
    let mut frames = SplitFrames::from_features(data, &feats, &Device::Cpu)?;
    drop(feats);
    let FrameSource::Cached(x) = std::mem::replace(&mut frames.source, FrameSource::Images(vec![]))
    else {
        unreachable!("from_features caches");
    };
    let cells = x.reshape((x.dim(0)? * ex.cells(), ex.cell_dim()))?;
    Ok(Split { frames, cells })
}

/// The shipped recipe's view damping, fitted on the pooled features (the
/// cells' mean) and applied to every cell (the map is linear).
fn damping(
    train: &mut Split,
    ex: &cells::CellExtractor,
    originals: usize,
    strength: f64,
) -> Result<Option<ViewDamping>> {
    if strength <= 0.0 {
        return Ok(None);
    }
    let pooled = pooled(&train.cells, ex.cells())?;
    train.frames.source = FrameSource::Cached(pooled);
    let d = ViewDamping::from_views(&train.frames, originals, strength)?;
    train.frames.source = FrameSource::Images(vec![]);
    Ok(d)
}

fn damp(split: &mut Split, damping: &Option<ViewDamping>) -> Result<()> {
    let Some(d) = damping else { return Ok(()) };
    let n = split.cells.dim(0)?;
    let chunks = (0..n)
        .step_by(65536)
        .map(|s| d.apply(&split.cells.narrow(0, s, (n - s).min(65536))?))
        .collect::<candle_core::Result<Vec<_>>>()?;
    split.cells = Tensor::cat(&chunks, 0)?;
    Ok(())
}

/// (frames, dim): each frame's cells averaged.
pub fn pooled(cells: &Tensor, per_frame: usize) -> Result<Tensor> {
    let (n, dim) = cells.dims2()?;
    Ok(cells.reshape((n / per_frame, per_frame, dim))?.mean(1)?)
}

/// One-hot rows of frame classes.
pub fn one_hot(labels: &[u32], k: usize) -> Result<Tensor> {
    let mut v = vec![0f32; labels.len() * k];
    for (i, &l) in labels.iter().enumerate() {
        v[i * k + l as usize] = 1.0;
    }
    Ok(Tensor::from_vec(v, (labels.len(), k), &Device::Cpu)?)
}

/// Frame weights that give every class the same total.
pub fn balanced(labels: &[u32]) -> Vec<f32> {
    let mut count = [0usize; Class::COUNT];
    labels.iter().for_each(|&l| count[l as usize] += 1);
    labels
        .iter()
        .map(|&l| 1.0 / count[l as usize] as f32)
        .collect()
}

/// Mean cross-entropy of frame probabilities against labels.
pub fn frame_loss(probs: &Tensor, labels: &[u32]) -> Result<f64> {
    let p: Vec<Vec<f32>> = probs.to_vec2()?;
    let w = balanced(labels);
    let total: f32 = w.iter().sum();
    let loss: f64 = p
        .iter()
        .zip(labels)
        .zip(&w)
        .map(|((row, &l), &wi)| -f64::from(wi) * f64::from(row[l as usize].max(1e-7)).ln())
        .sum();
    Ok(loss / f64::from(total))
}
