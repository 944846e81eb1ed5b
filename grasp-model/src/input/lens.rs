//! The camera a frame comes from, as much of it as a fixed-angle crop
//! needs: how many pixels the lens's focal length spans at a stated
//! resolution. Frames of another size (a recording scaled down, a camera
//! streaming at half resolution) scale the focal length with them, so a
//! calibration made at one resolution stays right at another.

use super::error::InputError;
use grasp_schema::plan::CameraIntrinsics;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The plausible field of view of a frame, in degrees, across its width:
/// narrower is a telescope, wider than 170 a fisheye no pinhole model
/// describes. A focal length given in millimetres instead of pixels lands
/// far outside it.
pub const FOV_RANGE_DEG: (f64, f64) = (10.0, 170.0);

/// Frames whose aspect ratio differs by more than this from the
/// calibration's were cropped, not scaled: their focal length is unknown.
const ASPECT_TOLERANCE: f64 = 0.01;

/// A camera's lens, as a fixed-angle crop needs it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Lens {
    /// A focal length in pixels (square pixels) measured at `width` x
    /// `height`: a calibration, or a renderer's intrinsics.
    Focal {
        focal_px: f64,
        width: u32,
        height: u32,
    },
    /// The angle the frame's width spans, whatever its resolution.
    HorizontalFov { hfov_deg: f64 },
}

/// A lens file as a user keeps it with the prosthesis (TOML): `focal_px`
/// with the `width` and `height` it was measured at, or `hfov_deg`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LensFile {
    focal_px: Option<f64>,
    width: Option<u32>,
    height: Option<u32>,
    hfov_deg: Option<f64>,
}

impl Lens {
    /// A focal length of `focal_px` pixels measured at `width` x `height`,
    /// checked for plausibility at that size.
    pub fn focal(focal_px: f64, width: u32, height: u32) -> Result<Lens, InputError> {
        let lens = Lens::Focal {
            focal_px,
            width,
            height,
        };
        lens.validate("focal_px")?;
        Ok(lens)
    }

    /// A lens whose frame width spans `hfov_deg` degrees.
    pub fn horizontal_fov(hfov_deg: f64) -> Result<Lens, InputError> {
        let lens = Lens::HorizontalFov { hfov_deg };
        lens.validate("hfov_deg")?;
        Ok(lens)
    }

    /// The lens a generated sequence was rendered through
    /// (`sequence.json`'s `plan.intrinsics`).
    pub fn from_intrinsics(k: &CameraIntrinsics) -> Result<Lens, InputError> {
        Lens::from_pinhole(k.fx, k.fy, k.width, k.height)
    }

    /// A pinhole camera's lens (`plan.intrinsics`' `fx`, `fy`, `width`,
    /// `height`): the focal length along the shorter side, which a centred
    /// square's angle follows.
    pub fn from_pinhole(fx: f64, fy: f64, width: u32, height: u32) -> Result<Lens, InputError> {
        let (focal_px, field) = if height <= width {
            (fy, "plan.intrinsics.fy")
        } else {
            (fx, "plan.intrinsics.fx")
        };
        let lens = Lens::Focal {
            focal_px,
            width,
            height,
        };
        lens.validate(field)?;
        Ok(lens)
    }

    /// Reads a lens file (TOML: `focal_px`, `width` and `height`, or
    /// `hfov_deg`).
    pub fn from_file(path: &Path) -> Result<Lens, InputError> {
        let file_error = |reason: String| InputError::LensFile {
            path: path.to_path_buf(),
            reason,
        };
        let text = std::fs::read_to_string(path).map_err(|e| file_error(e.to_string()))?;
        let file: LensFile = toml::from_str(&text).map_err(|e| file_error(e.to_string()))?;
        let lens = match file {
            LensFile {
                focal_px: Some(f),
                width: Some(w),
                height: Some(h),
                hfov_deg: None,
            } => Lens::focal(f, w, h),
            LensFile {
                hfov_deg: Some(a),
                focal_px: None,
                width: None,
                height: None,
            } => Lens::horizontal_fov(a),
            _ => {
                return Err(file_error(
                    "give focal_px with the width and height it was measured at, or hfov_deg \
                     alone"
                        .into(),
                ))
            }
        };
        lens.map_err(|e| file_error(e.to_string()))
    }

