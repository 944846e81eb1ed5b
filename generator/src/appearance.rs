//! Domain randomization: samples every appearance value of a sequence (room
//! materials, object material, lights, exposure, hand visibility) from the
//! sequence's own seed. The Blender worker applies the values verbatim, so a
//! sequence can be re-rendered exactly from its `sequence.json`.
//!
//! One texture family (`held_out_family`, a gingham cloth by default) is
//! reserved for the table of the `background` test condition, after the
//! paper's "different background" set; it is never drawn otherwise. The
//! `unseen_look` condition has families, lights and more of its own
//! ([`crate::unseen_look`]); training's further levers are in
//! [`crate::randomize`].

use crate::config::error::{ConfigError, Result};
use grasp_schema::appearance::{Appearance, Light, ObjectMaterial, SurfaceMaterial};
use grasp_schema::Condition;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The families training and the `background` condition draw from.
pub const BASE_FAMILIES: [&str; 8] = [
    "noise", "voronoi", "brick", "checker", "wave", "marble", "image", "gingham",
];
/// The texture families the Blender side knows (`blender_scripts/materials.py`):
/// the base families and those reserved for `unseen_look`.
pub const FAMILIES: [&str; 15] = concat(BASE_FAMILIES, crate::look::unseen_config::UNSEEN_FAMILIES);

