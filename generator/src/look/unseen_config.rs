//! The `unseen_look` condition's config (`[appearance.unseen_look]`): its
//! names, ranges and defaults, and the checks of its values alone. It sits
//! below [`crate::appearance`], whose config holds it; the sampling is in
//! [`crate::unseen_look`], the check against training's ranges in
//! [`crate::randomize`].

use super::{check_hdris, check_range};
use crate::config::error::{ConfigError, Result};
use serde::{Deserialize, Serialize};

/// Texture families only `unseen_look` may draw (`blender_scripts/materials.py`):
/// its defaults, `mosaic` and `rings`, kept for a second held-out look
/// (`configs/test-look-b.toml`, EXPERIMENTS-archive.md section 15), and `chevron`
/// and `triangles` for a third (`configs/test-look-c.toml`, section 16).
pub const UNSEEN_FAMILIES: [&str; 7] = [
    "dots",
    "gabor",
    "magic",
    "mosaic",
    "rings",
    "chevron",
    "triangles",
];
/// The families `[appearance.unseen_look]` draws by default.
pub const DEFAULT_UNSEEN_FAMILIES: [&str; 3] = ["dots", "gabor", "magic"];
/// Light kinds only `unseen_look` uses.
pub const UNSEEN_LIGHT_KINDS: [&str; 2] = ["sun", "ring"];
/// Lights of the ring the Blender side pools.
pub const MAX_RING_LIGHTS: u32 = 8;
/// View transforms the Blender side accepts.
pub const VIEW_TRANSFORMS: [&str; 4] = ["AgX", "Standard", "Filmic", "Khronos PBR Neutral"];

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct UnseenLookConfig {
    /// Procedural families of the walls, floor and table (some of dots,
    /// gabor, magic).
    pub families: Vec<String>,
    /// Sun strength (W/m^2) and elevation above the horizon (degrees); the
    /// room is open to the sky when it shines (see docs/rendering.md).
    pub sun_strength: [f64; 2],
    pub sun_elevation_deg: [f64; 2],
    /// Small area lights on a horizontal ring around the object, facing it.
    pub ring_lights: [u32; 2],
    pub ring_radius_m: [f64; 2],
    /// Ring height above the object's origin, metres.
    pub ring_height_m: [f64; 2],
    pub ring_power_w: [f64; 2],
    /// Colour temperature of the sun and the ring lights.
    pub color_temperature_k: [f64; 2],
    /// Bundled HDRI worlds of this condition, and their strength.
    pub hdris: Vec<String>,
    pub world_strength: [f64; 2],
    /// Lens: tan(half FOV) of the camera preset times this factor.
    pub fov_scale: [f64; 2],
    /// View transform and the looks drawn for it.
    pub view_transform: String,
    pub looks: Vec<String>,
    /// Exposure, stops.
    pub exposure: [f64; 2],
    /// Sensor noise (fraction of full scale) and defocus blur (pixels).
    pub noise_sigma: [f64; 2],
    pub blur_sigma_px: [f64; 2],
}

impl Default for UnseenLookConfig {
    fn default() -> Self {
        UnseenLookConfig {
            families: DEFAULT_UNSEEN_FAMILIES.map(String::from).to_vec(),
            sun_strength: [1.5, 3.0],
            sun_elevation_deg: [50.0, 80.0],
            ring_lights: [4, 6],
            ring_radius_m: [0.6, 1.1],
            ring_height_m: [0.6, 1.1],
            ring_power_w: [10.0, 30.0],
            color_temperature_k: [7500.0, 12000.0],
            hdris: ["courtyard", "forest"].map(String::from).to_vec(),
            world_strength: [0.3, 1.0],
            fov_scale: [1.35, 1.6],
            view_transform: "Khronos PBR Neutral".into(),
            looks: ["None", "Medium High Contrast"].map(String::from).to_vec(),
            exposure: [-1.0, -0.6],
            noise_sigma: [0.03, 0.045],
            blur_sigma_px: [0.6, 1.2],
        }
    }
}

impl UnseenLookConfig {
    /// Checks the values alone.
    pub fn validate(&self) -> Result<()> {
        let at = "[appearance.unseen_look]";
        if self.families.is_empty() {
            return Err(ConfigError::invalid(
                format!("{at} families"),
                "the list is empty",
            ));
        }
        for f in &self.families {
            ConfigError::check_one_of(format!("{at} families"), f, &UNSEEN_FAMILIES)?;
        }
        check_range(&format!("{at} sun_strength"), self.sun_strength, 0.0, 100.0)?;
        check_range(
            &format!("{at} sun_elevation_deg"),
            self.sun_elevation_deg,
            5.0,
            90.0,
        )?;
        if self.ring_lights[0] > self.ring_lights[1] || self.ring_lights[1] > MAX_RING_LIGHTS {
            return Err(ConfigError::invalid(
                format!("{at} ring_lights"),
                format!(
                    "need min <= max <= {MAX_RING_LIGHTS}, got {:?}",
                    self.ring_lights
                ),
            ));
        }
        check_range(
            &format!("{at} ring_radius_m"),
            self.ring_radius_m,
            0.05,
            5.0,
        )?;
        check_range(&format!("{at} ring_height_m"), self.ring_height_m, 0.0, 5.0)?;
        check_range(&format!("{at} ring_power_w"), self.ring_power_w, 0.0, 1e4)?;
        check_range(
            &format!("{at} color_temperature_k"),
            self.color_temperature_k,
            1000.0,
            25000.0,
        )?;
        check_hdris(&format!("{at} hdris"), &self.hdris)?;
        check_range(
            &format!("{at} world_strength"),
            self.world_strength,
            0.0,
            100.0,
        )?;
        check_range(&format!("{at} fov_scale"), self.fov_scale, 0.05, 20.0)?;
        ConfigError::check_one_of(
            format!("{at} view_transform"),
            &self.view_transform,
            &VIEW_TRANSFORMS,
        )?;
        if self.looks.is_empty() {
            return Err(ConfigError::invalid(
                format!("{at} looks"),
                "the list is empty (\"None\" is Blender's plain look)",
            ));
        }
        check_range(&format!("{at} exposure"), self.exposure, -10.0, 10.0)?;
        check_range(&format!("{at} noise_sigma"), self.noise_sigma, 0.0, 0.5)?;
        check_range(
            &format!("{at} blur_sigma_px"),
            self.blur_sigma_px,
            0.0,
            20.0,
        )?;
        Ok(())
    }
}
