//! Resizing a square to the backbone's input: the arithmetic of `image`'s
//! `imageops::resize` (its Catmull-Rom and triangle kernels and weights, a
//! vertical pass to floats then a horizontal one, each sum taken in the
//! same order, clamped and rounded the same way), so the output is `image`'s
//! to the bit, in two tight passes compiled for the vector unit. `image`'s
//! generic passes read every pixel through bounds-checked accessors and call
//! the C library's `roundf` for every value: 5 % of a frame on one thread.

use crate::ops::cpu::simd_dispatch;
use image::RgbImage;
use serde::{Deserialize, Serialize};

/// The filter that squashes frames to the input size.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ResizeFilter {
    /// Triangle (bilinear) filter, torchvision's default.
    #[default]
    Bilinear,
    /// Catmull-Rom (bicubic, a = -0.5, as PIL's BICUBIC).
    Bicubic,
}

impl ResizeFilter {
    pub(super) fn is_bilinear(&self) -> bool {
        *self == ResizeFilter::Bilinear
    }
}

/// `img` resized to `width` x `height` with `filter`.
pub fn resize(img: &RgbImage, width: u32, height: u32, filter: ResizeFilter) -> RgbImage {
    let (w, h) = img.dimensions();
    if w == 0 || h == 0 || width == 0 || height == 0 {
        return RgbImage::new(width, height);
    }
    let rows = Taps::new(h, height, filter);
    let columns = Taps::new(w, width, filter);
    let mut vertical = vec![0f32; w as usize * 3 * height as usize];
    vertical_pass(img.as_raw(), w as usize * 3, &rows, &mut vertical);
    let mut out = vec![0u8; width as usize * 3 * height as usize];
    horizontal_pass(&vertical, w as usize * 3, &columns, &mut out);
    RgbImage::from_raw(width, height, out).expect("the buffer has width x height pixels")
}

/// For every output coordinate, the first input coordinate it reads and
/// the normalised weights of the consecutive ones from there.
struct Taps {
    first: Vec<usize>,
    /// `weights[start[o]..start[o + 1]]` are output `o`'s.
    start: Vec<usize>,
    weights: Vec<f32>,
}

impl Taps {
    /// `image`'s sampling of `src` input pixels into `dst` outputs: the
    /// kernel centred on each output pixel's centre, widened by the ratio
    /// when shrinking, cut to the image, its weights divided by their sum.
    fn new(src: u32, dst: u32, filter: ResizeFilter) -> Taps {
        let (kernel, support): (fn(f32) -> f32, f32) = match filter {
            ResizeFilter::Bilinear => (triangle, 1.0),
            ResizeFilter::Bicubic => (catmull_rom, 2.0),
        };
        let ratio = src as f32 / dst as f32;
        let sratio = if ratio < 1.0 { 1.0 } else { ratio };
        let src_support = support * sratio;
        let mut taps = Taps {
            first: Vec::with_capacity(dst as usize),
            start: vec![0],
            weights: Vec::new(),
        };
        for out in 0..dst {
            let centre = (out as f32 + 0.5) * ratio;
            let left = ((centre - src_support).floor() as i64).clamp(0, i64::from(src) - 1);
            let right = ((centre + src_support).ceil() as i64).clamp(left + 1, i64::from(src));
            let centre = centre - 0.5;
            let from = taps.weights.len();
            let mut sum = 0.0;
            for i in left..right {
                let w = kernel((i as f32 - centre) / sratio);
                taps.weights.push(w);
                sum += w;
            }
            for w in &mut taps.weights[from..] {
                *w /= sum;
            }
            taps.first.push(left as usize);
            taps.start.push(taps.weights.len());
        }
        taps
    }

    fn of(&self, out: usize) -> (usize, &[f32]) {
        (
            self.first[out],
            &self.weights[self.start[out]..self.start[out + 1]],
        )
    }

    fn len(&self) -> usize {
        self.first.len()
    }
}

