//! Depthwise convolutions (3x3 or 5x5, stride 1 or 2, symmetric PyTorch or
//! TensorFlow "SAME" padding) as candle custom ops.
//!
//! candle's grouped convolution splits the input into one convolution per
//! channel, which is slow for the depthwise layers of MobileNetV2 and
//! EfficientNet-Lite. These kernels work plane by plane (one image, one
//! channel) in NCHW layout, in parallel over planes on candle's rayon pool.
//!
//! Each plane is first copied into a zero-padded scratch buffer split into
//! its stride x stride polyphase components (even/odd rows and columns for
//! stride 2), each `sh x sw` with `sw = ow + (k - 1) / stride`. Then every
//! tap (ky, kx) of every output (oy, ox) reads component (ky % s, kx % s) at
//! flat index `(oy + ky / s) * sw + ox + kx / s`: a constant offset per tap
//! from the output's flat "wide" index `oy * sw + ox`. One long vectorized
//! loop over the wide index computes all outputs (plus `sw - ow` throwaway
//! columns per row), so that even 7x7 planes fill whole vectors.
//!
//! - [`depthwise_conv`]: differentiable (input and weight gradients), any
//!   supported kernel, stride and padding ([`depthwise_conv3x3`]: 3x3 with
//!   padding 1, as MobileNetV2 trains; EfficientNet-Lite's fine-tuned
//!   blocks use 5x5 and 3x3 "SAME").
//! - [`depthwise_conv_bias_act`]: inference, any supported kernel, stride
//!   and padding, with a fused per-channel bias (folded batch norm) and
//!   optional ReLU6.

use super::cpu::{alloc_uninit, par_chunks, simd_dispatch};
use candle_core::{CpuStorage, CustomOp2, CustomOp3, Layout, Result, Shape, Tensor};

/// Output size of a 3x3 convolution with padding 1.
pub fn out_size(size: usize, stride: usize) -> usize {
    (size + 2 - 3) / stride + 1
}

/// How a convolution pads its input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Padding {
    /// `p` zeros on every side (PyTorch's `padding=p`).
    Symmetric(usize),
    /// TensorFlow's "SAME": output `ceil(size / stride)`, the padding that
    /// needs split with the extra pixel at the bottom/right.
    Same,
}

impl Padding {
    /// (output size, padding before) along one axis, or `None` when the
    /// kernel does not fit.
    pub fn resolve(self, size: usize, kernel: usize, stride: usize) -> Option<(usize, usize)> {
        if size == 0 || kernel == 0 || stride == 0 {
            return None;
        }
        match self {
            Padding::Symmetric(p) => {
                let padded = size + 2 * p;
                (padded >= kernel).then(|| ((padded - kernel) / stride + 1, p))
            }
            Padding::Same => {
                let out = size.div_ceil(stride);
                let total = ((out - 1) * stride + kernel).saturating_sub(size);
                Some((out, total / 2))
            }
        }
    }
}

/// Geometry of one depthwise call.
#[derive(Clone, Copy, Debug)]
struct Geom {
    n: usize,
    c: usize,
    h: usize,
    w: usize,
    k: usize,
    stride: usize,
    oh: usize,
    ow: usize,
    /// Padding above and to the left.
    pt: usize,
    pl: usize,
    /// The offset of tap (ky, kx) from the wide output index, at `ky * k +
    /// kx` (the rest 0): computed once per call, not per plane, for the
    /// divisions by the stride.
    off: [usize; MAX_TAPS],
}

/// Lanes of one block of outputs in the stencil loop (four AVX-512 vectors:
/// enough independent accumulators to hide the FMA latency).
const BLOCK: usize = 64;

