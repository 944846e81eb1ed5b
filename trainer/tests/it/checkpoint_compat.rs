//! Checkpoints record their backbone's architecture and preprocessing
//! (format 2); format-1 checkpoints, from before EfficientNet-Lite, have
//! neither and still load as MobileNetV2 with bilinear resizing.

use grasp_model::backbone::{Architecture, ResizeFilter};
use grasp_model::checkpoint::{Classifier, FORMAT_VERSION, META_FILE};
use trainer::config::TrainConfig;
use trainer::data::synthetic::class_image;
use trainer::stand_in::SmallSet;

#[test]
fn format_1_checkpoints_load_as_mobilenet_v2() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let set = SmallSet::generated(root, |spec| {
        spec.sequences_per_part = 2;
        spec.frames = 4;
        spec.no_grasp_frames = 1;
    })
    .unwrap();
    let set = set.random_mobilenet(0.25, 0).unwrap();
    let mut cfg = TrainConfig {
        max_epochs: 1,
        ..set.config("run")
    };
    cfg.split.val_fraction = 0.34;
    cfg.split.test_fraction = 0.0;
    let out = trainer::experiment::run(&cfg, 1).unwrap();
    let ckpt = out.runs[0].checkpoint.clone();
    let json_path = ckpt.join(META_FILE);
    let text = std::fs::read_to_string(&json_path).unwrap();
    let mut meta: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(meta["format_version"], FORMAT_VERSION);
    assert_eq!(meta["backbone"]["arch"], "mobilenet-v2");
    // the saved config says which backbone ran
    let saved = std::fs::read_to_string(root.join("run/config.toml")).unwrap();
    assert!(saved.contains("backbone = \"mobilenet-v2\""), "{saved}");

    let mut rng = trainer::rng::stream(5, "frames");
    let frames: Vec<_> = grasp_schema::taxonomy::Class::ALL
        .iter()
        .map(|c| class_image(*c, 48, 0.1, &mut rng))
        .collect();
    let now = Classifier::load(&ckpt, &candle_core::Device::Cpu).unwrap();
    let expected = now.predict(&frames).unwrap();

    // what a format-1 build wrote
    meta["format_version"] = 1.into();
    meta["backbone"].as_object_mut().unwrap().remove("arch");
    let input = meta.as_object_mut().unwrap().remove("input").unwrap();
    assert!(input["preprocess"].get("resize").is_none());
    meta["preprocessing"] = input["preprocess"].clone();
    std::fs::write(&json_path, serde_json::to_string_pretty(&meta).unwrap()).unwrap();
    let old = Classifier::load(&ckpt, &candle_core::Device::Cpu).unwrap();
    assert_eq!(old.meta.backbone.arch, Architecture::MobileNetV2);
    assert_eq!(old.meta.input.preprocess.resize, ResizeFilter::Bilinear);
    assert_eq!(old.predict(&frames).unwrap(), expected);

    // a future format is refused with the versions this build reads
    meta["format_version"] = (FORMAT_VERSION + 1).into();
    std::fs::write(&json_path, serde_json::to_string(&meta).unwrap()).unwrap();
    let msg = format!(
        "{:#}",
        Classifier::load(&ckpt, &candle_core::Device::Cpu)
            .err()
            .expect("a newer format must not load")
    );
    assert!(msg.contains("format_version"), "{msg}");
}
