//! A dense k x k convolution of a 3-channel NCHW image (EfficientNet-Lite's
//! stem: 3x3, stride 2, SAME) into a blocked map, with the bias and ReLU6.
//!
//! The NCHW path runs it as im2col, then a 1x1 convolution over the
//! `3 k k` rows. Here each output tile (two blocks of 16 output channels x
//! [`PIXELS`] pixels of a row) sums the same rows in the same order,
//! reading each tap's input in place, a padded one as zero: the same sums.

use super::{pack, split, BlockedMap, Geometry, OutPtr, Packed, LANES};
use crate::ops::depthwise::Padding;

/// Pixels per tile.
const PIXELS: usize = 12;

/// A dense convolution's weights (batch norm folded), packed.
pub struct StemWeights {
    /// `[cout block][cin * k * k][16]`, zero past `cout`.
    w: Packed,
    bias: Packed,
    cin: usize,
    cout: usize,
    k: usize,
    stride: usize,
    padding: Padding,
}

impl std::fmt::Debug for StemWeights {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (i, o, k, s) = (self.cin, self.cout, self.k, self.stride);
        write!(f, "StemWeights({i} -> {o}, {k}x{k}, stride {s})")
    }
}

struct Call<'a> {
    k: &'a StemWeights,
    x: &'a [f32],
    g: Geometry,
    out: OutPtr,
}

impl StemWeights {
    /// The packed weights and bias, for [`super::gather`].
    pub fn packed_mut(&mut self) -> [&mut Packed; 2] {
        [&mut self.w, &mut self.bias]
    }

    /// Packs `weight` (`cout` x `cin` x `k` x `k`, row-major) and `bias`.
    pub fn new(
        weight: &[f32],
        bias: &[f32],
        (cout, cin, k): (usize, usize, usize),
        stride: usize,
        padding: Padding,
    ) -> Self {
        assert_eq!(bias.len(), cout, "stem bias");
        assert!(stride > 0, "stem stride");
        let (w, padded) = pack(weight, bias, cin * k * k);
        StemWeights {
            w,
            bias: padded,
            cin,
            cout,
            k,
            stride,
            padding,
        }
    }

    /// `relu6(conv(x) + bias)` of one NCHW image `x` (`cin` x `h` x `w`);
    /// `None` when the kernel does not fit.
    pub fn run(&self, x: &[f32], h: usize, w: usize) -> Option<BlockedMap> {
        assert!(super::available(), "blocked stem kernel without AVX-512");
        assert_eq!(x.len(), self.cin * h * w, "stem input");
        let g = Geometry::new(h, w, self.k, self.stride, self.padding)?;
        let (oh, ow) = (g.oh, g.ow);
        let mut out = BlockedMap::uninit(self.cout, oh, ow);
        let call = Call {
            k: self,
            x,
            g,
            out: OutPtr(out.data.as_mut_slice().as_mut_ptr()),
        };
        let blocks = self.cout.div_ceil(LANES);
        split(oh, &|rows| {
            for oy in rows {
                for ox in (0..ow).step_by(PIXELS) {
                    let n = PIXELS.min(ow - ox);
                    let inside = n == PIXELS && call.inside(oy, ox);
                    for b in (0..blocks).step_by(2) {
                        // SAFETY: AVX-512 checked above; rows are this job's;
                        // unchecked taps only where `inside` holds.
                        unsafe {
                            match ((blocks - b).min(2), inside) {
                                (2, true) => avx512::tile::<2, false>(&call, b, oy, ox, n),
                                (2, false) => avx512::tile::<2, true>(&call, b, oy, ox, n),
                                (_, true) => avx512::tile::<1, false>(&call, b, oy, ox, n),
                                (_, false) => avx512::tile::<1, true>(&call, b, oy, ox, n),
                            }
                        }
                    }
                }
            }
        });
        Some(out)
    }
}

impl Call<'_> {
    /// Whether every tap of outputs (oy, ox..ox + PIXELS) is inside the image.
    fn inside(&self, oy: usize, ox: usize) -> bool {
        let (s, k) = (self.k.stride, self.k.k);
        let row = s * oy >= self.g.pt && s * oy + k <= self.g.h + self.g.pt;
        let last = ox + PIXELS - 1;
        row && s * ox >= self.g.pl && s * last + k <= self.g.w + self.g.pl
    }

    /// The input at tap (ky, kx) of output (oy, ox) in plane `c`; zero in
    /// the padding.
    #[inline(always)]
    fn tap(&self, c: usize, oy: usize, ox: usize, ky: usize, kx: usize) -> f32 {
        let s = self.k.stride;
        let (iy, ix) = (
            (s * oy + ky).wrapping_sub(self.g.pt),
            (s * ox + kx).wrapping_sub(self.g.pl),
        );
        if iy < self.g.h && ix < self.g.w {
            self.x[(c * self.g.h + iy) * self.g.w + ix]
        } else {
            0.0
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::{Call, LANES, PIXELS};
    use std::arch::x86_64::*;

    /// Output blocks `b..b + NB`, pixels `ox..ox + n` (n <= PIXELS) of row
    /// `oy`; `CHECKED`: taps outside the image read as zeros (otherwise
    /// every tap of the PIXELS outputs must be inside).
    ///
    /// # Safety
    /// AVX-512F; the outputs inside the map and this job's alone.
    // `acc[j][p]`: indexed by output block and pixel together
    #[allow(clippy::needless_range_loop)]
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn tile<const NB: usize, const CHECKED: bool>(
        c: &Call,
        b: usize,
        oy: usize,
        ox: usize,
        n: usize,
    ) {
        let (k, s) = (c.k.k, c.k.stride);
        let rows = c.k.cin * k * k;
        let w = c.k.w.as_slice().as_ptr().add(b * rows * LANES);
        let mut acc = [[_mm512_setzero_ps(); PIXELS]; NB];
        let mut r = 0;
        for ch in 0..c.k.cin {
            for ky in 0..k {
                for kx in 0..k {
                    let wv: [__m512; NB] =
                        std::array::from_fn(|j| _mm512_loadu_ps(w.add((j * rows + r) * LANES)));
                    // the first tap's input, when the tile is inside
                    let x = if CHECKED {
                        c.x.as_ptr()
                    } else {
                        let (iy, ix) = (s * oy + ky - c.g.pt, s * ox + kx - c.g.pl);
                        c.x.as_ptr().add((ch * c.g.h + iy) * c.g.w + ix)
                    };
                    for p in 0..PIXELS {
                        let v = if CHECKED {
                            c.tap(ch, oy, ox + p, ky, kx)
                        } else {
                            *x.add(s * p)
                        };
                        let xv = _mm512_set1_ps(v);
                        for j in 0..NB {
                            acc[j][p] = _mm512_fmadd_ps(wv[j], xv, acc[j][p]);
                        }
                    }
                    r += 1;
                }
            }
        }
        let (lo, hi) = (_mm512_setzero_ps(), _mm512_set1_ps(6.0));
        for (j, acc) in acc.iter().enumerate() {
            let bias = _mm512_loadu_ps(c.k.bias.as_slice().as_ptr().add((b + j) * LANES));
            for (p, &a) in acc.iter().take(n).enumerate() {
                let y = _mm512_min_ps(hi, _mm512_max_ps(lo, _mm512_add_ps(a, bias)));
                let at = (((b + j) * c.g.oh + oy) * c.g.ow + ox + p) * LANES;
                _mm512_storeu_ps(c.out.0.add(at), y);
            }
        }
    }
}
