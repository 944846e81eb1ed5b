//! Depthwise convolutions (3x3 or 5x5, stride 1 or 2, any padding) on
//! blocked maps, with the bias and optional ReLU6.
//!
//! Each output pixel of a block is one vector: the bias, plus each kernel
//! row's products summed before they are added (the order of the NCHW
//! stencil, `ops::depthwise`: the same outputs to the bit; fused
//! multiply-adds were no faster), taps outside the image skipped (the
//! stencil reads them as zeros). Interior pixels go [`RUN`] (or half as many) at a
//! time, sharing each tap's weight vector; the border ones one at a time with their own tap
//! ranges. Jobs are (channel block, band of output rows).

use super::{pack, split, BlockedMap, Geometry, OutPtr, Packed, JOBS, LANES};
use crate::ops::depthwise::Padding;
use std::ops::Range;

/// Interior output pixels computed together.
const RUN: usize = 8;

/// A depthwise convolution's weights (batch norm folded), packed.
pub struct DepthwiseWeights {
    /// `[channel block][k * k][16]`, zero past `channels`.
    w: Packed,
    bias: Packed,
    channels: usize,
    k: usize,
    stride: usize,
    padding: Padding,
}

impl std::fmt::Debug for DepthwiseWeights {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (c, k, s) = (self.channels, self.k, self.stride);
        write!(f, "DepthwiseWeights({c} channels, {k}x{k}, stride {s})")
    }
}

/// One call's geometry and operands.
struct Call<'a> {
    k: &'a DepthwiseWeights,
    x: &'a [f32],
    g: Geometry,
    relu6: bool,
    out: OutPtr,
}

impl DepthwiseWeights {
    /// The packed weights and bias, for [`super::gather`].
    pub fn packed_mut(&mut self) -> [&mut Packed; 2] {
        [&mut self.w, &mut self.bias]
    }

    /// Packs `weight` (`channels` x `k` x `k`) and `bias` (`channels`); `k`
    /// 3 or 5, `stride` 1 or 2.
    pub fn new(
        weight: &[f32],
        bias: &[f32],
        channels: usize,
        k: usize,
        stride: usize,
        padding: Padding,
    ) -> Self {
        assert!(
            matches!(k, 3 | 5) && matches!(stride, 1 | 2),
            "depthwise {k}x{k} /{stride}"
        );
        assert_eq!(bias.len(), channels, "depthwise bias");
        let (w, padded) = pack(weight, bias, k * k);
        DepthwiseWeights {
            w,
            bias: padded,
            channels,
            k,
            stride,
            padding,
        }
    }

    /// The convolution of `x`, on candle's rayon pool; `None` when the
    /// kernel does not fit the map.
    pub fn run(&self, x: &BlockedMap, relu6: bool) -> Option<BlockedMap> {
        assert!(
            super::available(),
            "blocked depthwise kernel without AVX-512"
        );
        assert_eq!(x.channels, self.channels, "depthwise channels");
        let (h, w) = x.dims();
        let g = Geometry::new(h, w, self.k, self.stride, self.padding)?;
        let (oh, ow) = (g.oh, g.ow);
        let mut out = BlockedMap::uninit(self.channels, oh, ow);
        let call = Call {
            k: self,
            x: x.data.as_slice(),
            g,
            relu6,
            out: OutPtr(out.data.as_mut_slice().as_mut_ptr()),
        };
        // (channel block, band of rows) jobs: bands only when there are
        // fewer blocks than jobs
        let blocks = x.blocks();
        let bands = JOBS.div_ceil(blocks).min(oh);
        split(blocks * bands, &|jobs| {
            for job in jobs {
                let (b, band) = (job / bands, job % bands);
                for oy in band * oh / bands..(band + 1) * oh / bands {
                    // SAFETY: AVX-512 checked above; each job writes its own rows.
                    unsafe {
                        match self.k {
                            3 => avx512::row::<3>(&call, b, oy),
                            _ => avx512::row::<5>(&call, b, oy),
                        }
                    }
                }
            }
        });
        Some(out)
    }
}