impl Geom {
    fn new(shape: &Shape, k: usize, stride: usize, padding: Padding) -> Result<Self> {
        if stride != 1 && stride != 2 {
            candle_core::bail!("depthwise: stride must be 1 or 2, got {stride}");
        }
        if k != 3 && k != 5 {
            candle_core::bail!("depthwise: kernel must be 3x3 or 5x5, got {k}x{k}");
        }
        let (n, c, h, w) = shape.dims4()?;
        let (Some((oh, pt)), Some((ow, pl))) =
            (padding.resolve(h, k, stride), padding.resolve(w, k, stride))
        else {
            candle_core::bail!("depthwise: a {k}x{k} kernel does not fit a {h}x{w} plane");
        };
        let mut g = Self {
            n,
            c,
            h,
            w,
            k,
            stride,
            oh,
            ow,
            pt,
            pl,
            off: [0; MAX_TAPS],
        };
        g.off = g.tap_offsets();
        Ok(g)
    }

    fn in_plane(&self) -> usize {
        self.h * self.w
    }

    fn out_plane(&self) -> usize {
        self.oh * self.ow
    }

    /// Width and height of one polyphase component.
    fn phase_dims(&self) -> (usize, usize) {
        let reach = (self.k - 1) / self.stride;
        (self.oh + reach, self.ow + reach)
    }

    fn phase_len(&self) -> usize {
        let (sh, sw) = self.phase_dims();
        sh * sw
    }

    /// Outputs in wide (row stride `sw`) layout, rounded up to whole blocks.
    fn wide_len(&self) -> usize {
        let (_, sw) = self.phase_dims();
        ((self.oh - 1) * sw + self.ow).next_multiple_of(BLOCK)
    }

    /// Scratch floats per worker: the phases (with a block of slack, read by
    /// the last block's taps), then the wide outputs.
    fn scratch_len(&self) -> usize {
        self.stride * self.stride * self.phase_len() + BLOCK + self.wide_len()
    }

    fn out_shape(&self) -> Shape {
        Shape::from((self.n, self.c, self.oh, self.ow))
    }

    /// Computes [`Geom::off`].
    fn tap_offsets(&self) -> [usize; MAX_TAPS] {
        let s = self.stride;
        let (_, sw) = self.phase_dims();
        let mut off = [0; MAX_TAPS];
        for ky in 0..self.k {
            for kx in 0..self.k {
                let phase = (ky % s) * s + kx % s;
                off[ky * self.k + kx] = phase * self.phase_len() + (ky / s) * sw + kx / s;
            }
        }
        off
    }
}

/// Taps of the largest kernel (5 x 5).
const MAX_TAPS: usize = 25;

fn contiguous<'a>(s: &'a CpuStorage, l: &Layout, what: &str) -> Result<&'a [f32]> {
    super::cpu::f32_slice("depthwise", s, l, what)
}

fn check_weight(g: &Geom, l: &Layout) -> Result<()> {
    let dims = l.dims();
    if dims != [g.c, 1, g.k, g.k] {
        candle_core::bail!(
            "depthwise: weight shape {dims:?} does not match [{}, 1, {}, {}]",
            g.c,
            g.k,
            g.k
        );
    }
    Ok(())
}

/// Splits a plane into its zero-padded polyphase components in `phases`
/// (stride `S`, a constant so that the index arithmetic is shifts).
#[inline(always)]
fn pad_plane<const S: usize>(g: &Geom, src: &[f32], phases: &mut [f32]) {
    let (sh, sw) = g.phase_dims();
    let plen = g.phase_len();
    phases.fill(0.0);
    for y in 0..g.h {
        // padded row y + pt lives in row (y + pt) / S of phase row (y + pt) % S
        let py = y + g.pt;
        let (prow, row) = (py % S, py / S);
        if row >= sh {
            break; // below every tap (SAME padding may drop the last rows)
        }
        let src_row = &src[y * g.w..(y + 1) * g.w];
        if S == 1 {
            // input column x sits at padded column x + pl
            let count = g.w.min(sw.saturating_sub(g.pl));
            let base = row * sw + g.pl;
            phases[base..base + count].copy_from_slice(&src_row[..count]);
            continue;
        }
        // stride 2: input column x sits at padded column x + pl, in phase
        // (x + pl) % 2 at (x + pl) / 2; even and odd input columns go to
        // the two column phases of this phase row
        let (first, rest) = phases[prow * 2 * plen..(prow * 2 + 2) * plen].split_at_mut(plen);
        let (even_x, odd_x) = if g.pl.is_multiple_of(2) {
            (
                &mut first[row * sw..(row + 1) * sw],
                &mut rest[row * sw..(row + 1) * sw],
            )
        } else {
            (
                &mut rest[row * sw..(row + 1) * sw],
                &mut first[row * sw..(row + 1) * sw],
            )
        };
        // x = 2t goes to index t + e0, x = 2t + 1 to t + o0
        let e0 = g.pl / 2;
        let o0 = g.pl.div_ceil(2);
        let even_n = g.w.div_ceil(2).min(sw.saturating_sub(e0));
        let odd_n = (g.w / 2).min(sw.saturating_sub(o0));
        deinterleave(
            src_row,
            &mut even_x[e0..e0 + even_n],
            &mut odd_x[o0..o0 + odd_n],
        );
    }
}

