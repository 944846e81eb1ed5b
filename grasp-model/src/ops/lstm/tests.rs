//! Unit tests of `lstm`, apart so that the kernel file holds only the kernel.

use super::*;
use crate::test_util::max_diff;
use candle_core::{Device, Var, D};

/// The LSTM written step by step with candle's tensor ops, as the head
/// used it before this op: `(B, T, 2H)` like the op.
fn reference(gates_x: &Tensor, w_hh: &Tensor, state0: &Tensor) -> Tensor {
    let (_, t_len, h4) = gates_x.dims3().unwrap();
    let h = h4 / 4;
    let mut hs = state0.narrow(1, 0, h).unwrap();
    let mut cs = state0.narrow(1, h, h).unwrap();
    let mut out = Vec::new();
    for t in 0..t_len {
        let z = (gates_x.narrow(1, t, 1).unwrap().squeeze(1).unwrap()
            + hs.matmul(&w_hh.t().unwrap()).unwrap())
        .unwrap();
        let z = z.chunk(4, D::Minus1).unwrap();
        let i = candle_nn::ops::sigmoid(&z[0]).unwrap();
        let f = candle_nn::ops::sigmoid(&z[1]).unwrap();
        let g = z[2].tanh().unwrap();
        let o = candle_nn::ops::sigmoid(&z[3]).unwrap();
        cs = ((f * &cs).unwrap() + (i * g).unwrap()).unwrap();
        hs = (o * cs.tanh().unwrap()).unwrap();
        out.push(Tensor::cat(&[&hs, &cs], 1).unwrap());
    }
    Tensor::stack(&out, 1).unwrap()
}

/// Forward values and the gradients of all three inputs against the
/// step-by-step reference, for a loss that weighs every h_t and c_t.
fn check_against_reference(b: usize, t: usize, h: usize, threads: usize) {
    let dev = Device::Cpu;
    let var = |shape: &[usize], scale: f64| {
        Var::from_tensor(&Tensor::randn(0f32, scale as f32, shape, &dev).unwrap()).unwrap()
    };
    let gates_x = var(&[b, t, 4 * h], 1.0);
    let w_hh = var(&[4 * h, h], 0.5);
    let state0 = var(&[b, 2 * h], 0.5);
    let ours = recurrence_in_parts(&gates_x, &w_hh, &state0, threads).unwrap();
    let theirs = reference(&gates_x, &w_hh, &state0);
    let case = format!("B {b} T {t} H {h} threads {threads}");
    assert_eq!(ours.dims(), &[b, t, 2 * h], "{case}");
    assert!(max_diff(&ours, &theirs) < 1e-5, "{case}: forward");
    let weights = Tensor::randn(0f32, 1.0, (b, t, 2 * h), &dev).unwrap();
    let loss = |y: Tensor| (y * &weights).unwrap().sum_all().unwrap();
    let g_ours = loss(ours).backward().unwrap();
    let g_ref = loss(theirs).backward().unwrap();
    for (name, v) in [("gates", &gates_x), ("w_hh", &w_hh), ("state0", &state0)] {
        let (a, r) = (g_ours.get(v).unwrap(), g_ref.get(v).unwrap());
        let scale = r.abs().unwrap().max_keepdim(0).unwrap().max(0).unwrap();
        let scale: f32 = scale
            .flatten_all()
            .unwrap()
            .max(0)
            .unwrap()
            .to_scalar()
            .unwrap();
        let d = max_diff(a, r);
        assert!(
            d <= 1e-5 * scale.max(1.0),
            "{case}: {name} gradient off by {d}"
        );
    }
}

#[test]
fn matches_step_by_step_reference() {
    for (b, t, h, threads) in [
        (3, 5, 7, 1),
        (3, 5, 7, 2),
        (4, 6, 7, 3),
        (2, 4, 16, 2),
        (1, 1, 1, 2),
        (1, 1, 5, 1),
        (5, 3, 2, 8),
    ] {
        check_against_reference(b, t, h, threads);
    }
}

