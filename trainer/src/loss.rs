//! Cross-entropy by log-sum-exp (softmax itself is grasp_model::softmax): `log p_i = x_i - m - log(sum_j
//! exp(x_j - m))` with `m = max_j x_j`, so no exponential ever overflows and
//! extreme logits (±1e30) give finite losses and gradients. The max is
//! detached: the result does not depend on it, and its gradient would only
//! add noise.

use candle_core::{DType, Result, Tensor};
use grasp_model::softmax::log_softmax;

/// Per-row negative log-likelihood of `targets` (u32, shape `(N,)`) under
/// `logits` `(N, C)`.
pub fn cross_entropy_per_row(logits: &Tensor, targets: &Tensor) -> Result<Tensor> {
    let logp = log_softmax(logits)?;
    let picked = logp.gather(&targets.unsqueeze(1)?, 1)?.squeeze(1)?;
    picked.neg()
}

/// Mean cross-entropy of `targets` under `logits` `(N, C)`.
pub fn cross_entropy(logits: &Tensor, targets: &Tensor) -> Result<Tensor> {
    cross_entropy_per_row(logits, targets)?.mean_all()
}

/// Cross-entropy averaged over the rows where `mask` (f32 0/1, `(N,)`) is 1,
/// for padded sequence batches.
pub fn masked_cross_entropy(logits: &Tensor, targets: &Tensor, mask: &Tensor) -> Result<Tensor> {
    let per_row = cross_entropy_per_row(logits, targets)?;
    let count = mask
        .sum_all()?
        .to_dtype(DType::F32)?
        .to_scalar::<f32>()?
        .max(1.0);
    (per_row * mask)?.sum_all()? / f64::from(count)
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{Device, Var};

    fn ce_and_grad(logits: &[f32], target: u32) -> (f32, Vec<f32>) {
        let dev = Device::Cpu;
        let x = Var::from_slice(logits, (1, logits.len()), &dev).unwrap();
        let t = Tensor::new(&[target], &dev).unwrap();
        let loss = cross_entropy(x.as_tensor(), &t).unwrap();
        let grads = loss.backward().unwrap();
        let g = grads.get(x.as_tensor()).unwrap().flatten_all().unwrap();
        (loss.to_scalar().unwrap(), g.to_vec1().unwrap())
    }

    #[test]
    fn matches_hand_computed_values() {
        // logits (0, ln 3): p = (1/4, 3/4).
        let (loss, grad) = ce_and_grad(&[0.0, 3f32.ln()], 1);
        assert!((loss - (4.0f32 / 3.0).ln()).abs() < 1e-6);
        assert!((grad[0] - 0.25).abs() < 1e-6);
        assert!((grad[1] + 0.25).abs() < 1e-6);
    }

    #[test]
    fn extreme_logits_stay_finite() {
        for big in [1e4f32, 1e30] {
            let (loss, grad) = ce_and_grad(&[big, -big, 0.0, 0.0, 0.0], 0);
            assert_eq!(loss, 0.0);
            assert!(grad.iter().all(|g| g.is_finite()));
            let (loss, grad) = ce_and_grad(&[big, -big, 0.0, 0.0, 0.0], 1);
            assert!(loss.is_finite());
            assert!((loss - 2.0 * big).abs() <= 2.0 * big * 1e-6);
            assert!((grad[0] - 1.0).abs() < 1e-6);
            assert!((grad[1] + 1.0).abs() < 1e-6);
            let (loss, grad) = ce_and_grad(&[big, big, -big, -big, -big], 1);
            assert!((loss - 2f32.ln()).abs() < 1e-6);
            assert!((grad[1] + 0.5).abs() < 1e-6);
        }
    }

    #[test]
    fn masked_rows_do_not_count() {
        let dev = Device::Cpu;
        let x = Tensor::new(&[[0f32, 3f32.ln()], [100.0, -100.0]], &dev).unwrap();
        let t = Tensor::new(&[1u32, 1], &dev).unwrap();
        let m = Tensor::new(&[1f32, 0.0], &dev).unwrap();
        let l: f32 = masked_cross_entropy(&x, &t, &m)
            .unwrap()
            .to_scalar()
            .unwrap();
        assert!((l - (4.0f32 / 3.0).ln()).abs() < 1e-6);
    }
}