/// `even[t] = src[2t]` and `odd[t] = src[2t + 1]`, as far as each reaches:
/// loops over pairs, which vectorise (`step_by(2)` did not).
#[inline(always)]
fn deinterleave(src: &[f32], even: &mut [f32], odd: &mut [f32]) {
    let pairs = src.chunks_exact(2);
    for (d, p) in even.iter_mut().zip(pairs.clone()) {
        *d = p[0];
    }
    for (d, p) in odd.iter_mut().zip(pairs) {
        *d = p[1];
    }
    // an odd row's last value is an even one, outside every pair
    let half = src.len() / 2;
    if !src.len().is_multiple_of(2) && even.len() > half {
        even[half] = src[src.len() - 1];
    }
}

/// The stencil over the wide outputs: `wide[q] = act(bias + sum_ky sum_kx
/// w[ky][kx] * src[off[ky][kx] + q])`, `BLOCK` outputs at a time. Each
/// kernel row is summed before it is added (the order of the earlier 3x3
/// kernel, which the MobileNetV2 parity tolerances were set with).
#[inline(always)]
fn stencil<const K: usize>(
    src: &[f32],
    off: &[[usize; K]; K],
    w: &[[f32; K]; K],
    bias: f32,
    relu6: bool,
    wide: &mut [f32],
) {
    // Each read below is BLOCK floats from a tap's offset plus q, with
    // q + BLOCK <= wide.len() (whole chunks): inside src when this holds.
    // Checked once, not at each read (a third of the loop's instructions).
    let mut max_off = 0;
    for row in off {
        for &o in row {
            max_off = max_off.max(o);
        }
    }
    assert!(
        max_off + wide.len() <= src.len(),
        "depthwise: scratch too small"
    );
    for (b, out) in wide.chunks_exact_mut(BLOCK).enumerate() {
        let q = b * BLOCK;
        let mut acc = [bias; BLOCK];
        for ky in 0..K {
            let mut row = [0f32; BLOCK];
            for kx in 0..K {
                let o = off[ky][kx] + q;
                // SAFETY: o + BLOCK <= max_off + wide.len() <= src.len().
                let x = unsafe { &*src.as_ptr().add(o).cast::<[f32; BLOCK]>() };
                let wt = w[ky][kx];
                if kx == 0 {
                    for l in 0..BLOCK {
                        row[l] = wt * x[l];
                    }
                } else {
                    for l in 0..BLOCK {
                        row[l] += wt * x[l];
                    }
                }
            }
            for l in 0..BLOCK {
                acc[l] += row[l];
            }
        }
        if relu6 {
            for a in acc.iter_mut() {
                *a = a.clamp(0.0, 6.0);
            }
        }
        out.copy_from_slice(&acc);
    }
}

