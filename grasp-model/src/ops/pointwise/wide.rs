//! 1x1 convolutions of maps wider than the narrow kernel's (more than 16
//! pixels: EfficientNet-Lite's 64 x 64 to 8 x 8 stages at the shipped
//! 128-pixel input), without `gemm`.
//!
//! `gemm` packs both operands on every call and writes its product before
//! the bias, residual and ReLU6 pass over it. Here the weights are packed
//! once, at the first map, into blocks of [`ROWS`] output channels,
//! `[block][cin][ROWS]`, and the input is read in place: its rows are
//! pixel-contiguous in NCHW. A tile keeps [`ROWS`] output channels of up to
//! 64 pixels in 24 AVX-512 registers; per input channel it loads four
//! vectors of pixels and broadcasts each channel's weight. The epilogue
//! runs on the registers, so each output is written once. Every output is
//! summed over the input channels in order from zero, then the bias and
//! the residual are added: `gemm`'s sums up to rounding (1e-6 on these
//! layers). AVX-512 only; elsewhere the caller uses `gemm`.

use super::packed::{available, PackCache, Packed};

/// Output channels per block (six rows of four vectors: 24 accumulators).
pub(super) const ROWS: usize = 6;
/// Pixels per tile: four AVX-512 vectors of f32.
const TILE: usize = 64;
/// Fewest jobs per call, so that one image still uses every thread.
const MIN_JOBS: usize = 4;

/// A layer's wide packing (blocks of [`ROWS`] outputs).
#[derive(Debug, Default)]
pub(super) struct WideCache(PackCache);

impl WideCache {
    pub(super) fn is_packed(&self) -> bool {
        self.0.is_packed()
    }

    /// See [`PackCache::packed`].
    pub(super) fn packed(&self, weight: &[f32], cout: usize, cin: usize) -> Option<&Packed> {
        self.0.packed(weight, cout, cin, ROWS)
    }
}

/// Which pixels and output blocks one job computes: pixel tiles when a map
/// has at least [`MIN_JOBS`] of them, otherwise blocks of output rows.
struct Split {
    tiles: usize,
    blocks: usize,
    tiles_per_job: usize,
    blocks_per_job: usize,
}

impl Split {
    fn new(hw: usize, cout: usize) -> Self {
        let tiles = hw.div_ceil(TILE);
        let blocks = cout.div_ceil(ROWS);
        let tiles_per_job = tiles.div_ceil(MIN_JOBS).max(1);
        let tile_jobs = tiles.div_ceil(tiles_per_job);
        let want = MIN_JOBS.div_ceil(tile_jobs);
        let blocks_per_job = blocks.div_ceil(want).max(1);
        Split {
            tiles,
            blocks,
            tiles_per_job,
            blocks_per_job,
        }
    }

    fn per_image(&self) -> usize {
        self.tiles.div_ceil(self.tiles_per_job) * self.blocks.div_ceil(self.blocks_per_job)
    }

    /// (pixel tiles, output blocks) of job `j` of one image.
    fn job(&self, j: usize) -> (std::ops::Range<usize>, std::ops::Range<usize>) {
        let tile_jobs = self.tiles.div_ceil(self.tiles_per_job);
        let (t, b) = (j % tile_jobs, j / tile_jobs);
        let t0 = t * self.tiles_per_job;
        let b0 = b * self.blocks_per_job;
        (
            t0..(t0 + self.tiles_per_job).min(self.tiles),
            b0..(b0 + self.blocks_per_job).min(self.blocks),
        )
    }
}