/// `a` followed by `b` (`N` must be their total length).
const fn concat<const A: usize, const B: usize, const N: usize>(
    a: [&'static str; A],
    b: [&'static str; B],
) -> [&'static str; N] {
    assert!(A + B == N);
    let mut out = [""; N];
    let mut i = 0;
    while i < N {
        out[i] = if i < A { a[i] } else { b[i - A] };
        i += 1;
    }
    out
}
pub const LIGHT_KINDS: [&str; 3] = ["point", "spot", "area"];

/// Ranges of the randomized appearance values (`[appearance]` in the config).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AppearanceConfig {
    /// Procedural families drawn for walls, floor and table.
    pub families: Vec<String>,
    /// The family reserved for the `background` condition's table.
    pub held_out_family: String,
    /// Optional folder of image textures (png, jpg); `image` materials are
    /// drawn from it with `image_probability`.
    pub image_dir: Option<PathBuf>,
    pub image_probability: f64,
    /// Pattern scale, texture repeats per metre.
    pub scale: [f64; 2],
    pub roughness: [f64; 2],
    /// HSV saturation and value ranges of the random colours.
    pub saturation: [f64; 2],
    pub value: [f64; 2],
    /// Probability that the object's own material is replaced by a random one.
    pub object_randomize_probability: f64,
    /// Number of lights (inclusive range).
    pub lights: [u32; 2],
    pub light_kinds: Vec<String>,
    /// Light positions: an axis-aligned box in the world frame, metres.
    pub light_box_min: [f64; 3],
    pub light_box_max: [f64; 3],
    /// Light power range, watts.
    pub light_power_w: [f64; 2],
    pub color_temperature_k: [f64; 2],
    /// Camera exposure range, stops.
    pub exposure: [f64; 2],
    /// Probability that the hand is partly in view at the top of the frame.
    pub hand_visible: f64,
    /// The `unseen_look` test condition's own appearance.
    pub unseen_look: crate::look::unseen_config::UnseenLookConfig,
}

impl Default for AppearanceConfig {
    fn default() -> Self {
        AppearanceConfig {
            families: ["noise", "voronoi", "brick", "checker", "wave", "marble"]
                .map(String::from)
                .to_vec(),
            held_out_family: "gingham".into(),
            image_dir: None,
            image_probability: 0.25,
            scale: [1.5, 12.0],
            roughness: [0.35, 0.9],
            saturation: [0.05, 0.6],
            value: [0.15, 0.85],
            object_randomize_probability: 0.3,
            lights: [1, 3],
            light_kinds: LIGHT_KINDS.map(String::from).to_vec(),
            light_box_min: [-1.6, -1.8, 1.7],
            light_box_max: [1.6, 1.8, 2.5],
            light_power_w: [80.0, 400.0],
            color_temperature_k: [2700.0, 6500.0],
            exposure: [-0.5, 0.5],
            hand_visible: 0.7,
            unseen_look: Default::default(),
        }
    }
}

impl AppearanceConfig {
    /// Checks names and ranges; errors name the `[appearance]` field.
    pub fn validate(&self) -> Result<()> {
        let known = |f: &str| FAMILIES.contains(&f);
        if self.families.is_empty() {
            return Err(ConfigError::invalid(
                "[appearance] families",
                "the list is empty",
            ));
        }
        for f in &self.families {
            if crate::look::unseen_config::UNSEEN_FAMILIES.contains(&f.as_str()) {
                return Err(ConfigError::invalid("[appearance] families", format!("'{f}' is reserved for the unseen_look condition and may not be drawn in training")));
            }
            if !known(f) || f == "image" {
                return Err(ConfigError::invalid("[appearance] families", format!("unknown procedural family '{f}' (expected some of noise, voronoi, brick, checker, wave, marble, gingham)")));
            }
            if *f == self.held_out_family {
                return Err(ConfigError::invalid("[appearance] families", format!("'{f}' is the held-out family and may only be used for the background condition")));
            }
        }
        if !known(&self.held_out_family)
            || self.held_out_family == "image"
            || crate::look::unseen_config::UNSEEN_FAMILIES.contains(&self.held_out_family.as_str())
        {
            return Err(ConfigError::invalid(
                "[appearance] held_out_family",
                format!("unknown family '{}'", self.held_out_family),
            ));
        }
        for k in &self.light_kinds {
            ConfigError::check_one_of("[appearance] light_kinds", k, &LIGHT_KINDS)?;
        }
        if self.light_kinds.is_empty() {
            return Err(ConfigError::invalid(
                "[appearance] light_kinds",
                "the list is empty",
            ));
        }
        // The Blender side pools 4 lights per kind.
        if self.lights[1] > 4 || self.lights[0] > self.lights[1] {
            return Err(ConfigError::invalid(
                "[appearance] lights",
                "need min <= max <= 4",
            ));
        }
        let ranges = [
            ("scale", self.scale),
            ("roughness", self.roughness),
            ("saturation", self.saturation),
            ("value", self.value),
            ("light_power_w", self.light_power_w),
            ("color_temperature_k", self.color_temperature_k),
            ("exposure", self.exposure),
        ];
        for (name, [lo, hi]) in ranges {
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(ConfigError::invalid(
                    format!("[appearance] {name}"),
                    format!("need a finite range [min, max], got [{lo}, {hi}]"),
                ));
            }
        }
        if self.color_temperature_k[0] < 1000.0 || self.color_temperature_k[1] > 25000.0 {
            return Err(ConfigError::invalid(
                "[appearance] color_temperature_k",
                "supported range is 1000 to 25000 K",
            ));
        }
        for (name, p) in [
            ("image_probability", self.image_probability),
            (
                "object_randomize_probability",
                self.object_randomize_probability,
            ),
            ("hand_visible", self.hand_visible),
        ] {
            if !(0.0..=1.0).contains(&p) {
                return Err(ConfigError::invalid(
                    format!("[appearance] {name}"),
                    format!("a probability must be in [0, 1], got {p}"),
                ));
            }
        }
        self.unseen_look.validate()
    }

    /// The image textures, sorted by name so draws are reproducible.
    pub fn images(&self) -> Result<Vec<String>> {
        let Some(dir) = &self.image_dir else {
            return Ok(Vec::new());
        };
        list_images(dir)
    }
}

