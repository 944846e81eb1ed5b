//! Depthwise convolution of small planes (at most [`MAX_OUT_PIXELS`]
//! outputs: EfficientNet-Lite's 8 x 8 and 4 x 4 stages at the shipped
//! 128-pixel input) with the vector along the channels.
//!
//! The plane-by-plane stencil computes whole 64-lane blocks of "wide"
//! outputs: a 4 x 4 plane under a 5 x 5 kernel is 32 wide outputs computed
//! as 64, after a padded copy of 64 floats, per channel. Here a job takes 16
//! channels of one image, copies them once into a zero-padded tile with the
//! channels innermost, and computes every output pixel as one 16-lane sum.
//! Each lane adds the same products in the same order as the stencil (bias,
//! then each kernel row summed before it is added, padding read as zeros),
//! so the outputs are the stencil's to the bit. x86-64 with AVX-512 only.

use super::Geom;
use crate::ops::cpu::{alloc_uninit, has_avx512, par_chunks};
use std::arch::x86_64::*;

/// Channels per job: one AVX-512 vector.
const LANES: usize = 16;
/// Largest output plane this path takes (8 x 8).
pub(super) const MAX_OUT_PIXELS: usize = 64;

/// Whether `g` is served here: small output planes, whole groups of 16
/// channels.
pub(super) fn applies(g: &Geom) -> bool {
    g.out_plane() <= MAX_OUT_PIXELS && g.c.is_multiple_of(LANES) && has_avx512()
}

/// Rows and columns of the zero-padded input every output reads from.
fn padded(g: &Geom) -> (usize, usize) {
    (g.stride * (g.oh - 1) + g.k, g.stride * (g.ow - 1) + g.k)
}

/// Forward over all (image, 16-channel group) jobs, in parallel.
pub(super) fn forward(
    g: &Geom,
    x: &[f32],
    w: &[f32],
    bias: Option<&[f32]>,
    relu6: bool,
) -> Vec<f32> {
    let (rows, cols) = padded(g);
    // every element is written by group()
    let mut out = alloc_uninit(g.n * g.c * g.out_plane());
    let groups = g.c / LANES;
    par_chunks(
        &mut out,
        LANES * g.out_plane(),
        rows * cols * LANES,
        |tile, job, dst| {
            let (img, c0) = (job / groups, (job % groups) * LANES);
            let planes = &x[(img * g.c + c0) * g.in_plane()..][..LANES * g.in_plane()];
            let taps = g.k * g.k;
            let weights = &w[c0 * taps..(c0 + LANES) * taps];
            let bias: [f32; LANES] = std::array::from_fn(|l| bias.map_or(0.0, |b| b[c0 + l]));
            group(g, planes, weights, &bias, relu6, tile, dst);
        },
    );
    out
}

/// One job: 16 planes of `x` (`planes`), their `k * k` weights each, into
/// `dst`'s 16 output planes.
fn group(
    g: &Geom,
    planes: &[f32],
    weights: &[f32],
    bias: &[f32; LANES],
    relu6: bool,
    tile: &mut [f32],
    dst: &mut [f32],
) {
    assert!(has_avx512(), "depthwise small-plane path without AVX-512");
    assert!(planes.len() >= LANES * g.in_plane() && dst.len() == LANES * g.out_plane());
    // SAFETY: AVX-512 checked above; the gathers and scatters stay inside
    // `planes` and `dst` (asserted lengths, lane l at l * plane + pixel).
    unsafe {
        match g.k {
            3 => group_k::<3>(g, planes, weights, bias, relu6, tile, dst),
            _ => group_k::<5>(g, planes, weights, bias, relu6, tile, dst),
        }
    }
}

#[target_feature(enable = "avx512f")]
unsafe fn group_k<const K: usize>(
    g: &Geom,
    planes: &[f32],
    weights: &[f32],
    bias: &[f32; LANES],
    relu6: bool,
    tile: &mut [f32],
    dst: &mut [f32],
) {
    let (_, cols) = padded(g);
    fill_tile(g, planes, tile);
    // w[ky][kx] holds the 16 channels' weight of tap (ky, kx). No closures
    // here: they would not inherit the target feature.
    let mut w = [[[0f32; LANES]; K]; K];
    for (l, taps) in weights.chunks_exact(K * K).take(LANES).enumerate() {
        for (t, &v) in taps.iter().enumerate() {
            w[t / K][t % K][l] = v;
        }
    }
    for oy in 0..g.oh {
        for ox in 0..g.ow {
            let mut acc = *bias;
            for (ky, w_row) in w.iter().enumerate() {
                let mut row = [0f32; LANES];
                for (kx, wt) in w_row.iter().enumerate() {
                    let at = ((g.stride * oy + ky) * cols + g.stride * ox + kx) * LANES;
                    let v = &tile[at..at + LANES];
                    for l in 0..LANES {
                        row[l] = if kx == 0 {
                            wt[l] * v[l]
                        } else {
                            row[l] + wt[l] * v[l]
                        };
                    }
                }
                for l in 0..LANES {
                    acc[l] += row[l];
                }
            }
            if relu6 {
                for a in &mut acc {
                    *a = a.clamp(0.0, 6.0);
                }
            }
            // lane l to output plane l
            let at = dst.as_mut_ptr().add(oy * g.ow + ox);
            _mm512_i32scatter_ps::<4>(at, stride(g.out_plane()), _mm512_loadu_ps(acc.as_ptr()));
        }
    }
}

/// Lane offsets 0, n, 2n, ... 15n.
#[inline(always)]
unsafe fn stride(n: usize) -> __m512i {
    let n = n as i32;
    _mm512_setr_epi32(
        0,
        n,
        2 * n,
        3 * n,
        4 * n,
        5 * n,
        6 * n,
        7 * n,
        8 * n,
        9 * n,
        10 * n,
        11 * n,
        12 * n,
        13 * n,
        14 * n,
        15 * n,
    )
}

/// The 16 input planes, channels innermost, in a zero-padded tile: each
/// pixel's 16 channels gathered across the planes into one vector.
#[target_feature(enable = "avx512f")]
unsafe fn fill_tile(g: &Geom, planes: &[f32], tile: &mut [f32]) {
    let (rows, cols) = padded(g);
    let tile = &mut tile[..rows * cols * LANES];
    tile.fill(0.0);
    let lanes = stride(g.in_plane());
    for iy in 0..g.h.min(rows - g.pt) {
        for ix in 0..g.w.min(cols - g.pl) {
            let px = _mm512_i32gather_ps::<4>(lanes, planes.as_ptr().add(iy * g.w + ix));
            let at = ((iy + g.pt) * cols + ix + g.pl) * LANES;
            _mm512_storeu_ps(tile[at..at + LANES].as_mut_ptr(), px);
        }
    }
}
