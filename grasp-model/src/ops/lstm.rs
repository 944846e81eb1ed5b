//! The LSTM recurrence over a whole chunk of sequences as one candle custom
//! op, forward and backward (PyTorch's gate order i, f, g, o).
//!
//! Written per time step with candle's tensor ops, the recurrence is a dozen
//! small ops per step, each allocating its output, and autograd walks them
//! back one by one; that made the LSTM head's epoch 6x slower than PyTorch.
//! Here a step is one small matrix product plus one fused pass over the
//! cells, and the backward pass runs the same loop in reverse.
//!
//! The hidden units are split into contiguous parts, one per worker thread.
//! A part owns the four gate rows of its units (`W_hh` rows are permuted so
//! they are adjacent), so it computes its gates, cells and hidden states
//! without waiting for the others; the threads meet once per step, because
//! every unit's next gates read the whole hidden state.
//!
//! Buffers are feature-major, `(units, batch)` per step, so that the cell
//! pass runs over contiguous rows. The forward pass keeps the gate
//! activations and the hidden and cell states of every step for the
//! backward pass (only when a gradient can be asked for).

use super::cpu::{alloc_uninit, f32_slice, gemm_into, simd_dispatch, transpose, with_f32, MatRef};
use candle_core::{CpuStorage, CustomOp3, Layout, Result, Shape, Tensor};
use rayon::prelude::*;
use std::borrow::Cow;
use std::sync::Mutex;

const OP: &str = "lstm";

/// Runs the recurrence over `gates_x (B, T, 4H)`, the input projection of
/// every step plus both biases, from `state0 (B, 2H)` (h0 then c0) with the
/// recurrent weights `w_hh (4H, H)`. Returns `(B, T, 2H)`: the hidden state
/// h_t then the cell state c_t after every step.
pub fn lstm_recurrence(gates_x: &Tensor, w_hh: &Tensor, state0: &Tensor) -> Result<Tensor> {
    // A step of a small batch (streaming inference) is too little work to
    // share: the threads would spend longer meeting than computing.
    let (b, _, h4) = gates_x.dims3()?;
    let threads = if b * h4 >= PARALLEL_STEP {
        rayon::current_num_threads()
    } else {
        1
    };
    recurrence_in_parts(gates_x, w_hh, state0, threads)
}

/// Batch x gate rows from which a step is split across threads.
const PARALLEL_STEP: usize = 8 * 1024;

fn recurrence_in_parts(
    gates_x: &Tensor,
    w_hh: &Tensor,
    state0: &Tensor,
    threads: usize,
) -> Result<Tensor> {
    let (b, _, h4) = gates_x.dims3()?;
    let h = h4 / 4;
    if h4 % 4 != 0 || w_hh.dims2()? != (h4, h) || state0.dims2()? != (b, 2 * h) {
        candle_core::bail!(
            "{OP}: gates {:?}, recurrent weights {:?} and state {:?} do not fit",
            gates_x.shape(),
            w_hh.shape(),
            state0.shape()
        );
    }
    let wants_grad = gates_x.track_op() || w_hh.track_op() || state0.track_op();
    let op = Recurrence {
        parts: Parts::new(h, threads),
        saved: wants_grad.then(|| Mutex::new(None)),
    };
    gates_x
        .contiguous()?
        .apply_op3(&w_hh.contiguous()?, &state0.contiguous()?, op)
}

/// The hidden units split into `count` contiguous parts of `size` units (the
/// last one may be smaller).
#[derive(Clone, Copy, Debug)]
struct Parts {
    hidden: usize,
    size: usize,
}

impl Parts {
    fn new(hidden: usize, threads: usize) -> Self {
        let count = threads.clamp(1, hidden.max(1));
        Parts {
            hidden,
            size: hidden.div_ceil(count).max(1),
        }
    }

