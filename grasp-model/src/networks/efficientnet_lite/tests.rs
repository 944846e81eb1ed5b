//! Unit tests of `efficientnet_lite`, apart from the network.

use super::*;

#[test]
fn lite0_has_the_published_layout() {
    let specs = LiteVariant::Lite0.config().block_specs();
    assert_eq!(specs.len(), 16);
    let strides: usize = specs.iter().map(|s| s.stride).product();
    assert_eq!(strides * 2, 32, "stem and blocks reduce by 32");
    let last = specs.last().unwrap();
    assert_eq!((last.cin, last.cout, last.kernel), (192, 320, 3));
    // residuals where stride 1 and channels stay: 16 blocks, 7 stage starts,
    // but stage 5's first block (80 -> 112, stride 1) has none either
    let residual = specs
        .iter()
        .filter(|s| s.stride == 1 && s.cin == s.cout)
        .count();
    assert_eq!(residual, 9);
}

#[test]
fn larger_variants_scale_the_middle_stages() {
    assert_eq!(LiteVariant::Lite1.config().block_specs().len(), 21);
    let lite2 = LiteVariant::Lite2.config().block_specs();
    assert_eq!(lite2.len(), 21);
    assert_eq!(lite2[0].cout, 16);
    assert_eq!(lite2.last().unwrap().cout, 352);
    assert_eq!((lite2[3].cout, lite2[4].cout), (24, 48));
}