    /// The lens a user gave, if any: `focal_px` with the `size` (width,
    /// height) it was measured at, `hfov_deg`, or a lens `file`; more than
    /// one way at once is an error.
    pub fn from_options(
        focal_px: Option<f64>,
        size: Option<(u32, u32)>,
        hfov_deg: Option<f64>,
        file: Option<&Path>,
    ) -> Result<Option<Lens>, InputError> {
        let given = [focal_px.is_some(), hfov_deg.is_some(), file.is_some()];
        if given.iter().filter(|g| **g).count() > 1 {
            return Err(InputError::Field {
                field: "lens",
                reason: "is given one way: a focal length, a field of view or a lens file".into(),
            });
        }
        match (focal_px, size, hfov_deg, file) {
            (Some(f), Some((w, h)), _, _) => Lens::focal(f, w, h).map(Some),
            (Some(_), None, _, _) => Err(InputError::Field {
                field: "lens.focal_px",
                reason: "needs the resolution it was measured at (--lens-size WxH): the focal \
                         length in pixels scales with the frame"
                    .into(),
            }),
            (None, Some(_), _, _) => Err(InputError::Field {
                field: "lens.size",
                reason: "(--lens-size) is given without the focal length measured at it: add \
                         --focal-px PIXELS, or give the lens as --hfov-deg or --lens-file alone"
                    .into(),
            }),
            (None, _, Some(a), _) => Lens::horizontal_fov(a).map(Some),
            (None, _, None, Some(path)) => Lens::from_file(path).map(Some),
            (None, None, None, None) => Ok(None),
        }
    }

    /// The focal length in pixels of `width` x `height` frames through this
    /// lens: scaled from the calibration's size, refused when the frames
    /// have another shape (cropped, not scaled) or the result is not a
    /// plausible lens.
    pub fn focal_px_at(&self, width: u32, height: u32) -> Result<f64, InputError> {
        if width == 0 || height == 0 {
            return Err(InputError::EmptyFrame { width, height });
        }
        let focal = match *self {
            Lens::Focal {
                focal_px,
                width: w0,
                height: h0,
            } => {
                let aspect = |w: u32, h: u32| f64::from(w) / f64::from(h);
                if h0 == 0
                    || (aspect(width, height) / aspect(w0, h0) - 1.0).abs() > ASPECT_TOLERANCE
                {
                    return Err(InputError::LensShape {
                        lens: self.describe(),
                        width,
                        height,
                    });
                }
                focal_px * f64::from(width) / f64::from(w0)
            }
            Lens::HorizontalFov { hfov_deg } => {
                f64::from(width) / 2.0 / (hfov_deg.to_radians() / 2.0).tan()
            }
        };
        check_fov(focal, width, self.source_field())?;
        Ok(focal)
    }

    /// Checks the lens at its own size (for a field of view, at any size).
    fn validate(&self, field: &'static str) -> Result<(), InputError> {
        match *self {
            Lens::Focal {
                focal_px,
                width,
                height,
            } => {
                if width == 0 || height == 0 {
                    return Err(InputError::EmptyFrame { width, height });
                }
                check_fov(focal_px, width, field)
            }
            Lens::HorizontalFov { hfov_deg } => {
                let (lo, hi) = FOV_RANGE_DEG;
                if hfov_deg.is_finite() && (lo..=hi).contains(&hfov_deg) {
                    Ok(())
                } else {
                    Err(InputError::Implausible {
                        field,
                        value: hfov_deg,
                        fov_deg: hfov_deg,
                        range_deg: FOV_RANGE_DEG,
                    })
                }
            }
        }
    }

    fn source_field(&self) -> &'static str {
        match self {
            Lens::Focal { .. } => "focal_px",
            Lens::HorizontalFov { .. } => "hfov_deg",
        }
    }

    /// One line for reports: "focal 291.8 px at 224x224" or "hfov 60°".
    pub fn describe(&self) -> String {
        match self {
            Lens::Focal {
                focal_px,
                width,
                height,
            } => format!("focal length {focal_px:.1} px at {width}x{height}"),
            Lens::HorizontalFov { hfov_deg } => format!("horizontal field of view {hfov_deg}°"),
        }
    }
}

/// Refuses a focal length whose field of view across `width` pixels is not
/// a plausible camera's.
fn check_fov(focal_px: f64, width: u32, field: &'static str) -> Result<(), InputError> {
    let fov_deg = 2.0 * (f64::from(width) / 2.0 / focal_px).atan().to_degrees();
    let (lo, hi) = FOV_RANGE_DEG;
    if focal_px.is_finite() && focal_px > 0.0 && (lo..=hi).contains(&fov_deg) {
        Ok(())
    } else {
        Err(InputError::Implausible {
            field,
            value: focal_px,
            fov_deg,
            range_deg: FOV_RANGE_DEG,
        })
    }
}

/// Parses a resolution `WIDTHxHEIGHT` (`--lens-size 640x480`).
pub fn parse_size(text: &str) -> Result<(u32, u32), String> {
    let parse = |s: &str| s.trim().parse::<u32>().ok().filter(|v| *v > 0);
    match text.split_once(['x', 'X']) {
        Some((w, h)) => match (parse(w), parse(h)) {
            (Some(w), Some(h)) => Ok((w, h)),
            _ => Err(format!(
                "'{text}' is not WIDTHxHEIGHT in pixels (e.g. 640x480)"
            )),
        },
        None => Err(format!(
            "'{text}' is not WIDTHxHEIGHT in pixels (e.g. 640x480)"
        )),
    }
}
