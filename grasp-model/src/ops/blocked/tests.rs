//! The blocked kernels against the NCHW ones: the packed 1x1 kernels and
//! the depthwise stencil to the bit (the same sums in the same order), and
//! `gemm`'s 1x1 convolution and im2col within rounding.

use super::*;
use crate::ops::depthwise::{depthwise_conv_bias_act, Padding};
use crate::ops::pointwise::{
    im2col, pointwise_conv_bias_act, pointwise_conv_bias_act_cached, NarrowCache,
};
use candle_core::{Device, Tensor};

/// Deterministic values in [-1, 1) (xorshift).
fn values(len: usize, seed: u64) -> Vec<f32> {
    let mut s = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    (0..len)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 40) as f32 / (1u64 << 23) as f32 - 1.0
        })
        .collect()
}

fn tensor(v: &[f32], dims: &[usize]) -> Tensor {
    Tensor::from_vec(v.to_vec(), dims, &Device::Cpu).unwrap()
}

fn flat(t: &Tensor) -> Vec<f32> {
    t.flatten_all().unwrap().to_vec1().unwrap()
}

/// Whether the blocked kernels run here; without AVX-512 the network
/// keeps the NCHW kernels, and these tests have nothing to compare.
fn avx512() -> bool {
    let ok = available();
    if !ok {
        eprintln!("no AVX-512 on this CPU: the blocked kernels are not used");
    }
    ok
}

/// Equal values (NaN never appears here); -0 equals 0.
fn assert_same(a: &[f32], b: &[f32], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!(x == y, "{what}: element {i}: {x} vs {y}");
    }
}

/// Whether the lanes of the last block past the channels hold zeros.
fn pad_lanes_are_zero(map: &BlockedMap) -> bool {
    let (h, w) = map.dims();
    let last = &map.data.as_slice()[(map.blocks() - 1) * h * w * LANES..];
    let used = map.channels() - (map.blocks() - 1) * LANES;
    last.chunks_exact(LANES)
        .all(|px| px[used..].iter().all(|v| *v == 0.0))
}

fn assert_close(a: &[f32], b: &[f32], tol: f32, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    let d = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / (1.0 + y.abs()))
        .fold(0.0, f32::max);
    assert!(d <= tol, "{what}: largest relative difference {d}");
}

#[test]
fn blocked_maps_round_trip_and_pool() {
    let (c, h, w) = (40, 3, 5);
    let x = values(c * h * w, 1);
    let map = BlockedMap::from_nchw(&x, c, h, w);
    assert_eq!(map.to_nchw(), x);
    assert_eq!(
        map.data.as_slice().len(),
        48 * h * w,
        "40 channels fill three blocks"
    );
    assert!(pad_lanes_are_zero(&map), "the third block's last 8 lanes");
    let pooled = map.mean_pool();
    let want = flat(&tensor(&x, &[c, h * w]).mean(1).unwrap());
    assert_close(&pooled, &want, 1e-6, "mean pool");
}

#[test]
fn pointwise_matches_the_nchw_kernels() {
    if !avx512() {
        return;
    }
    // (cin, cout, h, w, residual, relu6): Lite0's narrow (4 x 4) and wide
    // maps, channel counts off the block, ragged pixel tiles
    let cases = [
        (192, 1152, 4, 4, false, true),
        (1152, 192, 4, 4, true, false),
        (320, 1280, 4, 4, false, true),
        (16, 96, 64, 64, false, true),
        (144, 24, 32, 32, true, false),
        (40, 240, 16, 16, false, true),
        (24, 40, 9, 7, false, false),
        (3, 20, 5, 3, false, true),
        (80, 480, 3, 3, false, true),
        (17, 33, 1, 1, true, true),
    ];
    for (i, &(cin, cout, h, w, residual, relu6)) in cases.iter().enumerate() {
        let seed = 10 * i as u64;
        let x = values(cin * h * w, seed);
        let wt = values(cout * cin, seed + 1);
        let bias = values(cout, seed + 2);
        let res = residual.then(|| values(cout * h * w, seed + 3));
        let packed = PointwiseWeights::new(&wt, &bias, cout, cin);
        let res_map = res.as_ref().map(|r| BlockedMap::from_nchw(r, cout, h, w));
        let got = packed.run(
            &BlockedMap::from_nchw(&x, cin, h, w),
            res_map.as_ref(),
            relu6,
        );
        assert_eq!((got.channels(), got.dims()), (cout, (h, w)));
        assert!(got
            .data
            .as_slice()
            .chunks_exact(16)
            .all(|px| px.iter().all(|v| v.is_finite())));
        let xt = tensor(&x, &[1, cin, h, w]);
        let (wt, bias) = (tensor(&wt, &[cout, cin]), tensor(&bias, &[cout]));
        let rt = res.as_ref().map(|r| tensor(r, &[1, cout, h, w]));
        let cache = NarrowCache::default();
        let nchw =
            pointwise_conv_bias_act_cached(&xt, &wt, &bias, &cache, rt.as_ref(), relu6).unwrap();
        let what = format!("{cin}->{cout} at {h}x{w}");
        assert_same(&got.to_nchw(), &flat(&nchw), &what);
        let gemm = pointwise_conv_bias_act(&xt, &wt, &bias, rt.as_ref(), relu6).unwrap();
        assert_close(&got.to_nchw(), &flat(&gemm), 1e-5, &what);
        assert!(pad_lanes_are_zero(&got), "{what}: lanes past the channels");
    }
}

