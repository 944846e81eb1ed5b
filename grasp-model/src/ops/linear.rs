//! A linear layer `y = x W^T + b` as a candle custom op whose backward skips
//! the input gradient when the input is a constant.
//!
//! candle's matmul backward always computes both operand gradients. For the
//! heads trained on cached features the input gradient is thrown away, and
//! for the LSTM's input projection it is the largest product of the step
//! (frames x 4*hidden x 1280). Here it is computed only when the input takes
//! part in autograd (`Tensor::track_op`), as in from-scratch training.

use super::cpu::{alloc_uninit, f32_slice, gemm_into, transpose, with_f32, MatRef};
use candle_core::{CpuStorage, CustomOp3, Layout, Result, Shape, Tensor, D};

const OP: &str = "linear";

/// Inputs of at least this many rows use a transposed copy of the weights.
const TRANSPOSE_ROWS: usize = 256;

struct Linear {
    input_grad: bool,
}

/// `x (..., in) -> (..., out)` with `weight (out, in)` and `bias (out)`.
pub fn linear(x: &Tensor, weight: &Tensor, bias: &Tensor) -> Result<Tensor> {
    let (out_dim, in_dim) = weight.dims2()?;
    if x.dim(D::Minus1)? != in_dim || bias.dims1()? != out_dim {
        candle_core::bail!(
            "{OP}: input {:?}, weight {:?} and bias {:?} do not fit",
            x.shape(),
            weight.shape(),
            bias.shape()
        );
    }
    let mut out_shape = x.dims().to_vec();
    *out_shape.last_mut().expect("rank >= 1") = out_dim;
    let rows = x.elem_count() / in_dim.max(1);
    let op = Linear {
        input_grad: x.track_op(),
    };
    x.reshape((rows, in_dim))?
        .contiguous()?
        .apply_op3(&weight.contiguous()?, &bias.contiguous()?, op)?
        .reshape(out_shape)
}

impl CustomOp3 for Linear {
    fn name(&self) -> &'static str {
        OP
    }

    fn cpu_fwd(
        &self,
        xs: &CpuStorage,
        xl: &Layout,
        ws: &CpuStorage,
        wl: &Layout,
        bs: &CpuStorage,
        bl: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let (rows, in_dim) = xl.shape().dims2()?;
        let (out_dim, _) = wl.shape().dims2()?;
        let x = f32_slice(OP, xs, xl, "input")?;
        let w = f32_slice(OP, ws, wl, "weight")?;
        let b = f32_slice(OP, bs, bl, "bias")?;
        let mut y = alloc_uninit(rows * out_dim);
        for row in y.chunks_exact_mut(out_dim) {
            row.copy_from_slice(b);
        }
        // gemm runs faster from a row-major W^T than from W's transposed
        // strides (43 against 56 ms for the LSTM's projection of 2880
        // frames); a few rows (streaming inference) are not worth the copy.
        let wt = (rows >= TRANSPOSE_ROWS).then(|| transpose(w, out_dim, in_dim));
        let rhs = match &wt {
            Some(wt) => MatRef::rows(wt, out_dim),
            None => MatRef::transposed(w, in_dim),
        };
        gemm_into(
            &mut y,
            (rows, out_dim, in_dim),
            true,
            MatRef::rows(x, in_dim),
            rhs,
        );
        Ok((CpuStorage::F32(y), Shape::from((rows, out_dim))))
    }

    fn bwd(
        &self,
        x: &Tensor,
        w: &Tensor,
        _b: &Tensor,
        _y: &Tensor,
        grad: &Tensor,
    ) -> Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let (rows, in_dim) = x.dims2()?;
        let (out_dim, _) = w.dims2()?;
        let (dw, db) = with_f32(OP, grad, "output gradient", |g| {
            with_f32(OP, x, "input", |x| {
                let mut dw = alloc_uninit(out_dim * in_dim);
                gemm_into(
                    &mut dw,
                    (out_dim, in_dim, rows),
                    false,
                    MatRef::transposed(g, out_dim),
                    MatRef::rows(x, in_dim),
                );
                let mut db = vec![0f32; out_dim];
                for row in g.chunks_exact(out_dim) {
                    for (s, v) in db.iter_mut().zip(row) {
                        *s += v;
                    }
                }
                (dw, db)
            })
        })??;
        let dx = if self.input_grad {
            Some(grad.matmul(w)?)
        } else {
            None
        };
        let dev = x.device();
        Ok((
            dx,
            Some(Tensor::from_vec(dw, (out_dim, in_dim), dev)?),
            Some(Tensor::from_vec(db, out_dim, dev)?),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::max_diff;
    use candle_core::{Device, Var};

    /// Forward and all three gradients against candle's matmul, for a
    /// tracked input (3-d, as the LSTM's hidden states) and a constant one.
    #[test]
    fn matches_candle_matmul() {
        let dev = Device::Cpu;
        for tracked in [true, false] {
            let x0 = Tensor::randn(0f32, 1.0, (2, 7, 13), &dev).unwrap();
            let x = Var::from_tensor(&x0).unwrap();
            let w = Var::from_tensor(&Tensor::randn(0f32, 1.0, (5, 13), &dev).unwrap()).unwrap();
            let b = Var::from_tensor(&Tensor::randn(0f32, 1.0, 5, &dev).unwrap()).unwrap();
            let input = if tracked { x.as_tensor().clone() } else { x0 };
            let ours = linear(&input, &w, &b).unwrap();
            let reference = x
                .as_tensor()
                .broadcast_matmul(&w.t().unwrap())
                .unwrap()
                .broadcast_add(&b)
                .unwrap();
            assert_eq!(ours.dims(), &[2, 7, 5]);
            assert!(max_diff(&ours, &reference) < 1e-5);
            // A loss that weighs every output differently.
            let weights = Tensor::randn(0f32, 1.0, (2, 7, 5), &dev).unwrap();
            let g_ours = (ours * &weights)
                .unwrap()
                .sum_all()
                .unwrap()
                .backward()
                .unwrap();
            let g_ref = (reference * &weights)
                .unwrap()
                .sum_all()
                .unwrap()
                .backward()
                .unwrap();
            for v in [&w, &b] {
                let d = max_diff(g_ours.get(v).unwrap(), g_ref.get(v).unwrap());
                assert!(d < 1e-4, "{d}");
            }
            match g_ours.get(&x) {
                Some(dx) if tracked => assert!(max_diff(dx, g_ref.get(&x).unwrap()) < 1e-4),
                None if !tracked => {}
                other => panic!("input gradient {other:?} with tracked = {tracked}"),
            }
        }
    }

    #[test]
    fn rejects_mismatched_shapes() {
        let dev = Device::Cpu;
        let x = Tensor::zeros((3, 4), candle_core::DType::F32, &dev).unwrap();
        let w = Tensor::zeros((2, 5), candle_core::DType::F32, &dev).unwrap();
        let b = Tensor::zeros(2, candle_core::DType::F32, &dev).unwrap();
        let err = linear(&x, &w, &b).unwrap_err().to_string();
        assert!(err.contains("do not fit"), "{err}");
    }

    #[test]
    fn empty_batch_gives_empty_output() {
        let dev = Device::Cpu;
        let x = Tensor::zeros((0, 4), candle_core::DType::F32, &dev).unwrap();
        let w = Tensor::ones((2, 4), candle_core::DType::F32, &dev).unwrap();
        let b = Tensor::ones(2, candle_core::DType::F32, &dev).unwrap();
        assert_eq!(linear(&x, &w, &b).unwrap().dims(), &[0, 2]);
    }
}