fn list_images(dir: &Path) -> Result<Vec<String>> {
    let cannot_read = |source| ConfigError::Read {
        field: "[appearance] image_dir",
        path: dir.to_path_buf(),
        source,
    };
    let entries = std::fs::read_dir(dir).map_err(cannot_read)?;
    let mut images = Vec::new();
    for entry in entries {
        let path = entry.map_err(cannot_read)?.path();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if matches!(ext.as_deref(), Some("png" | "jpg" | "jpeg")) {
            let abs = std::fs::canonicalize(&path).unwrap_or(path);
            images.push(abs.to_string_lossy().into_owned());
        }
    }
    images.sort();
    Ok(images)
}

/// Samples the appearance of one sequence. `seed` is the sequence's
/// `appearance` sub-stream seed; the same inputs always give the same output.
pub fn sample(config: &AppearanceConfig, condition: Condition, seed: u64) -> Appearance {
    let images = config.images().unwrap_or_default();
    sample_with_images(config, condition, seed, &images)
}

/// [`sample`] with the image list given (listing a folder per sequence is
/// wasteful in long runs).
pub fn sample_with_images(
    config: &AppearanceConfig,
    condition: Condition,
    seed: u64,
    images: &[String],
) -> Appearance {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let wall = surface(config, images, &mut rng, None);
    let floor = surface(config, images, &mut rng, None);
    let held_out = (condition == Condition::Background).then_some(config.held_out_family.as_str());
    let table = surface(config, images, &mut rng, held_out);
    let randomized = rng.gen_bool(config.object_randomize_probability);
    let object = ObjectMaterial {
        randomized,
        color: random_color(config, &mut rng),
        roughness: uniform(&mut rng, config.roughness),
        plausible: false,
        surface: None,
    };
    let count = rng.gen_range(config.lights[0]..=config.lights[1].max(config.lights[0]));
    let lights = (0..count).map(|_| light(config, &mut rng)).collect();
    Appearance {
        wall,
        floor,
        table,
        object,
        lights,
        exposure: uniform(&mut rng, config.exposure),
        hand_visible: rng.gen_bool(config.hand_visible),
        tone: None,
        world: None,
        motion_blur: None,
        sensor: None,
    }
}

fn uniform(rng: &mut ChaCha8Rng, [lo, hi]: [f64; 2]) -> f64 {
    if hi > lo {
        rng.gen_range(lo..hi)
    } else {
        lo
    }
}

pub(crate) fn surface(
    config: &AppearanceConfig,
    images: &[String],
    rng: &mut ChaCha8Rng,
    forced_family: Option<&str>,
) -> SurfaceMaterial {
    // Draw every value whatever the family, so the stream never shifts.
    let use_image = rng.gen_bool(config.image_probability) && !images.is_empty();
    let image_index = rng.gen_range(0..images.len().max(1));
    let family_index = rng.gen_range(0..config.families.len().max(1));
    let color_a = random_color(config, rng);
    let color_b = random_color(config, rng);
    // Log-uniform: small and large patterns equally likely per octave.
    let [lo, hi] = config.scale;
    let scale = (uniform(rng, [lo.max(1e-6).ln(), hi.max(1e-6).ln()])).exp();
    let roughness = uniform(rng, config.roughness);
    let detail = rng.gen_range(0.0..1.0);
    let (family, image) = match forced_family {
        Some(f) => (f.to_string(), None),
        None if use_image => ("image".to_string(), Some(images[image_index].clone())),
        None => (
            config
                .families
                .get(family_index)
                .cloned()
                .unwrap_or_else(|| "noise".into()),
            None,
        ),
    };
    SurfaceMaterial {
        family,
        color_a,
        color_b,
        scale,
        roughness,
        detail,
        image,
    }
}

fn random_color(config: &AppearanceConfig, rng: &mut ChaCha8Rng) -> [f64; 3] {
    let h = rng.gen_range(0.0..1.0);
    let s = uniform(rng, config.saturation);
    let v = uniform(rng, config.value);
    hsv_to_linear_rgb(h, s, v)
}

