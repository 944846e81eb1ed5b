//! Image preprocessing for ImageNet-trained networks: resize to a square,
//! scale to [0, 1], normalize per channel with ImageNet's mean and std.

use candle_core::{Device, Result, Tensor};
use image::imageops::FilterType;
use image::RgbImage;

pub const IMAGENET_MEAN: [f32; 3] = [0.485, 0.456, 0.406];
pub const IMAGENET_STD: [f32; 3] = [0.229, 0.224, 0.225];

/// A normalized (N, 3, size, size) batch. Images not already `size x size`
/// are resized with a bilinear (triangle) filter.
pub fn to_tensor(images: &[RgbImage], size: u32, device: &Device) -> Result<Tensor> {
    if images.is_empty() {
        candle_core::bail!("to_tensor: no images");
    }
    if size == 0 {
        candle_core::bail!("to_tensor: size must be positive");
    }
    let plane = (size * size) as usize;
    let mut data = vec![0f32; images.len() * 3 * plane];
    for (img, out) in images.iter().zip(data.chunks_exact_mut(3 * plane)) {
        let resized;
        let img = if img.dimensions() == (size, size) {
            img
        } else {
            resized = image::imageops::resize(img, size, size, FilterType::Triangle);
            &resized
        };
        write_chw(img, out, plane);
    }
    Tensor::from_vec(
        data,
        (images.len(), 3, size as usize, size as usize),
        device,
    )
}

/// Writes one HWC u8 image as normalized CHW floats.
fn write_chw(img: &RgbImage, out: &mut [f32], plane: usize) {
    let scale: [f32; 3] = std::array::from_fn(|c| 1.0 / (255.0 * IMAGENET_STD[c]));
    let offset: [f32; 3] = std::array::from_fn(|c| -IMAGENET_MEAN[c] / IMAGENET_STD[c]);
    for (i, px) in img.pixels().enumerate() {
        for c in 0..3 {
            out[c * plane + i] = px.0[c] as f32 * scale[c] + offset[c];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalizes_per_channel_in_chw_order() {
        let mut img = RgbImage::new(2, 2);
        img.put_pixel(1, 0, image::Rgb([255, 0, 128]));
        let t = to_tensor(&[img], 2, &Device::Cpu).unwrap();
        assert_eq!(t.dims(), &[1, 3, 2, 2]);
        let v = t.flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let expect = |c: usize, x: f32| (x / 255.0 - IMAGENET_MEAN[c]) / IMAGENET_STD[c];
        // pixel (x=1, y=0) is index 1 in each plane
        assert!((v[1] - expect(0, 255.0)).abs() < 1e-5);
        assert!((v[4 + 1] - expect(1, 0.0)).abs() < 1e-5);
        assert!((v[8 + 1] - expect(2, 128.0)).abs() < 1e-5);
        assert!((v[0] - expect(0, 0.0)).abs() < 1e-5);
    }

    #[test]
    fn resizes_to_the_requested_size() {
        let img = RgbImage::from_pixel(5, 3, image::Rgb([10, 20, 30]));
        let t = to_tensor(&[img.clone(), img], 4, &Device::Cpu).unwrap();
        assert_eq!(t.dims(), &[2, 3, 4, 4]);
        // a constant image stays constant after resizing
        let v = t.flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let expect = (10.0 / 255.0 - IMAGENET_MEAN[0]) / IMAGENET_STD[0];
        assert!(v[..16].iter().all(|x| (x - expect).abs() < 1e-5));
    }

    #[test]
    fn rejects_empty_input() {
        assert!(to_tensor(&[], 4, &Device::Cpu).is_err());
    }
}
