//! The paper's frozen-backbone mode end to end on a tiny generated image
//! set: training, evaluation report, checkpoints reloaded through the
//! runtime API, the feature cache reused and runs repeated exactly for a
//! seed. (Learning itself is checked in train_learning.rs on generated
//! features: the stand-in backbone's eval-mode features barely vary between
//! images, see docs/trainer.md.)
//!
//! There are no pretrained weights on this machine: a randomly initialised
//! MobileNetV2 (width 0.25) stands in for `mobilenet_v2-b0353104.pth`; the
//! code path (weights file -> hash -> cached features -> head) is the same.

use grasp_model::checkpoint::Classifier;
use grasp_model::heads::HeadKind;
use std::path::Path;
use trainer::config::TrainConfig;
use trainer::plan::{DataPlan, RunPlan};

use trainer::stand_in::SmallSet;

/// The generated set, 6 sequences per part, and a random MobileNetV2
/// (width 0.25) calibrated on 40 of its frames.
fn setup(dir: &Path) -> TrainConfig {
    let set = SmallSet::generated(dir, |s| s.sequences_per_part = 6).unwrap();
    let set = set.random_mobilenet(0.25, 40).unwrap();
    let mut cfg = TrainConfig {
        batch_size: Some(16),
        max_epochs: 40,
        ..set.config("run")
    };
    cfg.split.val_fraction = 0.2;
    cfg.split.test_fraction = 0.2;
    cfg.optimizer.lr = 5e-3;
    cfg
}

fn train_and_check(head: HeadKind) {
    let dir = tempfile::tempdir().unwrap();
    let mut cfg = setup(dir.path());
    cfg.head = head;
    let outcome = trainer::experiment::run(&cfg, 1).unwrap();
    let report = outcome.report.expect("a test split");
    assert_eq!(report.mode, "frozen-pretrained");
    assert_eq!(report.runs[0].metrics.videos, 5);
    let h = &outcome.runs[0].history;
    assert!(h.len() >= 2 && h.iter().all(|e| e.train_loss.is_finite()));
    let md = std::fs::read_to_string(cfg.out.join("report/report.md")).unwrap();
    assert!(md.contains("**Mode: frozen-pretrained**"));
    assert!(cfg.out.join("report/time_accuracy.png").is_file());

    // The runtime API reloads the best checkpoint and predicts.
    let ckpt = &outcome.runs[0].checkpoint;
    let clf = Classifier::load(ckpt, &candle_core::Device::Cpu).unwrap();
    assert_eq!(clf.classes(), grasp_schema::taxonomy::Class::ALL);
    let seq = std::fs::read_dir(cfg.data.join("can/010_can/power_no3/Wrist_d435"))
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let frames: Vec<image::RgbImage> = (0..10)
        .map(|i| {
            image::open(seq.join(format!("{i:05}.png")))
                .unwrap()
                .to_rgb8()
        })
        .collect();
    let probs = clf.predict(&frames).unwrap();
    assert_eq!(probs.len(), 10);
    for p in &probs {
        assert!((p.iter().sum::<f32>() - 1.0).abs() < 1e-4);
    }
    // predict() = backbone features + head, as the evaluation computes them.
    let feats = grasp_model::extractor::FeatureExtractor::extract(clf.backbone(), &frames).unwrap();
    let again = clf.predict_features(&feats).unwrap();
    for (a, b) in probs.iter().zip(&again) {
        for k in 0..5 {
            assert!((a[k] - b[k]).abs() < 1e-5);
        }
    }
}

#[test]
fn fc_head_trains_end_to_end_and_reloads() {
    train_and_check(HeadKind::Fc);
}

