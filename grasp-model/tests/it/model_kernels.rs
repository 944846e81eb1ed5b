//! The custom depthwise and pointwise kernels against candle's reference
//! convolution, on random shapes including odd sizes and tiny planes.

use candle_core::{Device, Tensor, Var};
use grasp_model::ops::depthwise::{
    depthwise_conv3x3, depthwise_conv3x3_bias_act, depthwise_conv_bias_act, Padding,
};
use grasp_model::ops::pointwise::{
    im2col, narrow_kernel_available, pointwise_conv, pointwise_conv_bias_act,
    pointwise_conv_bias_act_cached, NarrowCache, NARROW_MAX_PIXELS,
};

fn max_abs_diff(a: &Tensor, b: &Tensor) -> f32 {
    assert_eq!(a.dims(), b.dims());
    (a - b)
        .unwrap()
        .abs()
        .unwrap()
        .flatten_all()
        .unwrap()
        .max(0)
        .unwrap()
        .to_scalar::<f32>()
        .unwrap()
}

fn randn(shape: &[usize]) -> Tensor {
    Tensor::randn(0f32, 1.0, shape, &Device::Cpu).unwrap()
}

/// (batch, channels, height, width) cases: odd, even, 1x1 and non-square planes.
const SHAPES: [(usize, usize, usize, usize); 7] = [
    (1, 1, 1, 1),
    (1, 3, 2, 2),
    (3, 5, 7, 9),
    (1, 8, 16, 16),
    (3, 4, 13, 6),
    (1, 16, 33, 31),
    (3, 2, 1, 17),
];

#[test]
fn depthwise_matches_grouped_conv2d() {
    for &(n, c, h, w) in &SHAPES {
        for stride in [1, 2] {
            let x = randn(&[n, c, h, w]);
            let k = randn(&[c, 1, 3, 3]);
            let reference = x.conv2d(&k, 1, stride, 1, c).unwrap();
            let ours = depthwise_conv3x3(&x, &k, stride).unwrap();
            let d = max_abs_diff(&ours, &reference);
            assert!(
                d < 1e-5,
                "shape {:?} stride {stride}: diff {d}",
                (n, c, h, w)
            );
        }
    }
}

#[test]
fn depthwise_accepts_non_contiguous_input() {
    let x = randn(&[2, 5, 9, 11]).transpose(2, 3).unwrap();
    let k = randn(&[5, 1, 3, 3]);
    let reference = x.conv2d(&k, 1, 2, 1, 5).unwrap();
    let d = max_abs_diff(&depthwise_conv3x3(&x, &k, 2).unwrap(), &reference);
    assert!(d < 1e-5, "diff {d}");
}

#[test]
fn depthwise_fused_bias_and_relu6() {
    let (n, c, h, w) = (3, 6, 10, 7);
    let x = (randn(&[n, c, h, w]) * 3.0).unwrap();
    let k = randn(&[c, 1, 3, 3]);
    let b = randn(&[c]);
    for stride in [1, 2] {
        let reference = x
            .conv2d(&k, 1, stride, 1, c)
            .unwrap()
            .broadcast_add(&b.reshape((1, c, 1, 1)).unwrap())
            .unwrap();
        let ours = depthwise_conv3x3_bias_act(&x, &k, &b, stride, false).unwrap();
        assert!(max_abs_diff(&ours, &reference) < 1e-5);
        let clamped = reference.clamp(0f32, 6f32).unwrap();
        let ours = depthwise_conv3x3_bias_act(&x, &k, &b, stride, true).unwrap();
        assert!(max_abs_diff(&ours, &clamped) < 1e-5);
    }
}

fn dot(a: &Tensor, b: &Tensor) -> f32 {
    (a * b)
        .unwrap()
        .sum_all()
        .unwrap()
        .to_scalar::<f32>()
        .unwrap()
}

/// Gradients of `sum(depthwise(x, k) * proj)` for a random `proj`.
fn gradients(x: &Var, k: &Var, proj: &Tensor, stride: usize, reference: bool) -> (Tensor, Tensor) {
    let c = k.dim(0).unwrap();
    let y = if reference {
        x.conv2d(k, 1, stride, 1, c).unwrap()
    } else {
        depthwise_conv3x3(x, k, stride).unwrap()
    };
    let grads = (y * proj).unwrap().sum_all().unwrap().backward().unwrap();
    let g = |v: &Var| grads.get(v.as_tensor()).unwrap().clone();
    (g(x), g(k))
}

