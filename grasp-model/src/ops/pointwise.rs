//! Pointwise (1x1, stride 1) convolutions as matrix products.
//!
//! In NCHW a 1x1 convolution of one image is `W[cout, cin] @ X[cin, H*W]`.
//! - [`pointwise_conv`]: differentiable, through candle's batched matmul.
//! - [`pointwise_conv_bias_act`]: inference, a custom op that runs `gemm`
//!   on column tiles of each image (parallel over images and tiles on
//!   candle's rayon pool) and applies the bias, the optional residual and
//!   the optional ReLU6 while the tile is still in cache.
//! - [`pointwise_conv_bias_act_cached`]: the same, with the layer's
//!   [`NarrowCache`], so that on AVX-512 CPUs maps of at most 16 pixels run
//!   the `narrow` kernel and wider ones the `wide` kernel, both on weights
//!   packed once, with no `gemm`.

mod narrow;
mod packed;
mod wide;

pub use narrow::{NarrowCache, MAX_PIXELS as NARROW_MAX_PIXELS};

/// Whether this CPU runs the narrow kernel (AVX-512); without it every map
/// goes through `gemm`.
pub fn narrow_kernel_available() -> bool {
    packed::available()
}

use super::cpu::{alloc_uninit, par_chunks, simd_dispatch, SendPtr};
use super::depthwise::Padding;
use candle_core::{CpuStorage, CustomOp3, Layout, Result, Shape, Tensor};
use rayon::prelude::*;

/// Most columns (pixels) per tile: keeps a `cout x TILE` output tile in L2.
const MAX_TILE: usize = 1024;
/// Fewest jobs per call, so that a single image still uses every thread.
const MIN_JOBS: usize = 4;

/// Splits each image's `cout x hw` output into jobs: column tiles when the
/// image has more pixels than output channels, row blocks otherwise (the
/// 7x7 and 14x14 layers with hundreds of channels). A job packs its rows of
/// the weights and its columns of the input, so splitting the larger side
/// packs the least; large tiles matter.
struct Tiling {
    cout: usize,
    hw: usize,
    tile: usize,
    col_tiles: usize,
    row_block: usize,
    row_blocks: usize,
    jobs_per_image: usize,
    n: usize,
}

impl Tiling {
    fn new(n: usize, cout: usize, hw: usize) -> Self {
        let tile = if hw >= cout {
            hw.div_ceil(MIN_JOBS)
                .next_multiple_of(16)
                .clamp(16, MAX_TILE)
        } else {
            hw.clamp(1, MAX_TILE)
        };
        let col_tiles = hw.div_ceil(tile);
        let want_rows = MIN_JOBS.div_ceil(col_tiles).max(1);
        let row_block = cout
            .div_ceil(want_rows)
            .next_multiple_of(16)
            .min(cout)
            .max(1);
        let row_blocks = cout.div_ceil(row_block);
        Self {
            cout,
            hw,
            tile,
            col_tiles,
            row_block,
            row_blocks,
            jobs_per_image: col_tiles * row_blocks,
            n,
        }
    }

    fn jobs(&self) -> usize {
        self.n * self.jobs_per_image
    }

    /// (image, first column, columns, first row, rows) of a job.
    fn job(&self, job: usize) -> (usize, usize, usize, usize, usize) {
        let img = job / self.jobs_per_image;
        let rest = job % self.jobs_per_image;
        let (ct, rb) = (rest % self.col_tiles, rest / self.col_tiles);
        let c0 = ct * self.tile;
        let r0 = rb * self.row_block;
        let cols = self.tile.min(self.hw - c0);
        let rows = self.row_block.min(self.cout - r0);
        debug_assert!(rb < self.row_blocks);
        (img, c0, cols, r0, rows)
    }
}

/// Differentiable 1x1 convolution of `x` (N, Cin, H, W) with `weight`
/// (Cout, Cin, 1, 1) or (Cout, Cin).
pub fn pointwise_conv(x: &Tensor, weight: &Tensor) -> Result<Tensor> {
    let (n, cin, h, w) = x.dims4()?;
    let cout = weight.dim(0)?;
    let wm = weight.reshape((cout, cin))?;
    let xm = x.reshape((n, cin, h * w))?;
    wm.broadcast_matmul(&xm)?.reshape((n, cout, h, w))
}

/// Inference 1x1 convolution: `act(weight @ x + bias [+ residual])`.
/// `weight` is (Cout, Cin, 1, 1) or (Cout, Cin); `bias` is (Cout).
pub fn pointwise_conv_bias_act(
    x: &Tensor,
    weight: &Tensor,
    bias: &Tensor,
    residual: Option<&Tensor>,
    relu6: bool,
) -> Result<Tensor> {
    run_op(x, weight, bias, None, residual, relu6)
}

