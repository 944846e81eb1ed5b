//! Unit tests of `depthwise`, apart so that the kernel file holds only the kernel.

use super::Padding;

#[test]
fn same_padding_puts_the_extra_pixel_after() {
    // (size, kernel, stride) -> (out, before), as TensorFlow computes them
    assert_eq!(Padding::Same.resolve(224, 3, 2), Some((112, 0)));
    assert_eq!(Padding::Same.resolve(225, 3, 2), Some((113, 1)));
    assert_eq!(Padding::Same.resolve(56, 5, 2), Some((28, 1)));
    assert_eq!(Padding::Same.resolve(57, 5, 2), Some((29, 2)));
    assert_eq!(Padding::Same.resolve(14, 5, 1), Some((14, 2)));
    assert_eq!(Padding::Same.resolve(1, 5, 2), Some((1, 2)));
    assert_eq!(Padding::Symmetric(1).resolve(7, 3, 2), Some((4, 1)));
    assert_eq!(Padding::Symmetric(0).resolve(2, 3, 1), None);
}

/// Small planes with the channels along the vector give the plane-by-plane
/// stencil's outputs to the bit: Lite0's small stages (8 x 8 and 4 x 4,
/// 5 x 5 and 3 x 3, stride 1 and 2 into them), odd and 1 x 1 planes, both
/// paddings, with and without bias and ReLU6.
#[cfg(target_arch = "x86_64")]
#[test]
fn small_planes_match_the_plane_stencil_to_the_bit() {
    use super::{forward_planes, small, Geom};
    use candle_core::Shape;
    if !crate::ops::cpu::has_avx512() {
        eprintln!("no AVX-512 on this CPU: small planes go plane by plane, nothing to compare");
        return;
    }
    let cases = [
        // (n, c, h, w, k, stride, padding)
        (1, 32, 8, 8, 5, 1, Padding::Same),
        (2, 16, 4, 4, 5, 1, Padding::Same),
        (1, 48, 4, 4, 3, 1, Padding::Same),
        (1, 16, 8, 8, 5, 2, Padding::Same),
        (1, 16, 16, 16, 3, 2, Padding::Same),
        (2, 32, 5, 7, 3, 1, Padding::Symmetric(1)),
        (1, 16, 9, 9, 3, 2, Padding::Symmetric(1)),
        (1, 16, 1, 1, 5, 1, Padding::Same),
        (3, 16, 3, 2, 5, 2, Padding::Same),
    ];
    let mut seed = 7u32;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        (seed as f32 / u32::MAX as f32) * 4.0 - 2.0
    };
    for (n, c, h, w, k, stride, padding) in cases {
        let g = Geom::new(&Shape::from((n, c, h, w)), k, stride, padding).unwrap();
        assert!(small::applies(&g), "{g:?}");
        let x: Vec<f32> = (0..n * c * h * w).map(|_| next()).collect();
        let wt: Vec<f32> = (0..c * k * k).map(|_| next()).collect();
        let b: Vec<f32> = (0..c).map(|_| next()).collect();
        for (bias, relu6) in [(Some(&b[..]), true), (None, false)] {
            let want = forward_planes(&g, &x, &wt, bias, relu6);
            let got = small::forward(&g, &x, &wt, bias, relu6);
            let differ = got
                .iter()
                .zip(&want)
                .filter(|(a, b)| a.to_bits() != b.to_bits());
            assert_eq!(differ.count(), 0, "{g:?} relu6 {relu6}");
        }
    }
    // wider planes and partial channel groups stay plane by plane
    let wide = Geom::new(&Shape::from((1, 16, 16, 16)), 3, 1, Padding::Same).unwrap();
    let ragged = Geom::new(&Shape::from((1, 24, 4, 4)), 3, 1, Padding::Same).unwrap();
    assert!(!small::applies(&wide) && !small::applies(&ragged));
}