#[test]
fn depthwise_matches_the_plane_stencil_to_the_bit() {
    if !avx512() {
        return;
    }
    // (c, h, w, k, stride, padding): Lite0's stages at 128 and 100 px,
    // planes smaller than the kernel, odd sides, both paddings
    let cases = [
        (32, 64, 64, 3, 1, Padding::Same),
        (96, 64, 64, 3, 2, Padding::Same),
        (144, 32, 32, 5, 2, Padding::Same),
        (240, 16, 16, 5, 1, Padding::Same),
        (672, 8, 8, 5, 2, Padding::Same),
        (1152, 4, 4, 5, 1, Padding::Same),
        (24, 13, 13, 5, 2, Padding::Same),
        (40, 7, 9, 3, 2, Padding::Same),
        (17, 2, 3, 5, 1, Padding::Same),
        (16, 1, 1, 5, 2, Padding::Same),
        (48, 9, 6, 3, 1, Padding::Symmetric(1)),
        (20, 5, 5, 3, 2, Padding::Symmetric(1)),
    ];
    for (i, &(c, h, w, k, stride, padding)) in cases.iter().enumerate() {
        for relu6 in [false, true] {
            let seed = 100 + 10 * i as u64;
            let x: Vec<f32> = values(c * h * w, seed).iter().map(|v| 4.0 * v).collect();
            let wt = values(c * k * k, seed + 1);
            let bias = values(c, seed + 2);
            let packed = DepthwiseWeights::new(&wt, &bias, c, k, stride, padding);
            let got = packed
                .run(&BlockedMap::from_nchw(&x, c, h, w), relu6)
                .unwrap();
            let want = depthwise_conv_bias_act(
                &tensor(&x, &[1, c, h, w]),
                &tensor(&wt, &[c, 1, k, k]),
                &tensor(&bias, &[c]),
                stride,
                padding,
                relu6,
            )
            .unwrap();
            let (_, _, oh, ow) = want.dims4().unwrap();
            assert_eq!(got.dims(), (oh, ow));
            let what = format!("{c}x{h}x{w}, {k}x{k} /{stride} {padding:?}, relu6 {relu6}");
            assert_same(&got.to_nchw(), &flat(&want), &what);
        }
    }
}

#[test]
fn depthwise_refuses_a_kernel_larger_than_the_padded_map() {
    if !avx512() {
        return;
    }
    let packed = DepthwiseWeights::new(&[0.0; 16 * 9], &[0.0; 16], 16, 3, 1, Padding::Symmetric(0));
    assert!(packed
        .run(&BlockedMap::from_nchw(&[0.0; 32], 16, 2, 1), false)
        .is_none());
}

#[test]
fn stem_matches_im2col_and_the_1x1_kernels() {
    if !avx512() {
        return;
    }
    // (cout, h, w, k, stride, padding): Lite0's stem at 128 and 100 px, odd sides
    let cases = [
        (32, 128, 128, 3, 2, Padding::Same),
        (32, 100, 100, 3, 2, Padding::Same),
        (20, 9, 14, 3, 2, Padding::Same),
        (16, 5, 3, 3, 1, Padding::Symmetric(1)),
    ];
    for (i, &(cout, h, w, k, stride, padding)) in cases.iter().enumerate() {
        let seed = 300 + 10 * i as u64;
        let x = values(3 * h * w, seed);
        let wt = values(cout * 3 * k * k, seed + 1);
        let bias = values(cout, seed + 2);
        let packed = StemWeights::new(&wt, &bias, (cout, 3, k), stride, padding);
        let got = packed.run(&x, h, w).unwrap();
        let cols = im2col(&tensor(&x, &[1, 3, h, w]), k, stride, padding).unwrap();
        let (wt, bias) = (tensor(&wt, &[cout, 3 * k * k]), tensor(&bias, &[cout]));
        let cache = NarrowCache::default();
        let want = pointwise_conv_bias_act_cached(&cols, &wt, &bias, &cache, None, true).unwrap();
        let (_, _, oh, ow) = want.dims4().unwrap();
        assert_eq!(got.dims(), (oh, ow));
        let what = format!("stem {cout} at {h}x{w} /{stride}");
        if oh * ow > crate::ops::pointwise::NARROW_MAX_PIXELS {
            assert_same(&got.to_nchw(), &flat(&want), &what);
        }
        let gemm = pointwise_conv_bias_act(&cols, &wt, &bias, None, true).unwrap();
        assert_close(&got.to_nchw(), &flat(&gemm), 1e-5, &what);
    }
}

#[test]
fn gathered_layers_keep_their_values_in_one_region() {
    let (w1, b1) = (values(40 * 24, 1), values(40, 2));
    let (w2, b2) = (values(24 * 40 * 9, 3), values(24, 4));
    let mut a = PointwiseWeights::new(&w1, &b1, 40, 24);
    let mut s = StemWeights::new(&w2, &b2, (24, 40, 3), 1, Padding::Same);
    let before: Vec<Vec<f32>> = a
        .packed_mut()
        .into_iter()
        .chain(s.packed_mut())
        .map(|p| p.as_slice().to_vec())
        .collect();
    gather(a.packed_mut().into_iter().chain(s.packed_mut()));
    let parts: Vec<&mut Packed> = a.packed_mut().into_iter().chain(s.packed_mut()).collect();
    for (p, v) in parts.iter().zip(&before) {
        assert_eq!(p.as_slice(), v.as_slice());
        assert!(Arc::ptr_eq(&p.region, &parts[0].region), "one region");
    }
    let total: usize = before.iter().map(Vec::len).sum();
    assert_eq!(parts[0].region.as_slice().len(), total);
}
