//! Image-space camera effects, applied in the worker (Rust) to every frame
//! Blender wrote, before the sequence is finished: the stored frame is the
//! degraded one. The parameters are the plan's
//! ([`SensorEffects`], drawn from the sequence's seed), so the same plan
//! always gives the same bytes.
//!
//! Order, after a camera's pipeline: white balance and defocus blur in
//! linear light, then the sRGB encoding, additive Gaussian noise and
//! quantisation to 8 bits, then an optional JPEG round trip. The PNG is
//! rewritten through a temporary file and a rename.

use super::error::{RenderError, Result};
use grasp_schema::appearance::SensorEffects;
use grasp_schema::plan::substream_seed;
use image::codecs::jpeg::JpegEncoder;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ImageEncoder, RgbImage};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;

/// Applies `effects` to frame `frame` of `camera` (its own noise stream).
pub fn apply(
    effects: &SensorEffects,
    camera: &str,
    frame: u64,
    img: &RgbImage,
) -> Result<RgbImage> {
    let (w, h) = img.dimensions();
    let lut = srgb_to_linear_lut();
    let mut lin: Vec<f32> = img.as_raw().iter().map(|&v| lut[v as usize]).collect();
    if let Some(gain) = effects.white_balance {
        for px in lin.chunks_exact_mut(3) {
            for c in 0..3 {
                px[c] = (px[c] * gain[c] as f32).min(1.0);
            }
        }
    }
    if let Some(sigma) = effects.blur_sigma_px.filter(|s| *s > 0.0) {
        gaussian_blur(&mut lin, w as usize, h as usize, sigma as f32);
    }
    let mut rng =
        ChaCha8Rng::seed_from_u64(substream_seed(effects.seed, &format!("{camera}/{frame}")));
    let sigma = effects.noise_sigma.unwrap_or(0.0) as f32;
    let mut out = Vec::with_capacity(lin.len());
    let mut spare: Option<f32> = None;
    for v in lin {
        let mut s = linear_to_srgb(v);
        if sigma > 0.0 {
            let n = match spare.take() {
                Some(n) => n,
                None => {
                    let (a, b) = gaussian_pair(&mut rng);
                    spare = Some(b);
                    a
                }
            };
            s += sigma * n;
        }
        out.push((s * 255.0).round().clamp(0.0, 255.0) as u8);
    }
    let img = RgbImage::from_raw(w, h, out)
        .ok_or(RenderError::BufferSize("image buffer of the wrong size"))?;
    match effects.jpeg_quality {
        Some(q) => jpeg_round_trip(&img, q),
        None => Ok(img),
    }
}

/// Rewrites every frame file of a camera folder with the effects applied.
/// Returns the seconds spent.
pub fn apply_to_frames(
    effects: &SensorEffects,
    camera: &str,
    dir: &Path,
    frame_files: &[String],
) -> Result<f64> {
    let start = std::time::Instant::now();
    for (k, name) in frame_files.iter().enumerate() {
        let path = dir.join(name);
        let img = image::open(&path)
            .map_err(|e| RenderError::image(format!("cannot read frame {}", path.display()), e))?
            .to_rgb8();
        let out = apply(effects, camera, k as u64, &img)?;
        let bytes = png_bytes(&out)?;
        grasp_support::atomic::write_atomic(&path, &bytes)?;
    }
    Ok(start.elapsed().as_secs_f64())
}

/// A PNG of `img` (fast compression, adaptive filters: a few ms at 224 px).
pub fn png_bytes(img: &RgbImage) -> Result<Vec<u8>> {
    let mut bytes = Vec::new();
    PngEncoder::new_with_quality(&mut bytes, CompressionType::Fast, FilterType::Adaptive)
        .write_image(
            img.as_raw(),
            img.width(),
            img.height(),
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| RenderError::image("encoding a PNG", e))?;
    Ok(bytes)
}

fn jpeg_round_trip(img: &RgbImage, quality: u8) -> Result<RgbImage> {
    let mut bytes = Vec::new();
    JpegEncoder::new_with_quality(&mut bytes, quality.clamp(1, 100))
        .encode_image(img)
        .map_err(|e| RenderError::image("JPEG encoding", e))?;
    Ok(
        image::load_from_memory_with_format(&bytes, image::ImageFormat::Jpeg)
            .map_err(|e| RenderError::image("JPEG decoding", e))?
            .to_rgb8(),
    )
}

/// Two independent standard normal values (Box-Muller).
fn gaussian_pair(rng: &mut ChaCha8Rng) -> (f32, f32) {
    // u1 in (0, 1]: ln never sees 0.
    let u1: f64 = 1.0 - rng.gen::<f64>();
    let u2: f64 = rng.gen();
    let r = (-2.0 * u1.ln()).sqrt();
    let t = std::f64::consts::TAU * u2;
    ((r * t.cos()) as f32, (r * t.sin()) as f32)
}

