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

//!
//! The config type and its own checks are in [`crate::look::unseen_config`]
//! (re-exported here); the check that training's ranges stay clear of these
//! values is [`crate::randomize::check_unseen_disjoint`].

use crate::appearance::{blackbody_tint, surface, AppearanceConfig};
use crate::look::{lever_rng, uniform, world_light};
use grasp_schema::appearance::{Appearance, Light, SensorEffects, ToneMapping};
use grasp_schema::plan::substream_seed;
use grasp_schema::Condition;
use rand::Rng;

pub use crate::look::unseen_config::{
    UnseenLookConfig, DEFAULT_UNSEEN_FAMILIES, MAX_RING_LIGHTS, UNSEEN_FAMILIES,
    UNSEEN_LIGHT_KINDS, VIEW_TRANSFORMS,
};

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