impl Call<'_> {
    /// The taps of one axis inside the image for output `o`: kernel
    /// offsets `lo..hi` (input `stride * o + t - pad`).
    fn taps(&self, o: usize, pad: usize, size: usize) -> Range<usize> {
        let at = (self.k.stride * o) as isize - pad as isize;
        let lo = (-at).max(0) as usize;
        let hi = (size as isize - at).clamp(0, self.k.k as isize) as usize;
        lo.min(hi)..hi
    }

    /// Output columns whose every tap is inside the image.
    fn interior(&self) -> Range<usize> {
        let (s, k) = (self.k.stride, self.k.k);
        let lo = self.g.pl.div_ceil(s).min(self.g.ow);
        let hi = match (self.g.w + self.g.pl).checked_sub(k) {
            Some(last) => (last / s + 1).min(self.g.ow),
            None => 0,
        };
        lo..hi.max(lo)
    }
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::{Call, LANES, RUN};
    use std::arch::x86_64::*;
    use std::ops::Range;

    /// Output row `oy` of channel block `b`.
    ///
    /// # Safety
    /// AVX-512F; `b` and `oy` inside the output; no other thread writes it.
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn row<const K: usize>(c: &Call, b: usize, oy: usize) {
        let rows = c.taps(oy, c.g.pt, c.g.h);
        let inner = c.interior();
        let mut ox = 0;
        while ox < inner.start {
            pixels::<K, 1>(c, b, oy, ox, rows.clone(), c.taps(ox, c.g.pl, c.g.w));
            ox += 1;
        }
        while ox + RUN <= inner.end {
            pixels::<K, RUN>(c, b, oy, ox, rows.clone(), 0..K);
            ox += RUN;
        }
        while ox + RUN / 2 <= inner.end {
            pixels::<K, { RUN / 2 }>(c, b, oy, ox, rows.clone(), 0..K);
            ox += RUN / 2;
        }
        while ox < c.g.ow {
            pixels::<K, 1>(c, b, oy, ox, rows.clone(), c.taps(ox, c.g.pl, c.g.w));
            ox += 1;
        }
    }

    /// Outputs `ox..ox + N` of row `oy`, block `b`, summing kernel rows
    /// `rows` and columns `cols` (the same for every one of them); the N
    /// sums are independent chains, which hides the latency of each.
    #[inline(always)]
    unsafe fn pixels<const K: usize, const N: usize>(
        c: &Call,
        b: usize,
        oy: usize,
        ox: usize,
        rows: Range<usize>,
        cols: Range<usize>,
    ) {
        let s = c.k.stride;
        let w = c.k.w.as_slice().as_ptr().add(b * K * K * LANES);
        let plane = c.x.as_ptr().add(b * c.g.h * c.g.w * LANES);
        let bias = _mm512_loadu_ps(c.k.bias.as_slice().as_ptr().add(b * LANES));
        let mut acc = [bias; N];
        for ky in rows {
            let iy = s * oy + ky - c.g.pt;
            let line = plane.add(iy * c.g.w * LANES);
            let mut sum = [_mm512_setzero_ps(); N];
            for (i, kx) in cols.clone().enumerate() {
                let wv = _mm512_loadu_ps(w.add((ky * K + kx) * LANES));
                for (p, sum) in sum.iter_mut().enumerate() {
                    let ix = s * (ox + p) + kx - c.g.pl;
                    let prod = _mm512_mul_ps(wv, _mm512_loadu_ps(line.add(ix * LANES)));
                    *sum = if i == 0 {
                        prod
                    } else {
                        _mm512_add_ps(*sum, prod)
                    };
                }
            }
            for (a, s) in acc.iter_mut().zip(sum) {
                *a = _mm512_add_ps(*a, s);
            }
        }
        let (lo, hi) = (_mm512_setzero_ps(), _mm512_set1_ps(6.0));
        for (p, mut y) in acc.into_iter().enumerate() {
            if c.relu6 {
                y = _mm512_min_ps(hi, _mm512_max_ps(lo, y));
            }
            let at = ((b * c.g.oh + oy) * c.g.ow + ox + p) * LANES;
            _mm512_storeu_ps(c.out.0.add(at), y);
        }
    }
}