#[test]
fn zero_steps_give_empty_output_and_zero_gradients() {
    let dev = Device::Cpu;
    let gates_x = Var::zeros((2, 0, 12), candle_core::DType::F32, &dev).unwrap();
    let w_hh = Var::ones((12, 3), candle_core::DType::F32, &dev).unwrap();
    let state0 = Var::ones((2, 6), candle_core::DType::F32, &dev).unwrap();
    let out = lstm_recurrence(&gates_x, &w_hh, &state0).unwrap();
    assert_eq!(out.dims(), &[2, 0, 6]);
    let grads = (out.sum_all().unwrap() + state0.sum_all().unwrap())
        .unwrap()
        .backward()
        .unwrap();
    let dw: f32 = grads
        .get(&w_hh)
        .unwrap()
        .abs()
        .unwrap()
        .sum_all()
        .unwrap()
        .to_scalar()
        .unwrap();
    assert_eq!(dw, 0.0);
}

/// A long sequence with saturating inputs: states stay bounded (|h| <= 1,
/// |c| <= t) and every gradient is finite.
#[test]
fn long_saturated_sequences_stay_finite() {
    let dev = Device::Cpu;
    let (b, t, h) = (2, 3000, 8);
    let gates_x =
        Var::from_tensor(&(Tensor::randn(0f32, 1.0, (b, t, 4 * h), &dev).unwrap() * 1e4).unwrap())
            .unwrap();
    let w_hh = Var::from_tensor(&Tensor::randn(0f32, 3.0, (4 * h, h), &dev).unwrap()).unwrap();
    let state0 = Tensor::zeros((b, 2 * h), candle_core::DType::F32, &dev).unwrap();
    let out = lstm_recurrence(&gates_x, &w_hh, &state0).unwrap();
    let hs: Vec<f32> = out
        .narrow(2, 0, h)
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1()
        .unwrap();
    assert!(hs.iter().all(|v| v.abs() <= 1.0));
    let cs: Vec<f32> = out
        .narrow(2, h, h)
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1()
        .unwrap();
    assert!(cs.iter().all(|v| v.is_finite() && v.abs() <= t as f32));
    let grads = out.sum_all().unwrap().backward().unwrap();
    for v in [&gates_x, &w_hh] {
        let g: Vec<f32> = grads
            .get(v)
            .unwrap()
            .flatten_all()
            .unwrap()
            .to_vec1()
            .unwrap();
        assert!(g.iter().all(|x| x.is_finite()));
    }
}

#[test]
fn exp_is_accurate_and_saturates() {
    let mut worst = 0f64;
    // The whole range inside the clamp at [-87, 88].
    for i in -86_999..=87_999 {
        let x = i as f32 * 1e-3;
        let want = f64::from(x).exp();
        worst = worst.max(((f64::from(exp(x)) - want) / want).abs());
    }
    assert!(worst < 3e-7, "worst relative error {worst}");
    assert!(exp(1e30).is_finite() && exp(1e30) > 1e38);
    assert!(exp(-1e30) >= 0.0 && exp(-1e30) < 1e-37);
    assert!(exp(f32::NAN).is_nan());
}

#[test]
fn sigmoid_and_tanh_match_libm() {
    for i in -2000..=2000 {
        let x = i as f32 * 0.01;
        assert!((sigmoid(x) - 1.0 / (1.0 + (-x).exp())).abs() < 2e-7, "{x}");
        assert!((tanh(x) - x.tanh()).abs() < 3e-7, "{x}");
    }
    assert_eq!(sigmoid(1e30), 1.0);
    assert!((0.0..1e-37).contains(&sigmoid(-1e30)));
    assert_eq!(tanh(1e30), 1.0);
    assert_eq!(tanh(-1e30), -1.0);
}

#[test]
fn permutation_round_trips() {
    for (h, threads) in [(5, 2), (7, 3), (1, 4), (256, 2)] {
        let parts = Parts::new(h, threads);
        let w: Vec<f32> = (0..4 * h * 3).map(|v| v as f32).collect();
        let p = parts.permute_rows(&w, 3);
        for (r, col) in parts.columns().iter().enumerate() {
            assert_eq!(p[r * 3..r * 3 + 3], w[col * 3..col * 3 + 3], "h {h}");
        }
        // Every permuted row is used once.
        let mut rows: Vec<usize> = (0..4)
            .flat_map(|k| (0..h).map(move |u| (k, u)))
            .map(|(k, u)| parts.row(k, u))
            .collect();
        rows.sort_unstable();
        assert_eq!(rows, (0..4 * h).collect::<Vec<_>>());
    }
}
