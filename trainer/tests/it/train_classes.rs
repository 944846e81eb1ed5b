//! A training split that lacks a pre-shape is refused (issue 15, item 12):
//! it would train to "100 %" on one-class data. `no_grasp` frames, which
//! every sequence has, do not make it a second class.

use grasp_schema::taxonomy::{Class, Preshape};
use trainer::config::TrainConfig;
use trainer::stand_in::SmallSet;

fn config(set: &SmallSet, allow: bool) -> TrainConfig {
    TrainConfig {
        max_epochs: 1,
        allow_missing_classes: allow,
        ..set.config(if allow { "allowed" } else { "refused" })
    }
}

#[test]
fn a_split_without_some_pre_shapes_is_refused_naming_them() {
    let dir = tempfile::tempdir().unwrap();
    // Power only (a can and a mug body), each sequence ending in no_grasp.
    let set = SmallSet::generated(dir.path(), |spec| {
        spec.objects.truncate(2);
        spec.objects[1].2.truncate(1);
        spec.sequences_per_part = 6;
    })
    .unwrap();

    let err = trainer::experiment::run(&config(&set, false), 1)
        .err()
        .expect("a power-only training set was accepted");
    let text = format!("{err:#}");
    assert!(text.contains("has sequences of power only"), "{text}");
    assert!(
        text.contains("no training sequence of lateral, pinch, pinch3"),
        "{text}"
    );
    assert!(text.contains("allow_missing_classes"), "{text}");
    assert!(!dir.path().join("refused/seed-0").exists());

    // Told otherwise, it trains (and its frames do hold two labels).
    let out = trainer::experiment::run(&config(&set, true), 1).unwrap();
    assert_eq!(out.runs.len(), 1);
    let data = trainer::data::read_dataset(
        &dir.path().join("data"),
        &Default::default(),
        &trainer::data::BadData::new(trainer::data::OnBadData::Fail),
    )
    .unwrap();
    let c = trainer::data::coverage::coverage(&data);
    assert_eq!(c.present, vec![Preshape::Power]);
    assert!(c.no_grasp_frames > 0);
    assert!(data
        .sequences
        .iter()
        .all(|s| s.labels.contains(&Class::NoGrasp)));
}

#[test]
fn every_pre_shape_present_trains() {
    let dir = tempfile::tempdir().unwrap();
    let set = SmallSet::generated(dir.path(), |_| {}).unwrap();
    let data = trainer::data::read_dataset(
        &set.data(),
        &Default::default(),
        &trainer::data::BadData::new(trainer::data::OnBadData::Fail),
    )
    .unwrap();
    let c = trainer::data::coverage::check_training_classes(&data, false).unwrap();
    assert!(c.missing.is_empty());
    assert_eq!(c.present.len(), 4);
}