fn srgb_to_linear_lut() -> [f32; 256] {
    std::array::from_fn(|i| {
        let c = i as f32 / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    })
}

fn linear_to_srgb(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Separable Gaussian blur of an interleaved RGB f32 image, edges clamped.
fn gaussian_blur(data: &mut [f32], w: usize, h: usize, sigma: f32) {
    let radius = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f32> = (-radius..=radius)
        .map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f32 = kernel.iter().sum();
    let kernel: Vec<f32> = kernel.iter().map(|k| k / sum).collect();
    let mut tmp = vec![0f32; data.len()];
    let pass = |src: &[f32], dst: &mut [f32], horizontal: bool| {
        for y in 0..h {
            for x in 0..w {
                let mut acc = [0f32; 3];
                for (j, k) in kernel.iter().enumerate() {
                    let o = j as isize - radius;
                    let (sx, sy) = if horizontal {
                        ((x as isize + o).clamp(0, w as isize - 1) as usize, y)
                    } else {
                        (x, (y as isize + o).clamp(0, h as isize - 1) as usize)
                    };
                    let i = 3 * (sy * w + sx);
                    for c in 0..3 {
                        acc[c] += k * src[i + c];
                    }
                }
                dst[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&acc);
            }
        }
    };
    pass(data, &mut tmp, true);
    pass(&tmp, data, false);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient() -> RgbImage {
        RgbImage::from_fn(32, 24, |x, y| {
            image::Rgb([(x * 8) as u8, (y * 10) as u8, ((x + y) * 3) as u8])
        })
    }

    fn none() -> SensorEffects {
        SensorEffects {
            seed: 7,
            white_balance: None,
            blur_sigma_px: None,
            noise_sigma: None,
            jpeg_quality: None,
        }
    }

    #[test]
    fn no_effect_keeps_every_pixel() {
        let img = gradient();
        assert_eq!(apply(&none(), "wrist", 0, &img).unwrap(), img);
    }

    #[test]
    fn same_parameters_same_bytes_and_frames_differ() {
        let e = SensorEffects {
            white_balance: Some([1.1, 1.0, 0.9]),
            blur_sigma_px: Some(0.8),
            noise_sigma: Some(0.03),
            jpeg_quality: Some(50),
            ..none()
        };
        let img = gradient();
        let a = apply(&e, "wrist", 3, &img).unwrap();
        assert_eq!(a, apply(&e, "wrist", 3, &img).unwrap());
        assert_eq!(
            png_bytes(&a).unwrap(),
            png_bytes(&apply(&e, "wrist", 3, &img).unwrap()).unwrap()
        );
        assert_ne!(a, apply(&e, "wrist", 4, &img).unwrap());
        assert_ne!(a, apply(&e, "head", 3, &img).unwrap());
        assert_ne!(a, img);
    }

    #[test]
    fn noise_has_the_asked_spread_and_white_balance_tints() {
        let flat = RgbImage::from_pixel(64, 64, image::Rgb([128, 128, 128]));
        let noisy = apply(
            &SensorEffects {
                noise_sigma: Some(0.02),
                ..none()
            },
            "wrist",
            0,
            &flat,
        )
        .unwrap();
        let d: Vec<f64> = noisy
            .as_raw()
            .iter()
            .map(|&v| f64::from(v) - 128.0)
            .collect();
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        let sd = (d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / d.len() as f64).sqrt();
        assert!(mean.abs() < 0.2, "{mean}");
        assert!((sd - 0.02 * 255.0).abs() < 0.3, "{sd}");
        let warm = apply(
            &SensorEffects {
                white_balance: Some([1.2, 1.0, 0.8]),
                ..none()
            },
            "wrist",
            0,
            &flat,
        )
        .unwrap();
        let p = warm.get_pixel(5, 5).0;
        assert!(p[0] > 128 && p[1] == 128 && p[2] < 128, "{p:?}");
    }

    #[test]
    fn blur_keeps_a_flat_image_and_softens_an_edge() {
        let flat = RgbImage::from_pixel(16, 16, image::Rgb([90, 90, 90]));
        let e = SensorEffects {
            blur_sigma_px: Some(1.5),
            ..none()
        };
        assert_eq!(apply(&e, "wrist", 0, &flat).unwrap(), flat);
        let edge = RgbImage::from_fn(16, 4, |x, _| image::Rgb([if x < 8 { 0 } else { 255 }; 3]));
        let soft = apply(&e, "wrist", 0, &edge).unwrap();
        let row: Vec<u8> = (0..16).map(|x| soft.get_pixel(x, 1).0[0]).collect();
        assert!(row[7] > 0 && row[8] < 255, "{row:?}");
        assert!(row.windows(2).all(|w| w[0] <= w[1]), "{row:?}");
    }
}
