//! Numerical stability: the LSTM over very long sequences, gradients under
//! truncated back-propagation, and the non-finite guards of training.

use candle_core::{DType, Device, Tensor};
use candle_nn::VarBuilder;
use grasp_model::checkpoint::TrainMode;
use grasp_model::heads::{Head, HeadConfig, HeadKind};
use trainer::config::TrainConfig;
use trainer::plan::FitPlan;
use trainer::train::{FrameSource, Prepared, SplitFrames};

fn lstm(feature_dim: usize) -> (Head, candle_nn::VarMap) {
    let cfg = HeadConfig {
        kind: HeadKind::Lstm,
        feature_dim,
        classes: 5,
        lstm_hidden: 256,
        step_hz: None,
        trace_s: None,
    };
    let vm = trainer::init::head_varmap(&cfg, 0, &Device::Cpu).unwrap();
    let head = Head::new(cfg, VarBuilder::from_varmap(&vm, DType::F32, &Device::Cpu)).unwrap();
    (head, vm)
}

#[test]
fn lstm_runs_ten_thousand_steps_without_nan() {
    let (head, _) = lstm(16);
    // Large inputs saturate every gate: the state must stay bounded.
    let x = (Tensor::randn(0f32, 1.0, (2, 10_000, 16), &Device::Cpu).unwrap() * 1e4).unwrap();
    let logits = head.detached().forward_sequences(&x).unwrap();
    assert_eq!(logits.dims(), &[2, 10_000, 5]);
    let v: Vec<f32> = logits.flatten_all().unwrap().to_vec1().unwrap();
    assert!(v.iter().all(|x| x.is_finite()));
    let p = grasp_model::checkpoint::probabilities(&logits.get(0).unwrap()).unwrap();
    assert!(p.iter().all(|r| (r.iter().sum::<f32>() - 1.0).abs() < 1e-4));
}

#[test]
fn truncated_backprop_gradients_stay_finite_over_long_sequences() {
    let (head, vm) = lstm(16);
    let t = 1_000;
    let k = 100;
    let x = Tensor::randn(0f32, 3.0, (2, t, 16), &Device::Cpu).unwrap();
    let targets = Tensor::zeros(2 * k, DType::U32, &Device::Cpu).unwrap();
    let mut state = head.zero_state(2, &x).unwrap().unwrap();
    let mut total: Option<Tensor> = None;
    for start in (0..t).step_by(k) {
        let (logits, s) = head
            .forward_chunk(&x.narrow(1, start, k).unwrap(), &state)
            .unwrap();
        state = s.detach();
        let l =
            trainer::loss::cross_entropy(&logits.reshape((2 * k, 5)).unwrap(), &targets).unwrap();
        total = Some(match total {
            None => l,
            Some(acc) => (acc + l).unwrap(),
        });
    }
    let loss = total.unwrap();
    assert!(loss.to_scalar::<f32>().unwrap().is_finite());
    let grads = loss.backward().unwrap();
    for var in trainer::init::trainable_vars(&vm) {
        let g = grads
            .get(var.as_tensor())
            .expect("every parameter has a gradient");
        let v: Vec<f32> = g.flatten_all().unwrap().to_vec1().unwrap();
        assert!(v.iter().all(|x| x.is_finite()));
        assert!(v.iter().any(|x| *x != 0.0));
    }
}

/// A prepared frozen-mode run on hand-made features.
fn prepared(features: Vec<f32>, dim: usize) -> Prepared {
    let n = features.len() / dim;
    let split = |x: Vec<f32>| SplitFrames {
        labels: (0..n as u32).map(|i| i % 5).collect(),
        seq_rows: (0..n)
            .collect::<Vec<_>>()
            .chunks(5)
            .map(|c| c.to_vec())
            .collect(),
        seq_times: (0..n)
            .collect::<Vec<_>>()
            .chunks(5)
            .map(|c| (0..c.len()).map(|f| f as f64 / 2.5).collect())
            .collect(),
        seq_class: vec![0; n.div_ceil(5)],
        seq_ids: (0..n.div_ceil(5)).map(|i| format!("seq{i}")).collect(),
        source: FrameSource::Cached(Tensor::from_vec(x, (n, dim), &Device::Cpu).unwrap()),
    };
    Prepared {
        train: split(features.clone()),
        val: split(features),
        real_data: false,
        train_sequences: n.div_ceil(5),
        backbone: Some(grasp_model::backbone::BackboneInfo::generated("test")),
        feature_dim: dim,
        preprocess: grasp_model::backbone::Preprocess::imagenet(224),
        tail: None,
        damping: None,
        step_hz: None,
    }
}

fn cfg(dir: &std::path::Path) -> TrainConfig {
    TrainConfig {
        data: dir.to_path_buf(),
        out: dir.join("run"),
        mode: TrainMode::FrozenPretrained,
        batch_size: Some(10),
        max_epochs: 3,
        balance_classes: false,
        ..Default::default()
    }
}

#[test]
fn a_nan_feature_stops_training_naming_the_batch() {
    let dir = tempfile::tempdir().unwrap();
    let dim = 8;
    let mut f: Vec<f32> = (0..40 * dim).map(|i| (i % 7) as f32).collect();
    f[3] = f32::NAN;
    let err = trainer::train::train(
        &FitPlan::of(&cfg(dir.path())).unwrap(),
        &prepared(f, dim),
        0,
        &dir.path().join("o"),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("non-finite feature"), "{err}");
    assert!(err.contains("epoch 1, batch"), "{err}");
    assert!(err.contains("seq"), "{err}");
}

#[test]
fn a_diverging_loss_stops_training_naming_the_batch() {
    let dir = tempfile::tempdir().unwrap();
    let dim = 64;
    let f: Vec<f32> = (0..40 * dim).map(|i| 100.0 + (i % 3) as f32).collect();
    let mut c = cfg(dir.path());
    // Adam moves every weight by about lr on the first step: the logits of
    // the next batch overflow.
    c.optimizer.lr = 1e37;
    let err = trainer::train::train(
        &FitPlan::of(&c).unwrap(),
        &prepared(f, dim),
        0,
        &dir.path().join("o"),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("non-finite training loss"), "{err}");
    assert!(err.contains("epoch 1, batch 1"), "{err}");
}
