//! Why a frame cannot become the backbone's input ([`InputError`]). Each
//! variant carries what its message shows, so the error imports nothing of
//! the crate's own: the crop (`mod.rs`) and the lens (`lens.rs`) return it.

use std::path::PathBuf;

/// Why a frame cannot become the backbone's input, or an input record is
/// unusable. Each names the field at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InputError {
    #[error("input.{field} {reason}")]
    Field { field: &'static str, reason: String },
    #[error(
        "the model crops a fixed angle of {angle_deg} degrees, so it needs the camera's focal \
         length: a sequence.json with plan.intrinsics, or a lens given as --focal-px with \
         --lens-size, --hfov-deg or --lens-file"
    )]
    NoLens { angle_deg: f64 },
    #[error(
        "{field} {value} is not a plausible camera: it gives a field of view of {fov_deg:.1} \
         degrees across the frame (a camera spans {} to {} degrees; a focal length is in pixels)",
        range_deg.0,
        range_deg.1
    )]
    Implausible {
        field: &'static str,
        value: f64,
        fov_deg: f64,
        /// The plausible range it is outside ([`crate::input::FOV_RANGE_DEG`]).
        range_deg: (f64, f64),
    },
    #[error(
        "the frames are {width}x{height}, another shape than the lens ({lens}) was measured at: \
         cropped frames have an unknown focal length"
    )]
    LensShape {
        /// The lens as [`crate::input::Lens::describe`] gives it.
        lens: String,
        width: u32,
        height: u32,
    },
    #[error("lens file {}: {reason}", path.display())]
    LensFile { path: PathBuf, reason: String },
    #[error("an empty frame ({width}x{height})")]
    EmptyFrame { width: u32, height: u32 },
    #[error(
        "the backbone would see a square of {side} px of the {width}x{height} frame, under the \
         {min_px} px minimum (input.crop {crop})"
    )]
    TooSmall {
        side: u32,
        width: u32,
        height: u32,
        crop: String,
        /// [`crate::input::MIN_INPUT_PX`].
        min_px: u32,
    },
}
