//! A from-scratch checkpoint used as the frozen backbone of a new run
//! (`--mode frozen-pretrained --weights RUN/seed-0`): its `backbone.*`
//! tensors, width multiplier and preprocessing are reused, its features are
//! cached under a key that includes its weights, only the head is trained,
//! and the report names the checkpoint.

use grasp_model::checkpoint::{Classifier, TrainMode};
use grasp_model::extractor::FeatureExtractor;
use grasp_model::heads::HeadKind;
use std::path::{Path, PathBuf};
use trainer::config::TrainConfig;
use trainer::stand_in::SmallSet;

fn scratch_cfg(set: &SmallSet) -> TrainConfig {
    TrainConfig {
        max_epochs: 2,
        ..set.config("scratch")
    }
}

/// A head on the frozen checkpoint `backbone` (its width and input size
/// replace the set's).
fn frozen_cfg(set: &SmallSet, backbone: &Path, head: HeadKind, out: &str) -> TrainConfig {
    TrainConfig {
        mode: TrainMode::FrozenPretrained,
        head,
        weights: Some(backbone.to_path_buf()),
        batch_size: Some(16),
        max_epochs: 3,
        ..set.config(out)
    }
}

fn cache_keys(root: &Path) -> Vec<PathBuf> {
    let mut keys: Vec<PathBuf> = std::fs::read_dir(root.join("cache"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    keys.sort();
    keys
}

#[test]
fn a_from_scratch_checkpoint_serves_as_a_frozen_backbone() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let set = SmallSet::generated(root, |spec| spec.sequences_per_part = 3).unwrap();
    let scratch = trainer::experiment::run(&scratch_cfg(&set), 2).unwrap();
    let (seed0, seed1) = (&scratch.runs[0].checkpoint, &scratch.runs[1].checkpoint);

    // A run's directory is not a checkpoint: the error points to a seed.
    let cfg = frozen_cfg(&set, &root.join("scratch"), HeadKind::Fc, "bad");
    let err = format!("{:#}", trainer::experiment::run(&cfg, 1).err().unwrap());
    assert!(err.contains("seed-0"), "{err}");

    // The directory and its best.json are both accepted.
    let cfg = frozen_cfg(&set, seed0, HeadKind::Fc, "fc");
    let fc = trainer::experiment::run(&cfg, 1).unwrap();
    let clf = Classifier::load(&fc.runs[0].checkpoint, &candle_core::Device::Cpu).unwrap();
    assert_eq!(clf.meta.mode, TrainMode::FrozenPretrained);
    assert_eq!(clf.meta.backbone.width_mult, 0.25);
    assert_eq!(clf.meta.input.preprocess.size, 32);
    assert_eq!(
        clf.meta.backbone.source_checkpoint.as_deref(),
        Some(seed0.as_path())
    );
    // The run's config says what was run: the backbone's size, not 224.
    let saved = TrainConfig::from_toml_file(&cfg.out.join("config.toml")).unwrap();
    assert_eq!((saved.input_size, saved.width_mult), (32, 0.25));
    // Only the head was saved: the backbone stays in its own checkpoint.
    let tensors = candle_core::safetensors::load(
        fc.runs[0].checkpoint.join("best.safetensors"),
        &candle_core::Device::Cpu,
    )
    .unwrap();
    assert!(
        tensors.keys().all(|k| k.starts_with("head.")),
        "{tensors:?}"
    );

    // The frozen backbone computes exactly the source checkpoint's features.
    let source = Classifier::load(seed0, &candle_core::Device::Cpu).unwrap();
    let frames: Vec<_> = (0..3)
        .map(|i| {
            trainer::data::synthetic::class_image(
                grasp_schema::taxonomy::Class::ALL[i],
                40,
                5.0,
                &mut trainer::rng::stream(i as u64, "frames"),
            )
        })
        .collect();
    let features = |c: &Classifier| -> Vec<f32> {
        let t = c.backbone().extract(&frames).unwrap();
        t.flatten_all().unwrap().to_vec1().unwrap()
    };
    assert_eq!(features(&source), features(&clf));

    // The report names the backbone.
    let report = fc.report.unwrap();
    assert_eq!(report.mode, "frozen-pretrained");
    assert_eq!(
        report.backbone,
        format!("frozen mobilenet-v2 from {}", seed0.display())
    );
    let md = std::fs::read_to_string(cfg.out.join("report/report.md")).unwrap();
    assert!(
        md.contains(&format!("frozen mobilenet-v2 from {}", seed0.display())),
        "{md}"
    );
    assert_eq!(cache_keys(root).len(), 1);

    // An LSTM head on the same backbone reuses the cache (no new key, the
    // entries untouched); another checkpoint's weights get their own key.
    let entries = |key: &Path| -> Vec<(PathBuf, std::time::SystemTime)> {
        let mut v: Vec<_> = std::fs::read_dir(key)
            .unwrap()
            .map(|e| {
                let e = e.unwrap();
                (e.path(), e.metadata().unwrap().modified().unwrap())
            })
            .collect();
        v.sort();
        v
    };
    let before = entries(&cache_keys(root)[0]);
    let json = seed0.join("best.json");
    trainer::experiment::run(&frozen_cfg(&set, &json, HeadKind::Lstm, "lstm"), 1).unwrap();
    assert_eq!(cache_keys(root).len(), 1);
    assert_eq!(entries(&cache_keys(root)[0]), before);
    trainer::experiment::run(&frozen_cfg(&set, seed1, HeadKind::Fc, "fc1"), 1).unwrap();
    assert_eq!(cache_keys(root).len(), 2);

    // Aggregating heads on different backbones is refused.
    let data = trainer::data::read_dataset(
        &root.join("data"),
        &Default::default(),
        &trainer::data::BadData::new(trainer::data::OnBadData::Fail),
    )
    .unwrap();
    let err = trainer::experiment::evaluate(
        &[fc.runs[0].checkpoint.clone(), root.join("fc1/seed-0")],
        &data,
        &root.join("cache"),
        8,
        &trainer::data::BadData::new(trainer::data::OnBadData::Fail),
        &Default::default(),
    )
    .err()
    .unwrap();
    assert!(
        format!("{err:#}").contains("different backbones"),
        "{err:#}"
    );
}

#[test]
fn feature_views_are_cached_extra_sequences_that_do_not_count_as_data() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let set = SmallSet::generated(root, |_| {}).unwrap();
    let scratch = trainer::experiment::run(&scratch_cfg(&set), 1).unwrap();
    let backbone = &scratch.runs[0].checkpoint;
    let count_entries = || std::fs::read_dir(&cache_keys(root)[0]).unwrap().count();

    let plain =
        trainer::experiment::run(&frozen_cfg(&set, backbone, HeadKind::Fc, "plain"), 1).unwrap();
    let plain_entries = count_entries();
    let mut cfg = frozen_cfg(&set, backbone, HeadKind::Fc, "views");
    cfg.views.count = 2;
    let viewed = trainer::experiment::run(&cfg, 1).unwrap();
    let load = |r: &trainer::train::TrainOutcome| {
        Classifier::load(&r.checkpoint, &candle_core::Device::Cpu).unwrap()
    };
    let (p, v) = (load(&plain.runs[0]), load(&viewed.runs[0]));
    let train = p.meta.train_sequences.unwrap();
    assert_eq!(
        v.meta.train_sequences,
        Some(train),
        "views are not new data"
    );
    // Two new cache entries per training sequence, none for the others.
    assert_eq!(count_entries(), plain_entries + 2 * train);
    // A second run reuses them.
    let mut again = cfg.clone();
    again.out = root.join("views-again");
    trainer::experiment::run(&again, 1).unwrap();
    assert_eq!(count_entries(), plain_entries + 2 * train);

    // From scratch, augmentation is per epoch: views are refused.
    let mut bad = scratch_cfg(&set);
    bad.views.count = 1;
    let err = format!("{:#}", trainer::experiment::run(&bad, 1).err().unwrap());
    assert!(err.contains("views.count"), "{err}");
}
