//! The wrist camera: lens presets, image intrinsics and the start region.
//!
//! Two presets:
//! - `d435` (default): the Intel RealSense D435 colour camera of the real
//!   setup, 69 x 42 degrees, starting at arm's length (0.3-0.7 m from the
//!   target).
//! - `authors`: the authors' Unity camera, 7 degrees vertical field of view,
//!   starting 4-5 m away on a plane in front of the table.
//!
//! The image is usually square (224 x 224) while the sensor is not. `fit`
//! says how the sensor maps to the image: `center_crop` (default) takes the
//! largest centred region of the sensor with the image's aspect, as a
//! resize-then-centre-crop of the real 16:9 frames does, so pixels stay
//! square and a square image sees 42 x 42 degrees; `stretch` squeezes the
//! whole sensor field into the image (fx != fy).

use crate::config::error::{ConfigError, Result};
use grasp_schema::plan::CameraIntrinsics;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CameraPreset {
    D435,
    Authors,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SensorFit {
    CenterCrop,
    Stretch,
}

/// Where the camera starts: on a vertical plane facing the table (normal
/// +X), `plane_distance_m` in front of the target, with a lateral offset
/// and a height above the table top.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StartRegion {
    /// Horizontal distance from the target to the start plane, towards the
    /// user (-X), metres.
    pub plane_distance_m: [f64; 2],
    /// Offset along the plane (world Y) from the target, metres.
    pub lateral_m: [f64; 2],
    /// Height of the start above the table top, metres.
    pub height_m: [f64; 2],
    /// Accepted straight-line distance from start to target, metres; other
    /// samples are redrawn.
    pub distance_m: [f64; 2],
}

/// The resolved camera settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "CameraConfigFile", into = "CameraConfigFile")]
pub struct CameraConfig {
    pub preset: CameraPreset,
    /// Field of view of the physical sensor (horizontal, vertical), degrees.
    pub sensor_fov_deg: [f64; 2],
    pub fit: SensorFit,
    /// Rendered image size (width, height), pixels.
    pub resolution: [u32; 2],
    /// Near and far clip distances, metres.
    pub clip_m: [f64; 2],
    pub start: StartRegion,
}

impl Default for CameraConfig {
    fn default() -> Self {
        CameraConfig::preset(CameraPreset::D435)
    }
}

impl CameraConfig {
    pub fn preset(preset: CameraPreset) -> CameraConfig {
        match preset {
            CameraPreset::D435 => CameraConfig {
                preset,
                sensor_fov_deg: [69.0, 42.0],
                fit: SensorFit::CenterCrop,
                resolution: [224, 224],
                clip_m: [0.01, 20.0],
                start: StartRegion {
                    plane_distance_m: [0.2, 0.6],
                    lateral_m: [-0.25, 0.25],
                    height_m: [0.15, 0.5],
                    distance_m: [0.3, 0.7],
                },
            },
            // scenario.json: 7 degrees vertical (12.41 horizontal at 16:9),
            // clip 0.1-10 m, start plane 4.0-5.4 m in front of the objects,
            // 0.33-1.55 m above the table top.
            CameraPreset::Authors => CameraConfig {
                preset,
                sensor_fov_deg: [12.411, 7.0],
                fit: SensorFit::CenterCrop,
                resolution: [224, 224],
                clip_m: [0.1, 10.0],
                start: StartRegion {
                    plane_distance_m: [3.9, 4.9],
                    lateral_m: [-1.2, 1.2],
                    height_m: [0.33, 1.55],
                    distance_m: [4.0, 5.0],
                },
            },
        }
    }

    /// Pinhole intrinsics of the rendered image. The principal point is the
    /// image centre in continuous pixel coordinates (pixel i spans [i, i+1]).
    pub fn intrinsics(&self) -> CameraIntrinsics {
        let [w, h] = self.resolution;
        let (wf, hf) = (f64::from(w), f64::from(h));
        let tx = (self.sensor_fov_deg[0].to_radians() / 2.0).tan();
        let ty = (self.sensor_fov_deg[1].to_radians() / 2.0).tan();
        let (tan_x, tan_y) = match self.fit {
            SensorFit::Stretch => (tx, ty),
            SensorFit::CenterCrop => {
                let image_aspect = wf / hf;
                if image_aspect < tx / ty {
                    (ty * image_aspect, ty) // crop the sides
                } else {
                    (tx, tx / image_aspect) // crop top and bottom
                }
            }
        };
        CameraIntrinsics {
            width: w,
            height: h,
            fx: wf / 2.0 / tan_x,
            fy: hf / 2.0 / tan_y,
            cx: wf / 2.0,
            cy: hf / 2.0,
            fov_x_deg: 2.0 * tan_x.atan().to_degrees(),
            fov_y_deg: 2.0 * tan_y.atan().to_degrees(),
            clip_near: self.clip_m[0],
            clip_far: self.clip_m[1],
        }
    }