fn light(config: &AppearanceConfig, rng: &mut ChaCha8Rng) -> Light {
    let kind = config.light_kinds[rng.gen_range(0..config.light_kinds.len())].clone();
    let position =
        std::array::from_fn(|i| uniform(rng, [config.light_box_min[i], config.light_box_max[i]]));
    let power_w = uniform(rng, config.light_power_w);
    let color_temperature_k = uniform(rng, config.color_temperature_k);
    Light {
        kind,
        position,
        power_w,
        color_temperature_k,
        tint: blackbody_tint(color_temperature_k),
    }
}

/// HSV (sRGB-encoded) to linear RGB, the space Blender's shader colours use.
pub fn hsv_to_linear_rgb(h: f64, s: f64, v: f64) -> [f64; 3] {
    let h6 = (h.rem_euclid(1.0)) * 6.0;
    let c = v * s;
    let x = c * (1.0 - ((h6 % 2.0) - 1.0).abs());
    let (r, g, b) = match h6 as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    [r + m, g + m, b + m].map(srgb_to_linear)
}

fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear-sRGB colour of a black body at `kelvin` (1667 to 25000 K), scaled
/// so its largest channel is 1. Closed form: the Kim et al. cubic fit of the
/// Planckian locus in CIE 1931 xy, then XYZ to linear sRGB.
pub fn blackbody_tint(kelvin: f64) -> [f64; 3] {
    let t = kelvin.clamp(1667.0, 25000.0);
    let (t1, t2, t3) = (1e3 / t, 1e6 / (t * t), 1e9 / (t * t * t));
    let x = if t <= 4000.0 {
        -0.2661239 * t3 - 0.2343589 * t2 + 0.8776956 * t1 + 0.179910
    } else {
        -3.0258469 * t3 + 2.1070379 * t2 + 0.2226347 * t1 + 0.240390
    };
    let y = if t <= 2222.0 {
        -1.1063814 * x.powi(3) - 1.34811020 * x.powi(2) + 2.18555832 * x - 0.20219683
    } else if t <= 4000.0 {
        -0.9549476 * x.powi(3) - 1.37418593 * x.powi(2) + 2.09137015 * x - 0.16748867
    } else {
        3.0817580 * x.powi(3) - 5.87338670 * x.powi(2) + 3.75112997 * x - 0.37001483
    };
    let (cx, cz) = (x / y, (1.0 - x - y) / y);
    let rgb = [
        3.2404542 * cx - 1.5371385 - 0.4985314 * cz,
        -0.9692660 * cx + 1.8760108 + 0.0415560 * cz,
        0.0556434 * cx - 0.2040259 + 1.0572252 * cz,
    ]
    .map(|c: f64| c.max(0.0));
    let max = rgb.iter().cloned().fold(f64::MIN, f64::max).max(1e-9);
    rgb.map(|c| c / max)
}

/// A stable, muted colour per object id (the catalog carries no materials):
/// a hue from a hash of the id.
pub fn default_object_color(object: &str) -> [f64; 3] {
    let [h, s, v] = default_object_hsv(object);
    hsv_to_linear_rgb(h, s, v)
}