/// An LSTM records the frame rate it was trained at and reads a video
/// recorded faster at that rate: the same frames at twice the rate (each
/// shown twice) get the same probabilities as the original. A head stepped
/// on every frame of the faster video reads another sequence.
#[test]
fn lstm_reads_a_faster_video_at_its_training_rate() {
    use trainer::data::{read_dataset, BadData, Dataset, OnBadData, ReaderOptions};
    let dir = tempfile::tempdir().unwrap();
    let mut cfg = setup(dir.path());
    cfg.head = HeadKind::Lstm;
    cfg.max_epochs = 3;
    let outcome = trainer::experiment::run(&cfg, 1).unwrap();
    let ckpt = &outcome.runs[0].checkpoint;
    let mut clf = Classifier::load(ckpt, &candle_core::Device::Cpu).unwrap();
    assert_eq!(
        clf.meta.head.step_hz,
        Some(10.0),
        "the synthetic set's rate"
    );

    let bad = BadData::new(OnBadData::Fail);
    let mut original = read_dataset(&cfg.data, &ReaderOptions::default(), &bad).unwrap();
    original.sequences.truncate(3);
    let doubled = Dataset {
        root: original.root.clone(),
        sequences: original
            .sequences
            .iter()
            .map(|s| {
                let mut d = s.clone();
                twice_as_fast(&mut d);
                d
            })
            .collect(),
    };
    let cache = trainer::features::FeatureCache::new(dir.path().join("cache"), 16);
    let predict = |clf: &Classifier, data: &Dataset| {
        trainer::eval::predict::predict_dataset(clf, data, &cache, &bad).unwrap()
    };
    let (slow, fast) = (predict(&clf, &original), predict(&clf, &doubled));
    for (s, f) in slow.iter().zip(&fast) {
        assert_eq!(s.probs.len(), 10);
        assert_eq!((&s.labels, &s.times_s), (&f.labels, &f.times_s));
        for (a, b) in s.probs.iter().zip(&f.probs) {
            assert!(
                a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-5),
                "{a:?} {b:?}"
            );
        }
    }
    // Without its step rate the head steps on all 20 frames.
    clf.meta.head.step_hz = None;
    let every = predict(&clf, &doubled);
    assert!(every.iter().all(|v| v.probs.len() == 20));
    let moved = slow.iter().zip(&every).any(|(s, e)| {
        s.probs
            .iter()
            .zip(e.probs.iter().step_by(2))
            .any(|(a, b)| a.iter().zip(b).any(|(x, y)| (x - y).abs() > 1e-4))
    });
    assert!(
        moved,
        "stepping twice per frame should change the LSTM's outputs"
    );
}

/// `seq` as if recorded twice as fast: every frame twice.
fn twice_as_fast(seq: &mut trainer::data::Sequence) {
    seq.fps *= 2.0;
    let frames = seq.frames.iter().flat_map(|f| [f.clone(), f.clone()]);
    seq.frames = frames.collect();
    seq.labels = seq.labels.iter().flat_map(|l| [*l, *l]).collect();
}

#[test]
fn lstm_head_trains_end_to_end_and_reloads() {
    train_and_check(HeadKind::Lstm);
}

/// An LSTM steps at one frame rate: a training set of two rates is refused,
/// naming them; an FC head trains on it.
#[test]
fn lstm_refuses_training_sequences_of_two_frame_rates() {
    let dir = tempfile::tempdir().unwrap();
    let mut cfg = setup(dir.path());
    // Every other sequence recorded at 20 frames/s: both rates in training.
    let records = grasp_test_support::files_under(&cfg.data)
        .into_iter()
        .filter(|p| p.ends_with("sequence.json"));
    for record in records.step_by(2) {
        let text = std::fs::read_to_string(&record).unwrap();
        let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
        json["plan"]["fps"] = serde_json::json!(20.0);
        std::fs::write(&record, serde_json::to_string(&json).unwrap()).unwrap();
    }
    cfg.head = HeadKind::Lstm;
    let err = trainer::experiment::run(&cfg, 1)
        .err()
        .expect("two rates refused");
    let msg = format!("{err:#}");
    assert!(
        msg.contains("one frame rate") && msg.contains("10, 20"),
        "{msg}"
    );
    cfg.head = HeadKind::Fc;
    cfg.max_epochs = 2;
    trainer::experiment::run(&cfg, 1).unwrap();
}