#[test]
fn depthwise_gradients_satisfy_the_adjoint_identity() {
    // The convolution is linear in x and in k, so for any probes v and u:
    //   <dL/dx, v> = <conv(v, k), proj>   and   <dL/dk, u> = <conv(x, u), proj>.
    // conv itself is checked against candle's conv2d above. candle's own
    // grouped-conv backward fails on some odd stride-2 shapes, so this
    // identity is the reference that covers every shape.
    for &(n, c, h, w) in &SHAPES {
        for stride in [1, 2] {
            let x = Var::from_tensor(&randn(&[n, c, h, w])).unwrap();
            let k = Var::from_tensor(&randn(&[c, 1, 3, 3])).unwrap();
            let (oh, ow) = ((h - 1) / stride + 1, (w - 1) / stride + 1);
            let proj = randn(&[n, c, oh, ow]);
            let (dx, dk) = gradients(&x, &k, &proj, stride, false);
            assert_eq!(dx.dims(), x.dims());
            assert_eq!(dk.dims(), k.dims());
            for _ in 0..3 {
                let v = randn(&[n, c, h, w]);
                let u = randn(&[c, 1, 3, 3]);
                let lhs = dot(&dx, &v);
                let rhs = dot(&depthwise_conv3x3(&v, &k, stride).unwrap(), &proj);
                let tol = 1e-4 * (1.0 + lhs.abs().max(rhs.abs()));
                assert!(
                    (lhs - rhs).abs() < tol,
                    "dx {:?} s{stride}: {lhs} vs {rhs}",
                    (n, c, h, w)
                );
                let lhs = dot(&dk, &u);
                let rhs = dot(&depthwise_conv3x3(&x, &u, stride).unwrap(), &proj);
                let tol = 1e-4 * (1.0 + lhs.abs().max(rhs.abs()));
                assert!(
                    (lhs - rhs).abs() < tol,
                    "dk {:?} s{stride}: {lhs} vs {rhs}",
                    (n, c, h, w)
                );
            }
        }
    }
}

#[test]
fn depthwise_gradients_match_grouped_conv2d_stride1() {
    for &(n, c, h, w) in &[(1, 2, 5, 5), (3, 3, 8, 7), (2, 4, 1, 6)] {
        let x = Var::from_tensor(&randn(&[n, c, h, w])).unwrap();
        let k = Var::from_tensor(&randn(&[c, 1, 3, 3])).unwrap();
        let proj = randn(&[n, c, h, w]);
        let (dx, dk) = gradients(&x, &k, &proj, 1, false);
        let (rx, rk) = gradients(&x, &k, &proj, 1, true);
        assert!(
            max_abs_diff(&dx, &rx) < 1e-4,
            "input grad {:?}",
            (n, c, h, w)
        );
        assert!(
            max_abs_diff(&dk, &rk) < 1e-4,
            "weight grad {:?}",
            (n, c, h, w)
        );
    }
}

#[test]
fn depthwise_rejects_bad_arguments() {
    let x = randn(&[1, 4, 5, 5]);
    assert!(depthwise_conv3x3(&x, &randn(&[4, 1, 3, 3]), 3).is_err());
    assert!(depthwise_conv3x3(&x, &randn(&[3, 1, 3, 3]), 1).is_err());
    assert!(depthwise_conv3x3(&x, &randn(&[4, 1, 5, 5]), 1).is_err());
}

#[test]
fn pointwise_matches_conv2d() {
    // one pixel; column tiles; row blocks with a ragged last block (tiny
    // image, many channels); more than the largest column tile, ragged
    let cases = [
        (1, 3, 5, 1, 1),
        (3, 16, 24, 17, 19),
        (2, 7, 9, 16, 16),
        (1, 8, 70, 3, 3),
        (1, 4, 8, 70, 70),
    ];
    for &(n, cin, cout, h, w) in &cases {
        let x = randn(&[n, cin, h, w]);
        let k = randn(&[cout, cin, 1, 1]);
        let b = randn(&[cout]);
        let conv = x.conv2d(&k, 0, 1, 1, 1).unwrap();
        assert!(max_abs_diff(&pointwise_conv(&x, &k).unwrap(), &conv) < 1e-4);
        let biased = conv
            .broadcast_add(&b.reshape((1, cout, 1, 1)).unwrap())
            .unwrap();
        let residual = randn(&[n, cout, h, w]);
        let ours = pointwise_conv_bias_act(&x, &k, &b, Some(&residual), false).unwrap();
        assert!(max_abs_diff(&ours, &(&biased + &residual).unwrap()) < 1e-4);
        let ours = pointwise_conv_bias_act(&x, &k, &b, None, true).unwrap();
        assert!(max_abs_diff(&ours, &biased.clamp(0f32, 6f32).unwrap()) < 1e-4);
    }
}

