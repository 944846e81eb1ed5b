//! 1x1 convolutions on blocked maps: `act(W x + bias [+ residual])`.
//!
//! The weights are packed once, `[output block][cin][16]`. A tile keeps
//! [`PAIR`] output blocks of up to [`PIXELS`] pixels in registers (24
//! accumulators); per input channel it loads one weight vector per block
//! and broadcasts each pixel's input from memory. Maps of at most 16 pixels
//! (the 4 x 4 layers) take one block of all their pixels per tile instead,
//! so that each weight is read once per image: those layers are bound by
//! the weights' bytes. Every output is summed over the input channels in
//! order from zero, then the bias and the residual are added, as the NCHW
//! kernels sum it.

use super::{pack, split, BlockedMap, OutPtr, Packed, LANES};

/// Output blocks per tile of a wide map.
const PAIR: usize = 2;
/// Pixels per tile of a wide map (2 x 12 accumulators).
const PIXELS: usize = 12;
/// Largest map whose tiles are one block of every pixel.
const NARROW: usize = 16;

/// A 1x1 convolution's weights (batch norm folded), packed.
pub struct PointwiseWeights {
    /// `[cout blocks][cin][16]`, zero past `cout`.
    w: Packed,
    /// `cout` rounded up to whole blocks, zero past `cout`.
    bias: Packed,
    cin: usize,
    cout: usize,
}

impl std::fmt::Debug for PointwiseWeights {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "PointwiseWeights({} -> {})", self.cin, self.cout)
    }
}

/// One call's operands, shared by its jobs.
struct Call<'a> {
    k: &'a PointwiseWeights,
    x: &'a [f32],
    residual: Option<&'a [f32]>,
    hw: usize,
    relu6: bool,
    out: OutPtr,
}

impl PointwiseWeights {
    /// The packed weights and bias, for [`super::gather`].
    pub fn packed_mut(&mut self) -> [&mut Packed; 2] {
        [&mut self.w, &mut self.bias]
    }

    /// Packs row-major `weight` (`cout` x `cin`) and `bias` (`cout`).
    pub fn new(weight: &[f32], bias: &[f32], cout: usize, cin: usize) -> Self {
        assert_eq!(bias.len(), cout, "pointwise bias of {cout}");
        let (w, padded) = pack(weight, bias, cin);
        PointwiseWeights {
            w,
            bias: padded,
            cin,
            cout,
        }
    }

    /// Output channels.
    pub fn cout(&self) -> usize {
        self.cout
    }

    /// `act(W x + bias [+ residual])`, ReLU6 if `relu6`, on candle's rayon
    /// pool.
    pub fn run(&self, x: &BlockedMap, residual: Option<&BlockedMap>, relu6: bool) -> BlockedMap {
        assert!(
            super::available(),
            "blocked pointwise kernel without AVX-512"
        );
        assert_eq!(x.channels, self.cin, "pointwise input channels");
        let (h, w) = x.dims();
        let mut out = BlockedMap::uninit(self.cout, h, w);
        if let Some(r) = residual {
            assert!(
                r.channels == self.cout && r.dims() == (h, w),
                "residual shape"
            );
        }
        let call = Call {
            k: self,
            x: x.data.as_slice(),
            residual: residual.map(|r| r.data.as_slice()),
            hw: h * w,
            relu6,
            out: OutPtr(out.data.as_mut_slice().as_mut_ptr()),
        };
        let blocks = self.cout.div_ceil(LANES);
        if call.hw <= NARROW {
            split(blocks, &|blocks| blocks.for_each(|b| call.narrow_block(b)));
        } else {
            // pixel tiles outermost: a tile's inputs stay in L1 across blocks
            let pairs = blocks.div_ceil(PAIR);
            split(call.hw.div_ceil(PIXELS), &|tiles| {
                for t in tiles {
                    (0..pairs).for_each(|pair| call.wide_tile(pair, t));
                }
            });
        }
        out
    }
}

