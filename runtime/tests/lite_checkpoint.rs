//! hannes-run loads a classifier whose frozen backbone is EfficientNet-Lite0
//! (the trainer's default) and classifies frames with it. The backbone is a
//! random Lite0 written here, so the test does not depend on the venv; the
//! architecture, the preprocessing and the loading path are the real ones.

use grasp_model::backbone::{Architecture, ResizeFilter};
use runtime::classifier::FrameClassifier;
use std::path::{Path, PathBuf};
use trainer::config::TrainConfig;
use trainer::stand_in::SmallSet;

/// A small generated set of `frames`-frame sequences in `root/data` and a
/// random Lite0 file; `cfg` shapes the run, trained on them (one seed) at
/// 40 px. Returns the checkpoint and the run's config.
fn train_on_random_lite0(
    root: &Path,
    frames: usize,
    cfg: impl FnOnce(TrainConfig) -> TrainConfig,
) -> (PathBuf, TrainConfig) {
    let set = SmallSet::generated(root, |spec| {
        spec.sequences_per_part = 2;
        spec.frames = frames;
        spec.no_grasp_frames = 1;
    })
    .unwrap();
    let set = set.random_lite0(3).unwrap();
    let mut cfg = cfg(TrainConfig {
        input_size: 40,
        max_epochs: 1,
        ..set.config("run")
    });
    cfg.split.val_fraction = 0.34;
    cfg.split.test_fraction = 0.0;
    let outcome = trainer::experiment::run(&cfg, 1).unwrap();
    (outcome.runs[0].checkpoint.clone(), cfg)
}

#[test]
fn a_lite0_checkpoint_loads_and_classifies_frames() {
    let dir = tempfile::tempdir().unwrap();
    let (ckpt, _) = train_on_random_lite0(dir.path(), 4, |cfg| cfg);
    let ckpt = &ckpt;

    let mut clf = runtime::model::load(ckpt).unwrap();
    assert_eq!(clf.meta.backbone.arch, Architecture::EfficientNetLite0);
    assert_eq!(clf.meta.input.preprocess.resize, ResizeFilter::Bicubic);
    assert_eq!(clf.meta.input.preprocess.size, 40);
    // frames of another size are resized as recorded
    let frame = image::RgbImage::from_fn(64, 48, |x, y| image::Rgb([x as u8, y as u8, 90]));
    let p = clf.classify(&frame, 0.0).unwrap();
    let sum: f32 = p.iter().sum();
    assert!(
        (sum - 1.0).abs() < 1e-4 && p.iter().all(|v| v.is_finite()),
        "{p:?}"
    );

    // A pooled block the network lacks, hand-edited into best.json: a
    // corrupt checkpoint naming its file, with no backtrace in the message
    // even under RUST_BACKTRACE=1 (a user's error, not a bug).
    std::env::set_var("RUST_BACKTRACE", "1");
    let json = ckpt.join(grasp_model::checkpoint::META_FILE);
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    meta["backbone"]["pooled_blocks"] = serde_json::json!([99]);
    std::fs::write(&json, serde_json::to_vec(&meta).unwrap()).unwrap();
    // As hannes-run prints it: the error and its causes on one line.
    let err = runtime::model::load(ckpt).err().expect("loaded block 99");
    let err = grasp_support::error_chain(&err);
    assert!(
        err.contains(&json.display().to_string()) && err.contains("pooled block 99"),
        "{err}"
    );
    assert!(!err.contains("backtrace") && !err.contains("\n"), "{err}");
}

/// The trace head (the approach's history, `grasp_model::trace`): what
/// `hannes-run` computes frame by frame equals what evaluation computes over
/// the whole video from the trainer's feature cache, a new approach forgets
/// the last, and the history changes the answer.
#[test]
fn a_trace_head_runs_frame_by_frame_as_evaluation_reads_the_video() {
    use trainer::data::{BadData, OnBadData};
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let (ckpt, cfg) = train_on_random_lite0(root, 6, |cfg| TrainConfig {
        head: grasp_model::heads::HeadKind::Trace,
        trace_s: 0.3,
        max_epochs: 2,
        ..cfg
    });
    let ckpt = &ckpt;
    let mut clf = runtime::model::load(ckpt).expect("hannes-run loads a trace head");
    assert_eq!(clf.meta.head.trace_s, Some(0.3));

    let bad = BadData::new(OnBadData::Fail);
    let data = trainer::data::reader::read_dataset(&root.join("data"), &cfg.reader, &bad).unwrap();
    let cache = trainer::features::FeatureCache::new(&cfg.cache_dir, 8);
    let videos = trainer::eval::predict::predict_dataset(&clf, &data, &cache, &bad).unwrap();
    let (seq, video) = (&data.sequences[0], &videos[0]);
    assert_eq!(video.probs.len(), seq.frames.len());

    let frames: Vec<image::RgbImage> = (0..seq.frames.len())
        .map(|i| seq.load_frame(i, &bad).unwrap().unwrap())
        .collect();
    let stream = |clf: &mut grasp_model::checkpoint::Classifier| -> Vec<[f32; 5]> {
        clf.begin_approach();
        frames
            .iter()
            .zip(&video.times_s)
            .map(|(f, t)| clf.classify(f, *t).unwrap())
            .collect()
    };
    let streamed = stream(&mut clf);
    for (i, (a, b)) in streamed.iter().zip(&video.probs).enumerate() {
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() < 1e-5, "frame {i}: {a:?} against {b:?}");
        }
    }
    // A second approach starts afresh: the same answers again.
    assert_eq!(stream(&mut clf), streamed);
    // The first frame read after the whole video carries its history,
    // unlike the same frame as an approach's first.
    let t_last = video.times_s[frames.len() - 1];
    let after_history = {
        clf.begin_approach();
        for (f, t) in frames.iter().zip(&video.times_s) {
            clf.classify(f, *t).unwrap();
        }
        clf.classify(&frames[0], t_last + 0.05).unwrap()
    };
    let first_alone = {
        clf.begin_approach();
        clf.classify(&frames[0], 0.0).unwrap()
    };
    assert_ne!(after_history, first_alone, "the history changes the answer");
}