/// [`pointwise_conv_bias_act`] for a layer that keeps its packed weights in
/// `cache` (one cache per weight tensor): maps of at most 16 pixels then
/// skip `gemm` on CPUs with AVX-512.
pub fn pointwise_conv_bias_act_cached(
    x: &Tensor,
    weight: &Tensor,
    bias: &Tensor,
    cache: &NarrowCache,
    residual: Option<&Tensor>,
    relu6: bool,
) -> Result<Tensor> {
    run_op(x, weight, bias, Some(cache), residual, relu6)
}

fn run_op(
    x: &Tensor,
    weight: &Tensor,
    bias: &Tensor,
    narrow: Option<&NarrowCache>,
    residual: Option<&Tensor>,
    relu6: bool,
) -> Result<Tensor> {
    let op = PointwiseBiasAct {
        relu6,
        residual: residual.map(|r| r.contiguous()).transpose()?,
        narrow,
    };
    x.contiguous()?
        .apply_op3_no_bwd(&weight.contiguous()?, &bias.contiguous()?, &op)
}

struct PointwiseBiasAct<'a> {
    relu6: bool,
    residual: Option<Tensor>,
    narrow: Option<&'a NarrowCache>,
}

fn f32_slice<'a>(s: &'a CpuStorage, l: &Layout, what: &str) -> Result<&'a [f32]> {
    super::cpu::f32_slice("pointwise conv", s, l, what)
}

impl CustomOp3 for PointwiseBiasAct<'_> {
    fn name(&self) -> &'static str {
        "pointwise-bias-act"
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
        let (n, cin, h, w) = l1.shape().dims4()?;
        let cout = l2.dims()[0];
        if l2.shape().elem_count() != cout * cin || l3.dims() != [cout] {
            candle_core::bail!(
                "pointwise conv: weight {:?} / bias {:?} do not fit {cin} -> {cout} channels",
                l2.dims(),
                l3.dims()
            );
        }
        let x = f32_slice(s1, l1, "input")?;
        let wt = f32_slice(s2, l2, "weight")?;
        let bias = f32_slice(s3, l3, "bias")?;
        let res_guard = match &self.residual {
            Some(r) => {
                if r.dims() != [n, cout, h, w] {
                    candle_core::bail!("pointwise conv: residual shape {:?}", r.dims());
                }
                Some(r.storage_and_layout())
            }
            None => None,
        };
        let residual = match &res_guard {
            Some((storage, layout)) => match &**storage {
                candle_core::Storage::Cpu(s) => Some(f32_slice(s, layout, "residual")?),
                _ => candle_core::bail!("pointwise conv: residual must be on the CPU"),
            },
            None => None,
        };
        let hw = h * w;
        // every element is written by run_tile, narrow::run or wide::run
        let mut out = alloc_uninit(n * cout * hw);
        let layer = narrow::Layer {
            x,
            bias,
            residual,
            cin,
            cout,
            hw,
            relu6: self.relu6,
        };
        if let Some(cache) = self.narrow {
            if run_packed(cache, wt, &layer, n, &mut out) {
                return Ok((CpuStorage::F32(out), Shape::from((n, cout, h, w))));
            }
        }
        let plan = Tiling::new(n, cout, hw);
        let ptr = SendPtr(out.as_mut_ptr());
        (0..plan.jobs()).into_par_iter().for_each(|job| {
            let (img, c0, cols, r0, rows) = plan.job(job);
            // SAFETY: each job owns rows r0..r0+rows, columns c0..c0+cols of its image.
            unsafe {
                let dst = ptr.at(img * cout * hw + r0 * hw + c0);
                run_tile(
                    TileArgs {
                        x: &x[img * cin * hw + c0..],
                        wt: &wt[r0 * cin..(r0 + rows) * cin],
                        bias: &bias[r0..r0 + rows],
                        residual: residual.map(|r| &r[img * cout * hw + r0 * hw + c0..]),
                        cin,
                        cout: rows,
                        hw,
                        cols,
                        relu6: self.relu6,
                    },
                    dst,
                )
            }
        });
        Ok((CpuStorage::F32(out), Shape::from((n, cout, h, w))))
    }
}

/// Runs the layer on weights packed once (`narrow` up to 16 pixels, `wide`
/// above); false when this CPU has neither kernel (no AVX-512), and `gemm`
/// must.
fn run_packed(
    cache: &NarrowCache,
    wt: &[f32],
    layer: &narrow::Layer,
    n: usize,
    out: &mut [f32],
) -> bool {
    let (cout, cin) = (layer.cout, layer.cin);
    if layer.hw <= narrow::MAX_PIXELS {
        let Some(packed) = cache.packed(wt, cout, cin) else {
            return false;
        };
        narrow::run(packed, layer, n, out);
    } else {
        let Some(packed) = cache.wide.packed(wt, cout, cin) else {
            return false;
        };
        wide::run(packed, layer, n, out);
    }
    true
}

struct TileArgs<'a> {
    x: &'a [f32],
    wt: &'a [f32],
    bias: &'a [f32],
    residual: Option<&'a [f32]>,
    cin: usize,
    cout: usize,
    hw: usize,
    cols: usize,
    relu6: bool,
}

