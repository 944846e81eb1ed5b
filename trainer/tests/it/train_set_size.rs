//! `sequences_per_pair`: the training split keeps at most N sequences of
//! every object-part pair, validation and test are untouched, and the cap is
//! recorded in the run's config, its checkpoints and its report.

use trainer::config::TrainConfig;
use trainer::data::split::Split;
use trainer::stand_in::SmallSet;

#[test]
fn sequences_per_pair_caps_training_only_and_is_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let set = SmallSet::generated(dir.path(), |spec| {
        spec.sequences_per_part = 7;
        spec.frames = 6;
    })
    .unwrap();
    let cfg = |out: &str, cap: Option<usize>| TrainConfig {
        max_epochs: 1,
        sequences_per_pair: cap,
        ..set.config(out)
    };
    trainer::experiment::run(&cfg("full", None), 1).unwrap();
    let out = trainer::experiment::run(&cfg("capped", Some(2)), 1).unwrap();
    let full = Split::load(&dir.path().join("full/split.json")).unwrap();
    let capped = Split::load(&dir.path().join("capped/split.json")).unwrap();
    // 5 object-part pairs of 7 sequences: 1 val, 1 test, 5 train each.
    assert_eq!(full.train.len(), 25);
    assert_eq!(capped.train.len(), 10);
    assert!(capped.train.iter().all(|id| full.train.contains(id)));
    assert_eq!((&capped.val, &capped.test), (&full.val, &full.test));
    let pair = |id: &str| id.split('/').take(3).collect::<Vec<_>>().join("/");
    let mut pairs: Vec<String> = capped.train.iter().map(|id| pair(id)).collect();
    pairs.sort();
    pairs.dedup();
    assert_eq!(pairs.len(), 5, "{:?}", capped.train);

    let saved = TrainConfig::from_toml_file(&dir.path().join("capped/config.toml")).unwrap();
    assert_eq!(saved.sequences_per_pair, Some(2));
    let report = out.report.unwrap();
    assert_eq!(report.sequences_per_pair, Some(2));
    assert_eq!(report.train_sequences, Some(10));
    let md = std::fs::read_to_string(dir.path().join("capped/report/report.md")).unwrap();
    assert!(
        md.contains("Training set: 10 sequences (at most 2 per object-part pair)"),
        "{md}"
    );
    assert!(TrainConfig {
        sequences_per_pair: Some(0),
        ..cfg("zero", None)
    }
    .validate()
    .is_err());
}
