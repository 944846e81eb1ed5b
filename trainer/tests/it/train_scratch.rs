//! From-scratch mode (no pretrained weights): the whole MobileNetV2 is
//! trained, with augmentation, at a small width and input size; the
//! checkpoint carries the backbone and every report names the mode.

use grasp_model::checkpoint::{Classifier, TrainMode};
use trainer::config::TrainConfig;
use trainer::data::synthetic::{Layout, SyntheticSpec};
use trainer::stand_in::SmallSet;

#[test]
fn from_scratch_trains_the_backbone_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    // The authors' layout: labels from folders (real-data batch size 32).
    let mut spec = SyntheticSpec::small(Layout::Authors);
    spec.sequences_per_part = 3;
    let set = SmallSet::write(dir.path(), spec).unwrap();
    let mut cfg = TrainConfig {
        max_epochs: 8,
        ..set.config("run")
    };
    cfg.reader.real_fps = 4.0; // 0.5 s = the last 2 of 10 frames
    cfg.optimizer.lr = 5e-3;
    let out = trainer::experiment::run(&cfg, 1).unwrap();
    let h = &out.runs[0].history;
    // Tiny batches with augmentation and batch norm in training mode make
    // single epochs (and the training loss) noisy: compare the accuracy of
    // the last three epochs with the first. The validation loss of 25
    // frames is no signal at this size: on an AVX2 machine it rose over the
    // 8 epochs at every learning rate tried (1e-3 to 5e-3), where earlier
    // CI machines saw it fall.
    let last3 = |f: fn(&trainer::train::EpochStats) -> f64| {
        h[h.len() - 3..].iter().map(f).sum::<f64>() / 3.0
    };
    assert!(last3(|e| e.train_accuracy) > h[0].train_accuracy, "{h:?}");
    assert!(h.iter().all(|e| e.val_loss.is_finite()), "{h:?}");
    let report = out.report.unwrap();
    assert_eq!(report.mode, "from-scratch");
    let md = std::fs::read_to_string(cfg.out.join("report/report.md")).unwrap();
    assert!(md.contains("**Mode: from-scratch**"));

    let clf = Classifier::load(&out.runs[0].checkpoint, &candle_core::Device::Cpu).unwrap();
    assert_eq!(clf.meta.mode, TrainMode::FromScratch);
    assert!(clf.meta.backbone.weights_path.is_none());
    let frame = trainer::data::synthetic::class_image(
        grasp_schema::taxonomy::Class::Pinch,
        32,
        0.0,
        &mut trainer::rng::stream(0, "x"),
    );
    let p = clf.predict(&[frame]).unwrap();
    assert!((p[0].iter().sum::<f32>() - 1.0).abs() < 1e-4);
}
