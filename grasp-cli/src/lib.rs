//! Command-line pieces that more than one program defines the same way,
//! each flag written once: the camera's lens, which `grasp-train train`,
//! `grasp-train eval` and `hannes-run` take for frames without a
//! `sequence.json`; the model's named choices as clap values
//! ([`ArchitectureArg`], [`HeadKindArg`]), since grasp-model does not
//! link clap; and the decision policy's flags ([`DecisionArgs`]).

mod choices;
mod policy;

pub use choices::{ArchitectureArg, HeadKindArg};
pub use policy::{DecisionArgs, OnInvalidArg};

use clap::Args;
use grasp_model::input::{parse_size, InputError, Lens};
use std::path::PathBuf;

/// The camera's lens, for frames without a sequence.json (the authors'
/// layout, a user's own recordings, a live camera): a fixed-angle crop
/// needs it.
#[derive(Args, Clone, Debug, Default)]
pub struct LensArgs {
    /// The camera's focal length in pixels, measured at --lens-size
    /// (scaled when frames are another size).
    #[arg(long, value_name = "PIXELS", requires = "lens_size")]
    pub focal_px: Option<f64>,
    /// The resolution --focal-px was measured at.
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    pub lens_size: Option<(u32, u32)>,
    /// The angle the frames' width spans, in degrees.
    #[arg(long, value_name = "DEGREES", conflicts_with_all = ["focal_px", "lens_file"])]
    pub hfov_deg: Option<f64>,
    /// A lens file, e.g. a calibration kept with the prosthesis (TOML:
    /// focal_px, width and height; or hfov_deg).
    #[arg(long, value_name = "FILE", conflicts_with = "focal_px")]
    pub lens_file: Option<PathBuf>,
}

impl LensArgs {
    /// Whether any lens flag was given.
    pub fn given(&self) -> bool {
        self.focal_px.is_some() || self.hfov_deg.is_some() || self.lens_file.is_some()
    }

    /// The lens the flags describe, checked; None when none was given.
    pub fn lens(&self) -> Result<Option<Lens>, InputError> {
        Lens::from_options(
            self.focal_px,
            self.lens_size,
            self.hfov_deg,
            self.lens_file.as_deref(),
        )
    }
}
