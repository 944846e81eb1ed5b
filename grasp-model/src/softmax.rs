//! Softmax by log-sum-exp: `log p_i = x_i - m - log(sum_j exp(x_j - m))`
//! with `m = max_j x_j`, so no exponential ever overflows and extreme logits
//! (±1e30) give finite probabilities. The max is detached: the result does
//! not depend on it, and its gradient would only add noise.

use candle_core::{Result, Tensor, D};

/// Log-probabilities over the last dimension.
pub fn log_softmax(logits: &Tensor) -> Result<Tensor> {
    let max = logits.max_keepdim(D::Minus1)?.detach();
    let shifted = logits.broadcast_sub(&max)?;
    let lse = shifted.exp()?.sum_keepdim(D::Minus1)?.log()?;
    shifted.broadcast_sub(&lse)
}

/// Probabilities over the last dimension.
pub fn softmax(logits: &Tensor) -> Result<Tensor> {
    log_softmax(logits)?.exp()
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;

    #[test]
    fn softmax_of_huge_logits_sums_to_one() {
        let x = Tensor::new(&[[1e30f32, 1e30, -1e30]], &Device::Cpu).unwrap();
        let p: Vec<f32> = softmax(&x)
            .unwrap()
            .flatten_all()
            .unwrap()
            .to_vec1()
            .unwrap();
        assert_eq!(p, vec![0.5, 0.5, 0.0]);
    }
}