/// Every image's output `out` (N, cout, hw) on candle's rayon pool.
pub(super) fn run(packed: &Packed, layer: &super::narrow::Layer, n: usize, out: &mut [f32]) {
    use rayon::prelude::*;
    assert!(available(), "wide pointwise kernel without AVX-512");
    let (cin, cout, hw) = (layer.cin, layer.cout, layer.hw);
    assert!(packed.cin == cin && packed.cout == cout);
    assert!(layer.x.len() >= n * cin * hw && out.len() == n * cout * hw);
    assert!(layer.bias.len() == cout && layer.residual.is_none_or(|r| r.len() == out.len()));
    let split = Split::new(hw, cout);
    let per_image = split.per_image();
    let ptr = crate::ops::cpu::SendPtr(out.as_mut_ptr());
    (0..n * per_image).into_par_iter().for_each(|job| {
        let img = job / per_image;
        let (tiles, blocks) = split.job(job % per_image);
        // pixel tiles outermost: a tile's inputs stay in L1 across blocks
        for t in tiles {
            let cols = t * TILE..((t + 1) * TILE).min(hw);
            for b in blocks.clone() {
                let rows = b * ROWS..((b + 1) * ROWS).min(cout);
                #[cfg(target_arch = "x86_64")]
                // SAFETY: AVX-512 checked above; the job owns rows x cols of
                // its image's output, and the asserts keep every read of the
                // input, bias and residual in bounds.
                unsafe {
                    avx512::tile(packed.block(b), layer, img, rows, cols.clone(), ptr)
                }
            }
        }
    });
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::ROWS;
    use crate::ops::cpu::SendPtr;
    use crate::ops::pointwise::narrow::Layer;
    use std::arch::x86_64::*;
    use std::ops::Range;

    /// The mask of the first `n` of 16 lanes.
    #[inline(always)]
    fn lanes(n: usize) -> __mmask16 {
        if n >= 16 {
            0xffff
        } else {
            (1u16 << n) - 1
        }
    }

    /// Outputs `rows` x `cols` (at most 6 x 64) of image `img`; `w` is the
    /// rows' packed block.
    ///
    /// # Safety
    /// AVX-512F; `rows` and `cols` inside the layer; no other thread writes
    /// these outputs.
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn tile(
        w: &[f32],
        l: &Layer,
        img: usize,
        rows: Range<usize>,
        cols: Range<usize>,
        out: SendPtr,
    ) {
        let (cin, cout, hw) = (l.cin, l.cout, l.hw);
        let width = cols.len();
        let m = [0, 1, 2, 3].map(|v| lanes(width.saturating_sub(16 * v)));
        let x = l.x.as_ptr().add(img * cin * hw + cols.start);
        let mut acc = [[_mm512_setzero_ps(); 4]; ROWS];
        let wp = w.as_ptr();
        for c in 0..cin {
            let xr = x.add(c * hw);
            let xv = [0, 1, 2, 3].map(|v| _mm512_maskz_loadu_ps(m[v], xr.add(16 * v)));
            for (r, acc) in acc.iter_mut().enumerate() {
                let wv = _mm512_set1_ps(*wp.add(c * ROWS + r));
                for v in 0..4 {
                    acc[v] = _mm512_fmadd_ps(wv, xv[v], acc[v]);
                }
            }
        }
        let (lo, hi) = (_mm512_setzero_ps(), _mm512_set1_ps(6.0));
        for (r, o) in rows.enumerate() {
            let at = img * cout * hw + o * hw + cols.start;
            let bias = _mm512_set1_ps(l.bias[o]);
            for v in 0..4 {
                if m[v] == 0 {
                    break;
                }
                let mut y = _mm512_add_ps(acc[r][v], bias);
                if let Some(res) = l.residual {
                    let rv = _mm512_maskz_loadu_ps(m[v], res.as_ptr().add(at + 16 * v));
                    y = _mm512_add_ps(y, rv);
                }
                if l.relu6 {
                    // y second: a NaN passes through, as f32::clamp keeps it
                    y = _mm512_min_ps(hi, _mm512_max_ps(lo, y));
                }
                _mm512_mask_storeu_ps(out.at(at + 16 * v), m[v], y);
            }
        }
    }
}