    /// First unit and unit count of part `part`.
    fn units(&self, part: usize) -> (usize, usize) {
        let u0 = part * self.size;
        (u0, self.size.min(self.hidden - u0))
    }

    /// Row of gate `k` of unit `u0 + q` in the permuted layout: part blocks
    /// of 4 * n rows, gate-major inside a block.
    fn row(&self, k: usize, u: usize) -> usize {
        let part = u / self.size;
        let (u0, n) = self.units(part);
        4 * u0 + k * n + (u - u0)
    }

    /// For every permuted row, its row in PyTorch's layout (gate-major).
    fn columns(&self) -> Vec<usize> {
        let mut cols = vec![0; 4 * self.hidden];
        for k in 0..4 {
            for u in 0..self.hidden {
                cols[self.row(k, u)] = k * self.hidden + u;
            }
        }
        cols
    }

    /// `w (4H, cols)` with its rows moved to the permuted layout (one part
    /// keeps PyTorch's layout: no copy).
    fn permute_rows<'a>(&self, w: &'a [f32], cols: usize) -> Cow<'a, [f32]> {
        if self.size >= self.hidden {
            return Cow::Borrowed(w);
        }
        let h = self.hidden;
        let mut out = alloc_uninit(w.len());
        for k in 0..4 {
            for u in 0..h {
                let src = (k * h + u) * cols;
                let dst = self.row(k, u) * cols;
                out[dst..dst + cols].copy_from_slice(&w[src..src + cols]);
            }
        }
        Cow::Owned(out)
    }
}

/// What the backward pass needs from the forward pass.
struct Saved {
    /// Hidden states, `(T + 1, H, B)`: slot 0 is h0, slot t + 1 is h_t.
    h: Vec<f32>,
    /// Cell states, same layout.
    c: Vec<f32>,
    /// Gate activations i, f, g, o, `(T, 4H permuted, B)`.
    gates: Vec<f32>,
}

struct Recurrence {
    parts: Parts,
    saved: Option<Mutex<Option<Saved>>>,
}

/// Sizes of one call.
#[derive(Clone, Copy)]
struct Dims {
    batch: usize,
    steps: usize,
    hidden: usize,
}

impl Dims {
    /// From the shape of the gates, `(B, T, 4H)`.
    fn of(gates: &Shape) -> Result<Self> {
        let (batch, steps, h4) = gates.dims3()?;
        Ok(Dims {
            batch,
            steps,
            hidden: h4 / 4,
        })
    }

    /// One step's `(H, B)` state.
    fn state(&self) -> usize {
        self.hidden * self.batch
    }
}

impl CustomOp3 for Recurrence {
    fn name(&self) -> &'static str {
        OP
    }

    fn cpu_fwd(
        &self,
        xs: &CpuStorage,
        xl: &Layout,
        ws: &CpuStorage,
        wl: &Layout,
        ss: &CpuStorage,
        sl: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let d = Dims::of(xl.shape())?;
        let gates_x = f32_slice(OP, xs, xl, "gates")?;
        let w = self
            .parts
            .permute_rows(f32_slice(OP, ws, wl, "weights")?, d.hidden);
        let state0 = f32_slice(OP, ss, sl, "state")?;
        let saved = self.forward(d, gates_x, &w, state0);
        let out = output(d, &saved);
        if let Some(slot) = &self.saved {
            *slot.lock().expect("lstm saved state") = Some(saved);
        }
        Ok((
            CpuStorage::F32(out),
            Shape::from((d.batch, d.steps, 2 * d.hidden)),
        ))
    }

    fn bwd(
        &self,
        gates_x: &Tensor,
        w_hh: &Tensor,
        _state0: &Tensor,
        _out: &Tensor,
        grad: &Tensor,
    ) -> Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let d = Dims::of(gates_x.shape())?;
        let slot = self
            .saved
            .as_ref()
            .ok_or_else(|| candle_core::Error::Msg(format!("{OP}: no state kept for backward")))?
            .lock()
            .expect("lstm saved state");
        let saved = slot
            .as_ref()
            .ok_or_else(|| candle_core::Error::Msg(format!("{OP}: backward before forward")))?;
        let grads = with_f32(OP, w_hh, "weights", |w| {
            let w = self.parts.permute_rows(w, d.hidden);
            with_f32(OP, grad, "output gradient", |g| {
                self.backward(d, saved, &w, g)
            })
        })??;
        let dev = gates_x.device();
        Ok((
            Some(Tensor::from_vec(grads.gates_x, gates_x.shape(), dev)?),
            Some(Tensor::from_vec(grads.w_hh, w_hh.shape(), dev)?),
            Some(Tensor::from_vec(
                grads.state0,
                (d.batch, 2 * d.hidden),
                dev,
            )?),
        ))
    }
}

