//! Fine-tuned mode (`--mode fine-tuned`): EfficientNet-Lite's last blocks
//! train with the head on cached activations of the blocks before them; the
//! checkpoint carries them as `tail.*`, and the classifier (the runtime's)
//! runs the pretrained blocks followed by the tuned ones.

use candle_core::{DType, Device, Tensor};
use candle_nn::VarBuilder;
use grasp_model::backbone::{Architecture, Backbone, BackboneInfo};
use grasp_model::checkpoint::{Classifier, TrainMode};
use grasp_model::extractor::FeatureExtractor;
use grasp_model::networks::LiteTail;
use std::path::Path;
use trainer::config::TrainConfig;
use trainer::stand_in::SmallSet;

fn cfg(set: &SmallSet) -> TrainConfig {
    let mut cfg = TrainConfig {
        mode: TrainMode::FineTuned,
        input_size: 64,
        batch_size: Some(16),
        max_epochs: 2,
        ..set.config("tuned")
    };
    cfg.fine_tune.blocks = 2;
    cfg.fine_tune.lr = 1e-2;
    cfg
}

/// The generated set, 3 sequences per part, and random EfficientNet-Lite0
/// weights beside it.
fn data_and_weights(root: &Path) -> SmallSet {
    let set = SmallSet::generated(root, |spec| spec.sequences_per_part = 3).unwrap();
    set.random_lite0(7).unwrap()
}

fn frames() -> Vec<image::RgbImage> {
    (0..3)
        .map(|i| {
            trainer::data::synthetic::class_image(
                grasp_schema::taxonomy::Class::ALL[i],
                80,
                5.0,
                &mut trainer::rng::stream(i as u64, "frames"),
            )
        })
        .collect()
}

fn values(t: &Tensor) -> Vec<f32> {
    t.flatten_all().unwrap().to_vec1().unwrap()
}

#[test]
fn tuned_blocks_travel_in_the_checkpoint_and_run_at_inference() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let set = data_and_weights(root);
    let weights = set.weights().unwrap().to_path_buf();

    let cfg = cfg(&set);
    let run = trainer::experiment::run(&cfg, 1).unwrap();
    let ckpt = &run.runs[0].checkpoint;

    // Only the head and the last two blocks (14, 15) plus the head
    // convolution are saved.
    let dev = Device::Cpu;
    let saved = candle_core::safetensors::load(ckpt.join("best.safetensors"), &dev).unwrap();
    assert!(saved
        .keys()
        .all(|k| k.starts_with("head.") || k.starts_with("tail.")));
    for name in [
        "tail._blocks.14._expand_conv.weight",
        "tail._blocks.15._project_conv.bias",
        "tail._conv_head.weight",
    ] {
        assert!(
            saved.contains_key(name),
            "{name} missing: {:?}",
            saved.keys()
        );
    }
    assert!(!saved.keys().any(|k| k.contains("_blocks.13.")));

    // Training moved the tuned blocks away from the pretrained ones.
    let info = BackboneInfo::pretrained(&weights, Architecture::EfficientNetLite0, 1.0).unwrap();
    let pre = Architecture::EfficientNetLite0.preprocess(64);
    let pretrained = Backbone::load_pretrained(&info, pre, &dev).unwrap();
    let lite = trainer::train::lite(&pretrained).unwrap();
    let start: std::collections::HashMap<String, Tensor> =
        lite.tail_tensors(14).into_iter().collect();
    let w = "_conv_head.weight";
    let moved = (&saved[&format!("tail.{w}")] - &start[w]).unwrap();
    let moved: f32 = moved
        .abs()
        .unwrap()
        .max_keepdim(0)
        .unwrap()
        .max_all()
        .unwrap()
        .to_scalar()
        .unwrap();
    assert!(moved > 1e-4, "the head convolution did not train ({moved})");

    // The classifier runs the pretrained blocks, then the tuned ones: its
    // features are the training module's on the same activations, and not
    // the pretrained network's.
    let clf = Classifier::load(ckpt, &dev).unwrap();
    assert_eq!(clf.meta.mode, TrainMode::FineTuned);
    assert_eq!(clf.meta.backbone.tuned.as_ref().unwrap().from_block, 14);
    let images = frames();
    let x = pretrained.input(&images).unwrap();
    let acts = lite.feature_map_until(&x, 14).unwrap();
    let vb = unsafe {
        VarBuilder::from_mmaped_safetensors(&[ckpt.join("best.safetensors")], DType::F32, &dev)
    }
    .unwrap();
    let tail = LiteTail::new(&vb.pp("tail"), &lite.tail_layout(14)).unwrap();
    let expected = values(&tail.forward(&acts).unwrap());
    let got = values(&clf.backbone().extract(&images).unwrap());
    let frozen = values(&pretrained.extract(&images).unwrap());
    let largest = frozen.iter().fold(0f32, |m, v| m.max(v.abs()));
    assert!(
        largest > 1e-2,
        "features vanished ({largest}): the comparisons would be vacuous"
    );
    let close = |a: &[f32], b: &[f32]| {
        a.iter()
            .zip(b)
            .all(|(a, b)| (a - b).abs() <= 1e-4 * (1.0 + b.abs()))
    };
    assert!(close(&got, &expected));
    assert!(!close(&got, &frozen), "the tuned blocks were not loaded");

    // Its features are cached apart from the pretrained ones and from the
    // training activations, and the report names the mode.
    assert_ne!(clf.backbone().id(), pretrained.id());
    let report = run.report.unwrap();
    assert_eq!(report.mode, "fine-tuned");
    assert!(
        report.backbone.contains("fine-tuned"),
        "{}",
        report.backbone
    );

    // The same seed trains the same tensors.
    let mut again = cfg.clone();
    again.out = root.join("again");
    let rerun = trainer::experiment::run(&again, 1).unwrap();
    let reread =
        candle_core::safetensors::load(rerun.runs[0].checkpoint.join("best.safetensors"), &dev)
            .unwrap();
    assert_eq!(reread.len(), saved.len());
    for (name, t) in &saved {
        assert_eq!(
            values(t),
            values(&reread[name]),
            "{name} differs between runs"
        );
    }

    // The same checkpoint serves as a frozen backbone, tuned blocks included.
    let (as_backbone, _) = BackboneInfo::from_checkpoint(ckpt).unwrap();
    let reused =
        Backbone::load_pretrained(&as_backbone, clf.meta.input.preprocess.clone(), &dev).unwrap();
    assert!(close(&values(&reused.extract(&images).unwrap()), &expected));
}