/// [`default_object_color`] as HSV (of its sRGB colour).
pub fn default_object_hsv(object: &str) -> [f64; 3] {
    let hash = object.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    });
    [(hash % 360) as f64 / 360.0, 0.55, 0.75]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_appearance_and_seeds_differ() {
        let c = AppearanceConfig::default();
        let a = sample(&c, Condition::Default, 7);
        assert_eq!(a, sample(&c, Condition::Default, 7));
        assert_ne!(a, sample(&c, Condition::Default, 8));
    }

    #[test]
    fn held_out_family_only_for_background_tables() {
        let c = AppearanceConfig::default();
        c.validate().unwrap();
        for seed in 0..300 {
            for cond in Condition::ALL {
                let a = sample(&c, cond, seed);
                let fams = [&a.wall.family, &a.floor.family, &a.table.family];
                if cond == Condition::Background {
                    assert_eq!(a.table.family, "gingham");
                    assert_ne!(a.wall.family, "gingham");
                } else {
                    assert!(fams.iter().all(|f| *f != "gingham"), "{cond}: {fams:?}");
                }
            }
        }
    }

    #[test]
    fn draws_cover_the_configured_ranges() {
        let c = AppearanceConfig::default();
        let all: Vec<_> = (0..500)
            .map(|s| sample(&c, Condition::Default, s))
            .collect();
        for fam in &c.families {
            assert!(
                all.iter().any(|a| &a.wall.family == fam),
                "{fam} never drawn"
            );
        }
        let n_lights: Vec<usize> = all.iter().map(|a| a.lights.len()).collect();
        assert_eq!(*n_lights.iter().min().unwrap(), 1);
        assert_eq!(*n_lights.iter().max().unwrap(), 3);
        let visible = all.iter().filter(|a| a.hand_visible).count() as f64 / 500.0;
        assert!((0.6..0.8).contains(&visible), "{visible}");
        for a in &all {
            assert!(a.exposure >= -0.5 && a.exposure < 0.5);
            assert!(a.wall.scale >= 1.5 && a.wall.scale <= 12.0);
            for l in &a.lights {
                assert!(l.position[2] >= 1.7 && l.position[2] <= 2.5);
                assert!(l.tint.iter().all(|t| (0.0..=1.0).contains(t)));
            }
        }
    }

    #[test]
    fn blackbody_is_warm_to_cold_and_white_near_6500k() {
        let warm = blackbody_tint(2000.0);
        assert!(warm[0] == 1.0 && warm[2] < 0.2, "{warm:?}");
        // The Planckian locus passes just below D65 (slightly magenta).
        let white = blackbody_tint(6504.0);
        assert!(white.iter().all(|c| *c > 0.9), "{white:?}");
        let cold = blackbody_tint(25000.0);
        assert!(cold[2] == 1.0 && cold[0] < 0.8, "{cold:?}");
        // Extremes are clamped, never NaN.
        assert!(blackbody_tint(0.0).iter().all(|c| c.is_finite()));
        assert!(blackbody_tint(1e9).iter().all(|c| c.is_finite()));
    }

    #[test]
    fn hsv_primaries() {
        assert_eq!(hsv_to_linear_rgb(0.0, 1.0, 1.0), [1.0, 0.0, 0.0]);
        assert_eq!(hsv_to_linear_rgb(1.0 / 3.0, 1.0, 1.0), [0.0, 1.0, 0.0]);
        assert_eq!(hsv_to_linear_rgb(0.5, 0.0, 0.0), [0.0, 0.0, 0.0]);
    }

    #[test]
    fn bad_config_names_the_field() {
        let c = AppearanceConfig {
            families: vec!["gingham".into()],
            ..Default::default()
        };
        assert!(format!("{:#}", c.validate().unwrap_err()).contains("held-out"));
        let c = AppearanceConfig {
            hand_visible: 1.5,
            ..Default::default()
        };
        assert!(format!("{:#}", c.validate().unwrap_err()).contains("hand_visible"));
    }

    #[test]
    fn images_are_drawn_from_the_folder() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["b.png", "a.jpg", "notes.txt"] {
            std::fs::write(dir.path().join(name), b"x").unwrap();
        }
        let c = AppearanceConfig {
            image_dir: Some(dir.path().to_path_buf()),
            image_probability: 1.0,
            ..Default::default()
        };
        let images = c.images().unwrap();
        assert_eq!(images.len(), 2);
        assert!(images[0].ends_with("a.jpg"));
        let a = sample(&c, Condition::Default, 1);
        assert_eq!(a.wall.family, "image");
        assert!(images.contains(a.wall.image.as_ref().unwrap()));
        // The background table still gets the held-out family.
        assert_eq!(sample(&c, Condition::Background, 1).table.family, "gingham");
    }
}
