//! hannes-run loads a classifier whose frozen backbone is EfficientNet-Lite0
//! (the trainer's default) and classifies frames with it. The backbone is a
//! random Lite0 written here, so the test does not depend on the venv; the
//! architecture, the preprocessing and the loading path are the real ones.

use grasp_model::backbone::{Architecture, ResizeFilter};
use runtime::classifier::FrameClassifier;
use trainer::data::synthetic::{write_synthetic, Layout, SyntheticSpec};

#[test]
fn a_lite0_checkpoint_loads_and_classifies_frames() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let mut spec = SyntheticSpec::small(Layout::Generated);
    spec.sequences_per_part = 2;
    spec.frames = 4;
    spec.no_grasp_frames = 1;
    write_synthetic(&root.join("data"), &spec).unwrap();
    let weights = root.join("lite0.safetensors");
    trainer::init::write_random_lite(&weights, grasp_model::networks::LiteVariant::Lite0, 3)
        .unwrap();
    let mut cfg = trainer::config::TrainConfig {
        data: root.join("data"),
        out: root.join("run"),
        weights: Some(weights),
        input_size: 40,
        max_epochs: 1,
        cache_dir: root.join("cache"),
        ..Default::default()
    };
    cfg.split.val_fraction = 0.34;
    cfg.split.test_fraction = 0.0;
    let outcome = trainer::experiment::run(&cfg, 1).unwrap();
    let ckpt = &outcome.runs[0].checkpoint;

    let mut clf = runtime::model::load(ckpt).unwrap();
    assert_eq!(clf.meta.backbone.arch, Architecture::EfficientNetLite0);
    assert_eq!(clf.meta.input.preprocess.resize, ResizeFilter::Bicubic);
    assert_eq!(clf.meta.input.preprocess.size, 40);
    // frames of another size are resized as recorded
    let frame = image::RgbImage::from_fn(64, 48, |x, y| image::Rgb([x as u8, y as u8, 90]));
    let p = clf.classify(&frame).unwrap();
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
