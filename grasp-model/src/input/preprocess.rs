//! Image preprocessing of a backbone: resize to a square with the filter
//! the network was trained with, scale to [0, 1], normalize per channel.
//!
//! Each backbone has its own: torchvision's MobileNetV2 resizes bilinearly
//! and normalizes with ImageNet's mean and std; the EfficientNet-Lite files
//! resize bicubically and map a pixel x to (x - 127) / 128, which is a mean
//! of 127/255 and a std of 128/255 in [0, 1] units. A checkpoint records
//! its backbone's [`Preprocess`] and inference applies exactly that.

use candle_core::{Device, Result, Tensor};
use image::RgbImage;
use serde::{Deserialize, Serialize};

pub use super::resize::ResizeFilter;

pub const IMAGENET_MEAN: [f32; 3] = [0.485, 0.456, 0.406];
pub const IMAGENET_STD: [f32; 3] = [0.229, 0.224, 0.225];
/// EfficientNet-Lite's (x - 127) / 128 in [0, 1] units.
pub const LITE_MEAN: [f32; 3] = [127.0 / 255.0; 3];
pub const LITE_STD: [f32; 3] = [128.0 / 255.0; 3];

/// Input preprocessing: squash to `size` x `size` with `resize`, scale to
/// [0, 1], then normalize per channel: (x / 255 - mean) / std.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Preprocess {
    pub size: u32,
    pub mean: [f32; 3],
    pub std: [f32; 3],
    /// Absent in checkpoints and cache keys from before it existed, which
    /// were all bilinear; left out when bilinear so those keys stay valid.
    #[serde(default, skip_serializing_if = "ResizeFilter::is_bilinear")]
    pub resize: ResizeFilter,
}

impl Preprocess {
    /// torchvision's ImageNet preprocessing (MobileNetV2).
    pub fn imagenet(size: u32) -> Preprocess {
        Preprocess {
            size,
            mean: IMAGENET_MEAN,
            std: IMAGENET_STD,
            resize: ResizeFilter::Bilinear,
        }
    }

    /// EfficientNet-Lite's: bicubic resize, (x - 127) / 128.
    pub fn efficientnet_lite(size: u32) -> Preprocess {
        Preprocess {
            size,
            mean: LITE_MEAN,
            std: LITE_STD,
            resize: ResizeFilter::Bicubic,
        }
    }

    /// Per-channel (scale, offset) with normalized = pixel * scale + offset
    /// for a pixel value in 0..=255.
    fn affine(&self) -> Result<([f32; 3], [f32; 3])> {
        if self.std.iter().any(|s| !(s.is_finite() && *s > 0.0))
            || self.mean.iter().any(|m| !m.is_finite())
        {
            candle_core::bail!(
                "preprocessing: std must be positive and mean finite, got mean {:?}, std {:?}",
                self.mean,
                self.std
            );
        }
        let scale = std::array::from_fn(|c| 1.0 / (255.0 * self.std[c]));
        let offset = std::array::from_fn(|c| -self.mean[c] / self.std[c]);
        Ok((scale, offset))
    }

    /// `img` resized to the input size (borrowed when it already is).
    pub fn resize<'a>(&self, img: &'a RgbImage) -> std::borrow::Cow<'a, RgbImage> {
        if img.dimensions() == (self.size, self.size) {
            std::borrow::Cow::Borrowed(img)
        } else {
            std::borrow::Cow::Owned(super::resize::resize(
                img,
                self.size,
                self.size,
                self.resize,
            ))
        }
    }
}

/// A normalized (N, 3, size, size) batch of `images`, each resized and
/// normalized as `pre` says.
/// The central square whose side is `fraction` of the shorter side (at
/// least one pixel): the view a checkpoint trained with `--center-crop`
/// expects.
pub fn center_crop(img: &RgbImage, fraction: f64) -> RgbImage {
    let (x, y, side) = grasp_schema::dataset::centre_square(img.width(), img.height(), fraction);
    image::imageops::crop_imm(img, x, y, side, side).to_image()
}

pub fn to_tensor(images: &[RgbImage], pre: &Preprocess, device: &Device) -> Result<Tensor> {
    if images.is_empty() {
        candle_core::bail!("to_tensor: no images");
    }
    if pre.size == 0 {
        candle_core::bail!("to_tensor: size must be positive");
    }
    let (scale, offset) = pre.affine()?;
    let size = pre.size as usize;
    let plane = size * size;
    let mut data = vec![0f32; images.len() * 3 * plane];
    for (img, out) in images.iter().zip(data.chunks_exact_mut(3 * plane)) {
        write_chw(&pre.resize(img), out, plane, scale, offset);
    }
    Tensor::from_vec(data, (images.len(), 3, size, size), device)
}

