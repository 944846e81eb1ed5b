//! How a camera frame becomes the backbone's input, typed once.
//!
//! An [`InputSpec`] is what a checkpoint was trained with: the centre crop
//! (the whole frame, a fixed fraction of it, or the square spanning a fixed
//! angle of the world), whether that square is denoised, and the backbone's
//! preprocessing (input size, resize filter, normalisation). The trainer's
//! reader, `grasp-train eval`, [`crate::checkpoint::Classifier`] and
//! `hannes-run` all cut frames through [`Crop::fraction`] and
//! [`InputSpec::prepare`]; none re-derives the rule.
//!
//! A fixed-angle crop needs the camera's [`Lens`]: its fraction of a frame
//! follows from the focal length at the frame's own size.

pub mod denoise;
mod error;
mod lens;
pub mod preprocess;
mod resize;

pub use error::InputError;
pub use lens::{parse_size, Lens, FOV_RANGE_DEG};

use image::RgbImage;
use preprocess::{center_crop, Preprocess};
use serde::{Deserialize, Serialize};

/// The smallest square, in pixels, that the backbone may be fed: below it
/// the resize to the input size shows it nothing but blur (a focal length
/// given in millimetres crops under a pixel).
pub const MIN_INPUT_PX: u32 = 16;

/// The centre crop a model sees of each frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Crop {
    /// The whole frame.
    #[default]
    Whole,
    /// The central square of this fraction (0, 1] of the shorter side.
    Fraction(f64),
    /// The central square spanning this angle in degrees (0, 180), its
    /// full width: the same part of the world through every lens.
    AngleDeg(f64),
}

impl Crop {
    /// A crop from the two ways of asking for one (`--center-crop`,
    /// `reader.crop = { angle_deg = D }`); both at once is an error.
    pub fn from_options(fraction: Option<f64>, angle_deg: Option<f64>) -> Result<Crop, InputError> {
        let crop = match (fraction, angle_deg) {
            (None, None) => Crop::Whole,
            (Some(f), None) => Crop::Fraction(f),
            (None, Some(a)) => Crop::AngleDeg(a),
            (Some(f), Some(a)) => {
                return Err(InputError::Field {
                    field: "crop",
                    reason: format!(
                        "is a fraction ({f}) or an angle ({a} degrees) of the frame, not both"
                    ),
                })
            }
        };
        crop.validate()?;
        Ok(crop)
    }

    pub fn validate(&self) -> Result<(), InputError> {
        let bad = |field, reason: String| Err(InputError::Field { field, reason });
        match *self {
            Crop::Whole => Ok(()),
            Crop::Fraction(f) if !(f > 0.0 && f <= 1.0) => bad(
                "crop.fraction",
                format!("must be a fraction in (0, 1], got {f}"),
            ),
            Crop::AngleDeg(a) if !(a > 0.0 && a < 180.0) => bad(
                "crop.angle_deg",
                format!("must be an angle in (0, 180) degrees, got {a}"),
            ),
            _ => Ok(()),
        }
    }

    /// The fraction of the shorter side of a `width` x `height` frame this
    /// crop takes, `None` for the whole frame. A fixed angle's follows
    /// from `lens` at the frame's size, and may exceed 1 through a lens too
    /// narrow to hold the angle (callers cut it to what they have).
    pub fn fraction(
        &self,
        lens: Option<&Lens>,
        width: u32,
        height: u32,
    ) -> Result<Option<f64>, InputError> {
        if width == 0 || height == 0 {
            return Err(InputError::EmptyFrame { width, height });
        }
        let fraction = match *self {
            Crop::Whole => None,
            Crop::Fraction(f) => Some(f),
            Crop::AngleDeg(angle_deg) => {
                let lens = lens.ok_or(InputError::NoLens { angle_deg })?;
                let focal = lens.focal_px_at(width, height)?;
                grasp_schema::dataset::angle_crop_fraction(angle_deg, focal, width, height)
            }
        };
        let side = grasp_schema::dataset::centre_square(width, height, fraction.unwrap_or(1.0)).2;
        if side < MIN_INPUT_PX {
            return Err(InputError::TooSmall {
                side,
                width,
                height,
                crop: self.describe(),
                min_px: MIN_INPUT_PX,
            });
        }
        Ok(fraction)
    }

    /// "whole frame", "0.42 of the frame" or "18.3 degrees".
    pub fn describe(&self) -> String {
        match self {
            Crop::Whole => "whole frame".into(),
            Crop::Fraction(f) => format!("{f} of the frame"),
            Crop::AngleDeg(a) => format!("{a} degrees"),
        }
    }
}

/// How frames become a checkpoint's backbone input (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputSpec {
    pub crop: Crop,
    /// The crop is denoised (non-local means at the noise level estimated
    /// in it) before the backbone.
    pub denoise: bool,
    /// Resize to the input size, scale and normalise.
    pub preprocess: Preprocess,
}

impl InputSpec {
    /// The one validation of an input record.
    pub fn validate(&self) -> Result<(), InputError> {
        self.crop.validate()?;
        let p = &self.preprocess;
        if p.size == 0 {
            return Err(InputError::Field {
                field: "preprocess.size",
                reason: "must be at least 1 pixel".into(),
            });
        }
        if p.std.iter().any(|s| !(s.is_finite() && *s > 0.0))
            || p.mean.iter().any(|m| !m.is_finite())
        {
            return Err(InputError::Field {
                field: "preprocess",
                reason: format!(
                    "std must be positive and mean finite, got mean {:?}, std {:?}",
                    p.mean, p.std
                ),
            });
        }
        Ok(())
    }

    /// The fraction of a `width` x `height` frame's shorter side the
    /// backbone sees, at most all of it (see [`Crop::fraction`]).
    pub fn crop_fraction(
        &self,
        lens: Option<&Lens>,
        width: u32,
        height: u32,
    ) -> Result<Option<f64>, InputError> {
        Ok(self.crop.fraction(lens, width, height)?.map(|f| f.min(1.0)))
    }

    /// A whole camera frame as the backbone is fed it, before the resize:
    /// centre-cropped, then denoised.
    pub fn prepare(&self, frame: &RgbImage, lens: Option<&Lens>) -> Result<RgbImage, InputError> {
        let square = match self.crop_fraction(lens, frame.width(), frame.height())? {
            Some(fraction) => center_crop(frame, fraction),
            None => frame.clone(),
        };
        Ok(self.filter(square))
    }

    /// What follows the crop: the denoiser, when the model was trained
    /// with it (the trainer's augmented views cut their own squares).
    pub fn filter(&self, square: RgbImage) -> RgbImage {
        filter(square, self.denoise)
    }

    /// One line for reports and logs.
    pub fn describe(&self) -> String {
        format!(
            "{}{}, {} px",
            self.crop.describe(),
            if self.denoise { ", denoised" } else { "" },
            self.preprocess.size
        )
    }
}

/// The filter after the crop: denoising when `denoise`.
pub fn filter(square: RgbImage, denoise: bool) -> RgbImage {
    if denoise {
        denoise::denoise(&square)
    } else {
        square
    }
}