struct Grads {
    gates_x: Vec<f32>,
    w_hh: Vec<f32>,
    state0: Vec<f32>,
}

impl Recurrence {
    fn forward(&self, d: Dims, gates_x: &[f32], w: &[f32], state0: &[f32]) -> Saved {
        let (b, h, hb) = (d.batch, d.hidden, d.state());
        let mut hs = alloc_uninit((d.steps + 1) * hb);
        let mut cs = alloc_uninit((d.steps + 1) * hb);
        for u in 0..h {
            for bi in 0..b {
                hs[u * b + bi] = state0[bi * 2 * h + u];
                cs[u * b + bi] = state0[bi * 2 * h + h + u];
            }
        }
        // The gate buffer starts as the input part of the pre-activations;
        // each step adds W_hh h_{t-1} and turns it into activations in place.
        let mut gates = self.gates_from_input(d, gates_x);
        let size = self.parts.size;
        for t in 0..d.steps {
            let (h_done, h_rest) = hs.split_at_mut((t + 1) * hb);
            let (c_done, c_rest) = cs.split_at_mut((t + 1) * hb);
            let (h_prev, c_prev) = (&h_done[t * hb..], &c_done[t * hb..]);
            let step_gates = &mut gates[t * 4 * hb..(t + 1) * 4 * hb];
            h_rest[..hb]
                .par_chunks_mut(size * b)
                .zip(c_rest[..hb].par_chunks_mut(size * b))
                .zip(step_gates.par_chunks_mut(4 * size * b))
                .enumerate()
                .for_each(|(part, ((h_next, c_next), z))| {
                    let (u0, n) = self.parts.units(part);
                    gemm_into(
                        z,
                        (4 * n, b, h),
                        true,
                        MatRef::rows(&w[4 * u0 * h..(4 * u0 + 4 * n) * h], h),
                        MatRef::rows(h_prev, b),
                    );
                    cells_forward(z, &c_prev[u0 * b..(u0 + n) * b], h_next, c_next);
                });
        }
        Saved {
            h: hs,
            c: cs,
            gates,
        }
    }

    /// `gates_x (B, T, 4H)` rearranged to `(T, 4H permuted, B)`.
    fn gates_from_input(&self, d: Dims, gates_x: &[f32]) -> Vec<f32> {
        let mut out = alloc_uninit(d.steps * 4 * d.state());
        to_step_major(gates_x, d, &self.parts.columns(), &mut out);
        out
    }

