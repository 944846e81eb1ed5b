//! Frame loading with bad-data reporting.

use super::BadData;
use crate::error::DataError;
use image::RgbImage;
use std::path::Path;

/// Decodes one frame as RGB; `None` when it is unreadable and the policy is
/// to skip (the problem is recorded with its path).
pub fn load_frame(path: &Path, bad: &BadData) -> Result<Option<RgbImage>, DataError> {
    match image::open(path) {
        Ok(img) => Ok(Some(img.to_rgb8())),
        Err(e) => {
            bad.report(path, format!("unreadable image: {e}"))?;
            Ok(None)
        }
    }
}

pub use grasp_model::input::preprocess::center_crop;
