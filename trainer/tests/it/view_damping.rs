//! View damping (`--view-damping`): the frozen features' directions that
//! the training views change are damped before the head, and the damping
//! is folded into the saved head, so the checkpoint reads plain features.
//! Look twins (`--look-twins`) join the views and are damped with them.

use grasp_model::heads::HeadKind;
use std::path::Path;
use trainer::config::TrainConfig;
use trainer::data::{BadData, OnBadData};
use trainer::plan::RunPlan;
use trainer::stand_in::SmallSet;
use trainer::train::{FrameSource, SplitFrames};

/// The generated set and random EfficientNet-Lite0 weights under `root`.
fn set(root: &Path) -> SmallSet {
    let set = SmallSet::generated(root, |_| {}).unwrap();
    set.random_lite0(3).unwrap()
}

/// A run on `set` with two style views of every training sequence.
fn cfg(set: &SmallSet, damping: f64, out: &str) -> TrainConfig {
    let mut cfg = TrainConfig {
        batch_size: Some(16),
        max_epochs: 2,
        view_damping: damping,
        ..set.config(out)
    };
    cfg.views.count = 2;
    cfg.views.style = 0.5;
    cfg
}

/// The mean squared change between a training frame and its views'
/// frames, over the features' mean squared spread.
fn relative_view_change(train: &SplitFrames, originals: usize) -> f32 {
    let FrameSource::Cached(x) = &train.source else {
        panic!("frozen mode caches features")
    };
    let x: Vec<Vec<f32>> = x.to_vec2().unwrap();
    let dim = x[0].len();
    let mean: Vec<f32> = (0..dim)
        .map(|c| x.iter().map(|r| r[c]).sum::<f32>() / x.len() as f32)
        .collect();
    let sq = |a: &[f32], b: &[f32]| a.iter().zip(b).map(|(p, q)| (p - q).powi(2)).sum::<f32>();
    let spread = x.iter().map(|r| sq(r, &mean)).sum::<f32>() / x.len() as f32;
    let (mut change, mut pairs) = (0.0, 0);
    for (i, rows) in train.seq_rows.iter().enumerate().skip(originals) {
        for (&v, &o) in rows.iter().zip(&train.seq_rows[i % originals]) {
            change += sq(&x[v], &x[o]);
            pairs += 1;
        }
    }
    assert!(pairs > 0);
    change / pairs as f32 / spread
}

#[test]
fn damping_brings_views_closer_to_their_frames() {
    let dir = tempfile::tempdir().unwrap();
    let bad = BadData::new(OnBadData::Fail);
    let dev = candle_core::Device::Cpu;
    let set = set(dir.path());
    let change = |damping: f64| {
        let cfg = cfg(&set, damping, "unused");
        let plan = RunPlan::resolve(&cfg).unwrap();
        let splits = trainer::train::load_splits(&plan.data, &bad).unwrap();
        let prep = trainer::train::prepare(plan.features, &plan.cache, &splits, &bad, &dev);
        let prep = prep.unwrap();
        assert_eq!(prep.damping.is_some(), damping > 0.0);
        relative_view_change(&prep.train, splits.train.sequences.len())
    };
    let (plain, damped) = (change(0.0), change(20.0));
    assert!(plain > 0.0, "the style views change the features");
    assert!(damped < 0.5 * plain, "damped {damped} against {plain}");
}

#[test]
fn a_damped_run_saves_a_plain_checkpoint_that_records_the_damping() {
    let dir = tempfile::tempdir().unwrap();
    let set = set(dir.path());
    let weights = |out: &str, damping: f64| {
        let run = trainer::experiment::run(&cfg(&set, damping, out), 1).unwrap();
        let ckpt = &run.runs[0].checkpoint;
        let classifier =
            grasp_model::checkpoint::Classifier::load(ckpt, &candle_core::Device::Cpu).unwrap();
        assert_eq!(classifier.meta.head.kind, HeadKind::Fc);
        let file = ckpt.join(grasp_model::checkpoint::WEIGHTS_FILE);
        let tensors = candle_core::safetensors::load(file, &candle_core::Device::Cpu).unwrap();
        let w: Vec<Vec<f32>> = tensors["head.fc.weight"].to_vec2().unwrap();
        w
    };
    let plain = weights("plain", 0.0);
    let damped = weights("damped", 3.0);
    assert_eq!(plain.len(), damped.len(), "the same head shape");
    assert_ne!(plain, damped, "the damping changed what the head reads");
    let saved = std::fs::read_to_string(set.root.join("damped/config.toml")).unwrap();
    assert!(saved.contains("view_damping = 3.0"), "{saved}");
}
