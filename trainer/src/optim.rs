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
use candle_core::{DType, Result, Tensor, Var};
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
    /// First and second moment estimates, updated in place.
    m: Vec<f32>,
    v: Vec<f32>,
}

pub struct Adam {
    slots: Vec<Slot>,
    step: i32,
    pub cfg: AdamConfig,
}

impl Adam {
    /// Adam over `vars`, which must be f32 (all of the trainer's are).
    pub fn new(vars: Vec<Var>, cfg: AdamConfig) -> Result<Self> {
        let slots = vars
            .into_iter()
            .map(|var| {
                if var.dtype() != DType::F32 {
                    candle_core::bail!("Adam: parameters must be f32, got {:?}", var.dtype());
                }
                let n = var.elem_count();
                Ok(Slot {
                    var,
                    m: vec![0.0; n],
                    v: vec![0.0; n],
                })
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
    /// they are (PyTorch skips parameters whose `.grad` is None). The scalar
    /// factors are computed in f64, as PyTorch computes them in Python, and
    /// each parameter is updated in one pass over its values.
    pub fn step(&mut self, grads: &GradStore) -> Result<()> {
        self.step += 1;
        let c = self.cfg;
        let k = Factors {
            beta1: c.beta1 as f32,
            beta2: c.beta2 as f32,
            eps: c.eps as f32,
            weight_decay: c.weight_decay as f32,
            step_size: (c.lr / (1.0 - c.beta1.powi(self.step))) as f32,
            inv_sqrt_bc2: (1.0 / (1.0 - c.beta2.powi(self.step)).sqrt()) as f32,
        };
        for slot in &mut self.slots {
            let Some(grad) = grads.get(slot.var.as_tensor()) else {
                continue;
            };
            let p: Vec<f32> = slot.var.as_tensor().flatten_all()?.to_vec1()?;
            let g: Vec<f32> = grad.flatten_all()?.to_dtype(DType::F32)?.to_vec1()?;
            let p = k.update(p, &g, &mut slot.m, &mut slot.v);
            let shape = slot.var.shape().clone();
            slot.var
                .set(&Tensor::from_vec(p, shape, slot.var.device())?)?;
        }
        Ok(())
    }
}

/// The per-step constants of the update.
struct Factors {
    beta1: f32,
    beta2: f32,
    eps: f32,
    weight_decay: f32,
    step_size: f32,
    inv_sqrt_bc2: f32,
}

impl Factors {
    fn update(&self, mut p: Vec<f32>, grad: &[f32], m: &mut [f32], v: &mut [f32]) -> Vec<f32> {
        for (((p, g), m), v) in p.iter_mut().zip(grad).zip(m).zip(v) {
            let g = g + self.weight_decay * *p;
            *m = self.beta1 * *m + (1.0 - self.beta1) * g;
            *v = self.beta2 * *v + (1.0 - self.beta2) * g * g;
            *p -= self.step_size * *m / (v.sqrt() * self.inv_sqrt_bc2 + self.eps);
        }
        p
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
        let var = Var::new(&[2.0f32], &Device::Cpu).unwrap();
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
            let got: Vec<f32> = var.as_tensor().to_vec1().unwrap();
            let got = f64::from(got[0]);
            assert!((got - p).abs() < 1e-6 * p.abs(), "step {t}: {got} vs {p}");
        }
    }

    #[test]
    fn rejects_non_f32_parameters() {
        let var = Var::new(&[1.0f64], &Device::Cpu).unwrap();
        let err = Adam::new(vec![var], AdamConfig::default()).err().unwrap();
        assert!(err.to_string().contains("f32"), "{err}");
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
        let var = Var::new(&[1.0f32], &Device::Cpu).unwrap();
        let mut adam = Adam::new(vec![var.clone()], cfg).unwrap();
        let loss = var.as_tensor().sum_all().unwrap();
        let mut grads = loss.backward().unwrap();
        grads.insert(
            var.as_tensor(),
            Tensor::new(&[0.0f32], &Device::Cpu).unwrap(),
        );
        adam.step(&grads).unwrap();
        let got: Vec<f32> = var.as_tensor().to_vec1().unwrap();
        assert!((got[0] - 0.99).abs() < 1e-6, "{}", got[0]);
    }
}
