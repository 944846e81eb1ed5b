//! Depthwise 3x3 convolution (padding 1, stride 1 or 2) as candle custom ops.
//!
//! candle's grouped convolution splits the input into one convolution per
//! channel, which is slow for MobileNetV2's depthwise layers. These kernels
//! work plane by plane (one image, one channel) in NCHW layout, in parallel
//! over planes on candle's rayon pool. Each plane is first copied into a
//! zero-padded scratch buffer (de-interleaved by column parity for stride 2)
//! so that the inner loops have no bounds special cases and vectorize.
//!
//! - [`depthwise_conv3x3`]: differentiable (input and weight gradients).
//! - [`depthwise_conv3x3_bias_act`]: inference, with a fused per-channel bias
//!   (folded batch norm) and optional ReLU6.

use super::cpu::{alloc_uninit, par_chunks, simd_dispatch};
use candle_core::{CpuStorage, CustomOp2, CustomOp3, Layout, Result, Shape, Tensor};

/// Output size of a 3x3 convolution with padding 1.
pub fn out_size(size: usize, stride: usize) -> usize {
    (size + 2 - 3) / stride + 1
}

/// Geometry of one depthwise call.
#[derive(Clone, Copy, Debug)]
struct Geom {
    n: usize,
    c: usize,
    h: usize,
    w: usize,
    oh: usize,
    ow: usize,
    stride: usize,
}

impl Geom {
    fn new(shape: &Shape, stride: usize) -> Result<Self> {
        if stride != 1 && stride != 2 {
            candle_core::bail!("depthwise3x3: stride must be 1 or 2, got {stride}");
        }
        let (n, c, h, w) = shape.dims4()?;
        if h == 0 || w == 0 {
            candle_core::bail!("depthwise3x3: empty spatial size {h}x{w}");
        }
        Ok(Self {
            n,
            c,
            h,
            w,
            oh: out_size(h, stride),
            ow: out_size(w, stride),
            stride,
        })
    }

    fn in_plane(&self) -> usize {
        self.h * self.w
    }

    fn out_plane(&self) -> usize {
        self.oh * self.ow
    }

    /// Width of one padded scratch row (both parities side by side for stride 2).
    fn pad_w(&self) -> usize {
        if self.stride == 1 {
            self.w + 2
        } else {
            // even columns then odd columns, each ceil((w + 2) / 2) long
            2 * (self.w + 3).div_euclid(2)
        }
    }

    fn pad_len(&self) -> usize {
        (self.h + 2) * self.pad_w()
    }

    fn out_shape(&self) -> Shape {
        Shape::from((self.n, self.c, self.oh, self.ow))
    }
}

fn contiguous<'a>(s: &'a CpuStorage, l: &Layout, what: &str) -> Result<&'a [f32]> {
    super::cpu::f32_slice("depthwise3x3", s, l, what)
}

fn check_weight(g: &Geom, l: &Layout) -> Result<()> {
    let dims = l.dims();
    if dims != [g.c, 1, 3, 3] {
        candle_core::bail!(
            "depthwise3x3: weight shape {dims:?} does not match [{}, 1, 3, 3]",
            g.c
        );
    }
    Ok(())
}

/// Copies a plane into `pad` with a zero border of one pixel. For stride 2
/// the padded columns are split: even columns first, then odd columns.
#[inline(always)]
fn pad_plane(g: &Geom, src: &[f32], pad: &mut [f32]) {
    let pw = g.pad_w();
    pad[..pw].fill(0.0);
    pad[(g.h + 1) * pw..].fill(0.0);
    for y in 0..g.h {
        let row = &src[y * g.w..(y + 1) * g.w];
        let dst = &mut pad[(y + 1) * pw..(y + 2) * pw];
        if g.stride == 1 {
            dst[0] = 0.0;
            dst[1..=g.w].copy_from_slice(row);
            dst[g.w + 1] = 0.0;
        } else {
            // padded column j holds row[j - 1]; even j -> even[j / 2], odd j -> odd[j / 2].
            // So row[2t] -> odd[t] and row[2t + 1] -> even[t + 1].
            let half = pw / 2;
            dst.fill(0.0);
            let (even, odd) = dst.split_at_mut(half);
            let pairs = row.chunks_exact(2);
            if let [last] = pairs.remainder() {
                odd[g.w / 2] = *last;
            }
            for ((pair, o), e) in pairs.zip(odd.iter_mut()).zip(even[1..].iter_mut()) {
                *o = pair[0];
                *e = pair[1];
            }
        }
    }
}