    fn backward(&self, d: Dims, saved: &Saved, w: &[f32], grad: &[f32]) -> Grads {
        let (b, h, hb, t_len) = (d.batch, d.hidden, d.state(), d.steps);
        let wt = transpose(w, 4 * h, h);
        let grad_t = grad_by_step(d, grad);
        let mut dz = alloc_uninit(t_len * 4 * hb);
        let mut dc = vec![0f32; hb];
        let mut dh = alloc_uninit(hb);
        let size = self.parts.size;
        for t in (0..t_len).rev() {
            let (dz_done, dz_later) = dz.split_at_mut((t + 1) * 4 * hb);
            let dz_now = &mut dz_done[t * 4 * hb..];
            let dz_next = (t + 1 < t_len).then(|| &dz_later[..4 * hb]);
            dh.par_chunks_mut(size * b)
                .zip(dc.par_chunks_mut(size * b))
                .zip(dz_now.par_chunks_mut(4 * size * b))
                .enumerate()
                .for_each(|(part, ((dh, dc), dz))| {
                    let (u0, n) = self.parts.units(part);
                    let units = u0 * b..(u0 + n) * b;
                    let g = &grad_t[t * 2 * hb..(t + 1) * 2 * hb];
                    dh.copy_from_slice(&g[units.clone()]);
                    if let Some(next) = dz_next {
                        gemm_into(
                            dh,
                            (n, b, 4 * h),
                            true,
                            MatRef::rows(&wt[u0 * 4 * h..(u0 + n) * 4 * h], 4 * h),
                            MatRef::rows(next, b),
                        );
                    }
                    cells_backward(
                        CellsBack {
                            gates: &saved.gates[t * 4 * hb + 4 * u0 * b..][..4 * n * b],
                            c: &saved.c[(t + 1) * hb..][units.clone()],
                            c_prev: &saved.c[t * hb..][units.clone()],
                            dc_out: &g[hb..][units],
                            dh,
                        },
                        dc,
                        dz,
                    );
                });
        }
        // Gradient of h0: W_hh^T dz_0; of c0: what the cells carried back.
        let mut dh0 = vec![0f32; hb];
        if t_len > 0 {
            gemm_into(
                &mut dh0,
                (h, b, 4 * h),
                false,
                MatRef::rows(&wt, 4 * h),
                MatRef::rows(&dz[..4 * hb], b),
            );
        }
        let mut state0 = alloc_uninit(b * 2 * h);
        for bi in 0..b {
            for u in 0..h {
                state0[bi * 2 * h + u] = dh0[u * b + bi];
                state0[bi * 2 * h + h + u] = dc[u * b + bi];
            }
        }
        let gates_x = self.input_grad(d, &dz);
        Grads {
            w_hh: recurrent_weight_grad(d, saved, &gates_x),
            gates_x,
            state0,
        }
    }

    /// `dz (T, 4H permuted, B)` rearranged to the layout of `gates_x`.
    fn input_grad(&self, d: Dims, dz: &[f32]) -> Vec<f32> {
        let mut out = alloc_uninit(d.batch * d.steps * 4 * d.hidden);
        let cols = self.parts.columns();
        to_batch_major(dz, 4 * d.state(), d, &cols, 4 * d.hidden, &mut out);
        out
    }
}

/// `dW_hh = sum over steps and sequences of dz_t h_{t-1}^T`, as one product
/// `(4H, B*T) @ (B*T, H)` of the pre-activation gradients (`gates_x`'s
/// layout) and the hidden states each step started from.
fn recurrent_weight_grad(d: Dims, saved: &Saved, dz: &[f32]) -> Vec<f32> {
    let h = d.hidden;
    let mut h_prev = alloc_uninit(d.batch * d.steps * h);
    let cols: Vec<usize> = (0..h).collect();
    to_batch_major(&saved.h, d.state(), d, &cols, h, &mut h_prev);
    let mut dw = alloc_uninit(4 * h * h);
    gemm_into(
        &mut dw,
        (4 * h, h, d.batch * d.steps),
        false,
        MatRef::transposed(dz, 4 * h),
        MatRef::rows(&h_prev, h),
    );
    dw
}

/// The op's output `(B, T, 2H)` from the saved states.
fn output(d: Dims, saved: &Saved) -> Vec<f32> {
    let (h, hb) = (d.hidden, d.state());
    let mut out = alloc_uninit(d.batch * d.steps * 2 * h);
    let h_cols: Vec<usize> = (0..h).collect();
    let c_cols: Vec<usize> = (h..2 * h).collect();
    to_batch_major(&saved.h[hb..], hb, d, &h_cols, 2 * h, &mut out);
    to_batch_major(&saved.c[hb..], hb, d, &c_cols, 2 * h, &mut out);
    out
}

