//! The `unseen_look` test condition: the default reach rendered with an
//! appearance that training never draws (`[appearance.unseen_look]`). On
//! every axis its values lie outside training's, and config validation
//! refuses a config where they would meet:
//!
//! | axis | training | unseen_look (defaults) |
//! |---|---|---|
//! | texture families | `[appearance] families` (noise, voronoi, ...) | `dots`, `gabor`, `magic` |
//! | lights | 1-3 point/spot/area lamps, 2700-6500 K | a sun and a ring of 4-6 small area lights: 5-7 lights, 7500-12000 K |
//! | environment | `[randomize.world_light] hdris` | the other bundled HDRIs (`courtyard`, `forest`) |
//! | lens | tan(half FOV) x `[randomize.fov] scale` (0.85-1.2) | x 1.35-1.6 (wide angle) |
//! | tone mapping | `[render] view_transform` (AgX), exposure -0.5..0.5 | Khronos PBR Neutral with its own looks, exposure -1.0..-0.6 |
//! | sensor | noise sigma 0-0.02, white balance, JPEG, motion blur | noise sigma 0.03-0.045, defocus blur 0.6-1.2 px |
//!
//! The object's material, the hand and the geometry (path, placement,
//! distractors, standoff, aim) follow training's rules: the condition
//! changes the look, not the task.

use crate::appearance::{blackbody_tint, surface, AppearanceConfig};
use crate::randomize::{check_hdris, check_range, lever_rng, uniform, world_light};
use anyhow::{bail, Result};
use grasp_schema::appearance::{Appearance, Light, SensorEffects, ToneMapping};
use grasp_schema::plan::substream_seed;
use grasp_schema::Condition;
use rand::Rng;
use serde::{Deserialize, Serialize};

/// Texture families only `unseen_look` may draw (`blender_scripts/materials.py`):
/// its defaults, `mosaic` and `rings`, kept for a second held-out look
/// (`configs/test-look-b.toml`, EXPERIMENTS.md section 15), and `chevron`
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

/// Two closed ranges share a point.
fn overlap([a0, a1]: [f64; 2], [b0, b1]: [f64; 2]) -> bool {
    a0 <= b1 && b0 <= a1
}

