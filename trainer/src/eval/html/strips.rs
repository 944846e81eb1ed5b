//! A video's frames as one small JPEG strip: the thumbnails side by side,
//! each with the square the model saw outlined and the rest dimmed. Frames
//! rendered only in their centre (`[render] center_region`, black around)
//! show the rendered square, so that small thumbnails are not mostly black.

use crate::data::Sequence;
use image::{imageops, Rgb, RgbImage};

/// Thumbnail height in pixels (the width keeps the frame's aspect).
pub const THUMB_H: u32 = 96;
/// JPEG quality of the strips: small frames compress well; below about 60
/// the crop's outline smears.
const QUALITY: u8 = 60;
/// The outline of the crop, and how much the outside is darkened.
const OUTLINE: Rgb<u8> = Rgb([255, 214, 0]);
const DIM: f32 = 0.5;

/// One video's strip.
pub struct Strip {
    /// `data:image/jpeg;base64,...`
    pub uri: String,
    pub thumb_w: u32,
    pub thumb_h: u32,
    /// The fraction of the shorter side the model saw (None: the whole
    /// frame, or a crop that could not be cut).
    pub crop: Option<f64>,
    /// The rendered centre shown instead of the whole frame, as a fraction
    /// of its shorter side (None: the whole frame).
    pub rendered: Option<f64>,
    /// Frames that could not be read (drawn grey).
    pub unreadable: usize,
}

/// The strip of `seq`'s frames `frames` (indices into `seq.frames`).
pub fn strip(seq: &Sequence, frames: &[usize]) -> Strip {
    let images: Vec<Option<RgbImage>> = frames
        .iter()
        .map(|&i| {
            let path = seq.frames.get(i)?;
            match image::open(path) {
                Ok(img) => Some(img.to_rgb8()),
                Err(e) => {
                    tracing::warn!("report.html: cannot read {}: {e}", path.display());
                    None
                }
            }
        })
        .collect();
    let (w, h) = images
        .iter()
        .flatten()
        .map(|i| (i.width(), i.height()))
        .next()
        .unwrap_or((THUMB_H, THUMB_H));
    let crop = seq.crop_fraction(w, h).ok().flatten();
    let rendered = seq.rendered_region.filter(|r| *r > 0.0 && *r < 1.0);
    // What a thumbnail shows: the whole frame, or its rendered square.
    let (sw, sh) = match rendered {
        Some(r) => {
            let (_, _, side) = grasp_schema::dataset::centre_square(w, h, r);
            (side, side)
        }
        None => (w, h),
    };
    let thumb_w = ((f64::from(sw) * f64::from(THUMB_H) / f64::from(sh.max(1))).round() as u32)
        .clamp(THUMB_H / 2, THUMB_H * 2);
    let n = frames.len().max(1) as u32;
    let mut out = RgbImage::from_pixel(thumb_w * n, THUMB_H, Rgb([90, 90, 90]));
    let mut unreadable = 0;
    for (k, img) in images.iter().enumerate() {
        let Some(img) = img else {
            unreadable += 1;
            continue;
        };
        let shown = match rendered {
            Some(r) => crate::data::images::center_crop(img, r),
            None => img.clone(),
        };
        let mut t = imageops::resize(&shown, thumb_w, THUMB_H, imageops::FilterType::Triangle);
        if let Some(f) = crop {
            // The crop as a fraction of what is shown.
            let f = f * f64::from(img.width().min(img.height()))
                / f64::from(shown.width().min(shown.height()).max(1));
            mark_crop(&mut t, shown.width(), shown.height(), f.min(1.0));
        }
        imageops::replace(&mut out, &t, i64::from(thumb_w) * k as i64, 0);
    }
    Strip {
        uri: super::data_uri("image/jpeg", &jpeg(&out)),
        thumb_w,
        thumb_h: THUMB_H,
        crop,
        rendered,
        unreadable,
    }
}

/// Dims what lies outside the centre square of `fraction` of a `w` x `h`
/// frame (drawn at the thumbnail's size) and outlines the square.
fn mark_crop(t: &mut RgbImage, w: u32, h: u32, fraction: f64) {
    let (x, y, side) = grasp_schema::dataset::centre_square(w, h, fraction);
    let sx = f64::from(t.width()) / f64::from(w.max(1));
    let sy = f64::from(t.height()) / f64::from(h.max(1));
    let x0 = (f64::from(x) * sx).round() as i64;
    let y0 = (f64::from(y) * sy).round() as i64;
    let x1 = ((f64::from(x + side) * sx).round() as i64 - 1).min(i64::from(t.width()) - 1);
    let y1 = ((f64::from(y + side) * sy).round() as i64 - 1).min(i64::from(t.height()) - 1);
    for (px, py, p) in t.enumerate_pixels_mut() {
        let (px, py) = (i64::from(px), i64::from(py));
        let inside = (x0..=x1).contains(&px) && (y0..=y1).contains(&py);
        let edge = inside && (px == x0 || px == x1 || py == y0 || py == y1);
        if edge {
            *p = OUTLINE;
        } else if !inside {
            for c in &mut p.0 {
                *c = (f32::from(*c) * DIM) as u8;
            }
        }
    }
}

fn jpeg(img: &RgbImage) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut enc = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, QUALITY);
    if let Err(e) = enc.encode_image(img) {
        tracing::warn!("report.html: cannot encode a strip: {e}");
        bytes.clear();
    }
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_crop_is_outlined_and_the_rest_dimmed() {
        let mut t = RgbImage::from_pixel(80, 80, Rgb([200, 200, 200]));
        // Half of a 224 px frame: the square from 56 to 167, at 80 px 20..59.
        mark_crop(&mut t, 224, 224, 0.5);
        assert_eq!(t.get_pixel(20, 20), &OUTLINE);
        assert_eq!(t.get_pixel(59, 40), &OUTLINE);
        assert_eq!(t.get_pixel(40, 40), &Rgb([200, 200, 200]));
        assert_eq!(t.get_pixel(5, 5), &Rgb([100, 100, 100]));
        assert_eq!(t.get_pixel(70, 40), &Rgb([100, 100, 100]));
    }
}