    // Negated comparisons: a NaN must fail these checks.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    pub fn validate(&self) -> Result<()> {
        for (i, f) in self.sensor_fov_deg.iter().enumerate() {
            if !(f.is_finite() && *f > 0.0 && *f < 179.0) {
                return Err(ConfigError::rule(
                    format!("plan.camera.sensor_fov_deg[{i}]"),
                    format!("must be in (0, 179), got {f}"),
                ));
            }
        }
        if !(self.resolution[0] > 0 && self.resolution[1] > 0) {
            return Err(ConfigError::rule(
                "plan.camera.resolution",
                format!("must be positive, got {:?}", self.resolution),
            ));
        }
        if !(self.clip_m[0] > 0.0 && self.clip_m[1] > self.clip_m[0]) {
            return Err(ConfigError::rule(
                "plan.camera.clip_m",
                format!("must satisfy 0 < near < far, got {:?}", self.clip_m),
            ));
        }
        let s = &self.start;
        for (name, r) in [
            ("plane_distance_m", s.plane_distance_m),
            ("lateral_m", s.lateral_m),
            ("height_m", s.height_m),
            ("distance_m", s.distance_m),
        ] {
            if !(r[0].is_finite() && r[1].is_finite() && r[0] <= r[1]) {
                return Err(ConfigError::rule(
                    format!("plan.camera.start.{name}"),
                    format!("must be a range [min, max], got {r:?}"),
                ));
            }
        }
        if !(s.distance_m[1] > 0.0) {
            return Err(ConfigError::rule(
                "plan.camera.start.distance_m",
                format!("must allow positive distances, got {:?}", s.distance_m),
            ));
        }
        Ok(())
    }
}

/// The config-file form: a preset name plus optional overrides of its
/// values, so `preset = "authors"` alone selects every authors' value.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct CameraConfigFile {
    preset: Option<CameraPreset>,
    sensor_fov_deg: Option<[f64; 2]>,
    fit: Option<SensorFit>,
    resolution: Option<[u32; 2]>,
    clip_m: Option<[f64; 2]>,
    start: Option<StartRegionFile>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct StartRegionFile {
    plane_distance_m: Option<[f64; 2]>,
    lateral_m: Option<[f64; 2]>,
    height_m: Option<[f64; 2]>,
    distance_m: Option<[f64; 2]>,
}

impl TryFrom<CameraConfigFile> for CameraConfig {
    type Error = String;
    fn try_from(f: CameraConfigFile) -> Result<Self, String> {
        let mut c = CameraConfig::preset(f.preset.unwrap_or(CameraPreset::D435));
        c.sensor_fov_deg = f.sensor_fov_deg.unwrap_or(c.sensor_fov_deg);
        c.fit = f.fit.unwrap_or(c.fit);
        c.resolution = f.resolution.unwrap_or(c.resolution);
        c.clip_m = f.clip_m.unwrap_or(c.clip_m);
        if let Some(s) = f.start {
            let d = &mut c.start;
            d.plane_distance_m = s.plane_distance_m.unwrap_or(d.plane_distance_m);
            d.lateral_m = s.lateral_m.unwrap_or(d.lateral_m);
            d.height_m = s.height_m.unwrap_or(d.height_m);
            d.distance_m = s.distance_m.unwrap_or(d.distance_m);
        }
        c.validate().map_err(|e| format!("{e:#}"))?;
        Ok(c)
    }
}

impl From<CameraConfig> for CameraConfigFile {
    fn from(c: CameraConfig) -> Self {
        CameraConfigFile {
            preset: Some(c.preset),
            sensor_fov_deg: Some(c.sensor_fov_deg),
            fit: Some(c.fit),
            resolution: Some(c.resolution),
            clip_m: Some(c.clip_m),
            start: Some(StartRegionFile {
                plane_distance_m: Some(c.start.plane_distance_m),
                lateral_m: Some(c.start.lateral_m),
                height_m: Some(c.start.height_m),
                distance_m: Some(c.start.distance_m),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_center_crop_keeps_the_vertical_fov_and_square_pixels() {
        let k = CameraConfig::default().intrinsics();
        assert!((k.fov_y_deg - 42.0).abs() < 1e-9);
        assert!((k.fov_x_deg - 42.0).abs() < 1e-9);
        assert!((k.fx - k.fy).abs() < 1e-9);
        assert_eq!((k.cx, k.cy), (112.0, 112.0));
    }

    #[test]
    fn stretch_keeps_both_sensor_angles() {
        let c = CameraConfig {
            fit: SensorFit::Stretch,
            ..CameraConfig::default()
        };
        let k = c.intrinsics();
        assert!((k.fov_x_deg - 69.0).abs() < 1e-9 && (k.fov_y_deg - 42.0).abs() < 1e-9);
        assert!(k.fx < k.fy);
    }

    #[test]
    fn wide_image_crops_top_and_bottom() {
        let c = CameraConfig {
            resolution: [640, 200],
            ..CameraConfig::default()
        };
        let k = c.intrinsics();
        assert!((k.fov_x_deg - 69.0).abs() < 1e-9);
        assert!(k.fov_y_deg < 42.0);
    }

    #[test]
    fn preset_name_alone_selects_all_its_values_and_overrides_apply() {
        let c: CameraConfig = toml::from_str("preset = \"authors\"").unwrap();
        assert_eq!(c, CameraConfig::preset(CameraPreset::Authors));
        let c: CameraConfig = toml::from_str(
            "preset = \"authors\"\nresolution = [64, 48]\n[start]\nheight_m = [0.5, 0.6]",
        )
        .unwrap();
        assert_eq!(c.resolution, [64, 48]);
        assert_eq!(c.start.height_m, [0.5, 0.6]);
        assert_eq!(c.start.distance_m, [4.0, 5.0]);
        let err = toml::from_str::<CameraConfig>("clip_m = [1.0, 0.5]").unwrap_err();
        assert!(err.to_string().contains("clip_m"), "{err}");
    }
}