/// The output gradient `(B, T, 2H)` rearranged to `(T, 2H, B)`.
fn grad_by_step(d: Dims, grad: &[f32]) -> Vec<f32> {
    let mut out = alloc_uninit(d.steps * 2 * d.state());
    let cols: Vec<usize> = (0..2 * d.hidden).collect();
    to_step_major(grad, d, &cols, &mut out);
    out
}

/// Batches of this many sequences are rearranged together: their values
/// of one row are adjacent in the step-major layout, so each cache line
/// read serves several of them.
const BATCH_BLOCK: usize = 8;

/// Scatters step-major rows into a batch-major `(B, T, width)` tensor: row
/// `r` of step `t` (`src[t * step_len + r * B..][..B]`) goes to column
/// `cols[r]` of `(b, t)` for every sequence `b`. Columns not in `cols` are
/// left as they are.
fn to_batch_major(
    src: &[f32],
    step_len: usize,
    d: Dims,
    cols: &[usize],
    width: usize,
    out: &mut [f32],
) {
    let (b, t_len) = (d.batch, d.steps);
    if out.is_empty() {
        return;
    }
    out.par_chunks_mut(BATCH_BLOCK * t_len * width)
        .enumerate()
        .for_each(|(block, seqs)| {
            let b0 = block * BATCH_BLOCK;
            let nb = seqs.len() / (t_len * width);
            for t in 0..t_len {
                let step = &src[t * step_len..];
                for (r, &col) in cols.iter().enumerate() {
                    let values = &step[r * b + b0..r * b + b0 + nb];
                    for (j, v) in values.iter().enumerate() {
                        seqs[(j * t_len + t) * width + col] = *v;
                    }
                }
            }
        });
}

/// Gathers a batch-major `(B, T, width)` tensor into step-major rows:
/// `out[t][r][b] = src[(b, t), cols[r]]`, `out` being `(T, cols.len(), B)`.
fn to_step_major(src: &[f32], d: Dims, cols: &[usize], out: &mut [f32]) {
    let (b, t_len) = (d.batch, d.steps);
    let width = src.len() / (b * t_len).max(1);
    if out.is_empty() {
        return;
    }
    out.par_chunks_mut(cols.len() * b)
        .enumerate()
        .for_each(|(t, step)| {
            for (row, &col) in step.chunks_exact_mut(b).zip(cols) {
                for (bi, v) in row.iter_mut().enumerate() {
                    *v = src[(bi * t_len + t) * width + col];
                }
            }
        });
}

simd_dispatch! {
/// One step of the cells of one part: `z` holds the pre-activations of the
/// part's gates, `(4n, B)` gate-major; they become activations in place.
fn cells_forward(z: &mut [f32], c_prev: &[f32], h_next: &mut [f32], c_next: &mut [f32]) {
    let len = c_prev.len();
    let (zi, rest) = z.split_at_mut(len);
    let (zf, rest) = rest.split_at_mut(len);
    let (zg, zo) = rest.split_at_mut(len);
    for j in 0..len {
        let i = sigmoid(zi[j]);
        let f = sigmoid(zf[j]);
        let g = tanh(zg[j]);
        let o = sigmoid(zo[j]);
        let c = flush(f * c_prev[j] + i * g);
        c_next[j] = c;
        h_next[j] = flush(o * tanh(c));
        (zi[j], zf[j], zg[j], zo[j]) = (i, f, g, o);
    }
}
}

