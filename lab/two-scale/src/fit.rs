//! A softmax regression on frame rows, one-hot targets, each frame
//! weighted; Adam with weight decay, the best validation epoch kept (the
//! trainer of lab/part-head at daaab93, its control path).

use anyhow::Result;
use candle_core::{DType, Device, Tensor, D};
use rand::seq::SliceRandom;
use rand::SeedableRng;

/// One row per frame.
pub struct Rows {
    pub x: Tensor,
    /// (frames, K) targets.
    pub y: Tensor,
    /// One weight per frame.
    pub weight: Vec<f32>,
}

pub struct Fitted {
    pub w: Tensor,
    pub b: Tensor,
}

impl Fitted {
    pub fn logits(&self, x: &Tensor) -> Result<Tensor> {
        Ok(x.matmul(&self.w)?.broadcast_add(&self.b)?)
    }
}

pub struct FitConfig {
    pub lr: f64,
    pub weight_decay: f64,
    pub epochs: usize,
    pub patience: usize,
    pub batch_frames: usize,
}

/// Trains on `train`; `val_loss` scores a candidate on the validation
/// frames (lower is better).
pub fn fit(
    train: &Rows,
    k: usize,
    cfg: &FitConfig,
    seed: u64,
    val_loss: &dyn Fn(&Fitted) -> Result<f64>,
) -> Result<Fitted> {
    let dev = Device::Cpu;
    let dim = train.x.dim(1)?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let init: Vec<f32> = (0..dim * k)
        .map(|_| (rand::Rng::gen::<f32>(&mut rng) - 0.5) * 0.02)
        .collect();
    let mut w = Tensor::from_vec(init, (dim, k), &dev)?;
    let mut b = Tensor::zeros(k, DType::F32, &dev)?;
    let (mut mw, mut vw) = (w.zeros_like()?, w.zeros_like()?);
    let (mut mb, mut vb) = (b.zeros_like()?, b.zeros_like()?);
    let frames = train.weight.len();
    let mut order: Vec<usize> = (0..frames).collect();
    let (mut best, mut best_loss, mut since) = (None, f64::INFINITY, 0);
    let mut step = 0i32;
    for epoch in 0..cfg.epochs {
        order.shuffle(&mut rng);
        for batch in order.chunks(cfg.batch_frames) {
            let rows: Vec<u32> = batch.iter().map(|&f| f as u32).collect();
            let idx = Tensor::new(rows.as_slice(), &dev)?;
            let xb = train.x.index_select(&idx, 0)?;
            let yb = train.y.index_select(&idx, 0)?;
            let wf: Vec<f32> = batch.iter().map(|&f| train.weight[f]).collect();
            let total: f32 = wf.iter().sum();
            let wt =
                Tensor::from_vec(wf, (rows.len(), 1), &dev)?.affine(1.0 / f64::from(total), 0.0)?;
            let logits = xb.matmul(&w)?.broadcast_add(&b)?;
            let p = candle_nn_softmax(&logits)?;
            let g = (p - yb)?.broadcast_mul(&wt)?;
            let (gw, gb) = (xb.t()?.matmul(&g)?, g.sum(0)?);
            let gw = (gw + w.affine(cfg.weight_decay, 0.0)?)?;
            step += 1;
            adam(&mut w, &gw, &mut mw, &mut vw, cfg.lr, step)?;
            adam(&mut b, &gb, &mut mb, &mut vb, cfg.lr, step)?;
        }
        let candidate = Fitted {
            w: w.clone(),
            b: b.clone(),
        };
        let loss = val_loss(&candidate)?;
        tracing::info!("epoch {epoch}: validation loss {loss:.4}");
        if loss < best_loss - 1e-5 {
            (best, best_loss, since) = (Some(candidate), loss, 0);
        } else {
            since += 1;
            if since >= cfg.patience {
                break;
            }
        }
    }
    Ok(best.unwrap_or(Fitted { w, b }))
}

fn candle_nn_softmax(x: &Tensor) -> Result<Tensor> {
    let max = x.max_keepdim(D::Minus1)?;
    let e = x.broadcast_sub(&max)?.exp()?;
    Ok(e.broadcast_div(&e.sum_keepdim(D::Minus1)?)?)
}

pub fn softmax(x: &Tensor) -> Result<Tensor> {
    candle_nn_softmax(x)
}

fn adam(p: &mut Tensor, g: &Tensor, m: &mut Tensor, v: &mut Tensor, lr: f64, t: i32) -> Result<()> {
    let (b1, b2, eps) = (0.9f64, 0.999f64, 1e-8);
    *m = (m.affine(b1, 0.0)? + g.affine(1.0 - b1, 0.0)?)?;
    *v = (v.affine(b2, 0.0)? + g.sqr()?.affine(1.0 - b2, 0.0)?)?;
    let mhat = m.affine(1.0 / (1.0 - b1.powi(t)), 0.0)?;
    let vhat = v.affine(1.0 / (1.0 - b2.powi(t)), 0.0)?;
    *p = (&*p
        - mhat
            .broadcast_div(&(vhat.sqrt()? + eps)?)?
            .affine(lr, 0.0)?)?;
    Ok(())
}