/// One output plane from a padded input plane: dst = act(bias + conv(pad, k)).
#[inline(always)]
fn conv_plane_body(g: &Geom, pad: &[f32], k: &[f32], bias: f32, relu6: bool, dst: &mut [f32]) {
    let pw = g.pad_w();
    let ow = g.ow;
    for (oy, out) in dst.chunks_exact_mut(ow).enumerate() {
        out.fill(bias);
        for ky in 0..3 {
            let r = &pad[(g.stride * oy + ky) * pw..(g.stride * oy + ky + 1) * pw];
            let (k0, k1, k2) = (k[3 * ky], k[3 * ky + 1], k[3 * ky + 2]);
            // taps: stride 1 -> r[x], r[x+1], r[x+2]; stride 2 -> even[x], odd[x], even[x+1]
            let (a, b, c) = if g.stride == 1 {
                (&r[..ow], &r[1..ow + 1], &r[2..ow + 2])
            } else {
                let half = pw / 2;
                (&r[..ow], &r[half..half + ow], &r[1..ow + 1])
            };
            for (((o, &a), &b), &c) in out.iter_mut().zip(a).zip(b).zip(c) {
                *o += k0 * a + k1 * b + k2 * c;
            }
        }
        if relu6 {
            for o in out.iter_mut() {
                *o = o.clamp(0.0, 6.0);
            }
        }
    }
}

simd_dispatch! {
/// [`conv_plane_body`] on the widest vector unit this CPU has.
fn conv_plane(g: &Geom, pad: &[f32], k: &[f32], bias: f32, relu6: bool, dst: &mut [f32]) {
    conv_plane_body(g, pad, k, bias, relu6, dst)
}
}

/// Forward over all planes, in parallel.
fn forward(g: &Geom, x: &[f32], w: &[f32], bias: Option<&[f32]>, relu6: bool) -> Vec<f32> {
    // every element is written by conv_plane (which starts from the bias)
    let mut out = alloc_uninit(g.n * g.c * g.out_plane());
    par_chunks(&mut out, g.out_plane(), g.pad_len(), |pad, plane, dst| {
        let ch = plane % g.c;
        pad_plane(g, &x[plane * g.in_plane()..(plane + 1) * g.in_plane()], pad);
        let b = bias.map_or(0.0, |b| b[ch]);
        conv_plane(g, pad, &w[9 * ch..9 * ch + 9], b, relu6, dst);
    });
    out
}

/// Gradient of the input: scatter every output gradient back through the taps.
fn backward_input(g: &Geom, grad: &[f32], w: &[f32]) -> Vec<f32> {
    let mut out = vec![0f32; g.n * g.c * g.in_plane()];
    let (s, ph, pw) = (g.stride, g.h + 2, g.w + 2);
    par_chunks(&mut out, g.in_plane(), ph * pw, |pad, plane, dst| {
        let k = &w[9 * (plane % g.c)..9 * (plane % g.c) + 9];
        let gp = &grad[plane * g.out_plane()..(plane + 1) * g.out_plane()];
        pad.fill(0.0);
        for oy in 0..g.oh {
            for ky in 0..3 {
                let row = &mut pad[(s * oy + ky) * pw..(s * oy + ky + 1) * pw];
                for kx in 0..3 {
                    let kv = k[3 * ky + kx];
                    for ox in 0..g.ow {
                        row[s * ox + kx] += kv * gp[oy * g.ow + ox];
                    }
                }
            }
        }
        for y in 0..g.h {
            dst[y * g.w..(y + 1) * g.w]
                .copy_from_slice(&pad[(y + 1) * pw + 1..(y + 1) * pw + 1 + g.w]);
        }
    });
    out
}