/// The Catmull-Rom spline (the BC-spline with B = 0, C = 0.5), as `image`
/// writes it.
fn catmull_rom(x: f32) -> f32 {
    let (b, c) = (0.0f32, 0.5f32);
    let a = x.abs();
    let k = if a < 1.0 {
        (12.0 - 9.0 * b - 6.0 * c) * a.powi(3)
            + (-18.0 + 12.0 * b + 6.0 * c) * a.powi(2)
            + (6.0 - 2.0 * b)
    } else if a < 2.0 {
        (-b - 6.0 * c) * a.powi(3)
            + (6.0 * b + 30.0 * c) * a.powi(2)
            + (-12.0 * b - 48.0 * c) * a
            + (8.0 * b + 24.0 * c)
    } else {
        0.0
    };
    k / 6.0
}

fn triangle(x: f32) -> f32 {
    if x.abs() < 1.0 {
        1.0 - x.abs()
    } else {
        0.0
    }
}

simd_dispatch! {
/// Each output row (`row_len` floats, interleaved RGB) as the weighted sum
/// of its input rows, in order.
fn vertical_pass(src: &[u8], row_len: usize, rows: &Taps, out: &mut [f32]) {
    for (o, dst) in out.chunks_exact_mut(row_len).enumerate().take(rows.len()) {
        let (first, weights) = rows.of(o);
        dst.fill(0.0);
        for (k, &w) in weights.iter().enumerate() {
            let row = &src[(first + k) * row_len..(first + k + 1) * row_len];
            for (d, &v) in dst.iter_mut().zip(row) {
                *d += f32::from(v) * w;
            }
        }
    }
}
}

simd_dispatch! {
/// Each row of `src` (`row_len` floats) resampled across into `out`'s,
/// clamped to [0, 255] and rounded half away from zero.
fn horizontal_pass(src: &[f32], row_len: usize, columns: &Taps, out: &mut [u8]) {
    let out_len = columns.len() * 3;
    for (row, dst) in src.chunks_exact(row_len).zip(out.chunks_exact_mut(out_len)) {
        for (o, px) in dst.chunks_exact_mut(3).enumerate() {
            let (first, weights) = columns.of(o);
            let mut t = [0f32; 3];
            for (k, &w) in weights.iter().enumerate() {
                let p = &row[(first + k) * 3..(first + k) * 3 + 3];
                for c in 0..3 {
                    t[c] += p[c] * w;
                }
            }
            for c in 0..3 {
                px[c] = t[c].clamp(0.0, 255.0).round() as u8;
            }
        }
    }
}
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::imageops::{self, FilterType};

    fn noise(w: u32, h: u32, seed: u32) -> RgbImage {
        let mut s = seed.wrapping_mul(2_654_435_761).wrapping_add(1);
        RgbImage::from_fn(w, h, |_, _| {
            let mut px = [0u8; 3];
            for v in &mut px {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                *v = (s >> 24) as u8;
            }
            image::Rgb(px)
        })
    }

    /// Up (the shipped 94 -> 128), down, to and from one pixel, and
    /// non-square, with both filters: `image`'s output to the bit.
    #[test]
    fn matches_image_resize_to_the_bit() {
        let cases = [
            (94, 94, 128, 128),
            (224, 224, 128, 128),
            (300, 171, 224, 224),
            (1, 1, 5, 3),
            (7, 2, 1, 1),
            (3, 9, 17, 4),
        ];
        for (i, &(w, h, nw, nh)) in cases.iter().enumerate() {
            let img = noise(w, h, i as u32);
            for (ours, theirs) in [
                (ResizeFilter::Bicubic, FilterType::CatmullRom),
                (ResizeFilter::Bilinear, FilterType::Triangle),
            ] {
                let got = resize(&img, nw, nh, ours);
                let want = imageops::resize(&img, nw, nh, theirs);
                assert_eq!(got.dimensions(), want.dimensions());
                let differ = got
                    .as_raw()
                    .iter()
                    .zip(want.as_raw())
                    .filter(|(a, b)| a != b);
                assert_eq!(differ.count(), 0, "{:?} {ours:?}", (w, h, nw, nh));
            }
        }
    }

    #[test]
    fn empty_images_give_black_outputs() {
        assert_eq!(
            resize(&RgbImage::new(0, 4), 3, 2, ResizeFilter::Bicubic).dimensions(),
            (3, 2)
        );
        assert_eq!(
            resize(&noise(4, 4, 1), 0, 2, ResizeFilter::Bilinear).dimensions(),
            (0, 2)
        );
    }
}
