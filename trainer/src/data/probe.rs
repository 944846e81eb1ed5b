//! A sensor's degradation of a sequence's frames (defocus blur, then
//! additive noise, as a noisier sensor adds it), applied to every frame
//! before the centre crop: training's sensor views (`[views] noise`,
//! `blur_px`) draw one per view. The noise of frame `i` of a sequence is
//! drawn from its id and `i`, so it is repeatable and its features are
//! cached like any other view of the frames.

use image::RgbImage;
use serde::{Deserialize, Serialize};

/// Degradation added to every frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SensorProbe {
    /// Standard deviation of the Gaussian noise added to each channel, as a
    /// fraction of full scale (0.02 is about 5 grey levels); 0: none.
    pub noise_sigma: f32,
    /// Gaussian blur before the noise, in pixels of the frame; 0: none.
    pub blur_sigma_px: f32,
}

/// The largest noise sigma (full scale) and blur (pixels) a view's sensor
/// range may ask for.
pub const MAX_NOISE_SIGMA: f32 = 1.0;
pub const MAX_BLUR_PX: f32 = 50.0;

impl SensorProbe {
    /// The probe, or None when it degrades nothing.
    pub fn active(self) -> Option<Self> {
        (self.noise_sigma > 0.0 || self.blur_sigma_px > 0.0).then_some(self)
    }

    /// `img` blurred, then with noise drawn from `key` (sequence id and
    /// frame index), rounded back to 8 bits.
    pub fn apply(&self, img: &RgbImage, key: &str) -> RgbImage {
        let mut out = if self.blur_sigma_px > 0.0 {
            image::imageops::blur(img, self.blur_sigma_px)
        } else {
            img.clone()
        };
        if self.noise_sigma > 0.0 {
            let mut rng = crate::rng::stream(0, &format!("probe/{key}"));
            let scale = 255.0 * self.noise_sigma;
            for v in out.iter_mut() {
                let noisy = f32::from(*v) + scale * crate::rng::standard_normal(&mut rng);
                *v = noisy.round().clamp(0.0, 255.0) as u8;
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grey(v: u8) -> RgbImage {
        RgbImage::from_pixel(64, 48, image::Rgb([v; 3]))
    }

    fn sensor(noise_sigma: f32, blur_sigma_px: f32) -> SensorProbe {
        SensorProbe {
            noise_sigma,
            blur_sigma_px,
        }
    }

    #[test]
    fn a_probe_of_zeros_is_no_probe() {
        assert_eq!(sensor(0.0, 0.0).active(), None);
        assert!(sensor(0.02, 0.0).active().is_some());
        assert!(sensor(0.0, 0.5).active().is_some());
    }

    #[test]
    fn noise_has_the_asked_spread_and_is_repeatable() {
        let probe = sensor(0.04, 0.0);
        let a = probe.apply(&grey(128), "seq/3");
        assert_eq!(a, probe.apply(&grey(128), "seq/3"));
        assert_ne!(a, probe.apply(&grey(128), "seq/4"));
        let values: Vec<f64> = a.iter().map(|v| f64::from(*v) - 128.0).collect();
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let sd = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
        assert!(mean.abs() < 0.5, "mean {mean}");
        // 0.04 of full scale is 10.2 grey levels.
        assert!((sd - 10.2).abs() < 0.6, "sd {sd}");
    }

    #[test]
    fn noise_clips_at_black_and_white_and_blur_alone_keeps_flat_frames() {
        let probe = sensor(0.5, 0.0);
        let black = probe.apply(&grey(0), "k");
        assert!(black.contains(&0) && black.iter().any(|v| *v > 0));
        let blur = sensor(0.0, 2.0);
        assert_eq!(blur.apply(&grey(77), "k"), grey(77));
        let mut edge = grey(0);
        for y in 0..48 {
            for x in 32..64 {
                edge.put_pixel(x, y, image::Rgb([255; 3]));
            }
        }
        let soft = blur.apply(&edge, "k");
        let at = |x| soft.get_pixel(x, 24).0[0];
        assert!(at(31) > 0 && at(32) < 255, "the edge is softened");
        assert_eq!((at(0), at(63)), (0, 255), "far from it nothing changes");
    }
}