/// One output plane: pad, run the stencil, compact the wide rows into `dst`.
#[inline(always)]
fn conv_plane_body(
    g: &Geom,
    src: &[f32],
    k: &[f32],
    bias: f32,
    relu6: bool,
    scratch: &mut [f32],
    dst: &mut [f32],
) {
    let phases_len = g.stride * g.stride * g.phase_len() + BLOCK;
    let (phases, wide) = scratch.split_at_mut(phases_len);
    if g.stride == 1 {
        pad_plane::<1>(g, src, &mut phases[..phases_len - BLOCK]);
    } else {
        pad_plane::<2>(g, src, &mut phases[..phases_len - BLOCK]);
    }
    let wide = &mut wide[..g.wide_len()];
    match g.k {
        3 => {
            let off = std::array::from_fn(|ky| std::array::from_fn(|kx| g.off[3 * ky + kx]));
            let w = std::array::from_fn(|ky| std::array::from_fn(|kx| k[3 * ky + kx]));
            stencil::<3>(phases, &off, &w, bias, relu6, wide);
        }
        _ => {
            let off = std::array::from_fn(|ky| std::array::from_fn(|kx| g.off[5 * ky + kx]));
            let w = std::array::from_fn(|ky| std::array::from_fn(|kx| k[5 * ky + kx]));
            stencil::<5>(phases, &off, &w, bias, relu6, wide);
        }
    }
    let (_, sw) = g.phase_dims();
    for (oy, row) in dst.chunks_exact_mut(g.ow).enumerate() {
        row.copy_from_slice(&wide[oy * sw..oy * sw + g.ow]);
    }
}

simd_dispatch! {
/// [`conv_plane_body`] on the widest vector unit this CPU has.
fn conv_plane(
    g: &Geom,
    src: &[f32],
    k: &[f32],
    bias: f32,
    relu6: bool,
    scratch: &mut [f32],
    dst: &mut [f32]
) {
    conv_plane_body(g, src, k, bias, relu6, scratch, dst)
}
}

/// Forward: small planes with the channels along the vector (`small`),
/// the rest plane by plane.
fn forward(g: &Geom, x: &[f32], w: &[f32], bias: Option<&[f32]>, relu6: bool) -> Vec<f32> {
    #[cfg(target_arch = "x86_64")]
    if small::applies(g) {
        return small::forward(g, x, w, bias, relu6);
    }
    forward_planes(g, x, w, bias, relu6)
}

/// Forward over all planes, in parallel.
fn forward_planes(g: &Geom, x: &[f32], w: &[f32], bias: Option<&[f32]>, relu6: bool) -> Vec<f32> {
    let taps = g.k * g.k;
    // every element is written by conv_plane
    let mut out = alloc_uninit(g.n * g.c * g.out_plane());
    par_chunks(
        &mut out,
        g.out_plane(),
        g.scratch_len(),
        |scratch, plane, dst| {
            let ch = plane % g.c;
            let src = &x[plane * g.in_plane()..(plane + 1) * g.in_plane()];
            let b = bias.map_or(0.0, |b| b[ch]);
            let k = &w[taps * ch..taps * (ch + 1)];
            conv_plane(g, src, k, b, relu6, scratch, dst);
        },
    );
    out
}

/// The zero-padded plane the backward kernels work on: (rows, columns),
/// enough for every tap of every output, and at least the padded input.
fn padded_dims(g: &Geom) -> (usize, usize) {
    let rows = (g.pt + g.h).max(g.stride * (g.oh - 1) + g.k);
    let cols = (g.pl + g.w).max(g.stride * (g.ow - 1) + g.k);
    (rows, cols)
}

