//! 2-d batch normalization with PyTorch's semantics and parameter names
//! (`weight`, `bias`, `running_mean`, `running_var`; eps 1e-5, momentum 0.1).
//!
//! Train mode normalizes with the batch statistics (biased variance) and
//! updates the running statistics in place (unbiased variance), as PyTorch
//! does. When built from a `VarMap`, the running statistics are the map's
//! own variables, so saving the map saves them. Eval mode is only used
//! through [`BatchNorm2d::fold`], which turns the layer into a per-channel
//! scale and shift for folding into the preceding convolution.

use candle_core::{DType, Result, Tensor, Var};
use candle_nn::{Init, VarBuilder};

pub const EPS: f64 = 1e-5;
pub const MOMENTUM: f64 = 0.1;

#[derive(Clone, Debug)]
pub struct BatchNorm2d {
    weight: Tensor,
    bias: Tensor,
    running_mean: Var,
    running_var: Var,
}

impl BatchNorm2d {
    pub fn new(channels: usize, vb: VarBuilder) -> Result<Self> {
        let weight = vb.get_with_hints(channels, "weight", Init::Const(1.0))?;
        let bias = vb.get_with_hints(channels, "bias", Init::Const(0.0))?;
        let mean = vb.get_with_hints(channels, "running_mean", Init::Const(0.0))?;
        let var = vb.get_with_hints(channels, "running_var", Init::Const(1.0))?;
        Ok(Self {
            weight,
            bias,
            running_mean: Var::from_tensor(&mean)?,
            running_var: Var::from_tensor(&var)?,
        })
    }

    /// Per-channel `(scale, shift)` with `bn(x) = scale * x + shift` in eval mode.
    pub fn fold(&self) -> Result<(Tensor, Tensor)> {
        self.fold_with_eps(EPS)
    }

    /// [`Self::fold`] with another epsilon (TensorFlow-trained files use 1e-3).
    pub fn fold_with_eps(&self, eps: f64) -> Result<(Tensor, Tensor)> {
        let inv_std = (self.running_var.as_tensor() + eps)?.sqrt()?.recip()?;
        let scale = (&self.weight * inv_std)?;
        let shift = (&self.bias - (self.running_mean.as_tensor() * &scale)?)?;
        Ok((scale, shift))
    }

    /// Train-mode normalization with batch statistics; updates the running ones.
    pub fn forward_train(&self, x: &Tensor) -> Result<Tensor> {
        let (n, c, h, w) = x.dims4()?;
        let count = n * h * w;
        if count < 2 {
            candle_core::bail!(
                "batch norm in train mode needs more than one value per channel, got input {:?}",
                x.dims()
            );
        }
        // (C, N*H*W): two-pass mean and variance per channel.
        let xc = x.transpose(0, 1)?.reshape((c, count))?;
        let mean = xc.mean_keepdim(1)?;
        let centered = xc.broadcast_sub(&mean)?;
        let var = centered.sqr()?.mean_keepdim(1)?;
        self.update_running(&mean, &var, count)?;
        let inv_std = (var + EPS)?.sqrt()?.recip()?;
        let scale = inv_std.broadcast_mul(&self.weight.reshape((c, 1))?)?;
        let y = centered
            .broadcast_mul(&scale)?
            .broadcast_add(&self.bias.reshape((c, 1))?)?;
        y.reshape((c, n, h, w))?.transpose(0, 1)?.contiguous()
    }

    fn update_running(&self, mean: &Tensor, var: &Tensor, count: usize) -> Result<()> {
        let mean = mean.detach().flatten_all()?.to_dtype(DType::F32)?;
        let unbiased = (var.detach().flatten_all()? * (count as f64 / (count as f64 - 1.0)))?;
        let rm = ((self.running_mean.as_tensor() * (1.0 - MOMENTUM))? + (mean * MOMENTUM)?)?;
        let rv = ((self.running_var.as_tensor() * (1.0 - MOMENTUM))? + (unbiased * MOMENTUM)?)?;
        self.running_mean.set(&rm)?;
        self.running_var.set(&rv)
    }
}