/// Writes one HWC u8 image as normalized CHW floats.
fn write_chw(img: &RgbImage, out: &mut [f32], plane: usize, scale: [f32; 3], offset: [f32; 3]) {
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
    fn center_crop_takes_the_middle_square() {
        let img = RgbImage::from_fn(10, 6, |x, y| image::Rgb([x as u8, y as u8, 0]));
        let c = center_crop(&img, 0.5);
        assert_eq!(c.dimensions(), (3, 3));
        assert_eq!(c.get_pixel(0, 0).0, [3, 1, 0]);
        assert_eq!(center_crop(&img, 1.0).dimensions(), (6, 6));
        assert_eq!(center_crop(&img, 0.0).dimensions(), (1, 1));
    }

    fn values(t: &Tensor) -> Vec<f32> {
        t.flatten_all().unwrap().to_vec1::<f32>().unwrap()
    }

    #[test]
    fn normalizes_per_channel_in_chw_order() {
        let mut img = RgbImage::new(2, 2);
        img.put_pixel(1, 0, image::Rgb([255, 0, 128]));
        let t = to_tensor(&[img], &Preprocess::imagenet(2), &Device::Cpu).unwrap();
        assert_eq!(t.dims(), &[1, 3, 2, 2]);
        let v = values(&t);
        let expect = |c: usize, x: f32| (x / 255.0 - IMAGENET_MEAN[c]) / IMAGENET_STD[c];
        // pixel (x=1, y=0) is index 1 in each plane
        assert!((v[1] - expect(0, 255.0)).abs() < 1e-5);
        assert!((v[4 + 1] - expect(1, 0.0)).abs() < 1e-5);
        assert!((v[8 + 1] - expect(2, 128.0)).abs() < 1e-5);
        assert!((v[0] - expect(0, 0.0)).abs() < 1e-5);
    }

    #[test]
    fn applies_the_recorded_normalization() {
        let mut img = RgbImage::new(1, 1);
        img.put_pixel(0, 0, image::Rgb([0, 127, 255]));
        let v =
            values(&to_tensor(&[img], &Preprocess::efficientnet_lite(1), &Device::Cpu).unwrap());
        // (x - 127) / 128
        for (got, x) in v.iter().zip([0.0f32, 127.0, 255.0]) {
            assert!((got - (x - 127.0) / 128.0).abs() < 1e-6, "{got} for {x}");
        }
    }

    #[test]
    fn resizes_with_the_recorded_filter() {
        let img = RgbImage::from_pixel(5, 3, image::Rgb([10, 20, 30]));
        let pre = Preprocess::imagenet(4);
        let t = to_tensor(&[img.clone(), img], &pre, &Device::Cpu).unwrap();
        assert_eq!(t.dims(), &[2, 3, 4, 4]);
        // a constant image stays constant after resizing
        let v = values(&t);
        let expect = (10.0 / 255.0 - IMAGENET_MEAN[0]) / IMAGENET_STD[0];
        assert!(v[..16].iter().all(|x| (x - expect).abs() < 1e-5));
        // a sharp edge: bicubic overshoots, bilinear never leaves the range
        let edge = RgbImage::from_fn(8, 8, |x, _| image::Rgb([if x < 4 { 50 } else { 200 }; 3]));
        let lin = Preprocess {
            size: 5,
            mean: [0.0; 3],
            std: [1.0 / 255.0; 3],
            resize: ResizeFilter::Bilinear,
        };
        let cubic = Preprocess {
            resize: ResizeFilter::Bicubic,
            ..lin.clone()
        };
        let range = |p: &Preprocess| {
            let v = values(&to_tensor(std::slice::from_ref(&edge), p, &Device::Cpu).unwrap());
            let lo = v.iter().copied().fold(f32::MAX, f32::min);
            let hi = v.iter().copied().fold(f32::MIN, f32::max);
            (lo, hi)
        };
        let (lo, hi) = range(&lin);
        assert!(lo >= 50.0 && hi <= 200.0, "{lo} {hi}");
        let (lo, hi) = range(&cubic);
        assert!(lo < 50.0 || hi > 200.0, "{lo} {hi}");
    }

    #[test]
    fn old_records_read_as_bilinear_and_keep_their_serialization() {
        let old = r#"{"size":224,"mean":[0.485,0.456,0.406],"std":[0.229,0.224,0.225]}"#;
        let p: Preprocess = serde_json::from_str(old).unwrap();
        assert_eq!(p, Preprocess::imagenet(224));
        assert_eq!(serde_json::to_string(&p).unwrap(), old);
        let lite = serde_json::to_string(&Preprocess::efficientnet_lite(224)).unwrap();
        assert!(lite.contains("\"resize\":\"bicubic\""), "{lite}");
    }

    #[test]
    fn rejects_empty_input_and_bad_statistics() {
        assert!(to_tensor(&[], &Preprocess::imagenet(4), &Device::Cpu).is_err());
        let img = RgbImage::new(2, 2);
        let mut p = Preprocess::imagenet(2);
        p.std[1] = 0.0;
        assert!(to_tensor(&[img], &p, &Device::Cpu).is_err());
    }
}