/// Gradient of the input: scatter each output gradient through the kernel
/// into a padded plane, then keep its interior.
fn backward_input(g: &Geom, grad: &[f32], w: &[f32]) -> Vec<f32> {
    let mut out = vec![0f32; g.n * g.c * g.in_plane()];
    let (s, k, kk) = (g.stride, g.k, g.k * g.k);
    let (ph, pw) = padded_dims(g);
    par_chunks(&mut out, g.in_plane(), ph * pw, |pad, plane, dst| {
        let taps = &w[kk * (plane % g.c)..kk * (plane % g.c + 1)];
        let gp = &grad[plane * g.out_plane()..(plane + 1) * g.out_plane()];
        pad.fill(0.0);
        for oy in 0..g.oh {
            for ky in 0..k {
                let row = &mut pad[(s * oy + ky) * pw..(s * oy + ky + 1) * pw];
                for kx in 0..k {
                    let kv = taps[k * ky + kx];
                    for ox in 0..g.ow {
                        row[s * ox + kx] += kv * gp[oy * g.ow + ox];
                    }
                }
            }
        }
        for y in 0..g.h {
            let from = (y + g.pt) * pw + g.pl;
            dst[y * g.w..(y + 1) * g.w].copy_from_slice(&pad[from..from + g.w]);
        }
    });
    out
}

/// Gradient of the weight: per channel, correlate the padded input with
/// the output gradient, summed over the batch in f64.
fn backward_weight(g: &Geom, x: &[f32], grad: &[f32]) -> Vec<f32> {
    let (s, k, kk) = (g.stride, g.k, g.k * g.k);
    let (ph, pw) = padded_dims(g);
    let mut out = vec![0f32; g.c * kk];
    par_chunks(&mut out, kk, ph * pw, |pad, ch, dst| {
        let mut acc = vec![0f64; kk];
        for n in 0..g.n {
            let plane = n * g.c + ch;
            let src = &x[plane * g.in_plane()..(plane + 1) * g.in_plane()];
            pad.fill(0.0);
            for y in 0..g.h {
                let to = (y + g.pt) * pw + g.pl;
                pad[to..to + g.w].copy_from_slice(&src[y * g.w..(y + 1) * g.w]);
            }
            let gp = &grad[plane * g.out_plane()..(plane + 1) * g.out_plane()];
            for oy in 0..g.oh {
                let grow = &gp[oy * g.ow..(oy + 1) * g.ow];
                for ky in 0..k {
                    let row = &pad[(s * oy + ky) * pw..(s * oy + ky + 1) * pw];
                    for kx in 0..k {
                        let dot: f32 = grow
                            .iter()
                            .enumerate()
                            .map(|(ox, &gv)| gv * row[s * ox + kx])
                            .sum();
                        acc[k * ky + kx] += dot as f64;
                    }
                }
            }
        }
        for (d, a) in dst.iter_mut().zip(acc) {
            *d = a as f32;
        }
    });
    out
}

/// Differentiable depthwise convolution: (x, weight).
struct Depthwise {
    stride: usize,
    padding: Padding,
}

impl Depthwise {
    fn geom(&self, input: &Shape, k: usize) -> Result<Geom> {
        Geom::new(input, k, self.stride, self.padding)
    }
}

impl CustomOp2 for Depthwise {
    fn name(&self) -> &'static str {
        "depthwise"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let g = self.geom(l1.shape(), l2.dims().get(2).copied().unwrap_or(0))?;
        check_weight(&g, l2)?;
        let (x, w) = (contiguous(s1, l1, "input")?, contiguous(s2, l2, "weight")?);
        Ok((
            CpuStorage::F32(forward(&g, x, w, None, false)),
            g.out_shape(),
        ))
    }

    fn bwd(
        &self,
        x: &Tensor,
        w: &Tensor,
        _res: &Tensor,
        grad: &Tensor,
    ) -> Result<(Option<Tensor>, Option<Tensor>)> {
        let grad = grad.contiguous()?;
        let backward = |wrt_input| Backward {
            stride: self.stride,
            padding: self.padding,
            kernel: w.dims().get(2).copied().unwrap_or(0),
            input_shape: x.shape().clone(),
            wrt_input,
        };
        let dx = grad.apply_op2_no_bwd(w, &backward(true))?;
        let dw = x.apply_op2_no_bwd(&grad, &backward(false))?;
        Ok((Some(dx), Some(dw)))
    }
}

/// Backward kernels: (grad, weight) -> dx, or (x, grad) -> dweight.
struct Backward {
    stride: usize,
    padding: Padding,
    kernel: usize,
    input_shape: Shape,
    wrt_input: bool,
}