/// Gradient of the weight: per channel, correlate the input with the output gradient.
fn backward_weight(g: &Geom, x: &[f32], grad: &[f32]) -> Vec<f32> {
    let (s, pw) = (g.stride, g.w + 2);
    let mut out = vec![0f32; g.c * 9];
    par_chunks(&mut out, 9, (g.h + 2) * pw, |pad, ch, dst| {
        let mut acc = [0f64; 9];
        for n in 0..g.n {
            let plane = n * g.c + ch;
            let src = &x[plane * g.in_plane()..(plane + 1) * g.in_plane()];
            pad.fill(0.0);
            for y in 0..g.h {
                pad[(y + 1) * pw + 1..(y + 1) * pw + 1 + g.w]
                    .copy_from_slice(&src[y * g.w..(y + 1) * g.w]);
            }
            let gp = &grad[plane * g.out_plane()..(plane + 1) * g.out_plane()];
            for oy in 0..g.oh {
                let grow = &gp[oy * g.ow..(oy + 1) * g.ow];
                for ky in 0..3 {
                    let row = &pad[(s * oy + ky) * pw..(s * oy + ky + 1) * pw];
                    for kx in 0..3 {
                        let dot: f32 = grow
                            .iter()
                            .enumerate()
                            .map(|(ox, &gv)| gv * row[s * ox + kx])
                            .sum();
                        acc[3 * ky + kx] += dot as f64;
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

/// Differentiable depthwise 3x3 convolution: (x, weight[C, 1, 3, 3]).
struct Depthwise3x3 {
    stride: usize,
}

impl CustomOp2 for Depthwise3x3 {
    fn name(&self) -> &'static str {
        "depthwise3x3"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let g = Geom::new(l1.shape(), self.stride)?;
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
        let dx = grad.apply_op2_no_bwd(
            w,
            &Backward {
                stride: self.stride,
                input_shape: x.shape().clone(),
                wrt_input: true,
            },
        )?;
        let dw = x.apply_op2_no_bwd(
            &grad,
            &Backward {
                stride: self.stride,
                input_shape: x.shape().clone(),
                wrt_input: false,
            },
        )?;
        Ok((Some(dx), Some(dw)))
    }
}

/// Backward kernels: (grad, weight) -> dx, or (x, grad) -> dweight.
struct Backward {
    stride: usize,
    input_shape: Shape,
    wrt_input: bool,
}

impl CustomOp2 for Backward {
    fn name(&self) -> &'static str {
        "depthwise3x3-backward"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let g = Geom::new(&self.input_shape, self.stride)?;
        let (a, b) = (contiguous(s1, l1, "arg 1")?, contiguous(s2, l2, "arg 2")?);
        if self.wrt_input {
            let dx = backward_input(&g, a, b);
            Ok((CpuStorage::F32(dx), self.input_shape.clone()))
        } else {
            let dw = backward_weight(&g, a, b);
            Ok((CpuStorage::F32(dw), Shape::from((g.c, 1, 3, 3))))
        }
    }
}

/// Inference depthwise 3x3 with fused bias and optional ReLU6: (x, weight, bias).
struct Depthwise3x3BiasAct {
    stride: usize,
    relu6: bool,
}

impl CustomOp3 for Depthwise3x3BiasAct {
    fn name(&self) -> &'static str {
        "depthwise3x3-bias-act"
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
        let g = Geom::new(l1.shape(), self.stride)?;
        check_weight(&g, l2)?;
        if l3.dims() != [g.c] {
            candle_core::bail!("depthwise3x3: bias shape {:?} is not [{}]", l3.dims(), g.c);
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
    x.contiguous()?
        .apply_op2(&weight.contiguous()?, Depthwise3x3 { stride })
}

/// Inference-only depthwise 3x3 with a per-channel `bias` (C) added and, if
/// `relu6`, the result clamped to [0, 6]. Not differentiable.
pub fn depthwise_conv3x3_bias_act(
    x: &Tensor,
    weight: &Tensor,
    bias: &Tensor,
    stride: usize,
    relu6: bool,
) -> Result<Tensor> {
    x.contiguous()?.apply_op3_no_bwd(
        &weight.contiguous()?,
        &bias.contiguous()?,
        &Depthwise3x3BiasAct { stride, relu6 },
    )
}