/// What one part's backward cell pass reads, all `(n, B)` except `gates`.
struct CellsBack<'a> {
    /// Activations i, f, g, o, `(4n, B)`.
    gates: &'a [f32],
    c: &'a [f32],
    c_prev: &'a [f32],
    /// Gradient reaching c_t from the op's output.
    dc_out: &'a [f32],
    /// Gradient reaching h_t (output plus recurrence).
    dh: &'a [f32],
}

simd_dispatch! {
/// Turns the gradients reaching h_t and c_t into those of the gate
/// pre-activations `dz (4n, B)`; `dc` carries the cell gradient from step
/// t + 1 in and to step t - 1 out.
fn cells_backward(a: CellsBack, dc: &mut [f32], dz: &mut [f32]) {
    let len = a.c.len();
    let (gi, rest) = a.gates.split_at(len);
    let (gf, rest) = rest.split_at(len);
    let (gg, go) = rest.split_at(len);
    let (di, rest) = dz.split_at_mut(len);
    let (df, rest) = rest.split_at_mut(len);
    let (dg, d_o) = rest.split_at_mut(len);
    for j in 0..len {
        let (i, f, g, o) = (gi[j], gf[j], gg[j], go[j]);
        let tc = tanh(a.c[j]);
        let dh = a.dh[j];
        let dcell = dc[j] + a.dc_out[j] + dh * o * (1.0 - tc * tc);
        d_o[j] = flush(dh * tc * o * (1.0 - o));
        di[j] = flush(dcell * g * i * (1.0 - i));
        df[j] = flush(dcell * a.c_prev[j] * f * (1.0 - f));
        dg[j] = flush(dcell * i * (1.0 - g * g));
        dc[j] = flush(dcell * f);
    }
}
}

/// Zero for magnitudes below 1e-30. Saturated gates multiply states by
/// values near 1e-38, and subnormal floats reaching the matrix products
/// make them about 40x slower (a 10 000-step sequence took 90 s instead of
/// 2); values this small change no sum they take part in.
#[inline(always)]
fn flush(x: f32) -> f32 {
    if x.abs() < 1e-30 {
        0.0
    } else {
        x
    }
}

/// e^x for |x| < 88 to about 2 ulp, written so that loops over it
/// vectorize (libm's `expf` is a call per element): Cody-Waite range
/// reduction to |r| <= ln2/2 and Cephes' degree-6 polynomial. NaN stays NaN.
#[inline(always)]
fn exp(x: f32) -> f32 {
    const LOG2_E: f32 = std::f32::consts::LOG2_E;
    const LN2_HI: f32 = 0.693_359_4;
    const LN2_LO: f32 = -2.121_944_4e-4;
    // Adding and subtracting 1.5 * 2^23 rounds to the nearest integer.
    const ROUND: f32 = 12_582_912.0;
    let x = x.clamp(-87.0, 88.0);
    let n = (x * LOG2_E + ROUND) - ROUND;
    let r = x - n * LN2_HI - n * LN2_LO;
    // 2^n from the bits of n + 127 read off a float in [2^23, 2^24), where
    // the unit is 1: no float-to-int conversion, so the loop vectorizes.
    let biased = (n + (ROUND + 127.0)).to_bits() & 0x3f_ffff;
    let mut p = 1.987_569_1e-4f32;
    p = p * r + 1.398_199_9e-3;
    p = p * r + 8.333_452e-3;
    p = p * r + 4.166_579_6e-2;
    p = p * r + 1.666_666_5e-1;
    p = p * r + 0.5;
    let e = p * r * r + r + 1.0;
    e * f32::from_bits(biased << 23)
}

#[inline(always)]
fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + exp(-x))
}

/// tanh(x) = 2 sigmoid(2x) - 1: absolute error about 1e-7 (relative error
/// grows near 0, where it does not matter to the cell's sums).
#[inline(always)]
fn tanh(x: f32) -> f32 {
    2.0 / (1.0 + exp(-2.0 * x)) - 1.0
}

#[cfg(test)]
mod tests;
