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