#[test]
fn fine_tuning_refuses_what_it_cannot_tune() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let set = SmallSet::generated(root, |_| {}).unwrap();
    let set = set.random_lite0(7).unwrap();

    let mut too_many = cfg(&set);
    too_many.fine_tune.blocks = 17;
    let err = format!(
        "{:#}",
        trainer::experiment::run(&too_many, 1).err().unwrap()
    );
    assert!(err.contains("16 blocks"), "{err}");

    let mut none = cfg(&set);
    none.fine_tune.blocks = 0;
    let err = format!("{:#}", none.validate().err().unwrap());
    assert!(err.contains("blocks must be at least 1"), "{err}");

    let mut scratch = cfg(&set);
    scratch.mode = TrainMode::FromScratch;
    scratch.pooled_blocks = vec![15];
    let err = format!("{:#}", scratch.validate().err().unwrap());
    assert!(err.contains("pooled_blocks"), "{err}");

    let mut mobilenet = cfg(&set);
    mobilenet.backbone = Some(Architecture::MobileNetV2);
    let err = format!("{:#}", mobilenet.validate().err().unwrap());
    assert!(err.contains("EfficientNet-Lite"), "{err}");
}

/// A linear probe (`probe_epochs`) trains the head alone before the blocks
/// tune: fine-tuning's first epoch then starts from a head that reads the
/// features, and the probe itself leaves the blocks as they were.
#[test]
fn a_linear_probe_trains_the_head_before_the_blocks() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let set = data_and_weights(root);
    let weights = set.weights().unwrap().to_path_buf();
    let first_epoch = |probe: usize, tune_lr: f64, out: &str| {
        let mut cfg = cfg(&set);
        cfg.out = root.join(out);
        cfg.max_epochs = 1;
        cfg.optimizer.lr = 1e-2; // a probe of a few batches an epoch
        cfg.fine_tune.probe_epochs = probe;
        cfg.fine_tune.lr = tune_lr;
        let run = trainer::experiment::run(&cfg, 1).unwrap();
        let out = &run.runs[0];
        (out.history[0].train_loss, out.checkpoint.clone())
    };
    let (unprobed, _) = first_epoch(0, 1e-4, "unprobed");
    let (probed, _) = first_epoch(20, 1e-4, "probed");
    assert!(
        probed < 0.8 * unprobed,
        "first epoch's loss {probed} after the probe, {unprobed} without"
    );

    // With the blocks' rate at 1e-30 only the probe and the head train: the
    // saved blocks are the pretrained ones (the probe, at the head's 1e-2,
    // would have moved them by far more).
    let (_, ckpt) = first_epoch(20, 1e-30, "blocks-still");
    let dev = Device::Cpu;
    let saved = candle_core::safetensors::load(ckpt.join("best.safetensors"), &dev).unwrap();
    let info = BackboneInfo::pretrained(&weights, Architecture::EfficientNetLite0, 1.0).unwrap();
    let pretrained =
        Backbone::load_pretrained(&info, Architecture::EfficientNetLite0.preprocess(64), &dev)
            .unwrap();
    for (name, t) in trainer::train::lite(&pretrained).unwrap().tail_tensors(14) {
        let (got, want) = (values(&saved[&format!("tail.{name}")]), values(&t));
        let worst = got
            .iter()
            .zip(&want)
            .map(|(g, w)| (g - w).abs())
            .fold(0f32, f32::max);
        assert!(worst < 1e-12, "{name} moved by {worst}");
    }
}

