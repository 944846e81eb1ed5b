//! Frame loading with bad-data reporting.

use super::BadData;
use anyhow::Result;
use image::RgbImage;
use std::path::Path;

/// Decodes one frame as RGB; `None` when it is unreadable and the policy is
/// to skip (the problem is recorded with its path).
pub fn load_frame(path: &Path, bad: &BadData) -> Result<Option<RgbImage>> {
    match image::open(path) {
        Ok(img) => Ok(Some(img.to_rgb8())),
        Err(e) => {
            bad.report(path, format!("unreadable image: {e}"))?;
            Ok(None)
        }
    }
}

/// [`load_frame`], then the central square of side `crop` times the shorter
/// side (`None`: the whole frame).
pub fn load_frame_cropped(
    path: &Path,
    crop: Option<f64>,
    bad: &BadData,
) -> Result<Option<RgbImage>> {
    let img = load_frame(path, bad)?;
    Ok(match crop {
        Some(f) => img.map(|i| center_crop(&i, f)),
        None => img,
    })
}

/// The central square whose side is `fraction` of the shorter side (at
/// least one pixel).
pub fn center_crop(img: &RgbImage, fraction: f64) -> RgbImage {
    let (w, h) = img.dimensions();
    let side = ((f64::from(w.min(h)) * fraction.clamp(0.0, 1.0)).round() as u32).clamp(1, w.min(h));
    image::imageops::crop_imm(img, (w - side) / 2, (h - side) / 2, side, side).to_image()
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
}