impl Call<'_> {
    /// Output block `b` at every pixel of a map of at most 16.
    fn narrow_block(&self, b: usize) {
        let mut p0 = 0;
        for width in [16, 8, 4, 2, 1] {
            while self.hw - p0 >= width {
                // SAFETY: AVX-512 checked in `run`; block b and pixels
                // p0..p0 + width are inside the map and this job's alone.
                unsafe {
                    match width {
                        16 => avx512::tile::<1, 16, true>(self, b, 1, p0),
                        8 => avx512::tile::<1, 8, true>(self, b, 1, p0),
                        4 => avx512::tile::<1, 4, true>(self, b, 1, p0),
                        2 => avx512::tile::<1, 2, true>(self, b, 1, p0),
                        _ => avx512::tile::<1, 1, true>(self, b, 1, p0),
                    }
                }
                p0 += width;
            }
        }
    }

    /// Output blocks `2 pair..` (two, or the last one) at pixel tile `t`.
    fn wide_tile(&self, pair: usize, t: usize) {
        let blocks = self.k.cout.div_ceil(LANES);
        let b = pair * PAIR;
        let nb = PAIR.min(blocks - b);
        let p0 = t * PIXELS;
        let np = PIXELS.min(self.hw - p0);
        // SAFETY: as in `narrow_block`, for blocks b..b + nb, pixels p0..p0 + np.
        unsafe {
            match (nb, np) {
                (2, 12) => avx512::tile::<2, 12, false>(self, b, nb, p0),
                (1, 12) => avx512::tile::<1, 12, false>(self, b, nb, p0),
                _ => self.ragged(b, nb, p0, np),
            }
        }
    }

    /// A tile narrower than [`PIXELS`]: the map's last one.
    unsafe fn ragged(&self, b: usize, nb: usize, mut p0: usize, np: usize) {
        let end = p0 + np;
        for width in [8, 4, 2, 1] {
            while end - p0 >= width {
                for b in b..b + nb {
                    match width {
                        8 => avx512::tile::<1, 8, false>(self, b, 1, p0),
                        4 => avx512::tile::<1, 4, false>(self, b, 1, p0),
                        2 => avx512::tile::<1, 2, false>(self, b, 1, p0),
                        _ => avx512::tile::<1, 1, false>(self, b, 1, p0),
                    }
                }
                p0 += width;
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::{Call, LANES};
    use std::arch::x86_64::*;

    /// Input channels (weight vectors) a streaming tile prefetches ahead
    /// into L2: 12 KiB, past the hardware prefetcher's reach (measured
    /// against 24: BENCHMARKS.md).
    const AHEAD: usize = 192;

    /// Output blocks `b..b + NB` at pixels `p0..p0 + NP`; `nb` must be NB.
    /// A `STREAM` tile reads its weights once per image (a narrow layer's)
    /// and prefetches them [`AHEAD`]: at the camera's pace they come from
    /// memory, where the cold stream is latency-bound.
    ///
    /// # Safety
    /// AVX-512F; the blocks and pixels inside the layer; no other thread
    /// writes these outputs.
    // `acc[j][p]`: indexed by output block and pixel together
    #[allow(clippy::needless_range_loop)]
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn tile<const NB: usize, const NP: usize, const STREAM: bool>(
        c: &Call,
        b: usize,
        nb: usize,
        p0: usize,
    ) {
        debug_assert_eq!(nb, NB);
        let (cin, hw) = (c.k.cin, c.hw);
        let w = c.k.w.as_slice().as_ptr().add(b * cin * LANES);
        let x = c.x.as_ptr();
        let mut acc = [[_mm512_setzero_ps(); NP]; NB];
        for cb in 0..cin.div_ceil(LANES) {
            let xb = x.add((cb * hw + p0) * LANES);
            for l in 0..LANES.min(cin - cb * LANES) {
                let ch = cb * LANES + l;
                if STREAM {
                    // past the block's end this is the next block's, past
                    // the layer's the next layer's (gathered in order); a
                    // prefetch past the region is dropped, never faults
                    let ahead = w.wrapping_add((ch + AHEAD) * LANES);
                    _mm_prefetch::<_MM_HINT_T1>(ahead.cast());
                }
                let wv: [__m512; NB] =
                    std::array::from_fn(|j| _mm512_loadu_ps(w.add((j * cin + ch) * LANES)));
                for p in 0..NP {
                    let xv = _mm512_set1_ps(*xb.add(p * LANES + l));
                    for j in 0..NB {
                        acc[j][p] = _mm512_fmadd_ps(wv[j], xv, acc[j][p]);
                    }
                }
            }
        }
        let (lo, hi) = (_mm512_setzero_ps(), _mm512_set1_ps(6.0));
        for (j, acc) in acc.iter().enumerate() {
            let bias = _mm512_loadu_ps(c.k.bias.as_slice().as_ptr().add((b + j) * LANES));
            for (p, &a) in acc.iter().enumerate() {
                let at = ((b + j) * hw + p0 + p) * LANES;
                let mut y = _mm512_add_ps(a, bias);
                if let Some(r) = c.residual {
                    y = _mm512_add_ps(y, _mm512_loadu_ps(r.as_ptr().add(at)));
                }
                if c.relu6 {
                    // y second: a NaN passes through, as f32::clamp keeps it
                    y = _mm512_min_ps(hi, _mm512_max_ps(lo, y));
                }
                _mm512_storeu_ps(c.out.0.add(at), y);
            }
        }
    }
}