#[test]
fn lstm_is_validated_at_its_training_rate() {
    use trainer::data::{BadData, OnBadData};
    let dir = tempfile::tempdir().unwrap();
    let mut cfg = setup(dir.path());
    let bad = BadData::new(OnBadData::Fail);
    let mut splits = trainer::train::load_splits(&DataPlan::of(&cfg), &bad).unwrap();
    let frames: Vec<usize> = splits
        .val
        .sequences
        .iter()
        .map(|s| s.frames.len())
        .collect();
    splits.val.sequences.iter_mut().for_each(twice_as_fast);
    let read = |cfg: &TrainConfig| {
        let plan = RunPlan::resolve(cfg).unwrap();
        let dev = candle_core::Device::Cpu;
        let prep = trainer::train::prepare(plan.features, &plan.cache, &splits, &bad, &dev);
        let prep = prep.unwrap();
        prep.val.seq_rows.iter().map(Vec::len).collect::<Vec<_>>()
    };
    cfg.head = HeadKind::Lstm;
    assert_eq!(read(&cfg), frames, "one step per training frame interval");
    // A frame classifier reads every frame.
    cfg.head = HeadKind::Fc;
    let doubled: Vec<usize> = frames.iter().map(|n| 2 * n).collect();
    assert_eq!(read(&cfg), doubled);
}

fn cache_files(dir: &Path) -> Vec<(std::path::PathBuf, std::time::SystemTime)> {
    let mut out = Vec::new();
    for key in std::fs::read_dir(dir).unwrap() {
        for f in std::fs::read_dir(key.unwrap().path()).unwrap() {
            let p = f.unwrap().path();
            let t = std::fs::metadata(&p).unwrap().modified().unwrap();
            out.push((p, t));
        }
    }
    out.sort();
    out
}

#[test]
fn feature_cache_is_reused_and_runs_repeat_for_a_seed() {
    let dir = tempfile::tempdir().unwrap();
    let mut cfg = setup(dir.path());
    cfg.max_epochs = 5;
    trainer::experiment::run(&cfg, 1).unwrap();
    let first = cache_files(&cfg.cache_dir);
    // train + val sequences cached (the test split is cached at evaluation).
    assert_eq!(first.len(), 30);
    assert!(first
        .iter()
        .all(|(p, _)| p.extension().unwrap() == "safetensors"));

    let out1 = cfg.out.clone();
    cfg.out = dir.path().join("run2");
    trainer::experiment::run(&cfg, 1).unwrap();
    assert_eq!(
        cache_files(&cfg.cache_dir),
        first,
        "cache entries were rewritten"
    );
    let a = std::fs::read(out1.join("seed-0/best.safetensors")).unwrap();
    let b = std::fs::read(cfg.out.join("seed-0/best.safetensors")).unwrap();
    assert_eq!(a, b, "same seed, different weights");
    let h1 = std::fs::read_to_string(out1.join("seed-0/history.json")).unwrap();
    let h2 = std::fs::read_to_string(cfg.out.join("seed-0/history.json")).unwrap();
    let strip = |h: &str| -> Vec<serde_json::Value> {
        let mut v: Vec<serde_json::Value> = serde_json::from_str(h).unwrap();
        for e in &mut v {
            e.as_object_mut().unwrap().remove("seconds");
        }
        v
    };
    assert_eq!(strip(&h1), strip(&h2));

    // Another seed trains differently.
    cfg.seed = 1;
    cfg.out = dir.path().join("run3");
    trainer::experiment::run(&cfg, 1).unwrap();
    let c = std::fs::read(cfg.out.join("seed-1/best.safetensors")).unwrap();
    assert_ne!(a, c);
}
