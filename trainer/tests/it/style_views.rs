//! Style views (`--feature-views N --view-style SIGMA`): the frozen
//! EfficientNet-Lite sees a view's frames with some blocks' channel
//! statistics moved, a new draw per frame. Their features differ from the
//! plain view's, repeat exactly, are cached under their own keys, and a
//! style of zero strength changes nothing.

use grasp_model::backbone::{Architecture, Backbone, BackboneInfo};
use grasp_model::checkpoint::{Classifier, TrainMode};
use grasp_model::extractor::FeatureExtractor;
use std::path::Path;
use trainer::config::TrainConfig;
use trainer::data::style::StyleDraw;
use trainer::data::{BadData, OnBadData};
use trainer::features::FeatureCache;
use trainer::stand_in::SmallSet;

/// The generated set and random EfficientNet-Lite0 weights beside it.
fn data_and_weights(root: &Path) -> SmallSet {
    let set = SmallSet::generated(root, |_| {}).unwrap();
    set.random_lite0(3).unwrap()
}

fn cfg(set: &SmallSet, out: &str) -> TrainConfig {
    TrainConfig {
        batch_size: Some(16),
        max_epochs: 2,
        ..set.config(out)
    }
}

fn cache_entries(root: &Path) -> usize {
    std::fs::read_dir(root.join("cache"))
        .unwrap()
        .map(|key| std::fs::read_dir(key.unwrap().path()).unwrap().count())
        .sum()
}

/// Trains `cfg` (one seed) and returns the real training sequences its
/// checkpoint counts.
fn train_sequences(cfg: &TrainConfig) -> usize {
    let run = trainer::experiment::run(cfg, 1).unwrap();
    Classifier::load(&run.runs[0].checkpoint, &candle_core::Device::Cpu)
        .unwrap()
        .meta
        .train_sequences
        .unwrap()
}

/// The frozen EfficientNet-Lite0 of `weights` at the tests' 32 px input.
fn lite0(weights: &Path) -> Backbone {
    let dev = candle_core::Device::Cpu;
    let info = BackboneInfo::pretrained(weights, Architecture::EfficientNetLite0, 1.0).unwrap();
    Backbone::load_pretrained(&info, Architecture::EfficientNetLite0.preprocess(32), &dev).unwrap()
}

#[test]
fn styled_features_differ_repeat_and_vanish_at_zero_strength() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let set = data_and_weights(root);
    let weights = set.weights().unwrap().to_path_buf();
    let net = lite0(&weights);
    assert_eq!(net.block_channels().len(), 16);

    let data = trainer::data::reader::read_dataset(
        &root.join("data"),
        &Default::default(),
        &BadData::new(OnBadData::Fail),
    )
    .unwrap();
    let plain = data.sequences[0].clone();
    let styled = |sigma: f32, seed: u64| {
        let mut s = plain.clone();
        s.style = Some(StyleDraw {
            sigma,
            blocks: vec![2, 4, 7],
            seed,
        });
        s
    };
    let bad = BadData::new(OnBadData::Fail);
    let features = |cache: &str, seq: &trainer::data::Sequence| {
        FeatureCache::new(root.join(cache), 8)
            .sequence(&net, seq, &bad)
            .unwrap()
    };
    let (base, _) = features("a", &plain);
    let (moved, hit) = features("a", &styled(0.5, 1));
    assert!(!hit, "a style is not the plain view's cache entry");
    let (again, hit) = features("b", &styled(0.5, 1));
    assert!(!hit);
    assert_eq!(moved.rows, again.rows, "a style's draws repeat");
    let (other, _) = features("a", &styled(0.5, 2));
    let diff = |a: &[f32], b: &[f32]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0f32, f32::max)
    };
    assert!(
        diff(&base.rows, &moved.rows) > 1e-3,
        "the style moved nothing"
    );
    assert!(
        diff(&moved.rows, &other.rows) > 1e-3,
        "the seed drew nothing"
    );
    // Zero strength: shifts 0 and scales 1, the plain features (up to the
    // spread's epsilon).
    let (none, _) = features("a", &styled(0.0, 1));
    assert!(diff(&base.rows, &none.rows) < 1e-3);
}