/// One output tile `dst[cout, cols]` (row stride `hw`): the product
/// written by `gemm`, then bias, residual and ReLU6 in one pass per row
/// while the tile is in cache.
///
/// # Safety
/// `dst` must point to a `cout x cols` tile with row stride `hw` that no one
/// else touches during the call.
unsafe fn run_tile(a: TileArgs, dst: *mut f32) {
    let hw = a.hw as isize;
    gemm::gemm(
        a.cout,
        a.cols,
        a.cin,
        dst,
        1,
        hw,
        false,
        a.wt.as_ptr(),
        1,
        a.cin as isize,
        a.x.as_ptr(),
        1,
        hw,
        0.0,
        1.0,
        false,
        false,
        false,
        gemm::Parallelism::None,
    );
    for co in 0..a.cout {
        let row = std::slice::from_raw_parts_mut(dst.add(co * a.hw), a.cols);
        let residual = a.residual.map(|r| &r[co * a.hw..co * a.hw + a.cols]);
        epilogue(row, a.bias[co], residual, a.relu6);
    }
}

simd_dispatch! {
/// `row = act(row + bias [+ residual])` on the widest vector unit.
fn epilogue(row: &mut [f32], bias: f32, residual: Option<&[f32]>, relu6: bool) {
    let (lo, hi) = if relu6 { (0.0, 6.0) } else { (f32::NEG_INFINITY, f32::INFINITY) };
    match residual {
        Some(r) => {
            for (o, &v) in row.iter_mut().zip(r) {
                *o = (*o + bias + v).clamp(lo, hi);
            }
        }
        None => {
            for o in row.iter_mut() {
                *o = (*o + bias).clamp(lo, hi);
            }
        }
    }
}
}

/// im2col for a dense 3x3, padding 1 convolution: (N, C, H, W) ->
/// (N, C*9, OH, OW), row `c*9 + ky*3 + kx` holding the input pixel under
/// tap (ky, kx). A dense 3x3 convolution is then a pointwise one with the
/// weight reshaped to (Cout, C*9). Inference only.
pub fn im2col3x3(x: &Tensor, stride: usize) -> Result<Tensor> {
    im2col(x, 3, stride, Padding::Symmetric(1))
}

/// im2col for a dense `k` x `k` convolution with `stride` and `padding`
/// (TensorFlow's SAME too): (N, C, H, W) -> (N, C*k*k, OH, OW), row
/// `c*k*k + ky*k + kx` holding the input pixel under tap (ky, kx), zero in
/// the padding. Inference only.
pub fn im2col(x: &Tensor, k: usize, stride: usize, padding: Padding) -> Result<Tensor> {
    x.contiguous()?
        .apply_op1_no_bwd(&Im2Col { k, stride, padding })
}

struct Im2Col {
    k: usize,
    stride: usize,
    padding: Padding,
}

impl candle_core::CustomOp1 for Im2Col {
    fn name(&self) -> &'static str {
        "im2col"
    }

    fn cpu_fwd(&self, storage: &CpuStorage, l: &Layout) -> Result<(CpuStorage, Shape)> {
        let (n, c, h, w) = l.shape().dims4()?;
        let (s, k) = (self.stride, self.k);
        let (Some((oh, pt)), Some((ow, pl))) =
            (self.padding.resolve(h, k, s), self.padding.resolve(w, k, s))
        else {
            candle_core::bail!("im2col: a {k}x{k} kernel does not fit a {h}x{w} plane");
        };
        let x = f32_slice(storage, l, "input")?;
        let taps = k * k;
        // every element is written below
        let mut out = alloc_uninit(n * c * taps * oh * ow);
        par_chunks(&mut out, oh * ow, 0, |_, row, dst| {
            let (plane, tap) = (row / taps, row % taps);
            let (ky, kx) = (tap / k, tap % k);
            let src = &x[plane * h * w..(plane + 1) * h * w];
            // Outputs lo..hi read input columns s * ox + kx - pl inside the
            // image, the same in every row; the rest are padding.
            let lo = pl.saturating_sub(kx).div_ceil(s).min(ow);
            let hi = (w + pl).saturating_sub(kx).div_ceil(s).clamp(lo, ow);
            for oy in 0..oh {
                let out = &mut dst[oy * ow..(oy + 1) * ow];
                let iy = (s * oy + ky).checked_sub(pt).filter(|iy| *iy < h);
                let Some(iy) = iy else {
                    out.fill(0.0); // padding
                    continue;
                };
                out[..lo].fill(0.0);
                out[hi..].fill(0.0);
                if lo < hi {
                    let from = &src[iy * w + lo * s + kx - pl..(iy + 1) * w];
                    for (d, v) in out[lo..hi].iter_mut().zip(from.iter().step_by(s)) {
                        *d = *v;
                    }
                }
            }
        });
        Ok((CpuStorage::F32(out), Shape::from((n, c * taps, oh, ow))))
    }
}