impl CustomOp2 for Backward {
    fn name(&self) -> &'static str {
        "depthwise-backward"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let g = Geom::new(&self.input_shape, self.kernel, self.stride, self.padding)?;
        let (a, b) = (contiguous(s1, l1, "arg 1")?, contiguous(s2, l2, "arg 2")?);
        if self.wrt_input {
            let dx = backward_input(&g, a, b);
            Ok((CpuStorage::F32(dx), self.input_shape.clone()))
        } else {
            let dw = backward_weight(&g, a, b);
            Ok((CpuStorage::F32(dw), Shape::from((g.c, 1, g.k, g.k))))
        }
    }
}

/// Inference depthwise with fused bias and optional ReLU6: (x, weight, bias).
struct DepthwiseBiasAct {
    stride: usize,
    padding: Padding,
    relu6: bool,
}

impl CustomOp3 for DepthwiseBiasAct {
    fn name(&self) -> &'static str {
        "depthwise-bias-act"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
        s3: &CpuStorage,
        l3: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let k = l2.dims().last().copied().unwrap_or(0);
        let g = Geom::new(l1.shape(), k, self.stride, self.padding)?;
        check_weight(&g, l2)?;
        if l3.dims() != [g.c] {
            candle_core::bail!("depthwise: bias shape {:?} is not [{}]", l3.dims(), g.c);
        }
        let x = contiguous(s1, l1, "input")?;
        let (w, b) = (contiguous(s2, l2, "weight")?, contiguous(s3, l3, "bias")?);
        let out = forward(&g, x, w, Some(b), self.relu6);
        Ok((CpuStorage::F32(out), g.out_shape()))
    }
}

/// Depthwise 3x3 convolution, padding 1, of `x` (N, C, H, W) with `weight`
/// (C, 1, 3, 3), like `conv2d(x, weight, 1, stride, 1, C)`. Differentiable.
pub fn depthwise_conv3x3(x: &Tensor, weight: &Tensor, stride: usize) -> Result<Tensor> {
    if weight.dims().get(2..) != Some(&[3, 3][..]) {
        candle_core::bail!("depthwise 3x3: weight shape {:?}", weight.dims());
    }
    depthwise_conv(x, weight, stride, Padding::Symmetric(1))
}

/// Depthwise convolution of `x` (N, C, H, W) with `weight` (C, 1, K, K),
/// K 3 or 5, stride 1 or 2, padded as `padding` says. Differentiable.
pub fn depthwise_conv(
    x: &Tensor,
    weight: &Tensor,
    stride: usize,
    padding: Padding,
) -> Result<Tensor> {
    x.contiguous()?
        .apply_op2(&weight.contiguous()?, Depthwise { stride, padding })
}

/// Inference-only depthwise 3x3, padding 1, with a per-channel `bias` (C)
/// added and, if `relu6`, the result clamped to [0, 6]. Not differentiable.
pub fn depthwise_conv3x3_bias_act(
    x: &Tensor,
    weight: &Tensor,
    bias: &Tensor,
    stride: usize,
    relu6: bool,
) -> Result<Tensor> {
    depthwise_conv_bias_act(x, weight, bias, stride, Padding::Symmetric(1), relu6)
}

/// Inference-only depthwise convolution of `x` (N, C, H, W) with `weight`
/// (C, 1, K, K), K 3 or 5, stride 1 or 2, padded as `padding` says, plus a
/// per-channel `bias` (C) and, if `relu6`, clamped to [0, 6].
pub fn depthwise_conv_bias_act(
    x: &Tensor,
    weight: &Tensor,
    bias: &Tensor,
    stride: usize,
    padding: Padding,
    relu6: bool,
) -> Result<Tensor> {
    x.contiguous()?.apply_op3_no_bwd(
        &weight.contiguous()?,
        &bias.contiguous()?,
        &DepthwiseBiasAct {
            stride,
            padding,
            relu6,
        },
    )
}

#[cfg(target_arch = "x86_64")]
mod small;
#[cfg(test)]
mod tests;