#[test]
fn pooled_blocks_travel_in_the_checkpoint_in_both_modes() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let set = data_and_weights(root);
    let weights = set.weights().unwrap().to_path_buf();
    let dev = Device::Cpu;
    let images = frames();
    // Lite0's blocks 13 and 15 have 192 and 320 channels
    let dim = 1280 + 192 + 320;

    // Fine-tuned from block 14: block 13 is the cached input, 15 is tuned.
    let mut tuned = cfg(&set);
    tuned.pooled_blocks = vec![13, 15];
    let run = trainer::experiment::run(&tuned, 1).unwrap();
    let clf = Classifier::load(&run.runs[0].checkpoint, &dev).unwrap();
    assert_eq!(clf.meta.backbone.pooled_blocks, [13, 15]);
    let got = clf.backbone().extract(&images).unwrap();
    assert_eq!(got.dims(), [3, dim]);
    let info = BackboneInfo::pretrained(&weights, Architecture::EfficientNetLite0, 1.0).unwrap();
    let pre = Architecture::EfficientNetLite0.preprocess(64);
    let pretrained = Backbone::load_pretrained(&info, pre.clone(), &dev).unwrap();
    let lite = trainer::train::lite(&pretrained).unwrap();
    let acts = lite
        .feature_map_until(&pretrained.input(&images).unwrap(), 14)
        .unwrap();
    let ckpt = run.runs[0].checkpoint.join("best.safetensors");
    let vb = unsafe { VarBuilder::from_mmaped_safetensors(&[ckpt], DType::F32, &dev) }.unwrap();
    let tail = LiteTail::new(&vb.pp("tail"), &lite.tail_layout(14))
        .unwrap()
        .with_pooled_blocks(14, &[13, 15])
        .unwrap();
    let expected = values(&tail.forward(&acts).unwrap());
    let got = values(&got);
    assert!(
        expected.iter().any(|v| v.abs() > 1e-2),
        "vacuous comparison"
    );
    assert!(got
        .iter()
        .zip(&expected)
        .all(|(a, b)| (a - b).abs() <= 1e-4 * (1.0 + b.abs())));

    // Frozen: the head trains on the longer features and the classifier
    // computes them.
    let mut frozen = cfg(&set);
    frozen.mode = TrainMode::FrozenPretrained;
    frozen.out = root.join("frozen");
    frozen.pooled_blocks = vec![13, 15];
    let run = trainer::experiment::run(&frozen, 1).unwrap();
    let clf = Classifier::load(&run.runs[0].checkpoint, &dev).unwrap();
    assert_eq!(clf.backbone().extract(&images).unwrap().dims(), [3, dim]);
    assert!(run.report.unwrap().backbone.contains("pooled too"));
    // Without its pooled blocks on record the checkpoint is refused at
    // load, with both widths named.
    let json = run.runs[0].checkpoint.join("best.json");
    let mut meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    meta["backbone"]["pooled_blocks"] = serde_json::json!([]);
    std::fs::write(&json, meta.to_string()).unwrap();
    let err = Classifier::load(&run.runs[0].checkpoint, &dev)
        .err()
        .unwrap();
    let err = format!("{err:#}");
    assert!(
        err.contains("best.json")
            && err.contains(&format!("reads {dim} features"))
            && err.contains("gives 1280"),
        "{err}"
    );

    // A pooled block the activation cache does not hold is refused before
    // anything is cached.
    let mut early = cfg(&set);
    early.out = root.join("early");
    early.cache_dir = root.join("early-cache");
    early.pooled_blocks = vec![12, 15];
    let err = format!("{:#}", trainer::experiment::run(&early, 1).err().unwrap());
    assert!(err.contains("pooled block 12"), "{err}");
    assert!(!early.cache_dir.exists(), "activations were cached");
}
