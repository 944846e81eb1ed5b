//! Both heads learn, with the paper's protocol, on generated per-frame
//! features: each class has its own mean vector, frames add Gaussian noise of
//! the same scale, and sequences look like the data's (eight frames of the
//! pre-shape, then two `no_grasp`). Chance is 1/5 per frame.

use candle_core::{Device, Tensor};
use grasp_model::checkpoint::TrainMode;
use grasp_model::heads::HeadKind;
use rand::Rng;
use trainer::config::{Selection, TrainConfig};
use trainer::plan::FitPlan;
use trainer::train::{FrameSource, Prepared, SplitFrames};

const DIM: usize = 64;
const FRAMES: usize = 10;

fn split(sequences: usize, seed: u64, means: &[Vec<f32>], noise: f32) -> SplitFrames {
    let mut rng = trainer::rng::stream(seed, "features");
    let (mut x, mut labels, mut seq_rows, mut seq_class, mut seq_ids) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for s in 0..sequences {
        let class = (s % 4) as u32;
        let mut rows = Vec::new();
        for f in 0..FRAMES {
            let label = if f >= FRAMES - 2 { 4 } else { class };
            rows.push(labels.len());
            labels.push(label);
            for m in &means[label as usize] {
                x.push(m + rng.gen_range(-noise..noise));
            }
        }
        seq_rows.push(rows);
        seq_class.push(class);
        seq_ids.push(format!("seq{s}"));
    }
    let n = labels.len();
    // Frames at 2.5 frames/s, the generator's default rate.
    let seq_times = vec![(0..FRAMES).map(|f| f as f64 / 2.5).collect(); sequences];
    SplitFrames {
        labels,
        seq_rows,
        seq_times,
        seq_class,
        seq_ids,
        source: FrameSource::Cached(Tensor::from_vec(x, (n, DIM), &Device::Cpu).unwrap()),
    }
}

/// `train` sequences of noise `noise` (and 12 validation sequences).
fn prepared(train: usize, noise: f32) -> Prepared {
    let mut rng = trainer::rng::stream(3, "means");
    let means: Vec<Vec<f32>> = (0..5)
        .map(|_| (0..DIM).map(|_| rng.gen_range(-1.0f32..1.0)).collect())
        .collect();
    Prepared {
        train: split(train, 1, &means, noise),
        val: split(12, 2, &means, noise),
        real_data: false,
        train_sequences: train,
        backbone: Some(grasp_model::backbone::BackboneInfo::generated(
            "generated-features",
        )),
        feature_dim: DIM,
        preprocess: grasp_model::backbone::Preprocess::imagenet(224),
        tail: None,
        damping: None,
        step_hz: None,
    }
}

fn config(dir: &std::path::Path, head: HeadKind) -> TrainConfig {
    TrainConfig {
        data: dir.into(),
        mode: TrainMode::FrozenPretrained,
        head,
        batch_size: Some(if head == HeadKind::Fc { 32 } else { 4 }),
        max_epochs: 15,
        ..Default::default()
    }
}

fn learn(head: HeadKind) -> f64 {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(dir.path(), head);
    let out = trainer::train::train(
        &FitPlan::of(&cfg).unwrap(),
        &prepared(40, 1.5),
        0,
        &dir.path().join("run"),
    )
    .unwrap();
    let best = &out.history[out.best_epoch - 1];
    assert!(dir.path().join("run/best.safetensors").is_file());
    assert!(out.history[0].val_loss > best.val_loss);
    best.val_accuracy
}

/// The epoch a finished run's checkpoint says it holds.
fn saved_epoch(run: &std::path::Path) -> usize {
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("best.json")).unwrap()).unwrap();
    meta["epoch"].as_u64().unwrap() as usize
}

#[test]
fn fc_head_beats_chance() {
    let acc = learn(HeadKind::Fc);
    assert!(acc > 0.6, "validation frame accuracy {acc}");
}

#[test]
fn lstm_head_beats_chance() {
    let acc = learn(HeadKind::Lstm);
    assert!(acc > 0.6, "validation frame accuracy {acc}");
}

/// Each selection keeps the epoch its rule names, and says so in the
/// checkpoint and the outcome.
#[test]
fn selection_keeps_the_epoch_its_rule_names() {
    // Few, noisy sequences and a high rate: the head overfits, so validation loss and
    // accuracy peak at different epochs.
    let prep = prepared(8, 3.0);
    let dir = tempfile::tempdir().unwrap();
    let mut kept = Vec::new();
    for select in [Selection::ValLoss, Selection::ValAccuracy, Selection::Last] {
        let cfg = TrainConfig {
            select,
            optimizer: trainer::optim::AdamConfig {
                lr: 5e-2,
                ..Default::default()
            },
            ..config(dir.path(), HeadKind::Fc)
        };
        let run = dir.path().join(format!("{select:?}"));
        let out = trainer::train::train(&FitPlan::of(&cfg).unwrap(), &prep, 0, &run).unwrap();
        let h = &out.history;
        let expected = match select {
            Selection::ValLoss => {
                let min = h.iter().map(|e| e.val_loss).fold(f64::INFINITY, f64::min);
                h.iter()
                    .position(|e| e.val_loss <= min * (1.0 + 1e-4))
                    .unwrap()
                    + 1
            }
            Selection::ValAccuracy => {
                let max = h.iter().map(|e| e.val_accuracy).fold(0.0, f64::max);
                h.iter().rposition(|e| e.val_accuracy == max).unwrap() + 1
            }
            Selection::Last => h.len(),
        };
        assert_eq!(out.best_epoch, expected, "{select:?}");
        assert_eq!(saved_epoch(&run), expected, "{select:?}");
        assert_eq!(out.best_val_loss, h[expected - 1].val_loss, "{select:?}");
        kept.push(expected);
    }
    kept.dedup();
    assert!(kept.len() > 1, "the rules should disagree here: {kept:?}");
}

/// `lstm_start_crop` trains the LSTM on sequences started at a random frame
/// of their first half: fewer frames per epoch than whole sequences (each
/// of the 40 ten-frame sequences keeps 5 to 10), the same draws on a rerun,
/// and a head that still learns.
#[test]
fn lstm_start_crop_trains_on_later_starts_and_repeats() {
    let prep = prepared(40, 1.5);
    let dir = tempfile::tempdir().unwrap();
    let whole = config(dir.path(), HeadKind::Lstm);
    let cropped = TrainConfig {
        lstm_start_crop: 0.5,
        ..whole.clone()
    };
    let run = |cfg: &TrainConfig, name: &str| {
        trainer::train::train(&FitPlan::of(cfg).unwrap(), &prep, 0, &dir.path().join(name)).unwrap()
    };
    let (a, b, w) = (run(&cropped, "a"), run(&cropped, "b"), run(&whole, "w"));
    let frames = |o: &trainer::train::TrainOutcome| -> Vec<usize> {
        o.history.iter().map(|e| e.train_frames).collect()
    };
    assert_eq!(frames(&a), frames(&b));
    assert_eq!(
        a.history.iter().map(|e| e.train_loss).collect::<Vec<_>>(),
        b.history.iter().map(|e| e.train_loss).collect::<Vec<_>>()
    );
    assert!(
        frames(&w).iter().all(|n| *n == 40 * FRAMES),
        "{:?}",
        frames(&w)
    );
    for n in frames(&a) {
        assert!((40 * 5..40 * FRAMES).contains(&n), "{n} frames in an epoch");
    }
    let best = &a.history[a.best_epoch - 1];
    assert!(
        best.val_accuracy > 0.6,
        "validation frame accuracy {}",
        best.val_accuracy
    );
}