/// Layers with a cache run maps of at most 16 pixels through the narrow
/// kernel on weights packed once (AVX-512 CPUs; elsewhere through `gemm`):
/// Lite0's last-stage shapes, output channels that fill no whole block of
/// 16, every pixel-tile width (16, 8, 4, 2, 1), several images.
#[test]
fn narrow_pointwise_matches_conv2d() {
    let cases = [
        (1, 1152, 320, 4, 4),
        (2, 37, 40, 3, 3),
        (3, 16, 17, 1, 1),
        (1, 8, 5, 3, 5),
        (2, 64, 48, 2, 2),
    ];
    if !narrow_kernel_available() {
        eprintln!("no AVX-512 on this CPU: the cached path is gemm's, checked the same way");
    }
    for &case in &cases {
        assert!(case.3 * case.4 <= NARROW_MAX_PIXELS);
        cached_matches_conv2d(case, NarrowCache::is_packed);
    }
    // a wider map packs the weights for the wide kernel instead
    let (x, k, b) = (randn(&[1, 8, 5, 5]), randn(&[16, 8, 1, 1]), randn(&[16]));
    let cache = NarrowCache::default();
    let ours = pointwise_conv_bias_act_cached(&x, &k, &b, &cache, None, false).unwrap();
    let plain = pointwise_conv_bias_act(&x, &k, &b, None, false).unwrap();
    assert!(max_abs_diff(&ours, &plain) < 1e-4);
    assert!(!cache.is_packed());
    assert_eq!(cache.is_packed_wide(), narrow_kernel_available());
}

/// Layers with a cache run maps of more than 16 pixels through the wide
/// kernel on weights packed once (AVX-512 CPUs; elsewhere `gemm`): Lite0's
/// shapes at 128 px (64 x 64 to 8 x 8), output channels that fill no whole
/// block of 6, pixel counts that fill no whole tile of 64 (the last vector
/// masked), several images, with and without residual and ReLU6.
#[test]
fn wide_pointwise_matches_conv2d() {
    let cases = [
        (1, 16, 96, 64, 64),
        (1, 672, 112, 8, 8),
        (2, 27, 32, 9, 7),
        (1, 5, 7, 17, 1),
        (3, 40, 16, 5, 13),
    ];
    for &case in &cases {
        assert!(case.3 * case.4 > NARROW_MAX_PIXELS);
        let (ours, x, k, b) = cached_matches_conv2d(case, NarrowCache::is_packed_wide);
        let plain = pointwise_conv_bias_act(&x, &k, &b, None, true).unwrap();
        let d = max_abs_diff(&ours, &plain);
        assert!(d < 1e-4, "{case:?}: {d} from gemm's");
    }
}

/// One 1x1 layer `(n, cin, cout, h, w)` through a fresh cache against
/// candle's `conv2d`: with a residual, then with ReLU6 on the weights the
/// first call packed (`packed` says which kernel's packing that is: there
/// only on AVX-512 CPUs). Returns the ReLU6 output and the inputs.
fn cached_matches_conv2d(
    case: (usize, usize, usize, usize, usize),
    packed: fn(&NarrowCache) -> bool,
) -> (Tensor, Tensor, Tensor, Tensor) {
    let (n, cin, cout, h, w) = case;
    let x = randn(&[n, cin, h, w]);
    let k = randn(&[cout, cin, 1, 1]);
    let b = randn(&[cout]);
    let biased = x
        .conv2d(&k, 0, 1, 1, 1)
        .unwrap()
        .broadcast_add(&b.reshape((1, cout, 1, 1)).unwrap())
        .unwrap();
    let residual = randn(&[n, cout, h, w]);
    let cache = NarrowCache::default();
    let ours = pointwise_conv_bias_act_cached(&x, &k, &b, &cache, Some(&residual), false);
    let d = max_abs_diff(&ours.unwrap(), &(&biased + &residual).unwrap());
    assert!(d < 1e-3, "{case:?}: diff {d}");
    assert_eq!(packed(&cache), narrow_kernel_available());
    // the packed weights are reused by the next call
    let ours = pointwise_conv_bias_act_cached(&x, &k, &b, &cache, None, true).unwrap();
    let d = max_abs_diff(&ours, &biased.clamp(0f32, 6f32).unwrap());
    assert!(d < 1e-3, "{case:?}: diff {d}");
    (ours, x, k, b)
}

/// `x` zero-padded as TensorFlow's SAME padding does for a `k`x`k`,
/// `stride` convolution (the extra pixel at the bottom/right), computed
/// here independently of the kernels' own `Padding::resolve`.
fn same_padded(x: &Tensor, k: usize, stride: usize) -> Tensor {
    let (_, _, h, w) = x.dims4().unwrap();
    let pads = |size: usize| {
        let out = size.div_ceil(stride);
        let total = ((out - 1) * stride + k).saturating_sub(size);
        (total / 2, total - total / 2)
    };
    let (top, bottom) = pads(h);
    let (left, right) = pads(w);
    x.pad_with_zeros(2, top, bottom)
        .unwrap()
        .pad_with_zeros(3, left, right)
        .unwrap()
}

