//! Adam with L2 weight decay coupled into the gradient, exactly as
//! `torch.optim.Adam(params, lr, betas, eps, weight_decay)` (amsgrad off):
//!
//! ```text
//! g  = grad + weight_decay * p
//! m  = b1 * m + (1 - b1) * g
//! v  = b2 * v + (1 - b2) * g^2
//! p -= lr / (1 - b1^t) * m / (sqrt(v) / sqrt(1 - b2^t) + eps)
//! ```
//!
//! candle-nn only ships AdamW (decoupled decay), which is a different method:
//! there the decay does not pass through the moment estimates.

use candle_core::backprop::GradStore;
use candle_core::{Result, Tensor, Var};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AdamConfig {
    pub lr: f64,
    pub beta1: f64,
    pub beta2: f64,
    pub eps: f64,
    pub weight_decay: f64,
}

impl Default for AdamConfig {
    /// The paper's: lr 5e-4, weight decay 5e-4, PyTorch's betas and eps.
    fn default() -> Self {
        AdamConfig {
            lr: 5e-4,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
            weight_decay: 5e-4,
        }
    }
}

struct Slot {
    var: Var,
    m: Tensor,
    v: Tensor,
}

pub struct Adam {
    slots: Vec<Slot>,
    step: i32,
    pub cfg: AdamConfig,
}

impl Adam {
    pub fn new(vars: Vec<Var>, cfg: AdamConfig) -> Result<Self> {
        let slots = vars
            .into_iter()
            .map(|var| {
                let m = var.zeros_like()?;
                let v = var.zeros_like()?;
                Ok(Slot { var, m, v })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Adam {
            slots,
            step: 0,
            cfg,
        })
    }

    pub fn learning_rate(&self) -> f64 {
        self.cfg.lr
    }

    pub fn set_learning_rate(&mut self, lr: f64) {
        self.cfg.lr = lr;
    }

    /// One update from `grads`. Parameters without a gradient are left as
    /// they are (PyTorch skips parameters whose `.grad` is None).
    pub fn step(&mut self, grads: &GradStore) -> Result<()> {
        self.step += 1;
        let c = self.cfg;
        let bc1 = 1.0 - c.beta1.powi(self.step);
        let bc2 = 1.0 - c.beta2.powi(self.step);
        let step_size = c.lr / bc1;
        let inv_sqrt_bc2 = 1.0 / bc2.sqrt();
        for slot in &mut self.slots {
            let Some(grad) = grads.get(slot.var.as_tensor()) else {
                continue;
            };
            let p = slot.var.as_tensor().detach();
            let g = if c.weight_decay != 0.0 {
                (grad + (&p * c.weight_decay)?)?
            } else {
                grad.clone()
            };
            slot.m = ((&slot.m * c.beta1)? + (&g * (1.0 - c.beta1))?)?;
            slot.v = ((&slot.v * c.beta2)? + (g.sqr()? * (1.0 - c.beta2))?)?;
            let denom = ((slot.v.sqrt()? * inv_sqrt_bc2)? + c.eps)?;
            let update = ((&slot.m / denom)? * step_size)?;
            slot.var.set(&(p - update)?)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;

    /// Minimises f(p) = 0.5 * p^2 (grad = p) for two steps and compares with
    /// the update computed by hand from PyTorch's formula.
    #[test]
    fn matches_hand_computed_steps() {
        let cfg = AdamConfig {
            lr: 0.1,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
            weight_decay: 0.5,
        };
        let var = Var::new(&[2.0f64], &Device::Cpu).unwrap();
        let mut adam = Adam::new(vec![var.clone()], cfg).unwrap();
        let (mut m, mut v, mut p) = (0.0f64, 0.0f64, 2.0f64);
        for t in 1..=2 {
            let loss = (var.as_tensor().sqr().unwrap() * 0.5)
                .unwrap()
                .sum_all()
                .unwrap();
            adam.step(&loss.backward().unwrap()).unwrap();
            let g = p + 0.5 * p;
            m = 0.9 * m + 0.1 * g;
            v = 0.999 * v + 0.001 * g * g;
            let bc1 = 1.0 - 0.9f64.powi(t);
            let bc2 = 1.0 - 0.999f64.powi(t);
            p -= 0.1 / bc1 * m / (v.sqrt() / bc2.sqrt() + 1e-8);
            let got: Vec<f64> = var.as_tensor().to_vec1().unwrap();
            assert!((got[0] - p).abs() < 1e-12, "step {t}: {} vs {p}", got[0]);
        }
    }

    #[test]
    fn weight_decay_is_coupled_not_decoupled() {
        // With a zero loss gradient, coupled L2 still moves p by a full Adam
        // step (lr), while AdamW would move it by lr * wd * p only.
        let cfg = AdamConfig {
            lr: 0.01,
            weight_decay: 1e-3,
            ..Default::default()
        };
        let var = Var::new(&[1.0f64], &Device::Cpu).unwrap();
        let mut adam = Adam::new(vec![var.clone()], cfg).unwrap();
        let loss = var.as_tensor().sum_all().unwrap();
        let mut grads = loss.backward().unwrap();
        grads.insert(
            var.as_tensor(),
            Tensor::new(&[0.0f64], &Device::Cpu).unwrap(),
        );
        adam.step(&grads).unwrap();
        let got: Vec<f64> = var.as_tensor().to_vec1().unwrap();
        assert!((got[0] - 0.99).abs() < 1e-6, "{}", got[0]);
    }
}
