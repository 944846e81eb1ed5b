//! Both heads learn, with the paper's protocol, on generated per-frame
//! features: each class has its own mean vector, frames add Gaussian noise of
//! the same scale, and sequences look like the data's (eight frames of the
//! pre-shape, then two `no_grasp`). Chance is 1/5 per frame.

use candle_core::{Device, Tensor};
use grasp_model::checkpoint::TrainMode;
use grasp_model::heads::HeadKind;
use rand::Rng;
use trainer::config::TrainConfig;
use trainer::train::{FrameSource, Prepared, SplitFrames};

const DIM: usize = 64;
const FRAMES: usize = 10;

fn split(sequences: usize, seed: u64, means: &[Vec<f32>]) -> SplitFrames {
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
                x.push(m + rng.gen_range(-1.5f32..1.5));
            }
        }
        seq_rows.push(rows);
        seq_class.push(class);
        seq_ids.push(format!("seq{s}"));
    }
    let n = labels.len();
    SplitFrames {
        labels,
        seq_rows,
        seq_class,
        seq_ids,
        source: FrameSource::Cached(Tensor::from_vec(x, (n, DIM), &Device::Cpu).unwrap()),
    }
}

fn learn(head: HeadKind) -> f64 {
    let mut rng = trainer::rng::stream(3, "means");
    let means: Vec<Vec<f32>> = (0..5)
        .map(|_| (0..DIM).map(|_| rng.gen_range(-1.0f32..1.0)).collect())
        .collect();
    let prep = Prepared {
        train: split(40, 1, &means),
        val: split(12, 2, &means),
        real_data: false,
        train_sequences: 40,
        backbone: Some(grasp_model::backbone::BackboneInfo::generated(
            "generated-features",
        )),
        feature_dim: DIM,
        preprocess: grasp_model::backbone::Preprocess::imagenet(224),
        tail: None,
    };
    let dir = tempfile::tempdir().unwrap();
    let cfg = TrainConfig {
        data: dir.path().into(),
        mode: TrainMode::FrozenPretrained,
        head,
        batch_size: Some(if head == HeadKind::Fc { 32 } else { 4 }),
        max_epochs: 15,
        ..Default::default()
    };
    let out = trainer::train::train(&cfg, &prep, 0, &dir.path().join("run")).unwrap();
    let best = &out.history[out.best_epoch - 1];
    assert!(dir.path().join("run/best.safetensors").is_file());
    assert!(out.history[0].val_loss > best.val_loss);
    best.val_accuracy
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
