//! Per-part reports, frame windows and the centre crop through the real
//! evaluation path (frozen stand-in backbone, FC head, generated images):
//! the mug's parts get their own rows, a window scores fewer frames, and a
//! run trained on centre crops evaluates on centre crops.

use std::path::Path;
use trainer::config::TrainConfig;
use trainer::data::{BadData, OnBadData};
use trainer::eval::metrics::FrameWindow;

use trainer::stand_in::SmallSet;

/// The generated set, 5 sequences per part, and a random MobileNetV2
/// (width 0.25) calibrated on 20 of its frames.
fn setup(dir: &Path) -> TrainConfig {
    let set = SmallSet::generated(dir, |s| s.sequences_per_part = 5).unwrap();
    let set = set.random_mobilenet(0.25, 20).unwrap();
    let mut cfg = TrainConfig {
        batch_size: Some(16),
        max_epochs: 4,
        ..set.config("run")
    };
    cfg.split.val_fraction = 0.2;
    cfg.split.test_fraction = 0.4;
    cfg
}

fn cache_entries(dir: &Path) -> usize {
    walk(dir)
}

fn walk(dir: &Path) -> usize {
    std::fs::read_dir(dir)
        .map(|it| {
            it.filter_map(Result::ok)
                .map(|e| {
                    let p = e.path();
                    if p.is_dir() {
                        walk(&p)
                    } else {
                        usize::from(p.extension().is_some_and(|x| x == "safetensors"))
                    }
                })
                .sum()
        })
        .unwrap_or(0)
}

#[test]
fn parts_windows_and_center_crop_through_evaluation() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = setup(dir.path());
    let outcome = trainer::experiment::run(&cfg, 1).unwrap();
    let report = outcome.report.unwrap();
    // The synthetic mug has a body (power) and a handle (lateral): a row
    // each, with the test split's videos of that part.
    let parts: Vec<(&str, &str)> = report
        .per_part
        .iter()
        .map(|p| (p.object.as_str(), p.part.as_str()))
        .collect();
    assert_eq!(parts, vec![("025_mug", "body"), ("025_mug", "handle")]);
    assert!(report.per_part.iter().all(|p| p.videos == 2));
    let md = std::fs::read_to_string(cfg.out.join("report/report.md")).unwrap();
    assert!(md.contains("| 025_mug | handle | lateral | 2 |"), "{md}");

    // A window keeps fewer frames, and the report says which.
    let bad = BadData::new(OnBadData::Fail);
    let test = trainer::experiment::test_split_of(&outcome.runs[0].checkpoint, &bad).unwrap();
    let ckpts = vec![outcome.runs[0].checkpoint.clone()];
    let window = FrameWindow {
        before_tail_s: Some(0.2),
        ..Default::default()
    };
    let scoring = trainer::eval::metrics::Scoring {
        window,
        ..Default::default()
    };
    let w =
        trainer::experiment::evaluate(&ckpts, &test, &cfg.cache_dir, 8, &bad, &scoring).unwrap();
    let all = &report.runs[0].metrics;
    let some = &w.runs[0].metrics;
    assert_eq!(some.videos, all.videos);
    assert!(some.frames < all.frames && some.frames > 0);
    assert_eq!(some.grasp_frames, some.frames, "only pre-shape frames");
    assert_eq!(w.window, window);
    trainer::eval::write_report(&w, &dir.path().join("windowed")).unwrap();
    let md = std::fs::read_to_string(dir.path().join("windowed/report.md")).unwrap();
    assert!(
        md.contains("the last 0.20 s before the no_grasp tail"),
        "{md}"
    );

    // Trained on centre crops: the crop is in the run's reader options, the
    // test split is read with it, and its features are cached apart.
    let before = cache_entries(&cfg.cache_dir);
    let mut crop = cfg.clone();
    crop.out = dir.path().join("crop");
    crop.reader.crop = grasp_model::input::Crop::Fraction(0.5);
    let c = trainer::experiment::run(&crop, 1).unwrap();
    assert!(
        cache_entries(&cfg.cache_dir) >= 2 * before,
        "cropped features cached apart"
    );
    let test = trainer::experiment::test_split_of(&c.runs[0].checkpoint, &bad).unwrap();
    assert!(test
        .sequences
        .iter()
        .all(|s| s.crop == grasp_model::input::Crop::Fraction(0.5)));
    let mut bad_crop = cfg.clone();
    bad_crop.reader.crop = grasp_model::input::Crop::Fraction(1.5);
    bad_crop.out = dir.path().join("bad");
    let err = format!(
        "{:#}",
        trainer::experiment::run(&bad_crop, 1).err().unwrap()
    );
    assert!(err.contains("crop.fraction"), "{err}");
}