#[test]
fn depthwise_same_padding_matches_grouped_conv2d() {
    // 3x3 and 5x5, stride 1 and 2, odd and even sides (asymmetric padding
    // at stride 2 on even sides), planes smaller than the kernel
    for &(n, c, h, w) in &SHAPES {
        for k in [3, 5] {
            for stride in [1, 2] {
                let x = randn(&[n, c, h, w]);
                let wt = randn(&[c, 1, k, k]);
                let b = randn(&[c]);
                let reference = same_padded(&x, k, stride)
                    .conv2d(&wt, 0, stride, 1, c)
                    .unwrap()
                    .broadcast_add(&b.reshape((1, c, 1, 1)).unwrap())
                    .unwrap();
                assert_eq!(reference.dims()[2], h.div_ceil(stride));
                let ours =
                    depthwise_conv_bias_act(&x, &wt, &b, stride, Padding::Same, false).unwrap();
                let d = max_abs_diff(&ours, &reference);
                assert!(d < 1e-4, "{:?} k {k} s {stride}: diff {d}", (n, c, h, w));
                let ours =
                    depthwise_conv_bias_act(&x, &wt, &b, stride, Padding::Same, true).unwrap();
                let d = max_abs_diff(&ours, &reference.clamp(0f32, 6f32).unwrap());
                assert!(
                    d < 1e-4,
                    "{:?} k {k} s {stride} relu6: diff {d}",
                    (n, c, h, w)
                );
            }
        }
    }
}

#[test]
fn depthwise_5x5_with_symmetric_padding_matches_grouped_conv2d() {
    for &(n, c, h, w) in &[(2, 3, 9, 8), (1, 4, 14, 14), (1, 2, 7, 7), (1, 3, 28, 27)] {
        for stride in [1, 2] {
            let x = randn(&[n, c, h, w]);
            let wt = randn(&[c, 1, 5, 5]);
            let b = Tensor::zeros(c, candle_core::DType::F32, &Device::Cpu).unwrap();
            let reference = x.conv2d(&wt, 2, stride, 1, c).unwrap();
            let ours =
                depthwise_conv_bias_act(&x, &wt, &b, stride, Padding::Symmetric(2), false).unwrap();
            let d = max_abs_diff(&ours, &reference);
            assert!(d < 1e-4, "{:?} stride {stride}: diff {d}", (n, c, h, w));
        }
    }
}

#[test]
fn depthwise_rejects_unsupported_kernels() {
    let x = randn(&[1, 2, 6, 6]);
    let b = randn(&[2]);
    for k in [1, 4, 7] {
        let wt = randn(&[2, 1, k, k]);
        assert!(depthwise_conv_bias_act(&x, &wt, &b, 1, Padding::Same, false).is_err());
    }
    let wt = randn(&[2, 1, 5, 5]);
    assert!(depthwise_conv_bias_act(&x, &wt, &b, 3, Padding::Same, false).is_err());
    assert!(depthwise_conv_bias_act(&x, &wt, &b, 1, Padding::Symmetric(0), false).is_ok());
    let tiny = randn(&[1, 2, 3, 3]);
    assert!(depthwise_conv_bias_act(&tiny, &wt, &b, 1, Padding::Symmetric(0), false).is_err());
}

#[test]
fn stem_im2col_with_same_padding_matches_conv2d() {
    // the EfficientNet-Lite stem: dense 3x3, stride 2, SAME, as im2col + 1x1
    for &(n, h, w) in &[
        (1, 224, 224),
        (2, 37, 37),
        (1, 48, 40),
        (1, 1, 2),
        (3, 9, 6),
    ] {
        let (cin, cout) = (3, 8);
        let x = randn(&[n, cin, h, w]);
        let wt = randn(&[cout, cin, 3, 3]);
        let b = randn(&[cout]);
        let reference = same_padded(&x, 3, 2)
            .conv2d(&wt, 0, 2, 1, 1)
            .unwrap()
            .broadcast_add(&b.reshape((1, cout, 1, 1)).unwrap())
            .unwrap();
        let cols = im2col(&x, 3, 2, Padding::Same).unwrap();
        let ours = pointwise_conv_bias_act(
            &cols,
            &wt.reshape((cout, cin * 9)).unwrap(),
            &b,
            None,
            false,
        )
        .unwrap();
        let d = max_abs_diff(&ours, &reference);
        assert!(d < 1e-4, "{:?}: diff {d}", (n, h, w));
    }
}
