//! Augmentation for training from scratch: random square crop, optional
//! horizontal flip, and colour jitter.
//!
//! The horizontal flip is OFF by default. Mirroring does not change a frame's
//! label (the taxonomy has no handedness), but it turns the right-hand wrist
//! camera's view into a left-hand approach: the hand seen at the top of the
//! frame, the approach direction and the side the thumb meets the object all
//! swap, producing views the prosthesis never sees at test time.

use image::{imageops, RgbImage};
use rand::Rng;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AugmentConfig {
    pub enabled: bool,
    /// Smallest crop side as a fraction of the shorter image side.
    pub crop_min: f32,
    pub hflip: bool,
    /// Jitter amplitudes: factors are drawn from [1 - a, 1 + a].
    pub brightness: f32,
    pub contrast: f32,
    pub saturation: f32,
}

impl Default for AugmentConfig {
    fn default() -> Self {
        AugmentConfig {
            enabled: true,
            crop_min: 0.8,
            hflip: false,
            brightness: 0.2,
            contrast: 0.2,
            saturation: 0.2,
        }
    }
}

/// Augments `img` and resizes it to `size`x`size`.
pub fn augment(img: &RgbImage, size: u32, cfg: &AugmentConfig, rng: &mut impl Rng) -> RgbImage {
    if !cfg.enabled {
        return resize(img, size);
    }
    let (w, h) = img.dimensions();
    let short = w.min(h);
    let side = ((short as f32 * rng.gen_range(cfg.crop_min.min(1.0)..=1.0)).round() as u32)
        .clamp(1, short);
    let x = rng.gen_range(0..=w - side);
    let y = rng.gen_range(0..=h - side);
    let mut out = resize(&imageops::crop_imm(img, x, y, side, side).to_image(), size);
    if cfg.hflip && rng.gen_bool(0.5) {
        imageops::flip_horizontal_in_place(&mut out);
    }
    let b = factor(cfg.brightness, rng);
    let c = factor(cfg.contrast, rng);
    let s = factor(cfg.saturation, rng);
    jitter(&mut out, b, c, s);
    out
}

/// Squashes `img` to `size`x`size` (the evaluation transform).
pub fn resize(img: &RgbImage, size: u32) -> RgbImage {
    if img.dimensions() == (size, size) {
        return img.clone();
    }
    imageops::resize(img, size, size, imageops::FilterType::Triangle)
}

fn factor(amplitude: f32, rng: &mut impl Rng) -> f32 {
    if amplitude <= 0.0 {
        1.0
    } else {
        rng.gen_range(1.0 - amplitude..=1.0 + amplitude)
    }
}

/// Brightness scales, contrast blends with the mean grey, saturation blends
/// with the pixel's own grey (luma weights of ITU-R BT.601).
pub(crate) fn jitter(img: &mut RgbImage, brightness: f32, contrast: f32, saturation: f32) {
    let luma = |p: &image::Rgb<u8>| 0.299 * p[0] as f32 + 0.587 * p[1] as f32 + 0.114 * p[2] as f32;
    let n = (img.width() * img.height()).max(1) as f32;
    let mean = img.pixels().map(luma).sum::<f32>() / n * brightness;
    for p in img.pixels_mut() {
        let grey = luma(p) * brightness;
        for ch in 0..3 {
            let v = p[ch] as f32 * brightness;
            let v = grey + (v - grey) * saturation;
            let v = mean + (v - mean) * contrast;
            p[ch] = v.round().clamp(0.0, 255.0) as u8;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn disabled_augmentation_only_resizes() {
        let img = RgbImage::from_pixel(10, 8, image::Rgb([10, 20, 30]));
        let cfg = AugmentConfig {
            enabled: false,
            ..Default::default()
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let out = augment(&img, 4, &cfg, &mut rng);
        assert_eq!(out.dimensions(), (4, 4));
        assert_eq!(out.get_pixel(1, 1), &image::Rgb([10, 20, 30]));
    }

    #[test]
    fn jitter_keeps_grey_grey_and_is_seeded() {
        let img = RgbImage::from_pixel(16, 16, image::Rgb([100, 100, 100]));
        let cfg = AugmentConfig::default();
        let a = augment(
            &img,
            8,
            &cfg,
            &mut rand_chacha::ChaCha8Rng::seed_from_u64(3),
        );
        let b = augment(
            &img,
            8,
            &cfg,
            &mut rand_chacha::ChaCha8Rng::seed_from_u64(3),
        );
        assert_eq!(a, b);
        let p = a.get_pixel(0, 0);
        assert_eq!(p[0], p[1]);
        assert_eq!(p[1], p[2]);
    }
}