impl UnseenLookConfig {
    /// Checks the values alone.
    pub fn validate(&self) -> Result<()> {
        let at = "[appearance.unseen_look]";
        if self.families.is_empty() {
            bail!("{at} families: the list is empty");
        }
        for f in &self.families {
            if !UNSEEN_FAMILIES.contains(&f.as_str()) {
                bail!(
                    "{at} families: '{f}' is not an unseen_look family (expected some of {})",
                    UNSEEN_FAMILIES.join(", ")
                );
            }
        }
        check_range(&format!("{at} sun_strength"), self.sun_strength, 0.0, 100.0)?;
        check_range(
            &format!("{at} sun_elevation_deg"),
            self.sun_elevation_deg,
            5.0,
            90.0,
        )?;
        if self.ring_lights[0] > self.ring_lights[1] || self.ring_lights[1] > MAX_RING_LIGHTS {
            bail!(
                "{at} ring_lights: need min <= max <= {MAX_RING_LIGHTS}, got {:?}",
                self.ring_lights
            );
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
        if !VIEW_TRANSFORMS.contains(&self.view_transform.as_str()) {
            bail!(
                "{at} view_transform: unknown '{}' (expected one of {})",
                self.view_transform,
                VIEW_TRANSFORMS.join(", ")
            );
        }
        if self.looks.is_empty() {
            bail!("{at} looks: the list is empty (\"None\" is Blender's plain look)");
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

    /// Refuses a config in which training could draw one of this
    /// condition's values: shared families, light kinds, light counts,
    /// colour temperatures, HDRIs, lens factors, view transform, exposure or
    /// noise levels. `render_view_transform` is `[render] view_transform`.
    pub fn check_disjoint(
        &self,
        training: &AppearanceConfig,
        levers: &crate::randomize::RandomizeConfig,
        render_view_transform: &str,
    ) -> Result<()> {
        let levers = &levers.effective();
        let at = "[appearance.unseen_look]";
        for f in &training.families {
            if self.families.contains(f) || UNSEEN_FAMILIES.contains(&f.as_str()) {
                bail!(
                    "[appearance] families: '{f}' is reserved for the unseen_look condition and \
                     may not be drawn in training"
                );
            }
        }
        if self.families.contains(&training.held_out_family) {
            bail!(
                "{at} families: '{}' is the background condition's held-out family",
                training.held_out_family
            );
        }
        for k in &training.light_kinds {
            if UNSEEN_LIGHT_KINDS.contains(&k.as_str()) {
                bail!("[appearance] light_kinds: '{k}' is reserved for the unseen_look condition");
            }
        }
        let unseen_count = [
            f64::from(self.ring_lights[0] + 1),
            f64::from(self.ring_lights[1] + 1),
        ];
        let training_count = training.lights.map(f64::from);
        if overlap(training_count, unseen_count) {
            bail!(
                "[appearance] lights {:?} overlaps the unseen_look light count {unseen_count:?} \
                 (a sun and ring_lights {:?})",
                training.lights,
                self.ring_lights
            );
        }
        if overlap(training.color_temperature_k, self.color_temperature_k) {
            bail!(
                "{at} color_temperature_k {:?} overlaps training's [appearance] color_temperature_k {:?}",
                self.color_temperature_k,
                training.color_temperature_k
            );
        }
        if levers.world_light.enabled {
            if let Some(h) = levers
                .world_light
                .hdris
                .iter()
                .find(|h| self.hdris.contains(h))
            {
                bail!("[randomize.world_light] hdris: '{h}' is also an unseen_look world ({at} hdris)");
            }
        }
        let fov = levers.training_fov_scale();
        if overlap(fov, self.fov_scale) {
            bail!(
                "{at} fov_scale {:?} overlaps training's lens range {fov:?} ([randomize.fov] scale, \
                 or 1 with the lever off)",
                self.fov_scale
            );
        }
        if self.view_transform == render_view_transform {
            bail!(
                "{at} view_transform: '{}' is also training's [render] view_transform",
                self.view_transform
            );
        }
        if overlap(training.exposure, self.exposure) {
            bail!(
                "{at} exposure {:?} overlaps training's [appearance] exposure {:?}",
                self.exposure,
                training.exposure
            );
        }
        if levers.sensor_noise.enabled && overlap(levers.sensor_noise.sigma, self.noise_sigma) {
            bail!(
                "{at} noise_sigma {:?} overlaps training's [randomize.sensor_noise] sigma {:?}",
                self.noise_sigma,
                levers.sensor_noise.sigma
            );
        }
        if self.blur_sigma_px[0] <= 0.0 {
            bail!("{at} blur_sigma_px: must be above 0 (training has no defocus blur)");
        }
        Ok(())
    }
}

/// The appearance of one `unseen_look` sequence. `seed` is the sequence's
/// `appearance` sub-stream (the object material and hand visibility follow
/// training's rules from it); this condition's own values come from the
/// `unseen_look` sub-stream of `stream`. `center` is the object's position:
/// the ring and the sun are placed around it.
pub fn sample(
    config: &AppearanceConfig,
    seed: u64,
    stream: u64,
    center: [f64; 3],
    images: &[String],
) -> Appearance {
    let u = &config.unseen_look;
    let base = crate::appearance::sample_with_images(config, Condition::Default, seed, images);
    let mut rng = lever_rng(stream, "unseen_look");
    let surfaces = AppearanceConfig {
        families: u.families.clone(),
        image_probability: 0.0,
        ..config.clone()
    };
    let wall = surface(&surfaces, &[], &mut rng, None);
    let floor = surface(&surfaces, &[], &mut rng, None);
    let table = surface(&surfaces, &[], &mut rng, None);
    let mut lights = vec![sun(u, center, &mut rng)];
    let n = rng.gen_range(u.ring_lights[0]..=u.ring_lights[1].max(u.ring_lights[0]));
    let radius = uniform(&mut rng, u.ring_radius_m);
    let height = uniform(&mut rng, u.ring_height_m);
    let phase = uniform(&mut rng, [0.0, std::f64::consts::TAU]);
    for i in 0..n {
        let a = phase + std::f64::consts::TAU * f64::from(i) / f64::from(n);
        let kelvin = uniform(&mut rng, u.color_temperature_k);
        lights.push(Light {
            kind: "ring".into(),
            position: [
                center[0] + radius * a.cos(),
                center[1] + radius * a.sin(),
                center[2] + height,
            ],
            power_w: uniform(&mut rng, u.ring_power_w),
            color_temperature_k: kelvin,
            tint: blackbody_tint(kelvin),
        });
    }
    let world = world_light(&mut rng, &u.hdris, u.world_strength);
    let look = u.looks[rng.gen_range(0..u.looks.len().max(1))].clone();
    let exposure = uniform(&mut rng, u.exposure);
    let sensor = SensorEffects {
        seed: substream_seed(stream, "sensor_frames"),
        white_balance: None,
        blur_sigma_px: Some(uniform(&mut rng, u.blur_sigma_px)),
        noise_sigma: Some(uniform(&mut rng, u.noise_sigma)),
        jpeg_quality: None,
    };
    Appearance {
        wall,
        floor,
        table,
        lights,
        exposure,
        tone: Some(ToneMapping {
            view_transform: u.view_transform.clone(),
            look,
        }),
        world: Some(world),
        motion_blur: None,
        sensor: Some(sensor),
        ..base
    }
}

/// The sun: from a random azimuth at the drawn elevation, 20 m away.
fn sun(u: &UnseenLookConfig, center: [f64; 3], rng: &mut rand_chacha::ChaCha8Rng) -> Light {
    let elevation = uniform(rng, u.sun_elevation_deg).to_radians();
    let azimuth = uniform(rng, [0.0, std::f64::consts::TAU]);
    let kelvin = uniform(rng, u.color_temperature_k);
    let d = 20.0;
    Light {
        kind: "sun".into(),
        position: [
            center[0] + d * elevation.cos() * azimuth.cos(),
            center[1] + d * elevation.cos() * azimuth.sin(),
            center[2] + d * elevation.sin(),
        ],
        power_w: uniform(rng, u.sun_strength),
        color_temperature_k: kelvin,
        tint: blackbody_tint(kelvin),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::randomize::RandomizeConfig;

    #[test]
    fn defaults_are_valid_and_disjoint_from_training() {
        assert!(DEFAULT_UNSEEN_FAMILIES
            .iter()
            .all(|f| UNSEEN_FAMILIES.contains(f)));
        let a = AppearanceConfig::default();
        a.unseen_look.validate().unwrap();
        a.unseen_look
            .check_disjoint(&a, &RandomizeConfig::default(), "AgX")
            .unwrap();
    }

    #[test]
    fn sample_uses_only_its_own_values() {
        let c = AppearanceConfig::default();
        for s in 0..100 {
            let a = sample(&c, s, s ^ 0xabc, [0.0, 0.0, 0.75], &[]);
            for f in [&a.wall.family, &a.floor.family, &a.table.family] {
                assert!(UNSEEN_FAMILIES.contains(&f.as_str()), "{f}");
            }
            assert_eq!(a.lights[0].kind, "sun");
            assert!((5..=7).contains(&a.lights.len()));
            assert!(a.lights[1..].iter().all(|l| l.kind == "ring"));
            let w = a.world.as_ref().unwrap();
            assert!(c.unseen_look.hdris.contains(&w.hdri));
            assert_eq!(
                a.tone.as_ref().unwrap().view_transform,
                "Khronos PBR Neutral"
            );
            assert!(a.sensor.as_ref().unwrap().blur_sigma_px.unwrap() >= 0.6);
        }
    }
}
