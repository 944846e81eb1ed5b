//! 1x1 convolutions of maps of at most [`MAX_PIXELS`] pixels: the last
//! stage of EfficientNet-Lite at the shipped 128-pixel input (4 x 4 maps,
//! 192 to 1280 channels), where `gemm` spends its time packing and in its
//! narrow kernel (18 % of a frame on one thread).
//!
//! The weights are packed once, at the first such map, into blocks of 16
//! output channels, `[block][cin][16]`, each block one contiguous stream.
//! A tile then keeps 16 output channels of up to 16 pixels in 16 AVX-512
//! registers (one per pixel) and, for each input channel, loads 16 weights
//! and multiplies them by each pixel's input broadcast from memory. Every
//! output is summed over the input channels in order, as `gemm` sums it up
//! to rounding. Only for CPUs with AVX-512: elsewhere the caller uses
//! `gemm`, and wider maps stay there too (from 64 pixels `gemm` is faster).
//! f16 weights were measured too: 3 % faster on these layers alone, no
//! faster in the frame; the kernel is not bound by the weights' bytes, so
//! they stay f32 (BENCHMARKS.md).

use super::packed::{available, PackCache, Packed};

/// Largest map (pixels per image) this kernel takes.
pub const MAX_PIXELS: usize = 16;
/// Output channels per block: one AVX-512 register of f32.
const LANES: usize = 16;

/// A layer's packed weights, built on first use: for maps of at most
/// [`MAX_PIXELS`] pixels (this kernel's) and for wider ones (`wide`'s).
/// Owned by the layer next to its weight tensor; a new weight needs a new
/// cache.
#[derive(Debug, Default)]
pub struct NarrowCache {
    narrow: PackCache,
    pub(super) wide: super::wide::WideCache,
}

impl NarrowCache {
    /// Whether a map of at most [`MAX_PIXELS`] pixels has packed the
    /// weights (it never does without AVX-512).
    pub fn is_packed(&self) -> bool {
        self.narrow.is_packed()
    }

    /// Whether a wider map has packed the weights for the wide kernel
    /// (never without AVX-512).
    pub fn is_packed_wide(&self) -> bool {
        self.wide.is_packed()
    }

    /// The packed form of `weight` (cout x cin), or `None` when this CPU
    /// has no AVX-512 or the cache was packed for another shape (the
    /// caller then uses `gemm`). Packs on the first call; later calls must
    /// pass the same weight.
    pub(super) fn packed(&self, weight: &[f32], cout: usize, cin: usize) -> Option<&Packed> {
        self.narrow.packed(weight, cout, cin, LANES)
    }
}

/// A layer's operands: the input, bias and residual of every image.
pub(super) struct Layer<'a> {
    pub x: &'a [f32],
    pub bias: &'a [f32],
    pub residual: Option<&'a [f32]>,
    pub cin: usize,
    pub cout: usize,
    pub hw: usize,
    pub relu6: bool,
}

/// Every image's output `out` (N, cout, hw), one job per block of 16
/// output channels, on candle's rayon pool.
pub(super) fn run(packed: &Packed, layer: &Layer, n: usize, out: &mut [f32]) {
    use rayon::prelude::*;
    let (cout, hw) = (layer.cout, layer.hw);
    let blocks = cout.div_ceil(LANES);
    let ptr = crate::ops::cpu::SendPtr(out.as_mut_ptr());
    (0..n * blocks).into_par_iter().for_each(|job| {
        let (img, b) = (job / blocks, job % blocks);
        let rows = b * LANES..((b + 1) * LANES).min(cout);
        let at = img * cout * hw + rows.start * hw;
        let len = rows.len() * hw;
        let args = BlockArgs {
            x: &layer.x[img * layer.cin * hw..(img + 1) * layer.cin * hw],
            bias: &layer.bias[rows],
            residual: layer.residual.map(|r| &r[at..at + len]),
            hw,
            relu6: layer.relu6,
        };
        // SAFETY: each job owns its image's block of rows, in bounds.
        let dst = unsafe { std::slice::from_raw_parts_mut(ptr.at(at), len) };
        run_block(packed, b, &args, dst);
    });
}

/// One output block's operands: 16 (or fewer, in the last block) output
/// channels of one image.
struct BlockArgs<'a> {
    /// The image's input, `cin x hw`.
    x: &'a [f32],
    /// The block's bias and residual rows (`rows x hw`), if any.
    bias: &'a [f32],
    residual: Option<&'a [f32]>,
    hw: usize,
    relu6: bool,
}

/// Writes `out` (the block's `rows x hw` outputs, rows = `args.bias.len()`)
/// for block `b` of `packed`.
fn run_block(packed: &Packed, b: usize, args: &BlockArgs, out: &mut [f32]) {
    assert!(available(), "narrow pointwise kernel without AVX-512");
    let rows = args.bias.len();
    assert!(args.hw <= MAX_PIXELS && rows <= LANES && out.len() == rows * args.hw);
    assert!(args.x.len() == packed.cin * args.hw);
    assert!(args.residual.is_none_or(|r| r.len() == out.len()));
    #[cfg(target_arch = "x86_64")]
    // SAFETY: AVX-512 checked above; the asserts keep every access in bounds.
    unsafe {
        avx512::block(packed.block(b), packed.cin, args, out)
    }
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::{BlockArgs, LANES};
    use std::arch::x86_64::*;

    /// The block's outputs in pixel tiles of 16, 8, 4, 2 and 1 (a 4 x 4
    /// map is one tile).
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn block(w: &[f32], cin: usize, a: &BlockArgs, out: &mut [f32]) {
        let mut p0 = 0;
        for width in [16, 8, 4, 2, 1] {
            while a.hw - p0 >= width {
                match width {
                    16 => tile::<16>(w, cin, a, p0, out),
                    8 => tile::<8>(w, cin, a, p0, out),
                    4 => tile::<4>(w, cin, a, p0, out),
                    2 => tile::<2>(w, cin, a, p0, out),
                    _ => tile::<1>(w, cin, a, p0, out),
                }
                p0 += width;
            }
        }
    }

    /// Pixels `p0..p0 + NP`: register `acc[p]` holds pixel p's 16 output
    /// channels.
    #[inline(always)]
    unsafe fn tile<const NP: usize>(
        w: &[f32],
        cin: usize,
        a: &BlockArgs,
        p0: usize,
        out: &mut [f32],
    ) {
        let (wp, xp) = (w.as_ptr(), a.x.as_ptr().add(p0));
        let mut acc = [_mm512_setzero_ps(); NP];
        for c in 0..cin {
            let weights = _mm512_loadu_ps(wp.add(c * LANES));
            let x = xp.add(c * a.hw);
            for (p, acc) in acc.iter_mut().enumerate() {
                *acc = _mm512_fmadd_ps(weights, _mm512_set1_ps(*x.add(p)), *acc);
            }
        }
        let mut sums = [[0f32; LANES]; NP];
        for (s, acc) in sums.iter_mut().zip(acc) {
            _mm512_storeu_ps(s.as_mut_ptr(), acc);
        }
        let (lo, hi) = if a.relu6 {
            (0.0, 6.0)
        } else {
            (f32::NEG_INFINITY, f32::INFINITY)
        };
        for (o, &bias) in a.bias.iter().enumerate() {
            let at = o * a.hw + p0;
            for (p, s) in sums.iter().enumerate() {
                let residual = a.residual.map_or(0.0, |r| r[at + p]);
                out[at + p] = (s[o] + bias + residual).clamp(lo, hi);
            }
        }
    }
}