#[test]
fn style_views_are_cached_apart_from_plain_views_and_trained_on() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let set = data_and_weights(root);

    let mut views = cfg(&set, "views");
    views.views.count = 1;
    trainer::experiment::run(&views, 1).unwrap();
    let plain_entries = cache_entries(root);
    let mut styled = cfg(&set, "styled");
    styled.views.count = 1;
    styled.views.style = 0.3;
    let train = train_sequences(&styled);
    assert!(train > 0);
    assert_eq!(cache_entries(root), plain_entries + train);
    // The run's config records the style; a second run computes nothing new.
    let saved = std::fs::read_to_string(root.join("styled/config.toml")).unwrap();
    assert!(saved.contains("style = 0.3"), "{saved}");
    let mut again = styled.clone();
    again.out = root.join("styled-again");
    trainer::experiment::run(&again, 1).unwrap();
    assert_eq!(cache_entries(root), plain_entries + train);

    // A style without views would do nothing: refused.
    let mut idle = cfg(&set, "idle");
    idle.views.style = 0.3;
    let err = format!("{:#}", trainer::experiment::run(&idle, 1).err().unwrap());
    assert!(err.contains("views.count"), "{err}");
}

#[test]
fn fine_tuned_style_views_restyle_the_frozen_blocks_only() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let set = data_and_weights(root);
    let mut tuned = cfg(&set, "tuned");
    tuned.mode = TrainMode::FineTuned;
    tuned.fine_tune.blocks = 2;
    tuned.max_epochs = 1;
    tuned.views.count = 1;
    tuned.views.style = 0.3;
    let train = train_sequences(&tuned);
    // The plain sequences, their styled views and the validation ones.
    assert!(cache_entries(root) >= 2 * train);

    // Block 14 is tuned: its output is not cached, so it cannot be restyled.
    let mut late = tuned.clone();
    late.out = root.join("late");
    late.views.style_blocks = vec![4, 14];
    let err = format!("{:#}", trainer::experiment::run(&late, 1).err().unwrap());
    assert!(
        err.contains("views.style_blocks") && err.contains("block 14"),
        "{err}"
    );
}

/// A sequence and its style views, extracted together, prepare each frame
/// once (decoded, cropped, denoised) and share it; their features are the
/// ones each gets alone, bit for bit.
#[test]
fn views_extracted_together_equal_views_extracted_alone() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let set = data_and_weights(root);
    let weights = set.weights().unwrap().to_path_buf();
    let net = lite0(&weights);
    let options = trainer::data::ReaderOptions {
        denoise: true,
        ..Default::default()
    };
    let bad = BadData::new(OnBadData::Fail);
    let mut data = trainer::data::reader::read_dataset(&root.join("data"), &options, &bad).unwrap();
    data.sequences.truncate(2);
    let cfg = trainer::data::view::ViewConfig {
        count: 2,
        scale: 0.0,
        shift: 0.0,
        color: 0.0,
        style: 0.3,
        style_blocks: vec![2, 4, 7],
        ..Default::default()
    };
    let with_views = trainer::data::view::with_views(&data, &cfg, 1);
    assert_eq!(with_views.sequences.len(), 3 * data.sequences.len());
    let together = FeatureCache::new(root.join("together"), 8)
        .dataset(&net, &with_views, &bad)
        .unwrap();
    for (seq, f) in with_views.sequences.iter().zip(&together) {
        let (alone, hit) = FeatureCache::new(root.join("alone"), 8)
            .sequence(&net, seq, &bad)
            .unwrap();
        assert!(!hit);
        assert_eq!(alone.rows, f.rows, "{}", seq.id);
        assert_eq!(alone.valid, f.valid, "{}", seq.id);
    }
}
