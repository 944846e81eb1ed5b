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

pub use grasp_model::model::preprocess::center_crop;
